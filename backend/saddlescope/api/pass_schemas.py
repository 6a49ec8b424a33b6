"""The passes of a ride that held several (issue 38) as the API serves them."""

from __future__ import annotations

from pydantic import BaseModel, Field

__all__ = ["PassOut", "PassesOut"]


class PassOut(BaseModel):
    """One pass of the horse in front of the cameras (a ride may hold several, issue 38)."""

    start_s: float | None = Field(description="first frame with every marker, s (end_s: the last)")
    end_s: float | None
    strides: int | None = Field(description="whole strides the pass's fits saw (0: left out)")
    speed_m_s: float | None
    used: bool
    reason: str | None = Field(description="why a pass was left out")
    acc_y_wb_rms: float | None = Field(description="the pass's own W_b r.m.s., m/s²")


class PassesOut(BaseModel):
    """The passes of a ride that held several: what the ride page's and the report's passes line say."""

    count: int = Field(description="passes whose strides are in the ride's numbers")
    strides: list[int] = Field(description="strides per used pass")
    line: str = Field(description='e.g. "3 passes: 2, 2 and 3 strides"')
    wb_rms_spread_percent: float | None = Field(description="the passes' W_b r.m.s. spread (std over mean), %")
    passes: list[PassOut]
