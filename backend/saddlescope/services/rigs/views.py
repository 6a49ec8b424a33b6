"""What the rig page shows: the board to print at true scale, the calibration in plain words, coverage.

The printable board is the board type's own texture (`BoardType.texture`, the same image the arena
renders), wrapped in an SVG whose width and height are in millimetres, so a browser printing at
100 % gives squares of exactly ``square_mm``.
"""

from __future__ import annotations

import base64
import html
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Literal

import cv2
import numpy as np

from saddlescope.core.calibration.boards import board_from_meta, board_type
from saddlescope.core.errors import InputError

__all__ = ["CalibrationQuality", "CameraCoverage", "Grade", "NotCalibrated", "board_svg", "board_svg_size_mm",
           "board_words", "calibration_words", "coverage_words"]

_PX_PER_SQUARE = 48
Grade = Literal["good", "fair", "poor"]


@dataclass(frozen=True)
class NotCalibrated:
    """A rig without a calibration: its quality is one sentence saying so."""

    sentences: tuple[str, ...] = ("Not calibrated yet.",)
    calibrated: Literal[False] = False


@dataclass(frozen=True)
class CalibrationQuality:
    """A rig's calibration in plain words (`calibration_words`)."""

    reprojection_px: float | None  # the worst camera's reprojection r.m.s.; None: no camera says
    board_square_error_mm: float | None  # how far the rebuilt board squares are off
    reprojection_grade: Grade | None
    square_grade: Grade | None
    flags: tuple[str, ...]
    n_views: Mapping[str, int] | None  # camera -> the board views its lens was fitted with
    sentences: tuple[str, ...]
    refined_by_wand: bool | None  # None: no wand was offered
    calibrated: Literal[True] = True


@dataclass(frozen=True)
class CameraCoverage:
    """Where in one camera's image the board has been (`coverage_words`)."""

    image_size: tuple[int, int]  # px, width and height
    corners_px: tuple[tuple[float, float], ...]  # the board corners seen (a sample)
    hull_px: tuple[tuple[float, float], ...] | None  # their convex hull; None: not stored
    area_fraction: float | None  # the hull's share of the image
    missed: tuple[str, ...] | None  # the ninths of the image no corner reached; None: corners not stored
    sentence: str


def board_svg_size_mm(board_meta: Mapping[str, Any]) -> tuple[float, float]:
    """Printed width and height (mm) of the board's SVG: its squares plus a one-square white margin."""
    board = board_from_meta(dict(board_meta))
    texture, px_per_mm, _ = board_type(board.kind).texture(board, px_per_square=_PX_PER_SQUARE)
    return texture.shape[1] / px_per_mm, texture.shape[0] / px_per_mm


def board_words(board_meta: Mapping[str, Any] | None) -> str:
    """The rig's board in words (its type's :meth:`describe`), or what is wrong with its description."""
    if not board_meta:
        return "no board described"
    try:
        board = board_from_meta(dict(board_meta))
    except InputError as exc:
        return f"a board not described right ({exc})"
    return board_type(board.kind).describe(board)


def board_svg(board_meta: Mapping[str, Any]) -> str:
    """The board as an SVG document at true scale (``width``/``height`` in mm, ``viewBox`` in mm).

    Raises
    ------
    InputError
        The board section is not a valid board.
    """
    try:
        board = board_from_meta(dict(board_meta))
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(f"the rig's board is not a valid board: {exc}") from None
    texture, px_per_mm, _ = board_type(board.kind).texture(board, px_per_square=_PX_PER_SQUARE)
    ok, png = cv2.imencode(".png", np.ascontiguousarray(texture))
    if not ok:  # pragma: no cover - OpenCV encodes any uint8 image
        raise InputError("the board image could not be drawn")
    width_mm, height_mm = texture.shape[1] / px_per_mm, texture.shape[0] / px_per_mm
    title = html.escape(board_type(board.kind).describe(board), quote=True)
    data = base64.b64encode(png.tobytes()).decode("ascii")
    return (
        f'<svg xmlns="http://www.w3.org/2000/svg" xmlns:xlink="http://www.w3.org/1999/xlink" '
        f'width="{width_mm:g}mm" height="{height_mm:g}mm" viewBox="0 0 {width_mm:g} {height_mm:g}" '
        f'role="img" aria-label="{title}">'
        f"<title>{title}</title>"
        f'<image x="0" y="0" width="{width_mm:g}" height="{height_mm:g}" preserveAspectRatio="none" '
        f'style="image-rendering:pixelated" href="data:image/png;base64,{data}"/>'
        "</svg>"
    )


def _grade(value: float | None, good: float, fair: float) -> Grade | None:
    if value is None or not np.isfinite(value):
        return None
    return "good" if value <= good else "fair" if value <= fair else "poor"


