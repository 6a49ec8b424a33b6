"""Rigid registration of the static-shot marker model to every frame (thesis 5.4, eq. 5.14-5.21).

The thesis (after Besl & McKay 1992) finds, per frame, the rotation and translation that best
map the measured markers onto the model (eq. 5.14), then moves the model back into the frame
(eq. 5.19-5.21) so that the distances between markers are those of the static shot. Here the
equivalent forward map is solved directly, ``measured ~ R @ model + t``, with Horn's closed-form
unit quaternion (the eigenvector of the largest eigenvalue of a symmetric 4x4 matrix), for all
frames at once. Registered positions are ``R @ model + t``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from saddlescope.core.errors import InputError, KinematicsError

__all__ = [
    "Registration",
    "layout_ratio",
    "check_marker_layout",
    "marker_model",
    "register_rigid",
    "broken_distance_samples",
]


@dataclass(frozen=True)
class Registration:
    """Per-frame rigid fit of the marker model.

    R : ndarray of shape (F, 3, 3)
        Rotation model -> frame (NaN where the frame could not be registered).
    t : ndarray of shape (F, 3)
        Translation, same units as the inputs: ``registered = model @ R.T + t``.
    registered : ndarray of shape (F, M, 3)
        The model moved into each frame (eq. 5.21); NaN where not registered.
    residual : ndarray of shape (F, M)
        Distance between each measured marker and its registered position (NaN if missing).
    rms_residual : ndarray of shape (F,)
        Root-mean-square of ``residual`` over the markers present: the rigidity error.
    n_markers : ndarray of shape (F,)
        Markers present in each frame.
    valid : ndarray of bool, shape (F,)
        Frames registered (at least ``min_markers`` present).
    """

    R: np.ndarray
    t: np.ndarray
    registered: np.ndarray
    residual: np.ndarray
    rms_residual: np.ndarray
    n_markers: np.ndarray
    valid: np.ndarray


def layout_ratio(points) -> float:
    """How far a marker layout is from collinear.

    For three markers: the triangle's smallest height over its longest side (2 area / longest
    side^2; 0.87 for an equilateral triangle, 0 when collinear). For more markers: the ratio of
    the second to the first singular value of the centred points.

    Parameters
    ----------
    points : ndarray of shape (M, 3)
        Marker positions, M >= 3.

    Returns
    -------
    ratio : float
        0 for collinear markers, larger the further from a line.
    """
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3 or p.shape[0] < 3:
        raise InputError(f"points must have shape (M, 3) with M >= 3, got {p.shape}")
    if p.shape[0] == 3:
        sides = np.linalg.norm(p - np.roll(p, 1, axis=0), axis=1)
        area2 = np.linalg.norm(np.cross(p[1] - p[0], p[2] - p[0]))
        longest = sides.max()
        return float(area2 / longest**2) if longest > 0 else 0.0
    s = np.linalg.svd(p - p.mean(axis=0), compute_uv=False)
    return float(s[1] / s[0]) if s[0] > 0 else 0.0


def check_marker_layout(points, *, min_height_ratio: float = 0.03, what: str = "the horse markers") -> float:
    """Raise KinematicsError if the markers are (nearly) collinear.

    Parameters
    ----------
    points : ndarray of shape (M, 3)
        Marker positions, M >= 3.
    min_height_ratio : float, optional
        Smallest :func:`layout_ratio` accepted.
    what : str, optional
        What the markers are, for the message.

    Returns
    -------
    ratio : float
        The layout's :func:`layout_ratio`.
    """
    ratio = layout_ratio(points)
    if not ratio >= min_height_ratio:
        raise KinematicsError(
            f"{what} are nearly collinear (smallest triangle height is {ratio:.3f} of the longest side, "
            f"below {min_height_ratio}): the body's rotation cannot be determined; place the markers in "
            "a triangle")
    return ratio


def marker_model(static_xyz, *, names: tuple[str, ...] | None = None, min_height_ratio: float = 0.03,
                 ) -> np.ndarray:
    """The marker model from the static shot: per-marker median over the static frames.

    Parameters
    ----------
    static_xyz : ndarray of shape (F, M, 3) or (M, 3)
        Static-shot marker positions, NaN where not found.
    names : tuple of str, optional
        Marker names for error messages.
    min_height_ratio : float, optional
        See :func:`check_marker_layout`.

    Returns
    -------
    model : ndarray of shape (M, 3)
    """
    x = np.asarray(static_xyz, dtype=np.float64)
    if x.ndim == 2:
        x = x[None]
    if x.ndim != 3 or x.shape[2] != 3:
        raise InputError(f"static_xyz must have shape (F, M, 3) or (M, 3), got {x.shape}")
    present = np.all(np.isfinite(x), axis=2)
    for m in range(x.shape[1]):
        if not present[:, m].any():
            label = names[m] if names is not None and m < len(names) else f"marker {m + 1}"
            raise KinematicsError(f"{label} is not found in any frame of the static shot")
    model = np.nanmedian(x, axis=0)
    check_marker_layout(model, min_height_ratio=min_height_ratio, what="the static-shot markers")
    return model


def _quaternion_to_matrix(q: np.ndarray) -> np.ndarray:
    """Unit quaternions (..., 4) as [q0, q1, q2, q3] -> rotation matrices (..., 3, 3) (eq. 5.16)."""
    q0, q1, q2, q3 = np.moveaxis(q, -1, 0)
    return np.stack([
        np.stack([q0**2 + q1**2 - q2**2 - q3**2, 2 * (q1 * q2 - q0 * q3), 2 * (q1 * q3 + q0 * q2)], -1),
        np.stack([2 * (q1 * q2 + q0 * q3), q0**2 + q2**2 - q1**2 - q3**2, 2 * (q2 * q3 - q0 * q1)], -1),
        np.stack([2 * (q1 * q3 - q0 * q2), 2 * (q2 * q3 + q0 * q1), q0**2 + q3**2 - q1**2 - q2**2], -1),
    ], -2)


def register_rigid(measured, model, *, min_markers: int = 3) -> Registration:
    """Fit the marker model rigidly to every frame (Horn's closed-form quaternion).

    Parameters
    ----------
    measured : ndarray of shape (F, M, 3)
        Measured marker positions, NaN where a marker is missing.
    model : ndarray of shape (M, 3)
        The static-shot model (same units, any frame), e.g. from :func:`marker_model`.
    min_markers : int, optional
        Fewest markers present for a frame to be registered (3 at least: three markers are the
        minimum, so with three markers a frame missing one is a gap).

    Returns
    -------
    Registration
    """
    x = np.asarray(measured, dtype=np.float64)
    a = np.asarray(model, dtype=np.float64)
    if x.ndim != 3 or x.shape[2] != 3:
        raise InputError(f"measured must have shape (F, M, 3), got {x.shape}")
    if a.shape != x.shape[1:]:
        raise InputError(f"model has shape {a.shape} but the measured frames have {x.shape[1:]} markers")
    if min_markers < 3:
        raise InputError(f"min_markers must be at least 3, got {min_markers}")
    n_frames, n_mark, _ = x.shape
    present = np.all(np.isfinite(x), axis=2)  # (F, M)
    n_present = present.sum(axis=1)
    valid = n_present >= max(min_markers, 3)
    R = np.full((n_frames, 3, 3), np.nan)
    t = np.full((n_frames, 3), np.nan)
    if valid.any():
        w = present[valid].astype(np.float64)  # (V, M)
        xv = np.where(present[valid, :, None], x[valid], 0.0)
        wsum = w.sum(axis=1)[:, None]
        ca = (w @ a) / wsum  # model centroid of the markers present, (V, 3)
        cb = np.einsum("vm,vmk->vk", w, xv) / wsum
        # Centre and scale before solving (numerical care): the rotation is scale-free.
        scale = np.sqrt(np.sum((a - a.mean(axis=0)) ** 2) / n_mark)
        scale = scale if scale > 0 else 1.0
        da = (a[None] - ca[:, None]) / scale
        db = (xv - cb[:, None]) / scale
        S = np.einsum("vm,vmi,vmj->vij", w, da, db)  # S_ij = sum a_i b_j
        sxx, sxy, sxz = S[:, 0, 0], S[:, 0, 1], S[:, 0, 2]
        syx, syy, syz = S[:, 1, 0], S[:, 1, 1], S[:, 1, 2]
        szx, szy, szz = S[:, 2, 0], S[:, 2, 1], S[:, 2, 2]
        N = np.stack([
            np.stack([sxx + syy + szz, syz - szy, szx - sxz, sxy - syx], -1),
            np.stack([syz - szy, sxx - syy - szz, sxy + syx, szx + sxz], -1),
            np.stack([szx - sxz, sxy + syx, -sxx + syy - szz, syz + szy], -1),
            np.stack([sxy - syx, szx + sxz, syz + szy, -sxx - syy + szz], -1),
        ], -2)
        _, vecs = np.linalg.eigh(N)
        q = vecs[:, :, -1]  # eigenvector of the largest eigenvalue
        Rv = _quaternion_to_matrix(q / np.linalg.norm(q, axis=1, keepdims=True))
        R[valid] = Rv
        t[valid] = cb - np.einsum("vij,vj->vi", Rv, ca)
    registered = np.einsum("fij,mj->fmi", R, a) + t[:, None, :]
    residual = np.linalg.norm(registered - x, axis=2)  # NaN where the marker is missing
    sq = np.where(present, residual, 0.0) ** 2
    rms = np.sqrt(sq.sum(axis=1) / np.maximum(n_present, 1))
    rms = np.where(valid, rms, np.nan)
    return Registration(R=R, t=t, registered=registered, residual=residual, rms_residual=rms,
                        n_markers=n_present, valid=valid)


def broken_distance_samples(xyz, *, min_jump: float = 30.0, n_sigma: float = 5.0) -> np.ndarray:
    """Marker samples that break the markers' rigid distances: a look-alike taken for a marker.

    The markers sit on one rigid-enough body, so each pair's distance stays near its median over the
    clip (skin sliding and camera noise move it by millimetres). A pair whose distance is off by more
    than ``n_sigma`` robust standard deviations and ``min_jump`` (units of ``xyz``) is broken. A
    marker in two broken pairs is the wrong one; a lone broken pair marks both of its markers (the
    distances cannot tell which); with three markers all broken, the whole frame goes.

    Parameters
    ----------
    xyz : ndarray of shape (F, M, 3)
        Tracked positions, NaN where missing; M >= 3.

    Returns
    -------
    ndarray of bool, shape (F, M)
        True for samples to drop (never True where the sample was already missing).
    """
    xyz = np.asarray(xyz, dtype=np.float64)
    if xyz.ndim != 3 or xyz.shape[2] != 3:
        raise InputError(f"xyz must have shape (F, M, 3), got {xyz.shape}")
    n_frames, n_markers, _ = xyz.shape
    bad_pairs = np.zeros((n_frames, n_markers), dtype=np.int64)  # broken pairs each marker is in
    pairs_ok = np.zeros(n_frames, dtype=np.int64)  # pairs measured in each frame
    drop = np.zeros((n_frames, n_markers), dtype=bool)  # only ever set where both markers were measured
    for i in range(n_markers):
        for j in range(i + 1, n_markers):
            d = np.linalg.norm(xyz[:, i] - xyz[:, j], axis=1)
            ok = np.isfinite(d)
            if ok.sum() < 5:
                continue
            dev = np.abs(d - np.median(d[ok]))
            sigma = 1.4826 * np.median(dev[ok])
            broken = ok & (dev > max(n_sigma * sigma, min_jump))
            bad_pairs[:, i] += broken
            bad_pairs[:, j] += broken
            pairs_ok += ok
            # a lone broken pair: both of its markers (resolved below where a third pair says more)
            drop[:, i] |= broken
            drop[:, j] |= broken
    # Where a marker sits in two or more broken pairs, the others in only one are innocent unless
    # every pair of the frame is broken.
    guilty = bad_pairs >= 2
    all_broken = (bad_pairs.sum(axis=1) == 2 * pairs_ok) & (pairs_ok > 0)
    some_guilty = guilty.any(axis=1) & ~all_broken
    drop[some_guilty] = guilty[some_guilty]
    return drop
