"""Angular kinematics of the marker triangle (thesis 6.1-6.4).

Angular velocity. For three markers the thesis writes v_i = v_j + ω × r_ji (r_ji: from marker j
to marker i) for the two other markers j, k and solves the pair in closed form (eq. 6.3-6.4,
from eq. 6.13-6.14): ω¹ = (v_j − v_i) × (v_k − v_i) / (−r_ki · (v_j − v_i)) and
ω² = (v_j − v_i) × (v_k − v_i) / (r_ji · (v_k − v_i)). Three choices of the reference marker i give
six versions. All share the singularity ω · n = 0 (eq. 6.35), n the normal of the markers'
plane: numerator and denominator both vanish. With markers in a row on the horse's side n is
lateral, so a roll or yaw (ω in the markers' plane) is singular while pitch (ω along n) is not.

The closed forms are only ill-conditioned, not short of information: with three non-collinear
markers the pairwise relations v_j − v_i = ω × (r_j − r_i) determine ω fully. The least-squares
solution over all pairs is therefore the default estimate; the versions are kept for comparison
with the thesis, with their spread and a per-version conditioning index, and those near their
singularity are excluded from their mean (and flagged).

Markers in a near row fix rotation about the row poorly: a millimetre of skin motion over a few
centimetres of the row's height reads as degrees of roll. The pipeline's estimate ("lsq_wiener")
keeps that weakest axis in proportion to how far its measured power exceeds what skin motion
predicts there. The prediction comes from the unregistered markers: their non-rigid part (the
residual of the rigid least-squares fit) gives the skin motion's size, and the markers' geometry its
effect on the weak axis. Rigid markers keep every axis whole (exact answers); skin motion that
swamps the roll drops it, as "lsq_observable" always does for a near row.

Angular acceleration (eq. 6.36-6.39): α × r_ji = a_i − a_j − ω × (ω × r_ji). The thesis prints
the known vectors of eq. 6.38-6.39 as a_j + ω × (ω × r_ji), dropping a_i; the derivation
(eq. 6.13-6.14 applied to eq. 6.36-6.37) gives K2 = a_j − a_i + ω × (ω × r_ji), used here.

The invisible saddle point follows from them in :mod:`saddlescope.core.kinematics.saddle_point`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from saddlescope.core.errors import InputError, KinematicsError
from saddlescope.core.findings import Finding
from saddlescope.core.kinematics.registration import check_marker_layout

__all__ = [
    "VERSION_NAMES",
    "ANGULAR_METHODS",
    "AngularKinematics",
    "unobservable_axis",
    "weak_axis_gain",
    "omega_versions",
    "alpha_versions",
    "omega_least_squares",
    "alpha_least_squares",
    "plane_normal",
    "singularity_index",
    "angular_kinematics",
]

# (reference marker i, other markers j, k) of versions 1-3 (thesis "ver1".."ver3").
_VERSIONS = ((0, 1, 2), (1, 0, 2), (2, 0, 1))
VERSION_NAMES = ("1,ver1", "2,ver1", "1,ver2", "2,ver2", "1,ver3", "2,ver3")
_PAIRS = ((0, 1), (0, 2), (1, 2))
ANGULAR_METHODS = ("lsq", "lsq_observable", "lsq_wiener", "versions")


@dataclass(frozen=True)
class AngularKinematics:
    """Angular velocity and acceleration of the marker triangle, with diagnostics.

    omega_rad_s, alpha_rad_s2 : ndarray of shape (F, 3)
        The final estimates (``method``).
    omega_lsq, alpha_lsq : ndarray of shape (F, 3)
        Least squares over the three marker pairs.
    omega_versions, alpha_versions : ndarray of shape (F, 6, 3)
        The six closed-form versions (eq. 6.3-6.4, 6.38-6.39), order of ``VERSION_NAMES``.
    omega_versions_mean, alpha_versions_mean : ndarray of shape (F, 3)
        Mean of the versions not excluded (NaN where all are excluded).
    version_conditioning : ndarray of shape (F, 6)
        |cos| of the angle between the two vectors of each version's denominator: near 0 the
        version divides by nearly zero.
    excluded : ndarray of bool, shape (F, 6)
        Versions left out of the mean (conditioning below the threshold).
    singularity_index : ndarray of shape (F,)
        |n · ω̂| (eq. 6.35): 1 = ω normal to the markers' plane (best), 0 = singular.
    omega_spread, alpha_spread : ndarray of shape (F,)
        Largest distance of a kept version from the least-squares estimate (rad/s, rad/s²).
    normal : ndarray of shape (F, 3)
        Unit normal n of the markers' plane (eq. 6.33).
    method : str
        ``"lsq"``, ``"lsq_observable"``, ``"lsq_wiener"`` or ``"versions"``.
    flags : tuple of Finding
    weak_axis_gain : tuple of float or None
        (ω, α) gains on the weakest rotation axis (``"lsq_wiener"`` only).
    """

    omega_rad_s: np.ndarray
    alpha_rad_s2: np.ndarray
    omega_lsq: np.ndarray
    alpha_lsq: np.ndarray
    omega_versions: np.ndarray
    alpha_versions: np.ndarray
    omega_versions_mean: np.ndarray
    alpha_versions_mean: np.ndarray
    version_conditioning: np.ndarray
    excluded: np.ndarray
    singularity_index: np.ndarray
    omega_spread: np.ndarray
    alpha_spread: np.ndarray
    normal: np.ndarray
    method: str
    flags: tuple[Finding, ...] = ()
    weak_axis_gain: tuple[float, float] | None = None

    @property
    def median_singularity_index(self) -> float:
        """One number for the result's ``angular.singularity_index``."""
        s = self.singularity_index[np.isfinite(self.singularity_index)]
        return float(np.median(s)) if s.size else float("nan")



