"""A synthetic scene's clips as each camera films them: uint8 frames and the exact marker pixels.

``render_clip_frames`` yields a camera's frames of one clip before encoding; ``true_marker_pixels``
gives the exact 2-D marker centres at every frame instant (the answer the marker stages are
checked against).
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from saddlescope.arena.content import ALL_CLIPS, BoardContent, HorseContent
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

__all__ = ["OCCLUDED_CLIPS", "SHUTTER_CLIPS", "frame_shape", "lighting_gain", "render_clip_frames", "row_instants",
           "true_marker_pixels"]

OCCLUDED_CLIPS = ("motion",)  # the jump-stand pole stands in the arena during the ride only
# a rolling shutter (RenderOptions.readout_s) sweeps the light of every clip (the flash, the lighting) down the
# rows; the content is drawn band by band at its rows' instants in these clips (the ride), where it moves fast;
# elsewhere it is drawn at the frame's instant (the horse and plumb line stand still, and the calibration uses
# the board's still views)
SHUTTER_CLIPS = ("motion",)


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
    times = timing.frame_times(camera)
    stop = len(times) if stop is None else min(int(stop), len(times))
    flash = flash_fraction(times, scene.rig.exposure_s, timing.flash_on_s, timing.flash_off_s, timing.flash_ramp_s)
    flash = flash if scene.options.flash else np.zeros_like(flash)  # the scene's lamp, whatever ``options`` says
    clip_no, cam_no = ALL_CLIPS.index(kind), CAMERA_ROLES.index(camera)
    bank = noise_bank(np.random.default_rng([scene.seed, 0x5ADD1E, clip_no, cam_no]), frame_shape(view))
    board_cache: dict = {}
    band = _RowBands(frame_shape(view)[0], scene.options.readout_s, scene.options.rolling_bands)
    for k in range(int(start), stop):
        t = float(times[k])
        rng = np.random.default_rng([scene.seed, 0x5ADD1E, clip_no, cam_no, k])
        if band.global_shutter:
            frame = _lit_frame(scene, view, kind, t, opts, board_cache)
            gain = lighting_gain(scene, camera, t) if opts.lighting_drift else 1.0
            yield finish_frame(frame, gain=gain, flash=float(flash[k]), rng=rng, options=opts, bank=bank)
            continue
        # a rolling shutter: each band of rows lit and flashed at its own instant (and drawn then in the ride)
        frame = np.empty(frame_shape(view), np.float32)
        still = None if kind in SHUTTER_CLIPS else _lit_frame(scene, view, kind, t, opts, board_cache)
        for r0, r1, delay_s in band.bands():
            t_b = t + delay_s
            part = (_lit_frame(scene, view, kind, t_b, opts, board_cache) if still is None else still)[r0:r1]
            gain = lighting_gain(scene, camera, t_b) if opts.lighting_drift else 1.0
            fl = float(flash_fraction(np.array([t_b]), scene.rig.exposure_s, timing.flash_on_s, timing.flash_off_s,
                                      timing.flash_ramp_s)[0]) if scene.options.flash else 0.0
            frame[r0:r1] = part * np.float32(gain) + np.float32(95.0 * fl)
        yield finish_frame(frame, gain=1.0, flash=0.0, rng=rng, options=opts, bank=bank)


class _RowBands:
    """A rolling shutter's row bands: row y is exposed ``y / rows * readout_s`` after the frame's instant."""

    def __init__(self, rows: int, readout_s: float, bands: int):
        self.rows, self.readout_s, self.n = int(rows), float(readout_s), max(1, min(int(bands), int(rows)))

    @property
    def global_shutter(self) -> bool:
        """True without a readout (every row at the frame's instant)."""
        return self.readout_s <= 0.0

    def bands(self) -> list[tuple[int, int, float]]:
        """(first row, end row, delay (s) of the band's middle row) per band."""
        edges = np.linspace(0, self.rows, self.n + 1).round().astype(int)
        return [(int(a), int(b), self.readout_s * 0.5 * (a + b) / self.rows) for a, b in zip(edges[:-1], edges[1:],
                                                                                            strict=True)]


def _lit_frame(scene: Scene, view: CameraView, kind: str, t: float, opts: RenderOptions, board_cache: dict
               ) -> np.ndarray:
    """One float frame (H, W) of clip ``kind`` at instant ``t``: content, markers, glints, boot, pole."""
    content = scene.contents[kind]
    rendered = np.asarray(content.rendered, np.bool_)
    frame = view.rendered_background().copy()
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
    if isinstance(content, HorseContent):
        content.draw_front(frame, view, t)  # the rider's boot, in front of the markers
    if opts.occluder and kind in OCCLUDED_CLIPS:
        composite_foreground(frame, view)
    return frame


def row_instants(scene: Scene, camera: str, kind: str, xy_px: np.ndarray) -> np.ndarray:
    """The instant (s) each image point (F, M, 2) of the clip's F frames was exposed at, shape (F, M).

    Its frame's instant plus its row's delay.

    With a global shutter (or a clip the rolling shutter is not applied to) the frames' instants.
    """
    times = scene.timings[kind].frame_times(camera)
    readout = scene.options.readout_s if kind in SHUTTER_CLIPS else 0.0
    rows = frame_shape(scene.views[camera])[0]
    delay = np.nan_to_num(readout * np.clip(xy_px[..., 1] + 0.5, 0, rows) / rows)
    return times[:, None] + delay


def true_marker_pixels(scene: Scene, camera: str, kind: str) -> dict:
    """Exact 2-D marker centres of every frame of one camera clip.

    Returns
    -------
    dict
        ``names`` (M,); ``xy_px`` ndarray of shape (F, M, 2), the distorted projection at each frame
        instant, NaN where the marker is not rendered (S during the ride), not wholly inside the
        image or touched by the pole or the rider's boot; ``visible`` (F, M) bool; ``occluded`` (F, M)
        bool (hidden by the pole, or at least partly covered by the boot); with a rolling shutter each
        point is where the marker was when its row was exposed; ``radius_px`` (F, M); ``frame_times_s`` (F,).
    """
    timing = scene.timings[kind]
    content = scene.contents[kind]
    view = scene.views[camera]
    times = timing.frame_times(camera)
    pts = content.markers_w(times)
    xy = view.project(pts)
    readout = scene.options.readout_s if kind in SHUTTER_CLIPS else 0.0
    if readout > 0 and pts.shape[1]:
        # a rolling shutter: each marker where it was when its row was exposed (two fixed-point steps)
        for _ in range(2):
            t_row = row_instants(scene, camera, kind, xy)
            pts = np.stack([content.markers_w(t_row[:, m])[:, m] for m in range(pts.shape[1])], axis=1)
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
    if isinstance(content, HorseContent):
        occluded = occluded | content.boot_covers(times)
    visible = inside & ~occluded & np.asarray(content.rendered, np.bool_)[None, :]
    out = np.where(visible[..., None], xy, np.nan)
    return {
        "names": tuple(content.marker_names),
        "xy_px": out,
        "visible": visible,
        "occluded": occluded & inside,
        "radius_px": radius,
        "frame_times_s": times,
    }
