"""The calibration board as a club prints it: sizes that fit A4 / A3 / a poster, tiles of A4 sheets, print pages.

A board is drawn as vector rectangles (its own texture, `BoardType.texture`, run-length merged into
black rectangles), so it prints sharp at any size and its squares can be measured in the PDF. A print
page is one HTML document whose ``@page`` size and every sheet are in millimetres, so that Chromium
(or any browser told "actual size") prints it at scale. Every sheet carries a 100 mm ruler bar: measure
it to see that the printer did not scale.

Which square size a camera needs (the trade-off the rig page states): a camera ``W`` pixels wide with a
horizontal field of view ``θ`` sees, at ``d`` metres, a strip ``2 d tan(θ/2)`` wide, so one pixel covers
``2 d tan(θ/2) / W`` metres. The corner detectors need a square of at least ``N`` pixels (the board
type's ``min_square_px``: 8 for a checkerboard: the detector searches a 2x enlarged frame for smaller
squares, but finds them less often and less exactly; 16 for a ChArUco board, whose markers' cells are an
eighth of a square and need 2 px each), hence a square of at least ``N · 2 d tan(θ/2) / W`` -- 47 mm at
8 m from a 1920-pixel phone with a 70° view, 23 mm at 4 m (the 50 mm squares the filming guide asks for
reach 8.6 m). A board's printed size is its type's texture's: the pattern and one square of white margin
all round.
"""

from __future__ import annotations

import html
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from saddlescope.core.calibration.boards import board_from_meta, board_type
from saddlescope.core.errors import InputError
from saddlescope.core.types import Board

__all__ = ["ASSUMED_HFOV_DEG", "ASSUMED_WIDTH_PX", "DISTANCES_M", "LAYOUTS", "PAPERS_MM", "BoardAdvice",
           "BoardLayout", "CameraView", "board_advice", "board_layouts", "board_print_html", "board_size_mm",
           "camera_view", "min_square_px", "square_needed_mm", "tile_grid"]

# Paper sizes (width, height) mm, portrait; A2-A0 are a print shop's posters.
PAPERS_MM: dict[str, tuple[float, float]] = {
    "a4": (210.0, 297.0), "a3": (297.0, 420.0), "a2": (420.0, 594.0), "a1": (594.0, 841.0), "a0": (841.0, 1189.0)}
# Print layouts: one sheet of each paper, or tiles of A4 sheets.
LAYOUTS = ("a4", "a3", "a2", "a1", "a0", "a4-tiles")
MARGIN_MM = 10.0  # an office printer leaves 3-5 mm blank at the edges; the marks and labels live here
FOOTER_MM = 18.0  # the label and the 100 mm ruler below the board
OVERLAP_MM = 10.0  # each tile repeats this much of its right and lower neighbour: the glue strip
RULER_MM = 100.0
_PX_PER_SQUARE = 48  # texture resolution before vectorising: ChArUco marker cells fall on whole pixels
ASSUMED_WIDTH_PX = 1920  # a phone filming 1080p
ASSUMED_HFOV_DEG = 70.0  # a phone's main camera, filming landscape
DISTANCES_M = (2.0, 4.0, 6.0, 8.0, 10.0, 12.0)


@dataclass(frozen=True)
class CameraView:
    """The camera the advice is for: its image width (px) and horizontal field of view (degrees)."""

    image_width_px: int
    hfov_deg: float
    source: str  # "calibration": the rig's own lenses; "clips": the clips' width, a phone's view; "assumed"


def camera_view(calibration: Mapping[str, Any] | None, clip_widths_px: list[int]) -> CameraView:
    """The widest camera of the rig: from its calibration (focal length), else its clips, else a 1080p phone."""
    views = []
    for cam in ((calibration or {}).get("cameras") or {}).values():
        try:
            width = float(cam["image_size"][0])
            fx = float(cam["K"][0][0])
        except (KeyError, IndexError, TypeError, ValueError):
            continue
        if width > 0 and fx > 0:
            views.append((width, math.degrees(2 * math.atan(width / (2 * fx)))))
    if views:
        width, hfov = max(views, key=lambda v: v[1])  # the widest view needs the biggest squares
        return CameraView(int(width), round(hfov, 1), "calibration")
    widths = [w for w in clip_widths_px if w]
    if widths:
        return CameraView(int(min(widths)), ASSUMED_HFOV_DEG, "clips")
    return CameraView(ASSUMED_WIDTH_PX, ASSUMED_HFOV_DEG, "assumed")