def _check_triplet(x, name: str) -> np.ndarray:
    x = np.asarray(x, dtype=np.float64)
    if x.ndim == 2:
        x = x[None]
    if x.ndim != 3 or x.shape[1:] != (3, 3):
        raise InputError(f"{name} must have shape (F, 3, 3) (frame, marker, xyz) for three markers, "
                         f"got {x.shape}")
    return x


def _pair_differences(x: np.ndarray) -> np.ndarray:
    """x_j − x_i for the marker pairs (1,2), (1,3), (2,3): (F, 3, 3) -> (F, P, 3)."""
    return np.stack([x[:, j] - x[:, i] for i, j in _PAIRS], axis=1)


def _pair_normal(d: np.ndarray) -> np.ndarray:
    """Normal matrix sum_p [d_p]×^T [d_p]× = sum_p (|d_p|² I − d_p d_pᵀ) of the pairs d (F, P, 3)."""
    dd = np.einsum("fpi,fpi->fp", d, d)
    return np.einsum("fp,ij->fij", dd, np.eye(3)) - np.einsum("fpi,fpj->fij", d, d)


def _skew_lsq(d: np.ndarray, rhs: np.ndarray, min_eig_ratio: float = 0.0, weak_gain: float | None = None
              ) -> np.ndarray:
    """Least-squares u of u × d_p = rhs_p over pairs p, per frame.

    d, rhs : (F, P, 3) -> u : (F, 3). u × d = -[d]× u, so the normal matrix is
    sum_p [d]×^T [d]× = sum_p (|d|² I − d dᵀ) and the right side sum_p -[d]×^T rhs = sum_p d × rhs.
    ``weak_gain`` scales the component along the normal matrix's weakest eigenvector (the
    shrinkage of :func:`weak_axis_gain`).
    """
    normal = _pair_normal(d)
    b = np.sum(np.cross(d, rhs), axis=1)
    out = np.full(b.shape, np.nan)
    ok = np.all(np.isfinite(normal), axis=(1, 2)) & np.all(np.isfinite(b), axis=1)
    if ok.any():
        e, V = np.linalg.eigh(normal[ok])
        # a (pseudo-)inverse: rotation about a direction the marker pairs barely span (the axis of a
        # near line of markers, below min_eig_ratio) is not observable and is left out (set to 0);
        # markers on one point span nothing (NaN)
        inv = np.where(e > max(min_eig_ratio, 1e-12) * e[:, -1:], 1.0 / np.maximum(e, 1e-300), 0.0)
        if weak_gain is not None:
            inv[:, 0] *= weak_gain
        u = np.einsum("fij,fj,fkj,fk->fi", V, inv, V, b[ok])
        u[~(e[:, -1] > 0)] = np.nan
        out[ok] = u
    return out


