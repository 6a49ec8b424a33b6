"""Use case: check calibration clips within a minute or two, before anyone rides (issue 35).

Each camera's clip is sampled (a few frames a second, at least ``MIN_SAMPLES`` frames of a short clip),
the board is searched in each sampled frame, and :func:`~saddlescope.core.calibration.coverage_check.
check_camera_coverage` judges where it went. The rig page runs it as the ``check_calibration`` job on
every calibration clip uploaded (its answer stored beside the rig's clips); ``saddlescope
check-calibration`` runs it on files.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from saddlescope.core.calibration import detect_board_views
from saddlescope.core.calibration.boards import board_from_meta
from saddlescope.core.calibration.coverage_check import CameraCoverageCheck, check_camera_coverage, check_wand_coverage
from saddlescope.core.calibration.wand import track_wand_ends, wand_length_problem
from saddlescope.core.errors import InputError
from saddlescope.core.findings import FINDING_KINDS
from saddlescope.core.types import CAMERA_ROLES
from saddlescope.io.findings_document import findings_to_list
from saddlescope.io.video import iter_gray_frames, probe_video

__all__ = ["CHECK_WIDTH_PX", "MIN_SAMPLES", "SAMPLE_FPS", "CalibrationCheck", "check_calibration_clips",
           "check_document", "check_storage_key", "check_wand_clips", "checked_with", "merged_check_document",
           "reusable_cameras", "sample_step"]

SAMPLE_FPS = 3.0  # frames a second looked at: the board moves slowly, and a view a third of a second on is new
MIN_SAMPLES = 40  # a short clip is looked at more densely, down to every frame
CHECK_WIDTH_PX = 1440  # frames are searched at this width: a 9 px square at 1080p keeps 6.75 px
# Raise when the check's answer for the same clip changes: a stored camera's answer is reused only by the same revision.
CHECK_REVISION = 1


def sample_step(fps: float, frame_count: int, *, sample_fps: float = SAMPLE_FPS,
                min_samples: int = MIN_SAMPLES) -> int:
    """Every how many frames one is looked at: ``sample_fps`` a second, but at least ``min_samples`` frames."""
    by_rate = max(1, int(round(float(fps) / sample_fps))) if fps and fps > 0 else 1
    by_count = max(1, int(frame_count) // min_samples) if frame_count else by_rate
    return min(by_rate, by_count)


@dataclass(frozen=True)
class CalibrationCheck:
    """The calibration clips checked: per camera the coverage, and the seconds the check took."""

    cameras: dict[str, CameraCoverageCheck]
    seconds: float
    what: str = "board"  # what the clips show: "board" (the board walk) or "wand"

    @property
    def film_again(self) -> bool:
        """Whether any camera's clip should be filmed again before riding."""
        return any(c.film_again for c in self.cameras.values())

    def verdict(self) -> str:
        """The answer in one sentence."""
        return _verdict([name for name, c in self.cameras.items() if c.film_again], self.what)


def _verdict(again: list[str], what: str) -> str:
    """The check's answer in one sentence, from the cameras whose clip should be filmed again."""
    if not again:
        return f"Ready to ride: the {what} was seen well in every camera's view."
    names = again[0] if len(again) == 1 else ", ".join(again[:-1]) + " and " + again[-1]
    if len(again) == 1:
        return f"Film again: the {names} camera's {what} clip does not cover its view well enough."
    return f"Film again: the {names} cameras' {what} clips do not cover their views well enough."


