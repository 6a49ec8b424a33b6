"""Response bodies of the similarity routes (`saddlescope.api.routers.similarity`)."""

from __future__ import annotations

import datetime as dt
from typing import Any, Literal

from pydantic import BaseModel, Field

from saddlescope.api.schemas import Gait, JobOut
from saddlescope.services.similarity.compare import MARKER_SETS, SPANS

__all__ = [
    "AlikeEntry", "AlikeOut", "ConsistencyGait", "ConsistencyOut", "ConsistencyRide", "Differences", "GaitScope",
    "MarkerDifference", "MarkerSet", "NotComparable", "PairOut", "PairView", "PendingOut", "RideSummary", "Span",
    "StridesView",
]

MarkerSet = Literal[MARKER_SETS]  # type: ignore[valid-type]
Span = Literal[SPANS]  # type: ignore[valid-type]
GaitScope = Literal["same", "any"]


class RideSummary(BaseModel):
    """A ride as a similarity list shows it."""

    ride_id: int
    horse_id: int
    horse: str
    gait: Gait
    ridden_on: dt.date | None


class AlikeEntry(BaseModel):
    """One ride of the most-alike list."""

    rank: int = Field(ge=1, description="1 = most alike")
    ride: RideSummary
    similarity: float = Field(ge=0, le=1, description="1 = the same motion")
    measure: str | None = Field(description="the measure `similarity` is")
    measures: dict[str, Any] = Field(description="every measure the method reports, by name")


class NotComparable(BaseModel):
    """A ride that could not be compared, and why."""

    ride: RideSummary
    reason: str


class AlikeOut(BaseModel):
    """A ride's most-alike rides in the club, most alike first (all comparisons from the cache)."""

    ride: RideSummary
    markers: MarkerSet
    span: Span
    gait: GaitScope
    method_version: str
    candidates: int = Field(description="rides compared (analysed, in the gait asked for)")
    items: list[AlikeEntry]
    not_comparable: list[NotComparable]


class PendingOut(BaseModel):
    """202: the comparisons are being computed by a job; poll it, then ask again."""

    job: JobOut
    cached: int = Field(description="comparisons already cached")
    pairs: int = Field(description="comparisons the answer needs")
    missing: int = Field(description="comparisons the job computes")
    markers: MarkerSet
    span: Span
    ride_id: int | None = None
    horse_id: int | None = None


class StridesView(BaseModel):
    """Both rides' mean strides over stride phase (mm), the second shifted to line up with the first."""

    phase: list[float]
    first_mm: list[list[float]]
    second_mm: list[list[float]]
    second_unaligned_mm: list[list[float]]
    shift_phase: float = Field(description="phase shift applied to the second stride (0-1)")


class PairView(BaseModel):
    """The saddle-point paths (travel and mean removed, mm, motion frame) and the aligned strides."""

    paths_mm: list[list[list[float]]]
    strides: StridesView | None
    reason: str | None


class MarkerDifference(BaseModel):
    """How far one track of the first ride is from the second's once both are in stride phase."""

    marker: str = Field(description="saddle, M1, M2 or M3")
    rms_mm: float = Field(ge=0, description="RMS distance of the phase-aligned mean strides")
    dtw: float = Field(ge=0, le=1, description="the track's DTW similarity (1 = the same motion)")
    per_stretch_mm: list[float] = Field(description="RMS distance in each stretch of the stride, in order")


class Differences(BaseModel):
    """Where the two motions differ: per track (spatial) and per stretch of the stride (temporal)."""

    time_base: str = Field(description="what the stretches cut: 'stride phase' for rides")
    stretches: int = Field(ge=1, description="equal stretches of the stride, the first from the first ride's start")
    per_marker: list[MarkerDifference]
    per_stretch_mm: list[float] = Field(description="RMS distance over the tracks in each stretch")
    most_different_marker: str
    most_different_stretch: int = Field(ge=0, description="index into per_stretch_mm")


class PairOut(BaseModel):
    """Two rides compared."""

    rides: list[RideSummary]
    markers: MarkerSet
    span: Span
    cached: bool = Field(description="served from the cache (else computed for this request)")
    similarity: float | None = Field(description="1 = the same motion; null when not comparable")
    measure: str | None
    measures: dict[str, Any]
    reason: str | None = Field(description="why the rides could not be compared")
    comparison: dict[str, Any] = Field(description="the similarity method's whole answer")
    differences: Differences | None = Field(
        default=None, description="where the motions differ; null when not comparable or cached by an older method")
    method_version: str
    view: PairView


class ConsistencyRide(BaseModel):
    """A ride of the horse against its earlier rides in the gait."""

    ride: RideSummary
    earlier: int = Field(description="earlier rides in this gait")
    vs_previous: float | None
    mean_vs_earlier: float | None
    min_vs_earlier: float | None


class ConsistencyGait(BaseModel):
    """The horse's rides in one gait, oldest first."""

    gait: Gait
    rides: list[ConsistencyRide]
    mean_vs_previous: float | None


class ConsistencyOut(BaseModel):
    """A horse's consistency: each ride against its own earlier rides, per gait."""

    horse_id: int
    horse: str
    markers: MarkerSet
    span: Span
    method_version: str
    gaits: list[ConsistencyGait]