def unobservable_axis(r, *, min_eig_ratio: float) -> tuple[np.ndarray, float]:
    """The least observable rotation axis of the marker triangle and its eigenvalue ratio.

    Parameters
    ----------
    r : ndarray of shape (F, 3, 3)
        Marker positions (frame, marker, xyz); frames with a missing marker are ignored.
    min_eig_ratio : float
        The ratio below which rotation about the axis counts as unobservable (for the caller).

    Returns
    -------
    axis : ndarray of shape (3,)
        Unit axis, in the frame of ``r``.
    ratio : float
        Median ratio of the smallest to the largest eigenvalue of the pairs' normal matrix. A ratio
        below ``min_eig_ratio`` means the angular velocity component about that axis is not
        observable from the markers (they lie near a line along it).
    """
    r = _check_triplet(r, "r")
    d = _pair_differences(r)
    ok = np.all(np.isfinite(d), axis=(1, 2))
    e, V = np.linalg.eigh(_pair_normal(d[ok]))
    axis = np.median(V[:, :, 0] * np.sign(V[:, :1, 0] + 1e-12), axis=0)
    return axis / np.linalg.norm(axis), float(np.median(e[:, 0] / e[:, -1]))


def _weak_component_and_noise(d: np.ndarray, rhs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per frame: the least-squares u's component along the weakest axis, and its noise variance.

    The variance is predicted from the fit's own residual (isotropic noise of std σ on each marker
    coordinate: residual sum of squares over the pairs = 9 σ², weak-axis variance = 3 σ² / e_min).
    """
    normal = _pair_normal(d)
    b = np.sum(np.cross(d, rhs), axis=1)
    ok = np.all(np.isfinite(normal), axis=(1, 2)) & np.all(np.isfinite(b), axis=1)
    e, V = np.linalg.eigh(normal[ok])
    # frames whose raw markers fall (almost) on one point or line say nothing about the weak axis
    keep = e[:, 0] > 1e-9 * np.maximum(e[:, -1], 1e-300)
    e, V, d_k, rhs_k, b_k = e[keep], V[keep], d[ok][keep], rhs[ok][keep], b[ok][keep]
    u = np.einsum("fij,fj,fkj,fk->fi", V, 1.0 / e, V, b_k)
    resid = rhs_k - np.cross(u[:, None, :], d_k)
    ss = np.einsum("fpi,fpi->f", resid, resid)
    return np.einsum("fi,fi->f", u, V[:, :, 0]), ss / (3.0 * e[:, 0])


def weak_axis_gain(r_raw, v_raw, a_raw, *, over_subtraction: float = 3.0) -> tuple[float, float]:
    """Wiener gains (0-1) for the weakest rotation axis of ω and of α, from unregistered markers.

    Registered markers are rigid by construction, so they hide how much of their rotation is skin
    motion. The raw fitted velocities and accelerations keep the non-rigid part: its size (the
    least-squares residual) predicts the noise of the weak-axis component, and the gain is
    1 − noise power / measured power (0 when the component is no larger than its noise).

    Parameters
    ----------
    r_raw, v_raw, a_raw : ndarray of shape (F, 3, 3)
        Unregistered marker positions (m) and their fitted velocities (m/s) and accelerations
        (m/s²), (frame, marker, xyz).
    over_subtraction : float, optional
        Factor on the predicted noise power (see the comment in the code).

    Returns
    -------
    gain_omega, gain_alpha : float
        Gains in [0, 1] on the weakest axis of ω and of α.
    """
    r, v, a = (_check_triplet(x, n) for x, n in ((r_raw, "r"), (v_raw, "v"), (a_raw, "a")))
    d = _pair_differences(r)
    dv = _pair_differences(v)
    w_weak, w_noise = _weak_component_and_noise(d, dv)
    w = omega_least_squares(r, v)
    da = _pair_differences(a)
    w3 = np.broadcast_to(w[:, None, :], d.shape)
    a_weak, a_noise = _weak_component_and_noise(d, da - np.cross(w3, np.cross(w3, d)))

    def gain(comp, noise):
        if comp.size == 0:
            return 0.0
        power = float(np.mean(comp ** 2))
        # The residual can underestimate the skin motion on the weak axis itself (the rigid fit takes
        # part of it for rotation there), so the predicted noise is over-subtracted. Exact markers of
        # 80 synthetic wide-rig rides (20 seeds per gait; walk / trots / canter, vertical error mean
        # and worst %): factor 1 kept up to 67 % of a roll that was all skin motion, 17.2 / 5.4 / 8.8,
        # worst 78 / 24 / 37; factor 3: 11.1 / 4.0 / 6.1, worst 25 / 7.3 / 12; factor 6 (near dropping
        # the axis): 10.5 / 3.7 / 5.8, worst 17 / 6.0 / 9.3, but with small random skin sliding
        # (skin_motion="noise") it lost real roll: trots 1.3 -> 2.6, canter 1.7 -> 3.3 (factor 3: 2.2, 2.5).
        return float(np.clip(1.0 - over_subtraction * np.mean(noise) / power, 0.0, 1.0)) if power > 0 else 0.0

    return gain(w_weak, w_noise), gain(a_weak, a_noise)


def _closed_form(k1: np.ndarray, k2: np.ndarray, k3: np.ndarray, k4: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Both solutions of K1 × u = K2, K3 × u = K4 (eq. 6.13-6.14) and their conditioning."""
    num = np.cross(k2, k4)
    den1 = -np.einsum("fi,fi->f", k2, k3)
    den2 = np.einsum("fi,fi->f", k1, k4)
    with np.errstate(divide="ignore", invalid="ignore"):
        u1 = num / den1[:, None]
        u2 = num / den2[:, None]
        c1 = np.abs(den1) / (np.linalg.norm(k2, axis=1) * np.linalg.norm(k3, axis=1))
        c2 = np.abs(den2) / (np.linalg.norm(k1, axis=1) * np.linalg.norm(k4, axis=1))
    return u1, u2, np.nan_to_num(c1, nan=0.0), np.nan_to_num(c2, nan=0.0)


