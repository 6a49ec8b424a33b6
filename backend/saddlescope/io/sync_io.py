"""Sync offsets of a clip set from files: brightness curves read cheaply, or ride.json's known offsets."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from saddlescope.core.errors import VideoError
from saddlescope.core.sync import clip_offsets, offsets_from_spec
from saddlescope.io.video import frame_brightness, probe_video


def clip_brightness(path: Path | str, *, clip: str, camera: str, downscale: int = 8) -> np.ndarray:
    """Mean grey level of every frame, shape (F,), from the luma plane on a coarse grid.

    Raises
    ------
    VideoError
        Naming the clip and camera when the file is missing, unreadable or truncated.
    """
    try:
        return frame_brightness(path, downscale=downscale)
    except VideoError as exc:
        raise VideoError(f"{clip} clip of the {camera} camera: {exc}") from None


def measure_offsets(paths_by_camera: Mapping[str, Path | str], *, clip: str, sync: Mapping | None = None,
                    fps_hint: float | None = None, **flash_kwargs) -> dict[str, float]:
    """Frame offsets of one clip set relative to its first camera.

    Parameters
    ----------
    paths_by_camera : dict camera -> video file or image folder (first camera = reference)
    clip : str
        Clip kind, e.g. "motion".
    sync : dict, optional
        ride.json's ``sync`` object: ``{"method": "offsets", ...}`` returns the given offsets (made
        relative to the first camera) without reading any video; otherwise the flash is measured.
    fps_hint : float, optional
        Frame rate of image folders.

    Returns
    -------
    dict camera -> offset in frames (see :func:`saddlescope.core.sync.clip_offsets`)
    """
    cameras = list(paths_by_camera)
    if sync is not None:
        known = offsets_from_spec(sync, clip=clip, cameras=cameras)
        if known is not None:
            return known
    fps, brightness = {}, {}
    for cam, path in paths_by_camera.items():
        try:
            fps[cam] = probe_video(path, fps_hint=fps_hint).fps
        except VideoError as exc:
            raise VideoError(f"{clip} clip of the {cam} camera: {exc}") from None
        brightness[cam] = clip_brightness(path, clip=clip, camera=cam)
    return clip_offsets(brightness, fps, clip=clip, **flash_kwargs)
