"""Kinematics of the invisible saddle point S from the marker triangle (thesis 6.4, eq. 6.41-6.55).

Saddle point S (eq. 6.41-6.55): body frame from markers 1-3, S's body coordinates from the
static shot, its position during the ride, and v_S = v_i + ω × r_iS, a_S = a_i + α × r_iS +
ω × (ω × r_iS) from each marker i, averaged, with their spread.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from saddlescope.core.errors import InputError, KinematicsError
from saddlescope.core.kinematics.registration import check_marker_layout
from saddlescope.core.kinematics.rigid_body import AngularKinematics, _check_triplet, unobservable_axis

__all__ = [
    "PointKinematics",
    "body_frame",
    "saddle_body_coordinates",
    "saddle_point_kinematics",
]


@dataclass(frozen=True)
class PointKinematics:
    """Kinematics of the invisible saddle point S in the motion frame.

    position_m, velocity_m_s, acceleration_m_s2 : ndarray of shape (F, 3)
        Position (eq. 6.48) and the mean over the three markers of eq. 6.54 / 6.55.
    velocity_per_marker, acceleration_per_marker : ndarray of shape (F, 3, 3)
        (frame, marker used, component).
    velocity_spread, acceleration_spread : ndarray of shape (F,)
        Largest distance of a per-marker estimate from the mean.
    body_coordinates_m : ndarray of shape (3,)
        S in the body frame (eq. 6.47).
    """

    position_m: np.ndarray
    velocity_m_s: np.ndarray
    acceleration_m_s2: np.ndarray
    velocity_per_marker: np.ndarray
    acceleration_per_marker: np.ndarray
    velocity_spread: np.ndarray
    acceleration_spread: np.ndarray
    body_coordinates_m: np.ndarray


def body_frame(r) -> np.ndarray:
    """Rotation body -> motion from markers 1-3 (eq. 6.41-6.45, 6.49-6.53).

    Parameters
    ----------
    r : ndarray of shape (F, 3, 3) or (3, 3)
        Positions of markers 1-3 (frame, marker, xyz).

    Returns
    -------
    R_MB : ndarray of shape (F, 3, 3) or (3, 3)
        Columns u1 (marker 1 -> 2), u2, u3 (normal).
    """
    x = np.asarray(r, dtype=np.float64)
    single = x.ndim == 2
    x = _check_triplet(x, "r")
    u1 = x[:, 1] - x[:, 0]
    u1 = u1 / np.linalg.norm(u1, axis=1, keepdims=True)  # eq. 6.41
    u2p = x[:, 2] - x[:, 0]
    u2p = u2p / np.linalg.norm(u2p, axis=1, keepdims=True)  # eq. 6.42
    u3 = np.cross(u1, u2p)
    u3 = u3 / np.linalg.norm(u3, axis=1, keepdims=True)  # eq. 6.43
    u2 = np.cross(u3, u1)  # eq. 6.44
    R = np.stack([u1, u2, u3], axis=2)  # eq. 6.45: columns
    return R[0] if single else R


def saddle_body_coordinates(static_markers, static_saddle, *, min_height_ratio: float = 0.03) -> np.ndarray:
    """S in the body frame from the static shot (eq. 6.47).

    Parameters
    ----------
    static_markers : ndarray of shape (3, 3)
        Markers 1-3 in the static shot (any frame, e.g. motion m or rig mm).
    static_saddle : ndarray of shape (3,)
        The saddle marker S in the same frame and units.

    Returns
    -------
    r_BS : ndarray of shape (3,)
        S relative to marker 1 in body axes (same units).
    """
    m = np.asarray(static_markers, dtype=np.float64)
    s = np.asarray(static_saddle, dtype=np.float64).reshape(-1)
    if m.shape != (3, 3) or s.shape != (3,):
        raise InputError(f"static_markers must be (3, 3) and static_saddle (3,), got {m.shape} and {s.shape}")
    if not (np.all(np.isfinite(m)) and np.all(np.isfinite(s))):
        raise KinematicsError("the static shot lacks a horse marker or the saddle marker")
    check_marker_layout(m, min_height_ratio=min_height_ratio, what="the static-shot markers")
    return body_frame(m).T @ (s - m[0])


def _position_with_weak_axis_shrunk(r: np.ndarray, rot: np.ndarray, r_bs: np.ndarray, gain: float,
                                    position: np.ndarray) -> np.ndarray:
    """S's position (F, 3) (eq. 6.48) with the rotation about the markers' weakest axis shrunk.

    That rotation is kept at ``gain`` of its deviation from the mean orientation, as ω keeps it:
    the same depth noise that swamps roll in ω makes the registered roll wander (on the thesis rig
    each marker's straight depth path has its own slope, and 0.3 m above the row S drifted 6 cm in
    two strides). The rotation is taken about the markers' centroid, the point they fix best.
    """
    from scipy.spatial.transform import Rotation

    ok = np.all(np.isfinite(rot), axis=(1, 2))
    if ok.sum() < 2:
        return position
    f0 = int(np.flatnonzero(ok)[0])
    body = rot[f0].T @ (r[f0] - r[f0, 0]).T  # markers in body coordinates (3, marker), constant
    axis_b, _ = unobservable_axis(body.T[None], min_eig_ratio=0.0)  # the weakest axis, body coordinates
    rots = Rotation.from_matrix(rot[ok])
    mean = rots.mean()
    phi = (mean.inv() * rots).as_rotvec()  # R(t) = R_mean exp([phi(t)]), phi in body coordinates
    phi_w = phi @ axis_b
    phi = phi + np.outer((gain - 1.0) * (phi_w - phi_w.mean()), axis_b)
    rot_kept = (mean * Rotation.from_rotvec(phi)).as_matrix()
    centroid_b = body.mean(axis=1)
    out = position.copy()
    out[ok] = r[ok].mean(axis=1) + np.einsum("fij,j->fi", rot_kept, r_bs - centroid_b)
    return out


def saddle_point_kinematics(r, v, a, angular: AngularKinematics, r_bs) -> PointKinematics:
    """Position, velocity and acceleration of the invisible point S (eq. 6.48, 6.54-6.55).

    Parameters
    ----------
    r, v, a : ndarray of shape (F, 3, 3)
        Registered positions (m), velocities (m/s) and accelerations (m/s²) of markers 1-3.
    angular : AngularKinematics
        Its ``omega_rad_s`` and ``alpha_rad_s2`` are used.
    r_bs : ndarray of shape (3,)
        S in body coordinates (m), from :func:`saddle_body_coordinates`.

    Returns
    -------
    PointKinematics
    """
    r = _check_triplet(r, "r")
    v = _check_triplet(v, "v")
    a = _check_triplet(a, "a")
    r_bs = np.asarray(r_bs, dtype=np.float64).reshape(3)
    rot = body_frame(r)
    position = np.einsum("fij,j->fi", rot, r_bs) + r[:, 0]  # eq. 6.48
    gain = None if angular.weak_axis_gain is None else angular.weak_axis_gain[0]
    if gain is not None and gain < 1.0:
        position = _position_with_weak_axis_shrunk(r, rot, r_bs, gain, position)
    w = angular.omega_rad_s
    al = angular.alpha_rad_s2
    r_is = position[:, None, :] - r  # (F, marker, 3): from marker i to S
    w3 = np.broadcast_to(w[:, None, :], r_is.shape)
    a3 = np.broadcast_to(al[:, None, :], r_is.shape)
    v_per = v + np.cross(w3, r_is)  # eq. 6.54
    a_per = a + np.cross(a3, r_is) + np.cross(w3, np.cross(w3, r_is))  # eq. 6.55
    v_mean = v_per.mean(axis=1)
    a_mean = a_per.mean(axis=1)
    return PointKinematics(
        position_m=position, velocity_m_s=v_mean, acceleration_m_s2=a_mean, velocity_per_marker=v_per,
        acceleration_per_marker=a_per,
        velocity_spread=np.linalg.norm(v_per - v_mean[:, None], axis=2).max(axis=1),
        acceleration_spread=np.linalg.norm(a_per - a_mean[:, None], axis=2).max(axis=1),
        body_coordinates_m=r_bs)