def omega_versions(r, v) -> tuple[np.ndarray, np.ndarray]:
    """The six closed-form angular velocities (eq. 6.3-6.4 for each reference marker).

    Parameters
    ----------
    r, v : ndarray of shape (F, 3, 3)
        Marker positions (m) and velocities (m/s), (frame, marker, xyz).

    Returns
    -------
    versions : ndarray of shape (F, 6, 3)
        In the order of ``VERSION_NAMES``; inf/NaN at exact singularities.
    conditioning : ndarray of shape (F, 6)
        |cos| between the two vectors of each denominator (0 = singular).
    """
    r = _check_triplet(r, "r")
    v = _check_triplet(v, "v")
    out = np.empty((r.shape[0], 6, 3))
    cond = np.empty((r.shape[0], 6))
    for n, (i, j, k) in enumerate(_VERSIONS):
        # v_i = v_j + ω × r_ji  <=>  r_ji × ω = v_j − v_i (K1 = r_ji, K2 = v_j − v_i); eq. 6.15-6.18.
        k1, k2 = r[:, i] - r[:, j], v[:, j] - v[:, i]
        k3, k4 = r[:, i] - r[:, k], v[:, k] - v[:, i]
        out[:, 2 * n], out[:, 2 * n + 1], cond[:, 2 * n], cond[:, 2 * n + 1] = _closed_form(k1, k2, k3, k4)
    return out, cond