def check_calibration_clips(
    paths: Mapping[str, Path],
    board_meta: Mapping[str, Any],
    *,
    sample_fps: float = SAMPLE_FPS,
    on_progress: Callable[[float, str], None] | None = None,
) -> CalibrationCheck:
    """Check each camera's calibration clip (any of left, middle, right present).

    Raises
    ------
    InputError
        The board section is not a valid board; VideoError: a clip does not decode.
    """
    board = board_from_meta(dict(board_meta))
    t0 = time.perf_counter()
    order = _camera_order(paths)
    out: dict[str, CameraCoverageCheck] = {}
    for n, camera in enumerate(order):
        if on_progress is not None:
            on_progress(n / len(order), f"the {camera} camera")
        clip = _SampledClip(Path(paths[camera]), sample_fps, width_px=CHECK_WIDTH_PX)
        # One search per frame at one width (max_width just under it: neither downscaled nor tried again
        # enlarged, as the calibration's finder does): the check wants where the board went, fast.
        width = max(2, round(clip.info.width * clip.scale))
        views, _ = detect_board_views(clip.frames(), board, track=False, max_width=width - 1)
        sightings = [((v.corners_px + 0.5) / clip.scale - 0.5, v.ids) for v in views]
        out[camera] = check_camera_coverage(camera, sightings, board, (clip.info.width, clip.info.height),
                                            frames_sampled=clip.sampled)
    return CalibrationCheck(out, time.perf_counter() - t0)


class _SampledClip:
    """One camera's clip as the checks look at it: every `step`-th frame (`sample_step`), at `width_px` wide.

    ``sampled`` counts the frames :meth:`frames` has yielded so far.
    """

    def __init__(self, path: Path, sample_fps: float, *, width_px: int | None = None) -> None:
        self.path = path
        self.info = probe_video(path, decode_tail=False)
        self.step = sample_step(self.info.fps, self.info.frame_count, sample_fps=sample_fps)
        self.scale = width_px / self.info.width if width_px and self.info.width else 1.0
        self.sampled = 0

    def frames(self) -> Iterator[tuple[int, np.ndarray]]:
        """(frame index, grey frame) of the sampled frames, resized to the check's width."""
        for index, gray in iter_gray_frames(self.path, step=self.step):
            self.sampled += 1
            yield index, (gray if self.scale == 1.0 else cv2.resize(
                gray, None, fx=self.scale, fy=self.scale,
                interpolation=cv2.INTER_AREA if self.scale < 1 else cv2.INTER_CUBIC))


def _camera_order(paths: Mapping[str, object]) -> list[str]:
    """The clips' cameras, the rig's roles first (left, middle, right), then any other by name."""
    return [c for c in CAMERA_ROLES if c in paths] + sorted(c for c in paths if c not in CAMERA_ROLES)


def check_wand_clips(paths: Mapping[str, Path], wand_length_m: float, *, sample_fps: float = 2 * SAMPLE_FPS,
                     on_progress: Callable[[float, str], None] | None = None) -> CalibrationCheck:
    """Check each camera's wand clip: where the wand's two ends went over the image and in depth.

    The wand moves all the time, so twice the board's rate of frames is looked at; the ends are found in
    each (:func:`~saddlescope.core.calibration.wand.track_wand_ends`) and judged by
    :func:`~saddlescope.core.calibration.coverage_check.check_wand_coverage`.

    Raises
    ------
    InputError
        The wand's length is outside `WAND_LENGTH_RANGE_M` (core.calibration.wand); VideoError: a clip does not decode.
    """
    if problem := wand_length_problem(wand_length_m):
        raise InputError(problem)
    t0 = time.perf_counter()
    order = _camera_order(paths)
    out: dict[str, CameraCoverageCheck] = {}
    for n, camera in enumerate(order):
        if on_progress is not None:
            on_progress(n / len(order), f"the {camera} camera")
        clip = _SampledClip(Path(paths[camera]), sample_fps)
        views = track_wand_ends(clip.frames())
        out[camera] = check_wand_coverage(camera, [v.ends_px for v in views], (clip.info.width, clip.info.height),
                                          frames_sampled=clip.sampled, wand_length_mm=1000.0 * float(wand_length_m))
    return CalibrationCheck(out, time.perf_counter() - t0, what="wand")


def check_storage_key(rig_id: int, what: str = "board") -> str:
    """Where a rig's latest check of its board (``what`` "board") or wand clips ("wand") is stored.

    Under the rig's own prefix, deleted with it.
    """
    if what not in ("board", "wand"):
        raise InputError(f"a calibration check is of the board or the wand clips, not {what!r}")
    return f"rigs/{int(rig_id)}/{'calibration' if what == 'board' else 'wand'}-check.json"