def min_square_px(kind: str) -> int:
    """Pixels a square needs in a frame for the board to be found surely (its type's: 8 checkerboard, 16 ChArUco)."""
    return board_type(kind).min_square_px


def square_needed_mm(distance_m: float, *, image_width_px: int, hfov_deg: float, kind: str) -> float:
    """Smallest square (mm) a camera ``image_width_px`` wide with view ``hfov_deg`` resolves at ``distance_m``."""
    mm_per_px = 2000.0 * distance_m * math.tan(math.radians(hfov_deg) / 2.0) / image_width_px
    return min_square_px(kind) * mm_per_px


def _board(board_meta: Mapping[str, Any]) -> Board:
    try:
        return board_from_meta(dict(board_meta))
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(f"the rig's board is not a valid board: {exc}") from None


def board_size_mm(board: Board) -> tuple[float, float]:
    """Printed width and height (mm): its type's texture, the pattern plus a one-square white margin all round."""
    # at print resolution: a ChArUco marker needs a few pixels a cell
    texture, px_per_mm, _ = board_type(board.kind).texture(board, px_per_square=_PX_PER_SQUARE)
    return round(texture.shape[1] / px_per_mm, 6), round(texture.shape[0] / px_per_mm, 6)  # whole squares


@dataclass(frozen=True)
class BoardLayout:
    """One way to print the board: its paper, sheets, whether it fits, the largest square it would allow."""

    layout: str
    label: str
    sheets: int
    fits: bool
    landscape: bool
    largest_square_mm: float  # the biggest square of this board's pattern that fits one such sheet
    reach_m: float  # how far from the camera that largest square is still resolved


def _printable_mm(paper: str, landscape: bool) -> tuple[float, float]:
    w, h = PAPERS_MM[paper]
    if landscape:
        w, h = h, w
    return w - 2 * MARGIN_MM, h - 2 * MARGIN_MM - FOOTER_MM


def _single_sheet(board: Board, paper: str) -> tuple[bool, bool, float]:
    """(fits, landscape, largest square mm) of the board on one sheet of ``paper``."""
    width_mm, height_mm = board_size_mm(board)
    best = (False, False, 0.0)
    for landscape in (False, True):
        pw, ph = _printable_mm(paper, landscape)
        largest = board.square_mm * min(pw / width_mm, ph / height_mm)  # the print scales with the square
        fits = width_mm <= pw + 1e-6 and height_mm <= ph + 1e-6
        if (fits, largest) > (best[0], best[2]):
            best = (fits, landscape, largest)
    return best


def tile_grid(board: Board, paper: str = "a4") -> tuple[int, int, bool, float, float]:
    """How A4 (or ``paper``) tiles cut the board's squares: (columns, rows, landscape, cell width, cell height mm).

    The tiles cover the squares only (the white margin is the mounting board's); each sheet owns an
    equal cell and repeats ``OVERLAP_MM`` of its neighbours to the right and below (the glue strip); the
    orientation giving fewer sheets wins.
    """
    width_mm, height_mm = (size - 2 * board.square_mm for size in board_size_mm(board))  # less the margin
    best: tuple[int, int, bool, float, float] | None = None
    for landscape in (False, True):
        pw, ph = _printable_mm(paper, landscape)
        n_cols = max(1, math.ceil(width_mm / (pw - OVERLAP_MM) - 1e-9))
        n_rows = max(1, math.ceil(height_mm / (ph - OVERLAP_MM) - 1e-9))
        if best is None or n_cols * n_rows < best[0] * best[1]:
            best = (n_cols, n_rows, landscape, width_mm / n_cols, height_mm / n_rows)
    assert best is not None
    return best