def alpha_versions(r, a, omega) -> tuple[np.ndarray, np.ndarray]:
    """The six closed-form angular accelerations (eq. 6.38-6.39, with the relative a_j − a_i).

    Parameters
    ----------
    r, a : ndarray of shape (F, 3, 3)
        Marker positions (m) and accelerations (m/s²).
    omega : ndarray of shape (F, 3)
        The angular velocity used in the centripetal terms.

    Returns
    -------
    versions : ndarray of shape (F, 6, 3)
        In the order of ``VERSION_NAMES`` (rad/s²); inf/NaN at exact singularities.
    conditioning : ndarray of shape (F, 6)
        |cos| between the two vectors of each denominator (0 = singular).
    """
    r = _check_triplet(r, "r")
    a = _check_triplet(a, "a")
    w = np.asarray(omega, dtype=np.float64).reshape(-1, 3)
    out = np.empty((r.shape[0], 6, 3))
    cond = np.empty((r.shape[0], 6))
    for n, (i, j, k) in enumerate(_VERSIONS):
        rji, rki = r[:, i] - r[:, j], r[:, i] - r[:, k]
        # a_i = a_j + ω × (ω × r_ji) + α × r_ji  <=>  r_ji × α = a_j − a_i + ω × (ω × r_ji)  (eq. 6.36)
        k2 = a[:, j] - a[:, i] + np.cross(w, np.cross(w, rji))
        k4 = a[:, k] - a[:, i] + np.cross(w, np.cross(w, rki))
        out[:, 2 * n], out[:, 2 * n + 1], cond[:, 2 * n], cond[:, 2 * n + 1] = _closed_form(rji, k2, rki, k4)
    return out, cond


def omega_least_squares(r, v, *, min_eig_ratio: float = 0.0, weak_gain: float | None = None) -> np.ndarray:
    """Angular velocity from all marker pairs: v_j − v_i = ω × (r_j − r_i), least squares per frame.

    Parameters
    ----------
    r, v : ndarray of shape (F, 3, 3)
        Marker positions (m) and velocities (m/s), (frame, marker, xyz).
    min_eig_ratio : float, optional
        Rotation about an axis whose eigenvalue of the pairs' normal matrix is below this fraction
        of the largest is left out (taken as zero).
    weak_gain : float, optional
        Gain on the component about the weakest axis (see :func:`weak_axis_gain`).

    Returns
    -------
    omega : ndarray of shape (F, 3)
        Angular velocity (rad/s); NaN where a marker is missing.
    """
    r = _check_triplet(r, "r")
    v = _check_triplet(v, "v")
    d = _pair_differences(r)
    dv = _pair_differences(v)
    return _skew_lsq(d, dv, min_eig_ratio, weak_gain)


