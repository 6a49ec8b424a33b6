"""Bodies of the comparisons: a horse across gaits, horses within a gait, grades against the indicators."""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, Field

__all__ = ["ComparisonOut", "CorrelationOut", "GaitComparison", "GroupStats", "HorseComparisonOut", "HorseGroupStats",
           "HorsesInGait"]


class GroupStats(BaseModel):
    """An indicator's statistics over the rides of one group."""

    group: str
    n: int
    mean: float | None
    std: float | None
    min: float | None
    max: float | None


class HorseGroupStats(GroupStats):
    """An indicator's statistics over one horse's rides."""

    horse_id: int | None
    horse: str


class GaitComparison(BaseModel):
    """One indicator of one horse, per gait."""

    unit: str
    gaits: list[GroupStats]


class HorseComparisonOut(BaseModel):
    """One horse's indicators across gaits."""

    horse_id: int
    horse: str
    rides: int
    uncertain_left_out: int = Field(default=0, description="rides too uncertain for a decision, not averaged")
    indicators: dict[str, GaitComparison]


class HorsesInGait(BaseModel):
    """One indicator within a gait, per horse."""

    unit: str
    horses: list[HorseGroupStats]


class ComparisonOut(BaseModel):
    """The club's horses compared within one gait."""

    gait: str
    saddle_id: int | None = Field(default=None, description="only rides in this saddle (None: all)")
    rides: int
    uncertain_left_out: int = Field(default=0, description="rides too uncertain for a decision, not averaged")
    indicators: dict[str, HorsesInGait]


class CorrelationOut(BaseModel):
    """Riders' grades against the indicators."""

    gait: str | None
    grades: int
    indicators: dict[str, dict[str, Any]] = Field(
        description="per indicator: n, pearson_r, pearson_p, spearman_rho, intervals, expected_sign, points; "
        "min_points and withheld_reason (the coefficients are null on fewer than min_points points)"
    )
