"""The leaderboard's response: horses ranked in a gait by an indicator, and the rides too uncertain to rank."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, Field

__all__ = ["LeaderboardEntry", "LeaderboardOut", "UncertainRide"]


class LeaderboardEntry(BaseModel):
    """One horse's place in a ranking."""

    rank: int
    horse_id: int | None
    horse: str
    n: int = Field(description="rides behind the mean")
    mean: float | None
    std: float | None
    min: float | None
    max: float | None
    spread: float | None = Field(description="max - min over the horse's rides")
    uncertain_rides: int = Field(0, description="rides behind the mean that are too uncertain for a decision")


class UncertainRide(BaseModel):
    """A ride too uncertain for a decision (docs/accuracy.md); ``included``: counted in the ranking."""

    ride_id: int
    horse_id: int | None
    horse: str
    value: float | None
    reason: str
    included: bool


class LeaderboardOut(BaseModel):
    """The club's horses ranked in a gait by an indicator, most comfortable first."""

    gait: str
    indicator: str
    unit: str
    better: Literal["lower", "higher"]
    rides: int
    entries: list[LeaderboardEntry]
    include_uncertain: bool = False
    saddle_id: int | None = Field(default=None, description="only rides in this saddle (None: all)")
    uncertain: list[UncertainRide] = Field(default_factory=list, description="rides too uncertain, with the reason")
