"""Request and response bodies of the REST API (pydantic; the OpenAPI at /docs comes from these)."""

from __future__ import annotations

import datetime as dt
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field


class PartHealth(BaseModel):
    ok: bool
    status: Literal["ok", "error"]
    detail: str


class HealthOut(BaseModel):
    status: Literal["ok", "error"]
    mode: Literal["embedded", "celery"]
    version: str
    parts: dict[str, PartHealth] = Field(description="database, broker and storage")


class JobCreate(BaseModel):
    model_config = ConfigDict(extra="forbid")

    kind: str = Field(description="job kind, e.g. 'probe', 'analyze' or 'selftest'", examples=["probe"])
    ride_id: int | None = Field(default=None, description="the ride to work on (probe, analyze)")
    rig_id: int | None = Field(default=None, description="the rig to work on (probe of calibration clips)")
    payload: dict[str, Any] = Field(default_factory=dict,
                                    description="kind-specific options, e.g. {'steps': 5} for selftest")


class JobOut(BaseModel):
    id: int
    kind: str
    status: Literal["queued", "running", "done", "failed", "cancelled"]
    stage: str | None = Field(description="stage running now (with a detail after ': ')")
    progress: float = Field(ge=0, le=1)
    timings_s: dict[str, float] = Field(description="wall seconds per finished stage, and 'total'")
    error: str | None
    ride_id: int | None
    rig_id: int | None
    payload: dict[str, Any]
    attempts: int
    code_version: str | None
    host: str | None
    created_at: dt.datetime
    started_at: dt.datetime | None
    finished_at: dt.datetime | None


class JobKindOut(BaseModel):
    name: str
    stages: list[str]
    needs_ride: bool
    description: str


class ErrorOut(BaseModel):
    detail: str
