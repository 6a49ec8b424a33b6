"""The choices a user may override for a ride's analysis, shared by every stage."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from saddlescope.core.detection.detectors import DetectionSettings

__all__ = ["PipelineParams"]


@dataclass(frozen=True)
class PipelineParams:
    """Choices a user may override; the defaults follow the thesis where it was right."""

    n_periods: int = 2
    smoothing: str = "none"  # or "rloess" (thesis 5.2.2); the Fourier fits smooth and reject outliers
    smoothing_span: float = 0.10
    smoothing_iterations: int = 4
    # gaps bridged for the registration (the fits skip bridged frames, and report the fits' positions
    # there): the arena's pole hid a marker for 0.2 s in a fast thesis-rig canter, and at 0.15 s the
    # longest stretch left was under two strides
    max_gap_s: float = 0.25
    triangulation: str = "nview"  # or "thesis_pairs"
    max_calibration_instants: int = 150
    calibration_step: int | None = None  # frames between board looks; None: every frame (tracking is cheap)
    still_board_only: bool = True  # calibrate from frames where the board was held still
    max_square_error_pct: float = 1.0
    singularity_threshold: float = 0.2
    # the motion markers' distances against the static shot's (RMS, mm): beyond it a look-alike was
    # tracked (wide-rig trot: 280 mm; true markers: depth noise and skin, a few to 20 mm)
    max_layout_mismatch_mm: float = 50.0
    # a plumb line leaning more than this from the cameras' image-down direction is not one (cameras
    # stand roughly level; the plumb search takes pairs within 25 degrees)
    max_plumb_lean_deg: float = 30.0
    # median rigidity residual (registration) above which the saddle point is flagged unreliable:
    # 1-3 mm on synthetic rides of both rigs (skin motion), 180 mm with two markers' labels swapped
    max_rigidity_residual_mm: float = 15.0
    depth_anisotropy: float = 5.0  # fit marker depth smoothly when the rig fixes it this many times worse
    depth_max_order: int = 0  # stride harmonics allowed in that depth fit (0: straight path only)
    # "lsq_wiener": least squares with the weakest axis shrunk by the skin motion the raw markers
    # show; "lsq_observable" drops it when the markers lie near a line; "lsq"; "versions" (thesis)
    angular_method: str = "lsq_wiener"
    x_model: str = "fourier"  # the thesis's "linear" drops the surge within the stride
    extra_orders: int = 3  # orders tried above the extrema rule's E/2 + 1 (chosen by AICc)
    omega_from: str = "vertical"  # series whose fitted fundamental is pooled (fitting.fit_marker_kinematics)
    # a straight line fitted with the y and z series: the registered markers keep slow drifts over the
    # fitted span (gravity's tilt across the depth travelled, each marker's straight depth path) that
    # a periodic series smears over its harmonics (a thesis-rig canter lost its fourth harmonic: 16 %)
    trend_degree: int = 1
    # "run": fit the tracked frames around the window, at most fit_margin_periods strides on either
    # side, and report the window; "window": the thesis's 5.5. The margin is bounded because a real
    # horse's stride drifts over a long side of the arena and one periodic fit would smear it.
    fit_span: str = "run"
    fit_margin_periods: float = 1.0
    max_order: int | None = None  # cap on the Fourier order the extrema rule and AICc choose
    # orders above the extrema rule's range tried while the criterion asks for them, up to what the frame
    # rate resolves (issue 38: a trot's 6th stride harmonic, 8-9 Hz, was cut: -2.5 % on W_b, -6.7 % on VDV)
    harmonics_up_to_frame_rate: bool = True
    # order criterion (fitting.CRITERIA): "aicc" takes the noise's correlation over frames into
    # account, "aicc_white" is the textbook AICc
    criterion: str = "aicc"
    # the marker detector (core.detection.detectors' registry) and, per clip kind ("motion", "static",
    # "plumb"), the user's typed overrides of its automatic choices
    marker_detector: str = "bright_discs"
    detection: Mapping[str, DetectionSettings] = field(default_factory=dict)
    # threads the analysis may use in all (camera threads, decoders, OpenCV); None: one per camera as
    # before, OpenCV's own default. The services set it from SADDLESCOPE_WORKER_THREADS (cgroup quota).
    threads: int | None = None

    def __post_init__(self) -> None:
        """Check the choices that would otherwise fail late (after the clips are decoded)."""
        from saddlescope.core.detection.detectors import DetectionSettings, marker_detector

        marker_detector(self.marker_detector)  # an InputError naming the known detectors
        for kind, settings in self.detection.items():
            if not isinstance(settings, DetectionSettings):
                raise TypeError(f"PipelineParams.detection[{kind!r}] must be DetectionSettings, not "
                                f"{type(settings).__name__}")