def board_layouts(board_meta: Mapping[str, Any], *, image_width_px: int, hfov_deg: float) -> list[BoardLayout]:
    """Every layout of :data:`LAYOUTS` for this board, with the largest square each paper allows and its reach."""
    board = _board(board_meta)
    px = min_square_px(board.kind)
    mm_per_px_per_m = 2000.0 * math.tan(math.radians(hfov_deg) / 2.0) / image_width_px

    def reach(square_mm: float) -> float:
        return square_mm / (px * mm_per_px_per_m)

    out = []
    for paper in PAPERS_MM:
        fits, landscape, largest = _single_sheet(board, paper)
        poster = " (a print shop's poster)" if paper in ("a2", "a1", "a0") else ""
        out.append(BoardLayout(paper, f"One {paper.upper()} sheet{poster}", 1, fits, landscape, largest,
                               reach(largest)))
    n_cols, n_rows, landscape, _, _ = tile_grid(board)
    out.append(BoardLayout("a4-tiles", f"A4 sheets glued together ({n_cols} \u00d7 {n_rows})", n_cols * n_rows,
                           True, landscape, board.square_mm, reach(board.square_mm)))
    return out


# ----------------------------------------------------------------------------------- drawing


def _dark_rects_mm(board: Board) -> list[tuple[float, float, float, float]]:
    """The board's black areas as rectangles (x, y, w, h) in mm, origin at the top-left of its margin."""
    texture, px_per_mm, _ = board_type(board.kind).texture(board, px_per_square=_PX_PER_SQUARE)
    dark = np.asarray(texture) < 128
    rects: list[tuple[float, float, float, float]] = []
    open_runs: dict[tuple[int, int], int] = {}  # a run (x0, x1) -> the row it started in
    for y in range(dark.shape[0] + 1):
        runs: set[tuple[int, int]] = set()
        if y < dark.shape[0]:
            edges = np.flatnonzero(np.diff(np.concatenate(([0], dark[y].astype(np.int8), [0]))))
            runs = {(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2], strict=True)}
        for run in [r for r in open_runs if r not in runs]:
            y0 = open_runs.pop(run)
            rects.append((run[0] / px_per_mm, y0 / px_per_mm, (run[1] - run[0]) / px_per_mm, (y - y0) / px_per_mm))
        for run in runs:
            open_runs.setdefault(run, y)
    return rects


def _n(value: float) -> str:
    return f"{value:.3f}".rstrip("0").rstrip(".")


def _board_group(board: Board) -> str:
    rects = "".join(f'<rect x="{_n(x)}" y="{_n(y)}" width="{_n(w)}" height="{_n(h)}"/>'
                    for x, y, w, h in _dark_rects_mm(board))
    return f'<g id="board" fill="#000">{rects}</g>'


def _ruler(x: float, y: float) -> str:
    """A 100 mm bar with ticks every 10 mm and the words to check it."""
    ticks = "".join(f'<line x1="{_n(x + i * 10)}" y1="{_n(y - (3 if i % 5 == 0 else 1.5))}" x2="{_n(x + i * 10)}" '
                    f'y2="{_n(y)}" stroke="#000" stroke-width="0.3"/>' for i in range(11))
    return (f'<rect class="ruler" x="{_n(x)}" y="{_n(y)}" width="{_n(RULER_MM)}" height="2.5" fill="#000"/>{ticks}'
            f'<text x="{_n(x)}" y="{_n(y + 6)}" font-size="2.8">This bar must measure exactly 100 mm; if not, '
            "print again at 100 % (actual size).</text>")


def _crop_marks(x: float, y: float, w: float, h: float) -> str:
    """Short lines in the margin continuing the cell's edges: cut along them."""
    lines = []
    for cx in (x, x + w):
        lines += [(cx, y - 8, cx, y - 2), (cx, y + h + 2, cx, y + h + 7)]
    for cy in (y, y + h):
        lines += [(x - 8, cy, x - 2, cy), (x + w + 2, cy, x + w + 8, cy)]
    return "".join(f'<line x1="{_n(a)}" y1="{_n(b)}" x2="{_n(c)}" y2="{_n(d)}" stroke="#000" stroke-width="0.25"/>'
                   for a, b, c, d in lines)


def _tile_name(row: int, col: int) -> str:
    return f"{chr(ord('A') + row)}{col + 1}"


def _sheet(page_w: float, page_h: float, body: str) -> str:
    return (f'<section class="sheet"><svg xmlns="http://www.w3.org/2000/svg" width="{_n(page_w)}mm" '
            f'height="{_n(page_h)}mm" viewBox="0 0 {_n(page_w)} {_n(page_h)}" font-family="sans-serif">'
            f"{body}</svg></section>")