def _rounded(values: np.ndarray, digits: int = 2) -> list[float | None]:
    return [round(float(v), digits) if np.isfinite(v) else None for v in values]


def _camera_document(c: CameraCoverageCheck) -> dict[str, Any]:
    known = c.distances_m[np.isfinite(c.distances_m)]
    edges = np.linspace(0.0, max(1.0, float(np.ceil(known.max()))) if len(known) else 1.0, 9)
    counts = np.histogram(known, bins=edges)[0] if len(known) else np.zeros(8, int)
    return {
        "camera": c.camera, "image_size": list(c.image_size), "frames_sampled": c.frames_sampled, "views": c.views,
        "grid": c.grid.astype(int).tolist(), "bands_missed": list(c.bands_missed),
        "corners_missed": list(c.corners_missed),
        "reach_x": [round(v, 3) for v in c.reach_x], "reach_y": [round(v, 3) for v in c.reach_y],
        "hull_fraction": round(c.hull_fraction, 3),
        "depth": {"near_m": round(float(np.percentile(known, 10)), 2) if len(known) else None,
                  "far_m": round(float(np.percentile(known, 90)), 2) if len(known) else None,
                  "bin_edges_m": _rounded(edges), "views": counts.astype(int).tolist()},
        "film_again": c.film_again,
        "findings": [{**f, "advice": FINDING_KINDS[f["code"]].advice} for f in findings_to_list(c.findings)],
    }


def check_document(check: CalibrationCheck, *, clips: Mapping[str, int] | None = None) -> dict[str, Any]:
    """The check as JSON (stored for the rig page, printed by the command line)."""
    cameras = {name: _camera_document(c) for name, c in check.cameras.items()}
    return {**_document(cameras, check.what, check.seconds), **({"clips": dict(clips)} if clips is not None else {})}


def _document(cameras: dict[str, dict[str, Any]], what: str, seconds: float) -> dict[str, Any]:
    """A check's document from its cameras' documents: the verdict follows their ``film_again``."""
    again = [name for name, answer in cameras.items() if answer.get("film_again")]
    return {"film_again": bool(again), "verdict": _verdict(again, what), "seconds": round(seconds, 1),
            "cameras": cameras}


def checked_with(what: str, *, board: Mapping[str, Any] | None = None, wand_length_m: float | None = None
                 ) -> dict[str, Any]:
    """What a camera's stored answer depends on besides its clip: the check's revision and the board (or wand)."""
    return {"revision": CHECK_REVISION, "what": what,
            **({"board": dict(board or {})} if what == "board" else {"wand_length_m": float(wand_length_m or 0.0)})}


def reusable_cameras(previous: Mapping[str, Any] | None, sha256: Mapping[str, str | None],
                     inputs: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    """The previous check's camera answers that still hold: the same clip bytes, board (or wand) and revision.

    Clips are uploaded one by one and each upload checks the rig's clips again; a clip already checked
    is not decoded and searched a second time (a minute on a 1080p clip). A camera's clip replaced by
    another take keeps its recording id, so the bytes' SHA-256 decides.
    """
    if not previous or previous.get("checked_with") != dict(inputs):
        return {}
    before, answers = previous.get("clip_sha256") or {}, previous.get("cameras") or {}
    return {role: dict(answers[role]) for role, digest in sha256.items()
            if digest and before.get(role) == digest and isinstance(answers.get(role), dict)}


def merged_check_document(check: CalibrationCheck | None, reused: Mapping[str, dict[str, Any]], *,
                          clips: Mapping[str, int], sha256: Mapping[str, str | None],
                          inputs: Mapping[str, Any]) -> dict[str, Any]:
    """The check's document from the cameras checked now (`check`) and the answers reused, in the rig's camera order."""
    fresh = {name: _camera_document(c) for name, c in check.cameras.items()} if check is not None else {}
    cameras = {role: (fresh[role] if role in fresh else dict(reused[role]))
               for role in _camera_order({**fresh, **reused})}
    return {**_document(cameras, str(inputs["what"]), check.seconds if check is not None else 0.0),
            "clips": dict(clips), "clip_sha256": dict(sha256), "checked_with": dict(inputs)}