def alpha_least_squares(r, a, omega, *, min_eig_ratio: float = 0.0, weak_gain: float | None = None
                        ) -> np.ndarray:
    """Angular acceleration from all pairs: a_j − a_i − ω × (ω × d) = α × d, d = r_j − r_i.

    Parameters
    ----------
    r, a : ndarray of shape (F, 3, 3)
        Marker positions (m) and accelerations (m/s²), (frame, marker, xyz).
    omega : ndarray of shape (F, 3)
        Angular velocity (rad/s) of the centripetal terms.
    min_eig_ratio, weak_gain : optional
        As in :func:`omega_least_squares`.

    Returns
    -------
    alpha : ndarray of shape (F, 3)
        Angular acceleration (rad/s²).
    """
    r = _check_triplet(r, "r")
    a = _check_triplet(a, "a")
    w = np.asarray(omega, dtype=np.float64).reshape(-1, 3)
    d = _pair_differences(r)
    da = _pair_differences(a)
    w3 = np.broadcast_to(w[:, None, :], d.shape)
    return _skew_lsq(d, da - np.cross(w3, np.cross(w3, d)), min_eig_ratio, weak_gain)


def plane_normal(r) -> np.ndarray:
    """Unit normal of the markers' plane, n = r21 × r31 / |r21 × r31| (eq. 6.33).

    Parameters
    ----------
    r : ndarray of shape (F, 3, 3)
        Marker positions (frame, marker, xyz).

    Returns
    -------
    n : ndarray of shape (F, 3)
    """
    r = _check_triplet(r, "r")
    c = np.cross(r[:, 0] - r[:, 1], r[:, 0] - r[:, 2])
    return c / np.linalg.norm(c, axis=1, keepdims=True)