def _single_sheets(board: Board, paper: str, title: str) -> tuple[float, float, list[str]]:
    fits, landscape, largest = _single_sheet(board, paper)
    width_mm, height_mm = board_size_mm(board)
    if not fits:
        raise InputError(
            f"the board is {width_mm:.0f} \u00d7 {height_mm:.0f} mm and does not fit on one {paper.upper()} sheet "
            f"(its squares could be at most {math.floor(largest)} mm there): print it on A4 tiles or a larger "
            "paper, or change the board's square size")
    page_w, page_h = PAPERS_MM[paper][::-1] if landscape else PAPERS_MM[paper]
    x = (page_w - width_mm) / 2
    y = MARGIN_MM
    body = (f'<use href="#board" x="{_n(x)}" y="{_n(y)}"/>'
            f'<text x="{_n(MARGIN_MM)}" y="{_n(y + height_mm + 6)}" font-size="3.5">{html.escape(title)}</text>'
            + _ruler(MARGIN_MM, y + height_mm + 10))
    return page_w, page_h, [_sheet(page_w, page_h, body)]


def _tile_sheets(board: Board, title: str) -> tuple[float, float, list[str]]:
    n_cols, n_rows, landscape, cell_w, cell_h = tile_grid(board)
    page_w, page_h = PAPERS_MM["a4"][::-1] if landscape else PAPERS_MM["a4"]
    sheets = []
    for row in range(n_rows):
        for col in range(n_cols):
            # the cell this sheet owns, in board mm (the squares start one square in, past the margin)
            bx, by = board.square_mm + col * cell_w, board.square_mm + row * cell_h
            show_w = cell_w + (OVERLAP_MM if col + 1 < n_cols else 0.0)
            show_h = cell_h + (OVERLAP_MM if row + 1 < n_rows else 0.0)
            x0, y0 = MARGIN_MM, MARGIN_MM
            name = _tile_name(row, col)
            notes = [f"Sheet {name}: row {row + 1} of {n_rows}, column {col + 1} of {n_cols}."]
            if col + 1 < n_cols:
                notes.append(f"{_tile_name(row, col + 1)} goes over the strip right of the marks.")
            if row + 1 < n_rows:
                notes.append(f"{_tile_name(row + 1, col)} over the strip below.")
            if col or row:
                notes.append("Cut along the marks left and top.")
            body = (f'<svg x="{_n(x0)}" y="{_n(y0)}" width="{_n(show_w)}" height="{_n(show_h)}" '
                    f'viewBox="{_n(bx)} {_n(by)} {_n(show_w)} {_n(show_h)}"><use href="#board"/></svg>'
                    + _crop_marks(x0, y0, cell_w, cell_h)
                    + f'<text x="{_n(x0 + 2)}" y="{_n(y0 - 3)}" font-size="4" font-weight="bold">{name}</text>'
                    + f'<text x="{_n(x0 + 12)}" y="{_n(y0 - 3)}" font-size="2.4">{html.escape(" ".join(notes))}</text>'
                    + f'<text x="{_n(MARGIN_MM)}" y="{_n(page_h - MARGIN_MM - FOOTER_MM + 8)}" font-size="3">'
                    + f"{html.escape(title)}</text>"
                    + _ruler(MARGIN_MM, page_h - MARGIN_MM - FOOTER_MM + 12))
            sheets.append(_sheet(page_w, page_h, body))
    return page_w, page_h, sheets


_STYLE = (
    "@page{{size:{w}mm {h}mm;margin:0}}"
    "html,body{{margin:0;padding:0}}"
    ".defs{{position:absolute;width:0;height:0;overflow:hidden}}"
    ".sheet{{width:{w}mm;height:{h}mm;overflow:hidden;break-after:page;background:#fff}}"
    ".sheet:last-child{{break-after:auto}}"
    ".sheet>svg{{display:block}}"
    "@media screen{{body{{background:#8a939e;font-family:sans-serif}}"
    ".sheet{{margin:8mm auto;box-shadow:0 1mm 4mm rgba(0,0,0,.4)}}"
    ".screen-note{{max-width:{w}mm;margin:6mm auto 0;background:#fff;padding:3mm 4mm;line-height:1.4}}}}"
    "@media print{{.screen-note{{display:none}}}}"
)


