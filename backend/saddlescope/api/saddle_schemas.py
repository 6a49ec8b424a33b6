"""Request and response bodies of the saddles' routes and the horse page's saddle comparison."""

from __future__ import annotations

import datetime as dt
from typing import Annotated

from pydantic import BaseModel, Field, StringConstraints

from saddlescope.api.schemas import Gait, Name, Text, _In, _Out
from saddlescope.db.enums import SaddleType

__all__ = [
    "HorseSaddlesOut", "MeanWithInterval", "SaddleAcrossHorsesOut", "SaddleDifference", "SaddleHorseStats",
    "SaddleIn", "SaddleOut", "SaddleRide", "SaddleStats", "SaddleUpdate",
]

Maker = Annotated[str, StringConstraints(strip_whitespace=True, max_length=200)]
TreeWidth = Annotated[str, StringConstraints(strip_whitespace=True, max_length=40)]


class SaddleIn(_In):
    """A new saddle of the club."""

    name: Name
    maker: Maker | None = None
    saddle_type: SaddleType | None = Field(default=None, description="gp, dressage, jump, treeless, ...")
    tree_width: TreeWidth | None = Field(default=None, description='as the maker states it ("medium", "32 cm")')
    notes: Text = ""


class SaddleUpdate(_In):
    """Changes to a saddle (unset fields stay; null clears maker, type, tree width or notes)."""

    name: Name | None = None
    maker: Maker | None = None
    saddle_type: SaddleType | None = None
    tree_width: TreeWidth | None = None
    notes: Text | None = None


class SaddleOut(_Out):
    """A saddle of the club, with how many rides name it."""

    id: int
    name: str
    maker: str | None
    saddle_type: str | None
    tree_width: str | None
    notes: str
    rides: int = Field(default=0, description="the club's rides in this saddle")
    created_at: dt.datetime


class MeanWithInterval(BaseModel):
    """An indicator over a group of rides: n, the mean and its 95 % interval (None below two rides)."""

    n: int
    mean: float | None
    sd: float | None
    low: float | None
    high: float | None


class SaddleStats(BaseModel):
    """One saddle on the horse: its rides and each indicator's mean with its interval."""

    saddle_id: int
    saddle: str
    rides: int
    indicators: dict[str, MeanWithInterval]


class SaddleDifference(BaseModel):
    """Saddle b against saddle a on one indicator (Welch): b - a, its 95 % interval and the verdict."""

    indicator: str
    saddle_a_id: int
    saddle_a: str
    saddle_b_id: int
    saddle_b: str
    difference: float | None = Field(description="mean of b - mean of a (None: a saddle has under two rides)")
    low: float | None
    high: float | None
    p_value: float | None
    exceeds_uncertainty: bool | None = Field(description="the interval of the difference excludes zero")
    sentence: str = Field(description="the comparison in words")


class HorseSaddlesOut(BaseModel):
    """One horse's saddles in one gait compared."""

    horse_id: int
    horse: str
    gait: Gait
    include_uncertain: bool
    uncertain_left_out: int = Field(description="rides too uncertain for a decision, not counted")
    without_saddle: int = Field(description="analysed rides with no saddle recorded")
    units: dict[str, str]
    labels: dict[str, str]
    saddles: list[SaddleStats]
    differences: list[SaddleDifference]
    method: str = Field(description="how the intervals and the verdict are computed")


class SaddleRide(BaseModel):
    """An analysed ride in the saddle."""

    ride_id: int
    date: dt.date | None
    horse_id: int
    horse: str
    rider: str
    gait: Gait
    uncertain_reason: str | None = Field(description="why it is too uncertain for a decision (None: it is not)")
    indicators: dict[str, float | None]


class SaddleHorseStats(BaseModel):
    """The saddle on one horse in one gait."""

    horse_id: int
    horse: str
    gait: Gait
    rides: int
    indicators: dict[str, MeanWithInterval]


class SaddleAcrossHorsesOut(BaseModel):
    """One saddle across the club's horses."""

    saddle: SaddleOut
    rides_total: int = Field(description="every ride in the saddle, analysed or not")
    gait: Gait | None
    include_uncertain: bool
    units: dict[str, str]
    labels: dict[str, str]
    rides: list[SaddleRide]
    horses: list[SaddleHorseStats]
    method: str
