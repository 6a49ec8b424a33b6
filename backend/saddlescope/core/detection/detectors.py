"""Marker detectors by name: one registry that the pipeline consults, like the board types'.

A marker detector follows one camera's markers through a clip and returns its 2-D tracks
(:class:`~saddlescope.core.types.ImageTracks`, NaN where a marker was not found). The default,
``"bright_discs"``, is the thesis's filter chain (:func:`~saddlescope.core.detection.track_markers`).
Another detector (coloured markers, a learned key-point model) is a class with a ``name`` and a
``track`` method: a module of :mod:`saddlescope.core.detection` that defines ``MARKER_DETECTOR`` (an
instance) registers it by being there, and code elsewhere (a plug-in, a test) calls
:func:`register_detector`; ``PipelineParams.marker_detector`` names the one a ride uses and is checked
when the parameters are built, before any frame is decoded.

The user's overrides of a detector's automatic choices are typed (:class:`TrackOptions`, per clip set
and per camera in :class:`DetectionSettings`) and checked when built, with a sentence naming the value.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, fields
from typing import Any, Protocol

import numpy as np

from saddlescope.core.detection.tracking import track_markers
from saddlescope.core.errors import InputError
from saddlescope.core.types import ImageTracks

__all__ = ["DEFAULT_DETECTOR", "BrightDiscs", "DetectionSettings", "MarkerDetector", "TrackOptions",
           "detector_names", "marker_detector", "register_detector", "unregister_detector"]

DEFAULT_DETECTOR = "bright_discs"


@dataclass(frozen=True)
class TrackOptions:
    """A user's overrides of the tracker's automatic choices (None: chosen from the footage).

    threshold : grey level a marker's pixels exceed (0-255); fixed where given.
    area_range_px : (smallest, largest) blob area in pixels a marker may have.
    window_px : the search window's width (or (width, height)) in pixels around the prediction.
    distance_tol : relative tolerance of the vector between two markers against the last frame (eq. 4.11).
    lost_frames : frames without any marker before the tracker searches the whole frame again.
    search_every : frames between whole-frame searches while the markers are lost.
    """

    threshold: float | None = None
    area_range_px: tuple[float, float] | None = None
    window_px: int | tuple[int, int] | None = None
    distance_tol: float = 0.25
    lost_frames: int = 5
    search_every: int = 3

    def __post_init__(self) -> None:
        if self.threshold is not None and not (math.isfinite(self.threshold) and 0 < self.threshold < 255):
            raise InputError(f"a marker threshold must be a grey level between 0 and 255, got {self.threshold}")
        if self.area_range_px is not None:
            low, high = self.area_range_px
            if not (0 < low < high and math.isfinite(high)):
                raise InputError(f"a marker's area range must be two areas in pixels, smallest first, got "
                                 f"{self.area_range_px}")
        if self.window_px is not None:
            sizes = (self.window_px,) if isinstance(self.window_px, int) else tuple(self.window_px)
            if len(sizes) not in (1, 2) or any(int(s) < 8 for s in sizes):
                raise InputError(f"a search window must be at least 8 pixels wide and high, got {self.window_px}")
        if not 0 < self.distance_tol < 1:
            raise InputError(f"the markers' distance tolerance is a share between 0 and 1, got {self.distance_tol}")
        if self.lost_frames < 1 or self.search_every < 1:
            raise InputError("lost_frames and search_every must be at least one frame")

    def keywords(self) -> dict[str, Any]:
        """The options that differ from the defaults, as keyword arguments of ``track_markers``."""
        default = TrackOptions()
        return {f.name: getattr(self, f.name) for f in fields(self) if getattr(self, f.name) != getattr(default,
                                                                                                       f.name)}


@dataclass(frozen=True)
class DetectionSettings:
    """One clip set's options: the same for every camera, or one camera's own."""

    common: TrackOptions = field(default_factory=TrackOptions)
    per_camera: Mapping[str, TrackOptions] = field(default_factory=dict)

    def for_camera(self, camera: str) -> TrackOptions:
        """The options camera ``camera`` tracks with."""
        return self.per_camera.get(camera, self.common)


class MarkerDetector(Protocol):
    """What the pipeline needs of a marker detector."""

    @property
    def name(self) -> str:
        """The name ride parameters give it by (``PipelineParams.marker_detector``)."""
        ...

    def track(self, frames: Iterable[tuple[int, np.ndarray]], *, n_markers: int, camera: str, clip: str,
              options: TrackOptions, first_frame_xy: np.ndarray | None = None,
              moving: bool = False) -> ImageTracks:
        """Follow ``n_markers`` markers through ``frames`` ((index, grey (H, W)) pairs, consumed lazily).

        ``first_frame_xy`` (n_markers, 2) px: where the markers are on the first frame, when another step
        found them (all cameras at once); ``moving``: only what moves is a marker (no rig yet).
        Raises :class:`~saddlescope.core.errors.DetectionError` when the markers are not found.
        """
        ...


@dataclass(frozen=True)
class BrightDiscs:
    """The thesis's chain (4.5): threshold, labelling, area filter, window, vectors between markers."""

    name: str = DEFAULT_DETECTOR

    def track(self, frames: Iterable[tuple[int, np.ndarray]], *, n_markers: int, camera: str, clip: str,
              options: TrackOptions, first_frame_xy: np.ndarray | None = None,
              moving: bool = False) -> ImageTracks:
        """Follow the markers with :func:`~saddlescope.core.detection.track_markers`."""
        return track_markers(frames, n_markers=n_markers, camera=camera, clip=clip, first_frame_xy=first_frame_xy,
                             moving=moving, **options.keywords())


_DETECTORS: dict[str, MarkerDetector] = {DEFAULT_DETECTOR: BrightDiscs()}
_DISCOVERED: list[bool] = []  # the package's modules were searched for MARKER_DETECTOR (once)


def _discover() -> None:
    """Register the ``MARKER_DETECTOR`` of every module of :mod:`saddlescope.core.detection` (once)."""
    if _DISCOVERED:
        return
    _DISCOVERED.append(True)
    import importlib
    import pkgutil

    import saddlescope.core.detection as package

    for info in pkgutil.iter_modules(package.__path__):
        found = getattr(importlib.import_module(f"{package.__name__}.{info.name}"), "MARKER_DETECTOR", None)
        if found is not None:
            register_detector(found)


def register_detector(detector: MarkerDetector, *, replace: bool = False) -> MarkerDetector:
    """Make a marker detector known by its ``name``; returns it.

    Raises
    ------
    InputError
        Another detector of that name is registered already (unless ``replace``).
    """
    if _DETECTORS.get(detector.name) is detector:
        return detector
    if detector.name in _DETECTORS and not replace:
        raise InputError(f"a marker detector named {detector.name!r} is registered already")
    _DETECTORS[detector.name] = detector
    return detector


def unregister_detector(name: str) -> None:
    """Forget a detector (a test's or a plug-in's); the default stays."""
    if name != DEFAULT_DETECTOR:
        _DETECTORS.pop(name, None)


def detector_names() -> list[str]:
    """The registered detectors' names, the default first."""
    _discover()
    return list(_DETECTORS)


def marker_detector(name: str) -> MarkerDetector:
    """The detector registered as ``name``; an InputError naming the known ones otherwise."""
    _discover()
    try:
        return _DETECTORS[name]
    except KeyError:
        raise InputError(f"no marker detector is called {name!r}; the known ones are "
                         f"{', '.join(detector_names())}") from None
