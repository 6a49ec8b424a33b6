"""A synthetic scene's clips as each camera films them: uint8 frames and the exact marker pixels.

``render_clip_frames`` yields a camera's frames of one clip before encoding; ``true_marker_pixels``
gives the exact 2-D marker centres at every frame instant (the answer the marker stages are
checked against).
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from saddlescope.arena.content import ALL_CLIPS, BoardContent
from saddlescope.arena.render import (
    CameraView,
    RenderOptions,
    composite_foreground,
    draw_markers,
    finish_frame,
    flash_fraction,
    noise_bank,
)
from saddlescope.arena.scene import Scene
from saddlescope.core.errors import InputError
from saddlescope.core.types import CAMERA_ROLES

__all__ = ["OCCLUDED_CLIPS", "frame_shape", "lighting_gain", "render_clip_frames", "true_marker_pixels"]

OCCLUDED_CLIPS = ("motion",)  # the jump-stand pole stands in the arena during the ride only


def _exposure_samples(scene: Scene, t: float, options: RenderOptions) -> np.ndarray:
    """Instants (s) over the exposure around ``t`` at which moving content is drawn (motion blur)."""
    if not options.motion_blur or options.blur_samples < 2:
        return np.array([t])
    e = scene.rig.exposure_s
    return t + (np.arange(options.blur_samples) / (options.blur_samples - 1) - 0.5) * e


def frame_shape(view: CameraView) -> tuple[int, int]:
    """Shape (H, W) of the camera's frames."""
    w, h = view.size
    return h, w


def lighting_gain(scene: Scene, role: str, t_s: float) -> float:
    """Slow lighting drift (clouds, auto-exposure), a few per cent."""
    cam_phase = {"left": 0.0, "middle": 1.3, "right": 2.9}.get(role, 0.0)
    return float(
        1.0
        + 0.035 * np.sin(2 * np.pi * t_s / 9.0 + scene.light_phase)
        + 0.008 * np.sin(2 * np.pi * t_s / 3.1 + cam_phase)
    )


def render_clip_frames(
    scene: Scene,
    camera: str,
    kind: str,
    *,
    start: int = 0,
    stop: int | None = None,
    options: RenderOptions | None = None,
) -> Iterator[np.ndarray]:
    """Yield camera ``camera``'s frames ``start..stop-1`` of clip ``kind``.

    These are the frames before encoding. Each frame's noise comes from its own seeded generator, so
    any sub-range is identical to the same frames of a full render. ``options`` overrides the
    scene's render options (e.g. no noise or blur for geometry tests; the background keeps the
    scene's layers).

    Yields
    ------
    ndarray of uint8, shape (H, W)
        One grey frame.
    """
    if kind not in scene.timings:
        raise InputError(f"unknown clip {kind!r}; this scene has {', '.join(scene.clips)}")
    if camera not in scene.views:
        raise InputError(f"unknown camera {camera!r}; expected one of {', '.join(CAMERA_ROLES)}")
    opts = options or scene.options
    timing = scene.timings[kind]
    view = scene.views[camera]
    content = scene.contents[kind]
    times = timing.frame_times(camera)
    stop = len(times) if stop is None else min(int(stop), len(times))
    flash = flash_fraction(times, scene.rig.exposure_s, timing.flash_on_s, timing.flash_off_s, timing.flash_ramp_s)
    flash = flash if scene.options.flash else np.zeros_like(flash)  # the scene's lamp, whatever ``options`` says
    clip_no, cam_no = ALL_CLIPS.index(kind), CAMERA_ROLES.index(camera)
    rendered = np.asarray(content.rendered, bool)
    bank = noise_bank(np.random.default_rng([scene.seed, 0x5ADD1E, clip_no, cam_no]), frame_shape(view))
    board_cache: dict = {}
    for k in range(int(start), stop):
        t = float(times[k])
        frame = view.background.copy()
        samples = _exposure_samples(scene, t, opts)
        if isinstance(content, BoardContent):
            content.draw_samples(frame, view, samples, opts, cache=board_cache)
        else:
            content.draw(frame, view, t)
        if rendered.any() and opts.markers:
            pts = content.markers_w(samples)[:, rendered]
            xy = view.project(pts)
            radii = view.radius_px(pts[len(samples) // 2], content.diameters_mm[rendered])
            draw_markers(frame, xy, radii, np.asarray(content.peaks)[rendered], options=opts)
        glints = content.glints(view, t) if opts.distractors else None
        if glints is not None:
            g_w, g_d, g_peak = glints
            g_xy = view.project(g_w)
            draw_markers(frame, g_xy[None], view.radius_px(g_w, g_d), g_peak, options=opts)
        if opts.occluder and kind in OCCLUDED_CLIPS:
            composite_foreground(frame, view)
        gain = lighting_gain(scene, camera, t) if opts.lighting_drift else 1.0
        rng = np.random.default_rng([scene.seed, 0x5ADD1E, clip_no, cam_no, k])
        yield finish_frame(frame, gain=gain, flash=float(flash[k]), rng=rng, options=opts, bank=bank)


def true_marker_pixels(scene: Scene, camera: str, kind: str) -> dict:
    """Exact 2-D marker centres of every frame of one camera clip.

    Returns
    -------
    dict
        ``names`` (M,); ``xy_px`` ndarray of shape (F, M, 2), the distorted projection at each frame
        instant, NaN where the marker is not rendered (S during the ride), not wholly inside the
        image or touched by the pole; ``visible`` (F, M) bool; ``occluded`` (F, M) bool (hidden by
        the pole); ``radius_px`` (F, M); ``frame_times_s`` (F,).
    """
    timing = scene.timings[kind]
    content = scene.contents[kind]
    view = scene.views[camera]
    times = timing.frame_times(camera)
    pts = content.markers_w(times)
    xy = view.project(pts)
    radius = view.radius_px(pts, content.diameters_mm[None, :]) if pts.shape[1] else np.zeros(pts.shape[:2])
    inside = (
        view.inside(xy, 0.0)
        & view.inside(xy + radius[..., None] + 1.0, 0.0)
        & view.inside(xy - radius[..., None] - 1.0, 0.0)
    )
    if scene.options.occluder and kind in OCCLUDED_CLIPS:
        occluded = view.fg_covers(xy, radius)
    else:
        occluded = np.zeros(xy.shape[:2], bool)
    visible = inside & ~occluded & np.asarray(content.rendered, bool)[None, :]
    out = np.where(visible[..., None], xy, np.nan)
    return {
        "names": tuple(content.marker_names),
        "xy_px": out,
        "visible": visible,
        "occluded": occluded & inside,
        "radius_px": radius,
        "frame_times_s": times,
    }
