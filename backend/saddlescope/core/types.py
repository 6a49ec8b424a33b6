"""Shared frozen dataclasses of the core.

Units: image points in pixels; 3-D points of calibration and triangulation in millimetres
(``*_mm``); kinematics in metres and seconds (``*_m``, ``*_s``). Camera poses are relative to the
left camera: ``x_cam = R @ x_left + t_mm`` (CONTRACTS section 2).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from saddlescope.core.camera_model import undistort_normalized
from saddlescope.core.findings import Finding

__all__ = ["CAMERA_ROLES", "CLIP_KINDS", "DIRECTIONS", "GAITS", "WAND_CLIP_KINDS", "AnalysisWindow", "Board",
           "BoardOptionValue", "Camera",
           "HorseMarkers", "ImageTracks", "LensModel", "MarkerTracks", "MotionFrameSummary", "RidePass", "RideResult",
           "Rig", "WandCheck", "WandRefinement",
           "SaddleKinematics", "SaddleRotation", "VerticalHarmonics"]

CAMERA_ROLES: tuple[str, ...] = ("left", "middle", "right")
CLIP_KINDS: tuple[str, ...] = ("calibration", "plumb", "static", "motion")
# A wand calibration's clip sets (issue 35): the wand waved through the volume by all cameras at once,
# and a small board filmed close to each camera for its lens (each camera on its own, no sync).
WAND_CLIP_KINDS: tuple[str, ...] = ("wand", "close_up")
GAITS: tuple[str, ...] = ("walk", "sitting_trot", "rising_trot", "canter")
DIRECTIONS: tuple[str, ...] = ("CW", "CCW")


@dataclass(frozen=True)
class Camera:
    """A pinhole camera with OpenCV distortion (k1, k2, p1, p2, k3).

    K : ndarray of shape (3, 3); dist : ndarray of shape (5,); image_size : (width, height) px;
    R : ndarray of shape (3, 3) and t_mm : ndarray of shape (3,) map rig (left-camera) coordinates in
    mm into this camera's coordinates. ``*_std`` hold one standard deviation where known.
    """

    name: str
    K: np.ndarray
    dist: np.ndarray
    image_size: tuple[int, int]
    R: np.ndarray = field(default_factory=lambda: np.eye(3))
    t_mm: np.ndarray = field(default_factory=lambda: np.zeros(3))
    rms_px: float | None = None
    K_std: np.ndarray | None = None
    dist_std: np.ndarray | None = None

    @property
    def rvec(self) -> np.ndarray:
        """Rotation vector (Rodrigues) of ``R``, shape (3,)."""
        return cv2.Rodrigues(np.asarray(self.R, dtype=np.float64))[0].ravel()

    @property
    def projection_matrix(self) -> np.ndarray:
        """P = K [R | t], shape (3, 4), for undistorted pixel coordinates."""
        P: np.ndarray = self.K @ np.hstack([self.R, np.reshape(self.t_mm, (3, 1))])
        return P

    @property
    def center_mm(self) -> np.ndarray:
        """Camera centre in rig coordinates, shape (3,)."""
        center: np.ndarray = -self.R.T @ np.reshape(self.t_mm, 3)
        return center

    def project(self, points_mm: np.ndarray) -> np.ndarray:
        """Project rig points to distorted pixels with OpenCV's ``projectPoints``.

        Parameters
        ----------
        points_mm : ndarray of shape (..., 3)
            Rig coordinates in mm; non-finite rows give NaN.

        Returns
        -------
        ndarray of shape (..., 2)
            Distorted pixel coordinates.
        """
        pts = np.asarray(points_mm, dtype=np.float64)
        shape = pts.shape[:-1]
        flat = pts.reshape(-1, 3)
        out = np.full((flat.shape[0], 2), np.nan)
        ok = np.all(np.isfinite(flat), axis=1)
        if ok.any():
            img, _ = cv2.projectPoints(flat[ok], self.rvec, np.asarray(self.t_mm, dtype=np.float64),
                                       np.asarray(self.K, dtype=np.float64),
                                       np.asarray(self.dist, dtype=np.float64))
            out[ok] = img.reshape(-1, 2)
        return out.reshape(*shape, 2)

    def undistort_points(self, xy_px: np.ndarray) -> np.ndarray:
        """Remove lens distortion with the exact (Newton-refined) inverse of the camera model.

        Parameters
        ----------
        xy_px : ndarray of shape (..., 2)
            Distorted pixel coordinates; NaN rows stay NaN.

        Returns
        -------
        ndarray of shape (..., 2)
            Ideal (undistorted) pixel coordinates with the same K.
        """
        xn = undistort_normalized(self, xy_px)
        K = np.asarray(self.K, dtype=np.float64)
        return xn @ K[:2, :2].T + K[:2, 2]


@dataclass(frozen=True)
class LensModel:
    """Which of a camera's lens parameters a calibration fitted; the others are held fixed.

    The full model is OpenCV's: fx, fy, cx, cy, k1, k2, p1, p2, k3. Where a camera's views do not pin a
    parameter down it is fixed instead: fx = fy (square pixels, ``equal_focal``), the principal point at
    the image centre (``principal_point`` False), no tangential term (``tangential`` False), k3 = 0
    (``k3`` False). ``given``: the intrinsics came from elsewhere (an earlier calibration, a lens
    profile) and only the pose was fitted. ``joint``: the joint adjustment of all cameras refined the
    lens (False: the lens is the camera's own views' fit, held while the rig's poses were adjusted).
    ``reason`` says in words why this model was chosen.
    """

    equal_focal: bool = False
    principal_point: bool = True
    tangential: bool = True
    k3: bool = False
    given: bool = False
    joint: bool = True
    reason: str = ""

    @property
    def n_intrinsics(self) -> int:
        """The number of intrinsic parameters fitted (focal, principal point, k1, k2, tangential, k3)."""
        if self.given:
            return 0
        return (1 if self.equal_focal else 2) + 2 * self.principal_point + 2 + 2 * self.tangential + self.k3

    @property
    def label(self) -> str:
        """The model in a few words, e.g. "fx=fy, centre, k1 k2"."""
        if self.given:
            return "given"
        parts = ["fx=fy" if self.equal_focal else "fx fy", "cx cy" if self.principal_point else "centre",
                 "k1 k2" + (" k3" if self.k3 else "")]
        if self.tangential:
            parts.append("p1 p2")
        return ", ".join(parts) + ("" if self.joint else "; own views, held")


@dataclass(frozen=True)
class WandCheck:
    """A rig checked on what its calibration did not fit, for the wand refinement's choice (issue 35).

    ``wand_length_rms_mm``: the wand's length, triangulated on the wand frames held out of the refinement,
    r.m.s. about its true length (NaN where no held-out frame was seen by two cameras);
    ``board_square_error_pct`` and ``board_rms_px``: the board walk's square check (percent of the square) and
    its corners' triangulation r.m.s. on the board views; ``reach_px``: per camera how far from the principal point the
    lens is known (:func:`~saddlescope.core.triangulation.lens_reach.board_reach_px`).
    """

    wand_length_rms_mm: float
    board_square_error_pct: float
    board_rms_px: float
    reach_px: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class WandRefinement:
    """Whether a board calibration was refined by a wand pass, and why (issue 35).

    ``kept``: the refined rig is the rig (False: the board's is, unchanged). ``reason`` says why in words;
    ``board`` and ``refined`` are the two rigs' checks (``refined`` None where the refinement failed);
    ``held_out_frames`` the wand frames the refinement did not see, on which both were checked.
    """

    kept: bool
    reason: str
    wand_length_mm: float
    held_out_frames: int
    board: WandCheck
    refined: WandCheck | None = None

    @property
    def sentence(self) -> str:
        """The choice in plain words, e.g. "Refined by the wand: the middle camera's lens is now known to 700 px"."""
        if not self.kept or self.refined is None:
            return f"Not refined by the wand: {self.reason}. The board's calibration is kept."
        grown = {c: (self.board.reach_px.get(c, 0.0), r) for c, r in self.refined.reach_px.items()}
        cam, (was, now) = max(grown.items(), key=lambda kv: kv[1][1] - kv[1][0])
        length = (f"; the wand's length on {self.held_out_frames} frames it did not fit is off by "
                  f"{self.refined.wand_length_rms_mm:.1f} mm r.m.s., was {self.board.wand_length_rms_mm:.1f} mm"
                  if np.isfinite(self.refined.wand_length_rms_mm) else "")
        return (f"Refined by the wand: the {cam} camera's lens is now known to {now:.0f} px from the centre of "
                f"its image, was {was:.0f} px{length}.")


@dataclass(frozen=True)
class Rig:
    """Calibrated cameras keyed by role (left, middle, right, or any names for other rigs).

    ``checks`` holds metric quality numbers (e.g. ``board_square_error_mm``); ``flags`` lists the
    calibration's findings (e.g. a metric error over its threshold, :mod:`saddlescope.core.findings`);
    ``lens_models`` which lens parameters each camera's calibration fitted (empty where unknown);
    ``wand_refinement`` whether a board calibration was refined by a wand pass (None: none was offered).
    """

    cameras: dict[str, Camera]
    checks: dict[str, float] = field(default_factory=dict)
    flags: tuple[Finding, ...] = ()
    pairs: dict[str, dict] = field(default_factory=dict)
    lens_models: dict[str, LensModel] = field(default_factory=dict)
    wand_refinement: WandRefinement | None = None

    @property
    def names(self) -> list[str]:
        """The cameras' names, the reference (first, left) camera first."""
        return list(self.cameras)


# A board option's value, as a board section's JSON holds it (number, text or flag).
BoardOptionValue = float | str | bool


@dataclass(frozen=True)
class Board:
    """A planar calibration board. ``inner_corners`` is (cols, rows) as OpenCV's pattern size.

    ``options`` are the fields its kind adds (a ChArUco board's ``dictionary``, ``marker_mm``, ``legacy``),
    as (name, value) pairs in the order the kind declares them; the kind's module
    (:mod:`saddlescope.core.calibration.boards`) reads and validates them.
    """

    kind: str
    inner_corners: tuple[int, int]
    square_mm: float
    options: tuple[tuple[str, BoardOptionValue], ...] = ()

    def option(self, name: str, default: BoardOptionValue | None = None) -> BoardOptionValue | None:
        """The value of one of the kind's fields, or ``default`` where the board has none."""
        return dict(self.options).get(name, default)

    def object_points_mm(self) -> np.ndarray:
        """Inner-corner coordinates in board mm, shape (cols*rows, 3), row-major as OpenCV returns.

        The rectangular grid of the checkerboard-like kinds; a kind whose points lie otherwise (the
        asymmetric circle grid) has its own: ask :func:`saddlescope.core.calibration.boards.object_points_mm`.
        """
        cols, rows = self.inner_corners
        grid = np.zeros((rows * cols, 3), np.float64)
        grid[:, :2] = np.mgrid[0:cols, 0:rows].T.reshape(-1, 2) * self.square_mm
        return grid


@dataclass(frozen=True)
class ImageTracks:
    """2-D marker tracks of one camera clip.

    xy_px : ndarray of shape (F, M, 2), NaN where a marker was not found (a gap, never a guess);
    area_px : ndarray of shape (F, M); frame_index : ndarray of shape (F,) of the clip's frames.
    """

    camera: str
    xy_px: np.ndarray
    frame_index: np.ndarray
    area_px: np.ndarray | None = None
    flags: tuple[str, ...] = ()


@dataclass(frozen=True)
class MarkerTracks:
    """3-D marker tracks in rig coordinates (mm).

    t_s : ndarray of shape (F,), time of each sample on the left camera's clock;
    xyz_mm : ndarray of shape (F, M, 3), NaN in gaps; reprojection_error_px : (F, M);
    views : (F, M) number of cameras used.
    """

    names: tuple[str, ...]
    t_s: np.ndarray
    xyz_mm: np.ndarray
    reprojection_error_px: np.ndarray | None = None
    views: np.ndarray | None = None


# --------------------------------------------------------------------------------------------------
# The result of a ride's analysis (CONTRACTS section 2); ``saddlescope.io.result_document`` turns it
# into the result document and back. Arrays are float64, NaN where there is no value.
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class AnalysisWindow:
    """The analysed stretch of the ride: a whole number of strides on the motion clip's clock."""

    start_s: float
    duration_s: float
    start_frame: int
    frames: int


@dataclass(frozen=True)
class RidePass:
    """One pass of the horse in front of the cameras (a ride may hold several, issue 38).

    ``start_s``/``end_s`` and ``start_frame``/``frames``: where its markers were tracked together on the
    motion clip's clock; ``strides`` the whole strides its fits saw; ``indicators`` its own (the ride's
    pool every used pass's strides); ``used`` False for a pass left out, with ``reason``.
    """

    start_s: float
    end_s: float
    start_frame: int
    frames: int
    strides: int
    speed_m_s: float | None
    stride_frequency_hz: float | None
    indicators: dict[str, float]
    intervals_95: dict[str, tuple[float, float]] = field(default_factory=dict)
    used: bool = True
    reason: str | None = None


@dataclass(frozen=True)
class SaddleKinematics:
    """The hidden saddle point S in the motion reference frame, over the window (thesis 6.3-6.4).

    t_s : ndarray of shape (F,); position_m, velocity_m_s, acceleration_m_s2 : ndarrays of shape (F, 3)
    (x travel, y gravity down, z = x × y); acceleration_spread_m_s2 : ndarray of shape (F,), the spread of
    S's acceleration over the ω versions; body_coordinates_m : ndarray of shape (3,), S in the markers'
    body frame.
    """

    t_s: np.ndarray
    position_m: np.ndarray
    velocity_m_s: np.ndarray
    acceleration_m_s2: np.ndarray
    acceleration_spread_m_s2: np.ndarray
    body_coordinates_m: np.ndarray


@dataclass(frozen=True)
class SaddleRotation:
    """The saddle's angular velocity and acceleration over the window (thesis 6.1-6.2).

    omega_rad_s, alpha_rad_s2 : ndarrays of shape (F, 3); singularity_index_per_frame : (F,);
    omega_versions_rad_s : (F, V, 3) the thesis's ω versions, omega_versions_excluded : (F, V) bool;
    omega_spread_rad_s : (F, 3); weak_axis_gain : (gain on ω, gain on α) of the weakly observed axis.
    """

    omega_rad_s: np.ndarray
    alpha_rad_s2: np.ndarray
    singularity_index: float
    singularity_index_per_frame: np.ndarray
    omega_versions_rad_s: np.ndarray
    omega_versions_excluded: np.ndarray
    omega_spread_rad_s: np.ndarray
    method: str
    weak_axis_gain: tuple[float, float] | None = None


@dataclass(frozen=True)
class HorseMarkers:
    """The three horse markers registered to the static shot, over the window (thesis 5.4-5.5).

    position_m, velocity_m_s, acceleration_m_s2 : ndarrays of shape (F, 3, 3) (frame, marker, axis);
    rigidity_residual_mm : (F,); fits : per axis ("x", "y", "z") a summary of each marker's fit.
    """

    names: tuple[str, ...]
    position_m: np.ndarray
    velocity_m_s: np.ndarray
    acceleration_m_s2: np.ndarray
    rigidity_residual_mm: np.ndarray
    fits: dict


@dataclass(frozen=True)
class MotionFrameSummary:
    """The motion reference frame (thesis 5.3): ``R_rig_to_motion`` (3, 3), ``origin_mm`` (3,)."""

    R_rig_to_motion: np.ndarray
    origin_mm: np.ndarray
    gravity_source: str


@dataclass(frozen=True)
class VerticalHarmonics:
    """S's vertical acceleration as a cosine series at the stride frequency (thesis 7).

    S's vertical acceleration as a cosine series at the stride frequency f0 (thesis 7):
    a(t) = Σ_k amplitudes_m_s2[k-1] cos(2π k f0 t + phases_rad[k-1]).
    """

    f0_hz: float
    amplitudes_m_s2: np.ndarray
    phases_rad: np.ndarray


@dataclass(frozen=True)
class RideResult:
    """Everything the analysis of one ride found (CONTRACTS section 2).

    ``rig`` is the calibration used (computed from the ride's clips, or reused);
    ``calibration_views`` and ``board_coverage_fraction`` per camera are set when it was computed.
    ``sync_offsets[kind][camera]`` are frame offsets against the first camera; ``indicators`` the
    rider's comfort indicators, ``indicators_interval_95`` their 95 % intervals; ``quality`` the checks
    and the figures behind them; ``findings`` what the stages found worth saying, in the order they
    raised it (the rig's and the input's first).
    """

    fps: float
    gait: str | None
    direction: str | None
    rig: Rig
    sync_offsets: dict[str, dict[str, float]]
    period_s: float
    window: AnalysisWindow
    saddle: SaddleKinematics
    angular: SaddleRotation
    markers: HorseMarkers
    motion_frame: MotionFrameSummary
    vertical_harmonics: VerticalHarmonics
    indicators: dict[str, float]
    quality: dict
    params: dict
    timings_s: dict[str, float]
    calibration_views: dict[str, int] | None = None
    board_coverage_fraction: dict[str, float] | None = None
    # 95 % interval (low, high) per indicator (core.vibration.intervals); None on results made before them
    indicators_interval_95: dict[str, tuple[float, float]] | None = None
    findings: tuple[Finding, ...] = ()
    # the passes in front of the cameras when the ride held several (issue 38); empty for one pass, whose
    # numbers are the window's. With several, the indicators and intervals pool every used pass's strides
    # and the series (saddle, angular, markers, window) are the pass with the most strides.
    passes: tuple[RidePass, ...] = ()

    @property
    def flags(self) -> list[str]:
        """The findings' expert sentences, in the order the stages raised them."""
        return [f.detail for f in self.findings]
