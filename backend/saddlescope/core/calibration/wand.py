"""Wand calibration: the cameras' poses and the scale from two markers at a known distance (issue 35 item 3).

Carrying a board to every corner of three views 8 m away is filming's hardest step; commercial motion
capture and field tools (easyWand, Argus) wave a wand instead: two bright markers a known distance apart
moved through the riding volume. Each camera's lens comes from close-up board clips (or is given), and
the wand gives the rest:

1. :func:`track_wand_ends` finds the wand's two ends in each frame of one camera's clip (the two most
   contrasted bright spots, :func:`saddlescope.core.detection.search.bright_spots`) and keeps them apart
   by their continuity in time; a frame with one end missing is skipped and starts a new segment.
2. :func:`calibrate_wand` tells the ends apart between cameras (each segment's labels are the ones that
   fit the epipolar geometry), starts from the essential matrix of the pair with most shared frames
   (``cv2.findEssentialMat`` / ``recoverPose`` on undistorted points), scales it by the wand's length,
   adds the other cameras by PnP on the triangulated ends, then bundle-adjusts every camera pose and the
   wand's pose in every frame (centre and direction; the length held, so it sets the scale) with
   ``scipy.optimize.least_squares`` and a sparse Jacobian.
3. The metric check triangulates both ends of every frame freely (:func:`triangulate_dlt`, no length
   constraint) and reports the spread of the wand's length in mm, as the board's square check does; a
   poor spread is a ``calibration.wand_length`` finding.

Units: pixels in images, millimetres for the wand and the poses; the first camera is the reference.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import cv2
import numpy as np
from scipy.optimize import least_squares
from scipy.sparse import lil_matrix

from saddlescope.core.calibration.checks import triangulate_dlt
from saddlescope.core.calibration.projection import _distort_project, _intr_vector, _rotation_matrices
from saddlescope.core.detection.search import bright_spots
from saddlescope.core.errors import CalibrationError, InputError
from saddlescope.core.findings import Finding
from saddlescope.core.types import Camera, LensModel, Rig

__all__ = ["WAND_LENGTH_RANGE_M", "WandView", "calibrate_wand", "relabel_with_rig",
           "track_wand_ends", "wand_length_errors", "wand_length_problem"]

MIN_WAND_FRAMES = 20  # frames two cameras must share for the first pair's essential matrix
WAND_LENGTH_LIMIT_PCT = 0.5  # the wand's length r.m.s. error (percent of its length) above which it is flagged
# A wand's length in m (its two markers' centres): a short stick to a long pole. The one range every layer
# checks (the rig's column and its API field, ride.json, the command line, the calibration itself).
WAND_LENGTH_RANGE_M = (0.05, 5.0)


def wand_length_problem(length_m: object) -> str | None:
    """Why ``length_m`` is not a wand's length in metres (a sentence), or None when it is one."""
    low, high = WAND_LENGTH_RANGE_M
    if isinstance(length_m, bool) or not isinstance(length_m, int | float) or not np.isfinite(length_m):
        return f"the wand's length {length_m!r} is not a number of metres"
    if low <= float(length_m) <= high:
        return None
    # A tape measure reads centimetres: 100 for a 1 m wand is the likely slip.
    hint = f" (in centimetres? {length_m:g} cm is {length_m / 100:.2f} m)" if high < length_m <= 100 * high else ""
    return (f"the wand's length {length_m:g} m is outside {low:g}-{high:g} m{hint}: measure it between the centres "
            "of its two markers, in metres (e.g. 1.0)")


@dataclass(frozen=True)
class WandView:
    """The wand's two ends in one frame of one camera.

    ``ends_px`` (2, 2): end A then end B, distorted pixels; ``segment`` numbers the runs of frames
    in which the ends were followed without a gap (labels are consistent within a segment).
    """

    frame: int
    ends_px: np.ndarray
    segment: int = 0


