"""Query enums and response bodies of the horse page's routes (`saddlescope.api.routers.horse_profile`)."""

from __future__ import annotations

import datetime as dt
from typing import Literal

from pydantic import BaseModel, Field

from saddlescope.api.schemas import Gait

__all__ = ["Band", "PageBand", "PairIndicator", "PairOut", "PairRide", "TrendOut", "TrendPoint"]


class Band(BaseModel):
    """The horse's own normal band: mean ± 2 SD over its earlier rides in the gait."""

    n: int = Field(description="earlier rides behind the band")
    mean: float
    sd: float = Field(description="sample standard deviation of the earlier rides")
    low: float = Field(description="mean - 2 SD")
    high: float = Field(description="mean + 2 SD")


class PageBand(Band):
    """The band the horse page draws across its trend, with where it comes from and its own uncertainty."""

    source: Literal["horse", "club"] = Field(description="the horse's own rides, or the club's horses in the gait")
    horses: int = Field(description="horses behind the band")
    reason: str = Field(description="where the band comes from, in words")
    low_interval_95: list[float] = Field(description="95 % interval of the band's lower edge", min_length=2,
                                         max_length=2)
    high_interval_95: list[float] = Field(description="95 % interval of the band's upper edge", min_length=2,
                                          max_length=2)


class TrendPoint(BaseModel):
    """One analysed ride on the trend, with the band of the rides before it."""

    ride_id: int
    date: dt.date | None = Field(description="the day ridden (None: not recorded)")
    rider: str
    value: float | None
    band: Band | None = Field(description="None while the horse has fewer earlier rides than the minimum")
    outside: bool | None = Field(description="the value lies outside the band (None: no band)")
    uncertain_reason: str | None = Field(default=None, description=(
        "why the ride is too uncertain for a decision (only with include_uncertain; None: it is not)"))


class TrendOut(BaseModel):
    """One indicator of one horse in one gait over its rides, oldest first."""

    horse_id: int
    horse: str
    gait: Gait
    indicator: str
    unit: str
    label: str
    min_rides_for_band: int
    uncertain_left_out: int = Field(default=0, description="rides too uncertain for a decision, not shown")
    min_own_rides: int = Field(description="rides the horse needs for the page's band to be its own")
    band: PageBand | None = Field(description="the band drawn across the chart (None: too few rides anywhere)")
    points: list[TrendPoint]


class PairRide(BaseModel):
    """One of the two rides compared."""

    ride_id: int
    date: dt.date | None
    gait: Gait
    rider: str


class PairIndicator(BaseModel):
    """An indicator of both rides and the second's % difference from the first."""

    key: str
    label: str
    unit: str
    better: Literal["lower", "higher"] | None
    a: float | None
    b: float | None
    difference_percent: float | None = Field(description="(b - a) / |a| × 100; None where a is 0 or missing")


class PairOut(BaseModel):
    """Two analysed rides of one horse side by side."""

    horse_id: int
    horse: str
    a: PairRide
    b: PairRide
    b_is_later: bool
    indicators: list[PairIndicator]
