"""The rig page's responses beyond the rig itself.

How to print its board, the check of its calibration clips, and its calibration's report.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import AfterValidator, BaseModel, ConfigDict, Field, WithJsonSchema

from saddlescope.core.calibration.wand import WAND_LENGTH_RANGE_M, wand_length_problem

__all__ = ["BoardLayoutOut", "BoardSizesOut", "CalibrateIn", "CalibrationCheckOut", "CalibrationQualityOut",
           "CalibrationReportOut", "CameraCheckOut", "CameraCoverageOut", "CheckFindingOut", "DepthCoverageOut",
           "NotCalibratedOut", "SquareAtDistance", "WandLengthM", "check_wand_length_m"]


def check_wand_length_m(value: float | None) -> float | None:
    """`value` if None or within `WAND_LENGTH_RANGE_M`; ValueError with the reason otherwise."""
    if value is None:
        return None
    if problem := wand_length_problem(value):
        raise ValueError(problem)
    return float(value)


WandLengthM = Annotated[
    float | None, AfterValidator(check_wand_length_m),
    WithJsonSchema({"anyOf": [{"type": "number", "minimum": WAND_LENGTH_RANGE_M[0],
                               "maximum": WAND_LENGTH_RANGE_M[1]}, {"type": "null"}],
                    "description": "the wand's length in m between its markers' centres (0.05-5); null: not given"}),
]


class CalibrateIn(BaseModel):
    """How to calibrate a rig: the board walk, a wand, or the board walk refined by the wand.

    Default: the board walk refined by the wand when the calibration and wand clips and the wand's length are
    there, else the wand when its clips and length are, else the board walk.
    """

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    method: Literal["board", "wand", "board+wand"] | None = Field(
        default=None, description="board: the calibration clips; wand: the wand and close-up clips; board+wand: "
                                  "the calibration clips refined by the wand clips where that helps")
    wand_length_m: WandLengthM = Field(default=None, description="sets the rig's wand length first")


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


class CheckFindingOut(BaseModel):
    """One finding of the check: its code (saddlescope.core.findings), severity, sentence and what to do."""

    code: str
    severity: Literal["ok", "check", "problem"]
    detail: str = Field(description="the sentence with its numbers")
    advice: str = Field(description="one sentence a club can act on")


class DepthCoverageOut(BaseModel):
    """The distances the board was held at from the camera: a histogram of views over distance bins."""

    near_m: float | None = Field(description="10th percentile of the views' distances")
    far_m: float | None = Field(description="90th percentile of the views' distances")
    bin_edges_m: list[float]
    views: list[int]


class CameraCheckOut(BaseModel):
    """One camera's calibration clip checked: coverage over the image and depth, reach, findings."""

    camera: str
    image_size: tuple[int, int]
    frames_sampled: int
    views: int = Field(description="sampled frames in which the board was found")
    grid: list[list[int]] = Field(description="rows x columns of the image: views whose corners fell in each cell")
    bands_missed: list[str] = Field(description="the thirds of the image no corner reached, in words")
    corners_missed: list[str]
    reach_x: tuple[float, float] = Field(description="leftmost and rightmost corner, shares of the width")
    reach_y: tuple[float, float] = Field(description="topmost and lowest corner, shares of the height")
    hull_fraction: float = Field(description="the corners' outline as a share of the image")
    depth: DepthCoverageOut
    film_again: bool
    findings: list[CheckFindingOut]


class WandCheckOut(BaseModel):
    """The rig's wand clips checked before anyone rides: per camera where the wand's two ends went."""

    film_again: bool
    verdict: str
    seconds: float | None = None
    clips: dict[str, int] = Field(default_factory=dict, description="camera -> the recording id checked")
    cameras: dict[str, CameraCheckOut] = Field(default_factory=dict)


class CalibrationCheckOut(BaseModel):
    """The rig's calibration clips checked before anyone rides (``checked`` False until the first check)."""

    checked: bool
    checking: bool = Field(description="a check is queued or running")
    film_again: bool | None = None
    verdict: str
    seconds: float | None = Field(default=None, description="how long the check took")
    clips: dict[str, int] = Field(default_factory=dict, description="camera -> the recording id checked")
    cameras: dict[str, CameraCheckOut] = Field(default_factory=dict)
    wand: WandCheckOut | None = Field(default=None, description="the wand clips' check, once the rig has wand "
                                      "clips and its wand's length (the same per camera: where the wand's ends went)")


Grade = Literal["good", "fair", "poor"]


class NotCalibratedOut(BaseModel):
    """A rig not calibrated yet: its quality is one sentence saying so."""

    model_config = ConfigDict(from_attributes=True)

    calibrated: Literal[False]
    sentences: list[str]


class CalibrationQualityOut(BaseModel):
    """A rig's calibration in plain words: each number with its grade, and sentences a club can act on."""

    model_config = ConfigDict(from_attributes=True)

    calibrated: Literal[True]
    reprojection_px: float | None = Field(description="the worst camera's reprojection r.m.s.; null: no camera says")
    board_square_error_mm: float | None = Field(description="how far the rebuilt board squares are off")
    reprojection_grade: Grade | None = Field(description="good under 0.5 px, fair under 1 px, else poor")
    square_grade: Grade | None = Field(description="good within 0.5 mm, fair within 1 mm, else poor")
    flags: list[str]
    n_views: dict[str, int] | None = Field(description="camera -> the board views its lens was fitted with")
    sentences: list[str]
    refined_by_wand: bool | None = Field(description="whether a wand refined the board's calibration; null: no wand "
                                                     "was offered")


class CameraCoverageOut(BaseModel):
    """Where in one camera's image the board has been (the lens is only known there)."""

    model_config = ConfigDict(from_attributes=True)

    image_size: tuple[int, int] = Field(description="width and height, px")
    corners_px: list[tuple[float, float]] = Field(description="the board corners seen (a sample), px")
    hull_px: list[tuple[float, float]] | None = Field(description="their convex hull, px; null: not stored")
    area_fraction: float | None = Field(description="the hull's share of the image")
    missed: list[str] | None = Field(description="the ninths of the image no corner reached, in words; null: the "
                                                 "corners are not stored for this calibration")
    sentence: str


class CalibrationReportOut(BaseModel):
    """A rig's calibration in plain words, and per camera where in the image the board has been."""

    model_config = ConfigDict(from_attributes=True)

    quality: Annotated[NotCalibratedOut | CalibrationQualityOut, Field(discriminator="calibrated")]
    coverage: dict[str, CameraCoverageOut] = Field(description="camera -> where its board has been")
    calibrating: bool = Field(description="a calibrate_rig job is queued or running")