def board_print_html(board_meta: Mapping[str, Any], layout: str, *, rig_name: str = "") -> str:
    """A print page of the board for ``layout`` (one of :data:`LAYOUTS`): every sheet at its size in mm.

    Raises
    ------
    InputError
        The layout is unknown, the board is not valid, or it does not fit one sheet of that paper.
    """
    if layout not in LAYOUTS:
        raise InputError(f"unknown print layout {layout!r}: choose one of {', '.join(LAYOUTS)}")
    board = _board(board_meta)
    width_mm, height_mm = board_size_mm(board)
    words = board_type(board.kind).describe(board)
    title = f"{words[:1].upper()}{words[1:]}; {width_mm:g} \u00d7 {height_mm:g} mm"
    if rig_name:
        title += f" \u2014 {rig_name}"
    if layout == "a4-tiles":
        page_w, page_h, sheets = _tile_sheets(board, title)
        how = (f"{len(sheets)} A4 sheets holding the squares. Cut each sheet but the first along its marks on the "
               "left and top, lay it over the strip its neighbour repeats so that the squares run on, and glue "
               f"the whole flat on a rigid white board leaving {board.square_mm:g} mm of white all round.")
    else:
        page_w, page_h, sheets = _single_sheets(board, layout, title)
        how = f"One {layout.upper()} sheet. Glue it flat on a rigid board."
    note = (f'<div class="screen-note"><strong>{html.escape(title)}</strong><br>{html.escape(how)} Print at '
            "100 % (\u201cactual size\u201d, margins none), then measure the 100 mm bar on every sheet and one square "
            f"({board.square_mm:g} mm).</div>")
    defs = (f'<svg class="defs" xmlns="http://www.w3.org/2000/svg" aria-hidden="true"><defs>{_board_group(board)}'
            "</defs></svg>")
    return ("<!doctype html><html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>{html.escape(title)}</title><style>{_STYLE.format(w=_n(page_w), h=_n(page_h))}</style></head>"
            f"<body>{note}{defs}{''.join(sheets)}</body></html>")


@dataclass(frozen=True)
class BoardAdvice:
    """What the rig page says about printing the board: its size, the layouts, the square each distance needs."""

    width_mm: float
    height_mm: float
    square_mm: float
    view: CameraView
    min_square_px: int
    square_needed_mm: dict[float, float]  # camera distance m -> smallest square mm
    reach_m: float  # how far from the camera this board's squares are still resolved
    layouts: list[BoardLayout]
    sentences: list[str]


def board_advice(board_meta: Mapping[str, Any], view: CameraView) -> BoardAdvice:
    """The board's printed size, where it fits, and the trade-off between square size and camera distance."""
    board = _board(board_meta)
    width_mm, height_mm = board_size_mm(board)
    layouts = board_layouts(board_meta, image_width_px=view.image_width_px, hfov_deg=view.hfov_deg)
    needed = {d: square_needed_mm(d, image_width_px=view.image_width_px, hfov_deg=view.hfov_deg, kind=board.kind)
              for d in DISTANCES_M}
    px = min_square_px(board.kind)
    reach = board.square_mm / square_needed_mm(1.0, image_width_px=view.image_width_px, hfov_deg=view.hfov_deg,
                                               kind=board.kind)
    camera = {"calibration": "your calibrated cameras", "clips": "your clips (a phone's view assumed)",
              "assumed": "a phone filming 1080p"}[view.source]
    fitting = [lay.layout.upper() for lay in layouts if lay.sheets == 1 and lay.fits]
    sentences = [
        f"Printed, this board is {width_mm:g} \u00d7 {height_mm:g} mm with squares of {board.square_mm:g} mm"
        + (f"; it fits one {fitting[0]} sheet." if fitting else "; it fits on no single sheet up to A0."),
        f"A camera {view.image_width_px} pixels wide with a {view.hfov_deg:g}\u00b0 view ({camera}) needs each "
        f"square to cover at least {px} pixels to find its corners: a square must be at least "
        f"{needed[4.0]:.0f} mm at 4 m and {needed[8.0]:.0f} mm at 8 m (square = {px} \u00d7 2 \u00d7 distance "
        f"\u00d7 tan(view / 2) / width).",
        f"These {board.square_mm:g} mm squares are found up to about {reach:.1f} m from the camera; carry the "
        "board no farther away than that.",
    ]
    return BoardAdvice(width_mm, height_mm, board.square_mm, view, px, needed, reach, layouts, sentences)