def calibration_words(calibration: Mapping[str, Any] | None) -> CalibrationQuality | NotCalibrated:
    """The calibration's quality in plain words: reprojection error (px), board square error (mm), wand refinement.

    ``refined_by_wand``: whether a wand refined the board's calibration (None where no wand was offered).

    Thresholds: a reprojection r.m.s. under 0.5 px is good, under 1 px fair (a phone video's corner
    noise); squares rebuilt within 0.5 mm good, within 1 mm fair (CONTRACTS' 1 mm board check).
    """
    if not calibration:
        return NotCalibrated()
    cams = calibration.get("cameras") or {}
    rms = [float(c["rms_px"]) for c in cams.values() if isinstance(c.get("rms_px"), int | float)]
    reproj = max(rms) if rms else None
    square = (calibration.get("checks") or {}).get("board_square_error_mm")
    square = float(square) if isinstance(square, int | float) else None
    sentences = []
    grade = _grade(reproj, 0.5, 1.0)
    if grade:
        sentences.append(
            f"Reprojection error {reproj:.2f} px (worst camera): "
            + {"good": "good, the corners fit the lens model closely.",
               "fair": "fair; usable, but sharper, slower board movement would help.",
               "poor": "poor: the board was blurred or badly lit; film the calibration again."}[grade])
    sq_grade = _grade(square, 0.5, 1.0)
    if sq_grade:
        sentences.append(
            f"Board squares rebuilt within {square:.2f} mm: "
            + {"good": "good, distances are measured accurately.",
               "fair": "fair; distances are within a millimetre.",
               "poor": "poor: check the square size typed for the board, and that the print was at 100 %."}[sq_grade])
    sentences += _lens_sentences(cams)
    refinement = calibration.get("wand_refinement")
    if isinstance(refinement, Mapping) and isinstance(refinement.get("sentence"), str):
        sentences.append(refinement["sentence"])  # issue 35: refined by the wand or not, and why
    n_views = calibration.get("n_views")
    return CalibrationQuality(
        reprojection_px=reproj, board_square_error_mm=square, reprojection_grade=grade, square_grade=sq_grade,
        flags=tuple(str(f) for f in calibration.get("flags") or []),
        n_views={str(c): int(n) for c, n in n_views.items()} if isinstance(n_views, Mapping) else None,
        sentences=tuple(sentences),
        refined_by_wand=bool(refinement.get("kept")) if isinstance(refinement, Mapping) else None)


def _lens_sentences(cams: Mapping[str, Any]) -> list[str]:
    """One sentence per camera whose lens was not fitted with all cameras' views: held from its own, or given.

    From each camera's ``lens_model`` (issue 35): which lens parameters its own views fixed, in words.
    """
    out = []
    for name, cam in cams.items():
        model = cam.get("lens_model") if isinstance(cam, Mapping) else None
        if not isinstance(model, Mapping) or (model.get("joint", True) and not model.get("given")):
            continue
        if model.get("given"):
            out.append(f"Camera {name}'s lens was given (an earlier calibration or a lens profile); "
                       "only its position was fitted.")
            continue
        fixed = [w for flag, w in (("equal_focal", "one focal length for x and y"),
                                   ("principal_point", "the principal point at the image centre"),
                                   ("tangential", "no tangential distortion"))
                 if bool(model.get(flag)) == (flag == "equal_focal")]
        how = f", in the simplest model they support ({', '.join(fixed)})" if fixed else ""
        out.append(f"Camera {name}'s lens comes from its own views{how}: the other cameras' views would have "
                   "bent it. Next time carry the board to the edges of its view.")
    return out


_REGIONS = [["top-left corner", "top edge", "top-right corner"],
            ["left edge", "centre", "right edge"],
            ["bottom-left corner", "bottom edge", "bottom-right corner"]]


def coverage_words(calibration: Mapping[str, Any] | None) -> dict[str, CameraCoverage]:
    """Per camera: image size, board corners seen (px), hull, share of the image, regions never reached.

    The image is cut in 3 x 3 parts; a part no corner reached is named in the sentence.
    """
    if not calibration:
        return {}
    corners = calibration.get("board_corners_px") or {}
    coverage = calibration.get("board_coverage") or {}
    return {name: _camera_coverage(name, cam, corners.get(name), coverage.get(name) or {})
            for name, cam in (calibration.get("cameras") or {}).items()}


def _points(stored: object) -> tuple[tuple[float, float], ...]:
    """Stored [[x, y], ...] pixel points as pairs of floats."""
    pts = np.asarray(stored or [], dtype=np.float64).reshape(-1, 2)
    return tuple((float(x), float(y)) for x, y in pts)


def _camera_coverage(name: str, cam: Mapping[str, Any], corners: object,
                     covered: Mapping[str, Any]) -> CameraCoverage:
    w, h = (int(v) for v in (cam.get("image_size") or [0, 0])[:2])
    pts = _points(corners)
    hull, area = covered.get("hull_px"), covered.get("area_fraction")
    missed: tuple[str, ...] | None = None
    if pts and w and h:
        cells = {(min(int(3 * y / h), 2), min(int(3 * x / w), 2)) for x, y in pts}
        missed = tuple(_REGIONS[r][c] for r in range(3) for c in range(3) if (r, c) not in cells)
        sentence = (
            f"The board reached every part of the {name} camera's image." if not missed else
            f"The board never reached the {', '.join(missed[:-1]) + ' and ' if len(missed) > 1 else ''}"
            f"{missed[-1]} of the {name} camera's image: distances measured there are less certain; "
            "carry the board there when you film the calibration again.")
    else:
        sentence = (f"Where the board was in the {name} camera's image is not stored for this "
                    "calibration; calibrate again to see it.")
    return CameraCoverage(image_size=(w, h), corners_px=pts, hull_px=_points(hull) if hull is not None else None,
                          area_fraction=float(area) if isinstance(area, int | float) else None, missed=missed,
                          sentence=sentence)