def _wand_spots(gray: np.ndarray, radius_px: int | None, min_contrast: float) -> np.ndarray:
    """The two ends' centres (2, 2) px in one frame, or an empty array where two are not clearly seen.

    Spots are found at half resolution (the top-hat costs a quarter) and their centres refined at full
    resolution: the intensity-weighted centroid above the patch's background. Two spots are kept only if
    the second is at least half as contrasted as the first (else it is a glint or plank edge, not an end).
    """
    small = cv2.resize(gray, (gray.shape[1] // 2, gray.shape[0] // 2), interpolation=cv2.INTER_AREA)
    r_small = max(3, (radius_px or max(4, round(gray.shape[1] / 110))) // 2)
    spots, peaks = bright_spots(small, max_spots=3, radius_px=r_small, min_contrast=min_contrast / 2,
                                return_peaks=True)
    if len(spots) < 2 or peaks[1] < 0.5 * peaks[0] or (len(spots) > 2 and peaks[2] > 0.7 * peaks[1]):
        return np.empty((0, 2))
    out = []
    h, w = gray.shape
    r = 2 * r_small
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
    for x, y in spots[:2] * 2 + 0.5:
        # the top-hat of a patch twice the kernel's reach: the disc above its surroundings, even where it
        # crosses an edge between brighter and darker background (sky and wall)
        x0, y0 = max(int(x) - 2 * r, 0), max(int(y) - 2 * r, 0)
        patch = gray[y0:min(int(y) + 2 * r + 1, h), x0:min(int(x) + 2 * r + 1, w)]
        if min(patch.shape) <= 2 * r:
            return np.empty((0, 2))
        lift = cv2.morphologyEx(patch, cv2.MORPH_TOPHAT, kernel).astype(np.float64)
        ys, xs = np.mgrid[y0:y0 + patch.shape[0], x0:x0 + patch.shape[1]]
        near = (np.abs(xs - x) <= r) & (np.abs(ys - y) <= r)
        lift = np.where(near, lift, 0.0)
        # the disc alone: the connected region above half its peak that holds the peak (not plank edges)
        _, labels = cv2.connectedComponents((lift > 0.5 * lift.max()).astype(np.uint8), connectivity=8)
        disc = labels == labels.flat[int(np.argmax(lift))]
        wgt = np.where(disc, lift - 0.5 * lift.max(), 0.0)
        out.append([float((wgt * xs).sum() / wgt.sum()), float((wgt * ys).sum() / wgt.sum())])
    return np.asarray(out)


def track_wand_ends(frames: Iterable[tuple[int, np.ndarray]], *, max_jump_px: float | None = None,
                    radius_px: int | None = None, min_contrast: float = 30.0) -> list[WandView]:
    """The wand's two ends in every frame of one camera's clip where both are seen.

    Each frame's two most contrasted small bright spots are the ends (:func:`_wand_spots`); they keep
    their labels from the previous frame by the nearer assignment. A frame without both ends, or whose
    ends jumped by more than ``max_jump_px`` (default a tenth of the image width), ends the segment: the
    next one's labels are settled between cameras by :func:`calibrate_wand`.
    """
    out: list[WandView] = []
    prev: np.ndarray | None = None
    segment = 0
    for frame, gray in frames:
        ends = _wand_spots(gray, radius_px, min_contrast)
        if len(ends) < 2:
            if prev is not None:
                segment += 1
            prev = None
            continue
        jump = max_jump_px if max_jump_px is not None else gray.shape[1] / 10
        if prev is not None:
            straight = np.linalg.norm(ends - prev, axis=1).sum()
            swapped = np.linalg.norm(ends[::-1] - prev, axis=1).sum()
            if swapped < straight:
                ends = ends[::-1].copy()
            if min(straight, swapped) > 2 * jump:
                segment += 1
        out.append(WandView(int(frame), ends, segment))
        prev = ends
    return out


def _normalized(cam: Camera, xy_px: np.ndarray) -> np.ndarray:
    """Undistorted normalised image coordinates (N, 2) of distorted pixels (N, 2)."""
    return cv2.undistortPoints(np.asarray(xy_px, np.float64).reshape(-1, 1, 2), cam.K, cam.dist).reshape(-1, 2)


def _shared(a: list[WandView], b: list[WandView]) -> tuple[list[WandView], list[WandView]]:
    fb = {v.frame: v for v in b}
    pairs = [(v, fb[v.frame]) for v in a if v.frame in fb]
    return [p[0] for p in pairs], [p[1] for p in pairs]


def _epipolar_errors(E: np.ndarray, xa: np.ndarray, xb: np.ndarray) -> np.ndarray:
    """Sampson distances (normalised units) of correspondences xa <-> xb (N, 2) under E (xb^T E xa = 0)."""
    ha, hb = np.column_stack([xa, np.ones(len(xa))]), np.column_stack([xb, np.ones(len(xb))])
    Ea, Eb = ha @ E.T, hb @ E
    num = np.einsum("ij,ij->i", hb, Ea) ** 2
    return np.sqrt(num / (Ea[:, 0] ** 2 + Ea[:, 1] ** 2 + Eb[:, 0] ** 2 + Eb[:, 1] ** 2))


def _swap_evidence(ref: Camera, cam: Camera, ref_views: list[WandView], views: list[WandView],
                   threshold: float) -> dict[int, tuple[int, float]]:
    """Per frame both cameras see: (the reference's segment, how much better swapped ends fit than straight).

    Every shared frame offers both labellings as correspondences; half of them are wrong, which a RANSAC
    essential matrix tolerates. The evidence is the difference of the Sampson errors.
    """
    va, vb = _shared(ref_views, views)
    if len(va) < MIN_WAND_FRAMES // 2:
        return {}
    xa = _normalized(ref, np.concatenate([v.ends_px for v in va]))
    xb = _normalized(cam, np.concatenate([v.ends_px for v in vb]))
    xb_swapped = _normalized(cam, np.concatenate([v.ends_px[::-1] for v in vb]))
    E, _ = cv2.findEssentialMat(np.vstack([xa, xa]), np.vstack([xb, xb_swapped]), np.eye(3), cv2.RANSAC,
                                0.999, threshold, 5000)
    if E is None or E.shape != (3, 3):
        return {}
    straight = _epipolar_errors(E, xa, xb).reshape(-1, 2).sum(axis=1)
    swapped = _epipolar_errors(E, xa, xb_swapped).reshape(-1, 2).sum(axis=1)
    return {v.frame: (u.segment, float(s - w)) for u, v, s, w in zip(va, vb, straight, swapped, strict=True)}


def _posed_swap_evidence(ref: Camera, cam: Camera, ref_views: list[WandView], views: list[WandView],
                         threshold: float) -> dict[int, tuple[int, float]]:
    """:func:`_swap_evidence` for two posed cameras: the epipolar geometry is the rig's, not estimated."""
    va, vb = _shared(ref_views, views)
    if not va:
        return {}
    R = cam.R @ ref.R.T
    t = cam.t_mm - R @ ref.t_mm
    E = np.array([[0, -t[2], t[1]], [t[2], 0, -t[0]], [-t[1], t[0], 0]]) @ R
    xa = _normalized(ref, np.concatenate([v.ends_px for v in va]))
    straight = _epipolar_errors(E, xa, _normalized(cam, np.concatenate([v.ends_px for v in vb])))
    swapped = _epipolar_errors(E, xa, _normalized(cam, np.concatenate([v.ends_px[::-1] for v in vb])))
    s, w = straight.reshape(-1, 2).sum(axis=1), swapped.reshape(-1, 2).sum(axis=1)
    return {v.frame: (u.segment, float(a - b)) for u, v, a, b in zip(va, vb, s, w, strict=True)}


def relabel_with_rig(rig: Rig, views_by_camera: Mapping[str, list[WandView]]) -> dict[str, list[WandView]]:
    """The wand's ends labelled alike in every camera of a calibrated rig (end A the same marker in each).

    Each camera's tracker labels the ends by their continuity in its own clip; across cameras the labels are
    settled as :func:`calibrate_wand` settles them, with the rig's own epipolar geometry (a board calibration
    being refined). The first camera with views keeps its labels. Without this, the rendered band ride's
    wand came out 4.4 m r.m.s. off its length with the board's rig (36.6 mm with it).
    """
    names = [n for n in rig.names if views_by_camera.get(n)]
    views = {n: list(views_by_camera[n]) for n in names}
    for i, name in enumerate(names[1:], 1):
        views[name] = _relabel(rig.cameras, names[:i], name, views, 0.0, evidence=_posed_swap_evidence)
    return views


def _relabel(cameras: Mapping[str, Camera], resolved: list[str], name: str,
             views: Mapping[str, list[WandView]], threshold: float, *, evidence=None) -> list[WandView]:
    """Camera ``name``'s views with the ends labelled as in the cameras already ``resolved``.

    A run of frames whose labels hold together is a (resolved camera, its run, this camera's segment)
    group: each group takes the labelling most of its frames' epipolar evidence favours. Frames no resolved
    camera sees keep their labels. The returned views' ``segment`` numbers these groups. ``evidence``: how
    two cameras' frames are judged (default :func:`_swap_evidence`, from the ends alone).
    """
    judge = evidence or _swap_evidence
    found = {r: judge(cameras[r], cameras[name], views[r], views[name], threshold) for r in resolved}
    keys: list[tuple] = []
    votes: dict[tuple, int] = {}
    for v in views[name]:
        key: tuple = ("alone", v.segment)
        for r in resolved:
            if v.frame in found[r]:
                seg_r, better = found[r][v.frame]
                key = (r, seg_r, v.segment)
                votes[key] = votes.get(key, 0) + (1 if better > 0 else -1)
                break
        keys.append(key)
    ids = {k: i for i, k in enumerate(dict.fromkeys(keys))}
    return [WandView(v.frame, v.ends_px[::-1].copy() if votes.get(k, 0) > 0 else v.ends_px, ids[k])
            for v, k in zip(views[name], keys, strict=True)]


def _triangulate_pair(ca: Camera, cb: Camera, xa: np.ndarray, xb: np.ndarray) -> np.ndarray:
    """Points (N, 3) in ``ca``'s rig frame from undistorted normalised coordinates of two posed cameras."""
    Pa = np.hstack([ca.R, ca.t_mm.reshape(3, 1)])
    Pb = np.hstack([cb.R, cb.t_mm.reshape(3, 1)])
    X = cv2.triangulatePoints(Pa, Pb, xa.T, xb.T)
    return (X[:3] / X[3]).T


def _first_pair(names: list[str], views: Mapping[str, list[WandView]]) -> tuple[str, str]:
    best, best_n = None, -1
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            n = len(_shared(views[a], views[b])[0])
            if n > best_n:
                best, best_n = (a, b), n
    if best is None or best_n < MIN_WAND_FRAMES:
        raise CalibrationError(f"no two cameras see both ends of the wand in {MIN_WAND_FRAMES} frames or more "
                               f"(at most {max(best_n, 0)}): wave the wand where the cameras' views overlap")
    return best


def _pair_poses(ca: Camera, cb: Camera, va: list[WandView], vb: list[WandView], length_mm: float,
                threshold: float) -> tuple[np.ndarray, np.ndarray]:
    """``cb``'s pose (R, t_mm) relative to ``ca`` from the essential matrix, scaled by the wand's length."""
    xa = _normalized(ca, np.concatenate([v.ends_px for v in va]))
    xb = _normalized(cb, np.concatenate([v.ends_px for v in vb]))
    E, mask = cv2.findEssentialMat(xa, xb, np.eye(3), cv2.RANSAC, 0.999, threshold, 5000)
    if E is None or E.shape != (3, 3):
        raise CalibrationError(f"cameras {ca.name} and {cb.name}: the wand's ends give no epipolar geometry")
    _, R, t, _ = cv2.recoverPose(E, xa, xb, np.eye(3), mask=mask)
    a0 = Camera(ca.name, np.eye(3), np.zeros(5), ca.image_size)
    b0 = Camera(cb.name, np.eye(3), np.zeros(5), cb.image_size, R=R, t_mm=t.ravel())
    X = _triangulate_pair(a0, b0, xa, xb).reshape(-1, 2, 3)
    lengths = np.linalg.norm(X[:, 0] - X[:, 1], axis=1)
    scale = length_mm / float(np.median(lengths[np.isfinite(lengths)]))
    return R, t.ravel() * scale


def _add_by_pnp(cam: Camera, posed: Mapping[str, Camera], views: Mapping[str, list[WandView]]) -> Camera | None:
    """``cam`` posed by PnP on the wand ends that the posed cameras triangulate, or None with too few."""
    names = list(posed)
    frames = sorted({v.frame for v in views[cam.name]})
    by_cam = {n: {v.frame: v for v in views[n]} for n in names}
    mine = {v.frame: v for v in views[cam.name]}
    xy = np.full((len(names), 2 * len(frames), 2), np.nan)
    for c, n in enumerate(names):
        for i, f in enumerate(frames):
            if f in by_cam[n]:
                xy[c, 2 * i:2 * i + 2] = by_cam[n][f].ends_px
    X, _ = triangulate_dlt([posed[n] for n in names], xy)
    img = np.concatenate([mine[f].ends_px for f in frames])
    ok = np.all(np.isfinite(X), axis=1)
    if ok.sum() < MIN_WAND_FRAMES:  # two points a frame: ten frames seen with the cameras already placed
        return None
    found, rvec, tvec, _ = cv2.solvePnPRansac(X[ok], img[ok], cam.K, cam.dist, reprojectionError=4.0,
                                              iterationsCount=500, flags=cv2.SOLVEPNP_EPNP)
    if not found:
        return None
    _, rvec, tvec = cv2.solvePnP(X[ok], img[ok], cam.K, cam.dist, rvec, tvec, useExtrinsicGuess=True)
    return Camera(cam.name, cam.K, cam.dist, cam.image_size, R=cv2.Rodrigues(rvec)[0], t_mm=tvec.ravel(),
                  rms_px=cam.rms_px, K_std=cam.K_std, dist_std=cam.dist_std)


def _direction(angles: np.ndarray) -> np.ndarray:
    """Unit vectors (N, 3) of (azimuth, elevation) pairs (N, 2)."""
    az, el = angles[:, 0], angles[:, 1]
    return np.column_stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])


class _WandBundle:
    """Residuals of the wand's bundle adjustment: poses of the non-reference cameras, the wand per frame."""

    def __init__(self, cams: list[Camera], frames: list[int], views: Mapping[str, list[WandView]],
                 length_mm: float):
        self.cams, self.L = cams, length_mm
        fi = {f: i for i, f in enumerate(frames)}
        rows = [(c, fi[v.frame], v.ends_px) for c, cam in enumerate(cams) for v in views[cam.name] if v.frame in fi]
        self.obs_cam = np.repeat([r[0] for r in rows], 2)
        self.obs_frame = np.repeat([r[1] for r in rows], 2)
        self.obs_end = np.tile([0, 1], len(rows))
        self.obs_xy = np.concatenate([r[2] for r in rows])
        self.intr = np.array([_intr_vector(c) for c in cams])[self.obs_cam]
        self.C, self.F = len(cams), len(frames)

    def points(self, wand: np.ndarray) -> np.ndarray:
        """Both ends (F, 2, 3) of wand poses (F, 5): centre mm, direction angles."""
        centre, d = wand[:, :3], _direction(wand[:, 3:])
        return np.stack([centre - d * self.L / 2, centre + d * self.L / 2], axis=1)

    def residuals(self, x: np.ndarray) -> np.ndarray:
        poses = np.vstack([np.zeros(6), x[:6 * (self.C - 1)].reshape(-1, 6)])
        wand = x[6 * (self.C - 1):].reshape(-1, 5)
        X = self.points(wand)[self.obs_frame, self.obs_end]
        R = _rotation_matrices(poses[:, :3])[self.obs_cam]
        xc = np.einsum("mij,mj->mi", R, X) + poses[self.obs_cam, 3:]
        return (_distort_project(xc, self.intr) - self.obs_xy).ravel()

    def sparsity(self) -> lil_matrix:
        M = len(self.obs_cam)
        S = lil_matrix((2 * M, 6 * (self.C - 1) + 5 * self.F), dtype=np.uint8)
        for m in range(M):
            c, f = self.obs_cam[m], self.obs_frame[m]
            if c > 0:
                S[2 * m:2 * m + 2, 6 * (c - 1):6 * c] = 1
            j = 6 * (self.C - 1) + 5 * f
            S[2 * m:2 * m + 2, j:j + 5] = 1
        return S


class _WandLensBundle(_WandBundle):
    """:class:`_WandBundle` with each camera's radial terms k1, k2 free too (after the poses, before the wand)."""

    def residuals(self, x: np.ndarray) -> np.ndarray:
        n_pose = 6 * (self.C - 1)
        radial = x[n_pose:n_pose + 2 * self.C].reshape(-1, 2)
        intr = self.intr.copy()
        intr[:, 4:6] = radial[self.obs_cam]
        keep = self.intr
        self.intr = intr
        try:
            return super().residuals(np.concatenate([x[:n_pose], x[n_pose + 2 * self.C:]]))
        finally:
            self.intr = keep

    def sparsity(self) -> lil_matrix:
        base = super().sparsity().tocsc()
        n_pose = 6 * (self.C - 1)
        M = len(self.obs_cam)
        lens = lil_matrix((2 * M, 2 * self.C), dtype=np.uint8)
        for m in range(M):
            c = self.obs_cam[m]
            lens[2 * m:2 * m + 2, 2 * c:2 * c + 2] = 1
        from scipy.sparse import hstack

        return hstack([base[:, :n_pose], lens.tocsc(), base[:, n_pose:]]).tolil()


def _wand_frames(cams: list[Camera], views: Mapping[str, list[WandView]]) -> tuple[list[int], np.ndarray]:
    """The frames two or more cameras saw the wand in, and its initial poses there (F, 5).

    Frames whose ends the initial cameras cannot triangulate are left out; fewer than
    :data:`MIN_WAND_FRAMES` left refuse the refinement.
    """
    seen: dict[int, int] = {}
    for c in cams:
        for v in views.get(c.name, []):
            seen[v.frame] = seen.get(v.frame, 0) + 1
    frames = sorted(f for f, n in seen.items() if n >= 2)
    wand = _initial_wand(cams, frames, views) if frames else np.empty((0, 5))
    good = np.all(np.isfinite(wand), axis=1)
    frames, wand = [f for f, g in zip(frames, good, strict=True) if g], wand[good]
    if len(frames) < MIN_WAND_FRAMES:
        raise CalibrationError(f"the wand was seen by two cameras at once in {len(frames)} frames; a refinement "
                               f"needs {MIN_WAND_FRAMES} or more")
    return frames, wand


def _initial_wand(cams: list[Camera], frames: list[int], views: Mapping[str, list[WandView]]) -> np.ndarray:
    """Wand poses (F, 5) from the ends the initial cameras triangulate."""
    by_cam = [{v.frame: v for v in views[c.name]} for c in cams]
    xy = np.full((len(cams), 2 * len(frames), 2), np.nan)
    for c in range(len(cams)):
        for i, f in enumerate(frames):
            if f in by_cam[c]:
                xy[c, 2 * i:2 * i + 2] = by_cam[c][f].ends_px
    X = triangulate_dlt(cams, xy)[0].reshape(-1, 2, 3)
    d = X[:, 1] - X[:, 0]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    angles = np.column_stack([np.arctan2(d[:, 1], d[:, 0]), np.arcsin(np.clip(d[:, 2], -1, 1))])
    return np.column_stack([X.mean(axis=1), angles])


def _bundle_adjust_wand(cams: list[Camera], views: Mapping[str, list[WandView]], length_mm: float,
                        loss: str) -> tuple[list[Camera], dict]:
    """Camera poses (the first held) and every frame's wand pose, jointly; the length held."""
    frames_seen: dict[int, int] = {}
    for c in cams:
        for v in views[c.name]:
            frames_seen[v.frame] = frames_seen.get(v.frame, 0) + 1
    frames = sorted(f for f, n in frames_seen.items() if n >= 2)
    wand = _initial_wand(cams, frames, views)
    good = np.all(np.isfinite(wand), axis=1)
    frames = [f for f, g in zip(frames, good, strict=True) if g]
    wand = wand[good]
    prob = _WandBundle(cams, frames, views, length_mm)
    x0 = np.concatenate([np.concatenate([c.rvec, c.t_mm]) for c in cams[1:]] + [wand.ravel()])
    r0 = prob.residuals(x0)
    sol = least_squares(prob.residuals, x0, jac_sparsity=prob.sparsity(), loss=loss, f_scale=1.0,
                        x_scale="jac", method="trf", max_nfev=100)
    poses = sol.x[:6 * (len(cams) - 1)].reshape(-1, 6)
    out = [cams[0]] + [Camera(c.name, c.K, c.dist, c.image_size, R=cv2.Rodrigues(p[:3])[0], t_mm=p[3:].copy(),
                              rms_px=c.rms_px, K_std=c.K_std, dist_std=c.dist_std)
                       for c, p in zip(cams[1:], poses, strict=True)]
    r = sol.fun.reshape(-1, 2)
    report = {"n_frames": len(frames), "n_observations": len(r), "initial_rms_px": float(np.sqrt(np.mean(
        r0.reshape(-1, 2) ** 2) * 2)), "rms_px": float(np.sqrt(np.mean(np.sum(r ** 2, axis=1)))),
        "n_evaluations": int(sol.nfev), "converged": bool(sol.success)}
    return out, report


def wand_length_errors(rig: Rig, views_by_camera: Mapping[str, list[WandView]], length_mm: float) -> np.ndarray:
    """Freely triangulated wand length minus the true length (mm), one per frame two or more cameras saw."""
    names = [n for n in rig.names if n in views_by_camera]
    by_cam = [{v.frame: v for v in views_by_camera[n]} for n in names]
    frames = sorted({f for b in by_cam for f in b if sum(f in bb for bb in by_cam) >= 2})
    if not frames:
        return np.empty(0)
    xy = np.full((len(names), 2 * len(frames), 2), np.nan)
    for c, b in enumerate(by_cam):
        for i, f in enumerate(frames):
            if f in b:
                xy[c, 2 * i:2 * i + 2] = b[f].ends_px
    X = triangulate_dlt([rig.cameras[n] for n in names], xy)[0].reshape(-1, 2, 3)
    err = np.linalg.norm(X[:, 0] - X[:, 1], axis=1) - length_mm
    return err[np.isfinite(err)]


def _to_reference(cams: Mapping[str, Camera], ref: str) -> dict[str, Camera]:
    """The same cameras with ``ref`` at the identity pose (x_ref = R_ref x + t_ref)."""
    Rr, tr = cams[ref].R, cams[ref].t_mm
    out = {}
    for n, c in cams.items():
        R = c.R @ Rr.T
        out[n] = Camera(n, c.K, c.dist, c.image_size, R=R, t_mm=c.t_mm - R @ tr, rms_px=c.rms_px,
                        K_std=c.K_std, dist_std=c.dist_std)
    return out


def calibrate_wand(views_by_camera: Mapping[str, list[WandView]], intrinsics: Mapping[str, Camera],
                   wand_length_mm: float, *, loss: str = "soft_l1", threshold_px: float = 2.0,
                   max_length_error_pct: float = WAND_LENGTH_LIMIT_PCT,
                   lens_models: Mapping[str, LensModel] | None = None) -> tuple[Rig, dict]:
    """The rig's poses and scale from the wand's ends seen by every camera (intrinsics held as given).

    Parameters
    ----------
    views_by_camera : dict name -> list of WandView
        Frame keys are synchronised instants (apply the sync offsets before).
    intrinsics : dict name -> Camera
        Each camera's lens (from close-up board clips or given); its pose is ignored.
    wand_length_mm : float
        The distance between the wand's two markers' centres.
    threshold_px : float
        RANSAC's epipolar threshold for telling the ends apart and for the first pair's geometry.

    Returns
    -------
    rig : Rig
        First camera = reference. ``checks`` holds ``wand_length_rms_mm``, ``wand_length_sd_mm``,
        ``wand_length_max_mm`` and ``wand_length_mm``; ``flags`` a ``calibration.wand_length`` finding
        where the r.m.s. exceeds ``max_length_error_pct`` of the length.
    report : dict
        ``first_pair``, ``bundle`` (the adjustment's numbers), ``n_views`` per camera, ``length_errors_mm``.
    """
    names = list(views_by_camera)
    if len(names) < 2:
        raise InputError("a wand calibration needs two or more cameras")
    missing = [n for n in names if n not in intrinsics]
    if missing:
        raise InputError(f"no intrinsics for camera(s) {', '.join(missing)}: film the board close to them "
                         "or give their lenses (saddlescope calibrate --intrinsics)")
    if problem := wand_length_problem(float(wand_length_mm) / 1000.0):
        raise InputError(problem)
    a, b = _first_pair(names, views_by_camera)
    base = {n: Camera(n, intrinsics[n].K, intrinsics[n].dist, intrinsics[n].image_size,
                      rms_px=intrinsics[n].rms_px, K_std=intrinsics[n].K_std, dist_std=intrinsics[n].dist_std)
            for n in names}
    thr = threshold_px / float(np.mean([base[n].K[0, 0] for n in names]))
    views = dict(views_by_camera)
    views[b] = _relabel(base, [a], b, views, thr)
    R, t = _pair_poses(base[a], base[b], *_shared(views[a], views[b]), wand_length_mm, thr)
    posed = {a: base[a], b: Camera(b, base[b].K, base[b].dist, base[b].image_size, R=R, t_mm=t)}
    for n in names:
        if n in posed:
            continue
        views[n] = _relabel(base, list(posed), n, views, thr)
        cam = _add_by_pnp(base[n], posed, views)
        if cam is None:
            raise CalibrationError(f"camera {n} sees the wand together with the others in too few frames "
                                   "to be placed in the rig: wave the wand where its view overlaps theirs")
        posed[n] = cam
    order = [a] + [n for n in names if n != a]
    adjusted, bundle = _bundle_adjust_wand([posed[n] for n in order], views, wand_length_mm, loss)
    cams = _to_reference({c.name: c for c in adjusted}, names[0])
    rig = Rig({n: cams[n] for n in names})
    err = wand_length_errors(rig, views, wand_length_mm)
    checks = {"wand_length_mm": float(wand_length_mm), "wand_frames": float(len(err)),
              "wand_length_rms_mm": float(np.sqrt(np.mean(err ** 2))) if len(err) else float("nan"),
              "wand_length_sd_mm": float(np.std(err)) if len(err) else float("nan"),
              "wand_length_max_mm": float(np.max(np.abs(err))) if len(err) else float("nan")}
    flags: list[Finding] = []
    limit_mm = wand_length_mm * max_length_error_pct / 100.0
    if not checks["wand_length_rms_mm"] <= limit_mm:
        flags.append(Finding("calibration.wand_length", (
            f"the wand's length, measured from the calibrated cameras, scatters by "
            f"{checks['wand_length_rms_mm']:.1f} mm r.m.s. about its {wand_length_mm:.0f} mm "
            f"(limit {limit_mm:.1f} mm): distances in the ride may be off by as much"),
            {"rms_mm": checks["wand_length_rms_mm"], "limit_mm": limit_mm}))
    models = dict(lens_models or {n: LensModel(given=True) for n in names})
    rig = Rig(rig.cameras, checks=checks, flags=tuple(flags), lens_models=models)
    report = {"first_pair": [a, b], "bundle": bundle, "n_views": {n: len(views[n]) for n in names},
              "length_errors_mm": err}
    return rig, report


def _within(cams: list[Camera], views: Mapping[str, list[WandView]], reach_px: Mapping[str, float] | None,
            factor: float) -> dict[str, list[WandView]]:
    """The views whose both ends lie within ``factor`` times each camera's lens reach (all where no reach)."""
    if reach_px is None or not np.isfinite(factor):
        return {c.name: list(views[c.name]) for c in cams}
    out = {}
    for c in cams:
        limit = factor * reach_px.get(c.name, np.inf)
        out[c.name] = [v for v in views[c.name] if np.linalg.norm(v.ends_px - c.K[:2, 2], axis=1).max() <= limit]
    return out


# The wand's ends are taken in by how far beyond each lens's reach they lie: the ends just outside it first,
# where the board's lens is still close, then the farther ones with the lens those fixed (the board's
# polynomial, extrapolated to the image edge, can start the ends there metres off).
_REFINE_STAGES = (1.3, 1.8, np.inf)