def singularity_index(r, omega) -> np.ndarray:
    """|n · ω̂| per frame (eq. 6.35): 0 where the closed-form versions are singular.

    Parameters
    ----------
    r : ndarray of shape (F, 3, 3)
        Marker positions (frame, marker, xyz).
    omega : ndarray of shape (F, 3)
        Angular velocity (rad/s).

    Returns
    -------
    ndarray of shape (F,)
        In [0, 1]; NaN where ω = 0 (no rotation: nothing to resolve).
    """
    n = plane_normal(r)
    w = np.asarray(omega, dtype=np.float64).reshape(-1, 3)
    norm = np.linalg.norm(w, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.abs(np.einsum("fi,fi->f", n, w)) / norm


def _mean_kept(versions: np.ndarray, excluded: np.ndarray) -> np.ndarray:
    kept = ~excluded & np.all(np.isfinite(versions), axis=2)
    count = kept.sum(axis=1)
    total = np.sum(np.where(kept[..., None], versions, 0.0), axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(count[:, None] > 0, total / count[:, None], np.nan)


def _spread(versions: np.ndarray, excluded: np.ndarray, reference: np.ndarray) -> np.ndarray:
    dist = np.linalg.norm(versions - reference[:, None, :], axis=2)
    dist = np.where(~excluded & np.isfinite(dist), dist, -np.inf)
    out = dist.max(axis=1)
    return np.where(np.isfinite(out), out, np.nan)


def angular_kinematics(r, v, a, *, singularity_threshold: float = 0.2, method: str = "lsq",
                       min_height_ratio: float = 0.03, observable_ratio: float = 0.05,
                       raw: tuple | None = None) -> AngularKinematics:
    """Angular velocity and acceleration of the three-marker body, every estimate and its flags.

    Parameters
    ----------
    r : ndarray of shape (F, 3, 3)
        Registered marker positions (m), motion frame.
    v, a : ndarray of shape (F, 3, 3)
        Marker velocities (m/s) and accelerations (m/s²) from the fits.
    singularity_threshold : float, optional
        Versions whose conditioning is below this are excluded from the versions' mean.
    method : {"lsq", "lsq_observable", "lsq_wiener", "versions"}
        Final estimate: least squares over the pairs (default, well posed whatever ω's direction);
        the same without the weakest axis when the markers lie near a line ("lsq_observable"); with
        that axis shrunk by a Wiener gain from the skin motion of the unregistered markers
        ("lsq_wiener", needs ``raw``); or the mean of the kept versions (the thesis's choice;
        frames where all are excluded fall back to least squares).
    min_height_ratio : float, optional
        Collinearity limit, see :func:`saddlescope.core.kinematics.registration.check_marker_layout`.
    raw : tuple of (r, v, a), optional
        Unregistered marker positions and their fitted velocities and accelerations, for "lsq_wiener".

    Returns
    -------
    AngularKinematics

    Raises
    ------
    KinematicsError
        If the markers are (nearly) collinear.
    """
    r, v, a, finite = _check_body(r, v, a, method=method, raw=raw, min_height_ratio=min_height_ratio)
    w_lsq = omega_least_squares(r, v)
    ratio_cut, gains, flags = _weak_axis(r[finite], method, observable_ratio, raw)
    w_ver, w_cond = omega_versions(r, v)
    w_excl = ~(w_cond >= singularity_threshold)
    w_mean = _mean_kept(w_ver, w_excl)
    omega = _final_omega(method, r, v, w_lsq, w_mean, ratio_cut, gains[0])
    a_lsq = alpha_least_squares(r, a, omega, min_eig_ratio=ratio_cut, weak_gain=gains[1])
    a_ver, a_cond = alpha_versions(r, a, omega)
    a_excl = ~(a_cond >= singularity_threshold)
    a_mean = _mean_kept(a_ver, a_excl)
    alpha = a_lsq if method != "versions" else np.where(np.isfinite(a_mean), a_mean, a_lsq)

    sing = singularity_index(r, w_lsq)
    flags += _singularity_flags(sing, finite, w_excl, a_excl, singularity_threshold)
    if method == "versions":
        fallback = finite & ~np.all(np.isfinite(w_mean), axis=1)
        if fallback.any():
            flags.append(Finding("rotation.all_versions_excluded",
                                 f"all ω versions excluded in {fallback[finite].mean():.0%} of frames; least "
                                 "squares used there", {"share_pct": 100 * float(fallback[finite].mean())}))
    return AngularKinematics(
        omega_rad_s=omega, alpha_rad_s2=alpha, omega_lsq=w_lsq, alpha_lsq=a_lsq,
        omega_versions=w_ver, alpha_versions=a_ver, omega_versions_mean=w_mean, alpha_versions_mean=a_mean,
        version_conditioning=w_cond, excluded=w_excl, singularity_index=sing,
        omega_spread=_spread(w_ver, w_excl, w_lsq), alpha_spread=_spread(a_ver, a_excl, a_lsq),
        normal=plane_normal(r), method=method, flags=tuple(flags),
        weak_axis_gain=gains if method == "lsq_wiener" else None)


def _check_body(r, v, a, *, method: str, raw: tuple | None, min_height_ratio: float
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """r, v, a as (F, 3, 3) arrays and the frames (F,) with all three markers; raise on bad input.

    KinematicsError if no frame has the three markers or they are (nearly) collinear.
    """
    if method not in ANGULAR_METHODS:
        raise InputError(f"method must be one of {', '.join(ANGULAR_METHODS)}, got {method!r}")
    if method == "lsq_wiener" and raw is None:
        raise InputError("method 'lsq_wiener' needs the unregistered markers' (r, v, a) as raw")
    r = _check_triplet(r, "r")
    v = _check_triplet(v, "v")
    a = _check_triplet(a, "a")
    if not (r.shape == v.shape == a.shape):
        raise InputError(f"r, v and a must have the same shape, got {r.shape}, {v.shape}, {a.shape}")
    finite = np.all(np.isfinite(r), axis=(1, 2))
    if not finite.any():
        raise KinematicsError("no frame has all three markers registered")
    check_marker_layout(r[np.flatnonzero(finite)[0]], min_height_ratio=min_height_ratio)
    return r, v, a, finite


def _weak_axis(r_finite: np.ndarray, method: str, observable_ratio: float, raw: tuple | None
               ) -> tuple[float, tuple, list[Finding]]:
    """How the markers' weakest rotation axis is treated, from the frames (F', 3, 3) with all markers.

    Returns the eigenvalue ratio below which an axis is left out ("lsq_observable"; 0 keeps every
    axis), the (ω, α) Wiener gains on that axis ("lsq_wiener"; else None) and the flags saying so.
    """
    flags: list[Finding] = []
    ratio_cut = 0.0
    if method == "lsq_observable":
        axis, ratio = unobservable_axis(r_finite, min_eig_ratio=observable_ratio)
        if ratio < observable_ratio:
            ratio_cut = observable_ratio
            flags.append(Finding("rotation.markers_in_line",
                                 f"the markers lie near a line (eigenvalue ratio {ratio:.3f} < {observable_ratio}): "
                                 f"rotation about it (axis {np.round(axis, 2).tolist()} in the motion frame) is not "
                                 "observable, so its component of ω and α is left out (taken as zero)",
                                 {"eigenvalue_ratio": ratio, "limit_ratio": observable_ratio}))
    gains: tuple[float, float] | tuple[None, None] = (None, None)
    if method == "lsq_wiener":
        assert raw is not None  # _check_body required it for this method
        omega_gain, alpha_gain = gains = weak_axis_gain(*raw)
        _, ratio = unobservable_axis(r_finite, min_eig_ratio=observable_ratio)
        flags.append(Finding("rotation.weak_axis",
                             f"rotation about the markers' weakest axis (eigenvalue ratio {ratio:.3f}) kept at "
                             f"{omega_gain:.0%} in ω and {alpha_gain:.0%} in α: the rest is what skin motion predicts",
                             {"eigenvalue_ratio": ratio, "omega_kept_pct": 100 * omega_gain,
                              "alpha_kept_pct": 100 * alpha_gain}))
    return ratio_cut, gains, flags


def _final_omega(method: str, r: np.ndarray, v: np.ndarray, w_lsq: np.ndarray, w_mean: np.ndarray,
                 ratio_cut: float, weak_gain: float | None) -> np.ndarray:
    """The angular velocity (F, 3) the ``method`` of :func:`angular_kinematics` reports (rad/s)."""
    if method == "lsq":
        return w_lsq
    if method == "lsq_observable":
        return omega_least_squares(r, v, min_eig_ratio=ratio_cut)
    if method == "lsq_wiener":
        return omega_least_squares(r, v, weak_gain=weak_gain)
    return np.where(np.isfinite(w_mean), w_mean, w_lsq)


def _singularity_flags(sing: np.ndarray, finite: np.ndarray, w_excl: np.ndarray, a_excl: np.ndarray,
                       threshold: float) -> list[Finding]:
    """Findings for ω near the markers' plane (``sing`` (F,), eq. 6.35) and versions (F, 6) left out."""
    flags = []
    valid = finite & np.isfinite(sing)
    if valid.any():
        med = float(np.median(sing[valid]))
        if med < threshold:
            flags.append(Finding("rotation.near_singularity",
                                 f"ω is nearly in the markers' plane (median |n·ω̂| = {med:.2f} < {threshold}): the "
                                 "thesis's closed-form versions are near their singularity (eq. 6.35) and "
                                 "unreliable; the least-squares estimate is not affected",
                                 {"singularity_index_median": med, "limit": threshold}))
    for name, excl in (("ω", w_excl), ("α", a_excl)):
        frac = excl[finite].mean(axis=0) if finite.any() else np.zeros(6)
        shares = [f"{name}^{vname} {f:.0%}" for vname, f in zip(VERSION_NAMES, frac, strict=True) if f > 0]
        if shares:  # one line per quantity: the share of frames each version was left out of
            flags.append(Finding("rotation.versions_excluded",
                                 f"{name} versions excluded near their singularity (conditioning below "
                                 f"{threshold}; share of frames): {', '.join(shares)}",
                                 {f"{vname.replace(',', '_')}_excluded_pct": 100 * float(f)
                                  for vname, f in zip(VERSION_NAMES, frac, strict=True) if f > 0}))
    return flags
