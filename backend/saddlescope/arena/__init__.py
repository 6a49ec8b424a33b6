"""The synthetic riding arena: complete rides with exact ground truth, for tests and the bench.

It renders with the science core's camera model and imports core; the core never imports it
(import-linter). Modules, from the bottom up:

- ``timing``: clip clocks, camera start offsets, the sync flash, phone frame-rate jitter;
- ``rig``: the thesis, wide and wide_partial camera rigs in the arena;
- ``gait``: the saddle body's exact motion as Fourier series, markers and skin sliding;
- ``render``: frame drawing (background, blobs, board, flash, noise) and per-camera views;
- ``content``: what the cameras film (horse and rider, board, plumb line, ball);
- ``placement``: where the boards, the standing horse, plumb line and ball stand;
- ``scene``: ``build_scene``, one ride setup drawn from a seed;
- ``clips``: ``render_clip_frames`` and ``true_marker_pixels``, the clips as each camera films them;
- ``truth``: ``build_truth`` (truth.json) and ``saddle_truth_at``;
- ``contracts``: ``ride_manifest`` (ride.json) and ``check_result_structure``.
"""

from saddlescope.arena.clips import (
    OCCLUDED_CLIPS,
    frame_shape,
    lighting_gain,
    render_clip_frames,
    true_marker_pixels,
)
from saddlescope.arena.content import (
    ALL_CLIPS,
    BOARD,
    DISTANCE_POINTS,
    EXTRA_CLIPS,
    GRAVITY_M_S2,
    BallContent,
    BoardContent,
    HorseContent,
    PlumbContent,
)
from saddlescope.arena.contracts import (
    RESULT_KEYS,
    check_result_structure,
    ride_manifest,
)
from saddlescope.arena.gait import (
    CHANNELS,
    GAIT_RANGES,
    MARKER_LAYOUTS,
    MARKER_NAMES,
    N_HARMONICS,
    SADDLE_NAME,
    SKIN_MODELS,
    SKIN_NOISE_BAND_HZ,
    SKIN_NOISE_COMPONENTS,
    SKIN_NOISE_RMS_M,
    GaitModel,
    acceleration_harmonics,
    fourier_series,
    saddle_vertical_peak_to_peak,
    sample_gait,
    with_t_cross,
)
from saddlescope.arena.placement import (
    add_static_glints,
    board_distance_poses,
    board_origin,
    board_pose_ok,
    board_rotation,
    out_of_view,
    place_ball,
    place_in_view,
    place_standing_horse,
    sample_board_poses,
    visible_everywhere,
    visible_in,
)
from saddlescope.arena.render import (
    CameraView,
    Pole,
    RenderOptions,
    board_patch,
    composite_foreground,
    composite_patch,
    draw_markers,
    fill_polygons,
    finish_frame,
    flash_fraction,
    marker_coverage,
    noise_bank,
    noise_texture,
    render_background,
    render_pole,
)
from saddlescope.arena.rig import (
    RIGS,
    SceneRig,
    make_rig,
    normalized_pixel_grid,
    thesis_rig,
    wide_partial_rig,
    wide_rig,
)
from saddlescope.arena.scene import (
    HOLD_FRAMES,
    MIN_MOTION_S,
    MOVE_FRAMES,
    Scene,
    build_scene,
)
from saddlescope.arena.timing import (
    FLASH_PLATEAU_FRAMES,
    FLASH_RAMP_FRAMES,
    VFR_DROP_RATE,
    VFR_JITTER_FRAMES,
    ClipTiming,
    clip_timing,
    variable_rate,
)
from saddlescope.arena.truth import (
    build_truth,
    saddle_truth_at,
)

__all__ = [
    "FLASH_PLATEAU_FRAMES",
    "FLASH_RAMP_FRAMES",
    "VFR_DROP_RATE",
    "VFR_JITTER_FRAMES",
    "ClipTiming",
    "clip_timing",
    "variable_rate",
    "RIGS",
    "SceneRig",
    "make_rig",
    "normalized_pixel_grid",
    "thesis_rig",
    "wide_partial_rig",
    "wide_rig",
    "CHANNELS",
    "GAIT_RANGES",
    "MARKER_LAYOUTS",
    "MARKER_NAMES",
    "N_HARMONICS",
    "SADDLE_NAME",
    "SKIN_MODELS",
    "SKIN_NOISE_BAND_HZ",
    "SKIN_NOISE_COMPONENTS",
    "SKIN_NOISE_RMS_M",
    "GaitModel",
    "acceleration_harmonics",
    "fourier_series",
    "saddle_vertical_peak_to_peak",
    "sample_gait",
    "with_t_cross",
    "CameraView",
    "Pole",
    "RenderOptions",
    "board_patch",
    "composite_foreground",
    "composite_patch",
    "draw_markers",
    "fill_polygons",
    "finish_frame",
    "flash_fraction",
    "marker_coverage",
    "noise_bank",
    "noise_texture",
    "render_background",
    "render_pole",
    "ALL_CLIPS",
    "BOARD",
    "DISTANCE_POINTS",
    "EXTRA_CLIPS",
    "GRAVITY_M_S2",
    "BallContent",
    "BoardContent",
    "HorseContent",
    "PlumbContent",
    "add_static_glints",
    "board_distance_poses",
    "board_origin",
    "board_pose_ok",
    "board_rotation",
    "out_of_view",
    "place_ball",
    "place_in_view",
    "place_standing_horse",
    "sample_board_poses",
    "visible_everywhere",
    "visible_in",
    "HOLD_FRAMES",
    "MIN_MOTION_S",
    "MOVE_FRAMES",
    "Scene",
    "build_scene",
    "OCCLUDED_CLIPS",
    "frame_shape",
    "lighting_gain",
    "render_clip_frames",
    "true_marker_pixels",
    "build_truth",
    "saddle_truth_at",
    "RESULT_KEYS",
    "check_result_structure",
    "ride_manifest",
]
