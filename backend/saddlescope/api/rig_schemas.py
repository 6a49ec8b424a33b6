"""The rig page's responses beyond the rig itself: how to print its board, and the check of its calibration clips."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, Field

__all__ = ["BoardLayoutOut", "BoardSizesOut", "SquareAtDistance"]


class BoardLayoutOut(BaseModel):
    """One way to print the board (one sheet of a paper size, or A4 tiles)."""

    layout: str = Field(description="a4, a3, a2, a1, a0 (one sheet) or a4-tiles")
    label: str
    sheets: int
    fits: bool = Field(description="the board at its square size fits this layout")
    landscape: bool
    largest_square_mm: float = Field(description="the largest square of this board's pattern that fits one sheet")
    reach_m: float = Field(description="how far from the camera the largest square is still resolved")


class SquareAtDistance(BaseModel):
    """The smallest square a camera resolves at a distance."""

    distance_m: float
    square_mm: float


class BoardSizesOut(BaseModel):
    """The board's printed size, the layouts it fits, and which square each camera distance needs."""

    width_mm: float
    height_mm: float
    square_mm: float
    image_width_px: int
    hfov_deg: float
    camera_source: Literal["calibration", "clips", "assumed"]
    min_square_px: int = Field(description="pixels a square must cover for its corners to be found")
    reach_m: float = Field(description="how far from the camera this board's squares are resolved")
    squares_needed: list[SquareAtDistance]
    layouts: list[BoardLayoutOut]
    sentences: list[str]
