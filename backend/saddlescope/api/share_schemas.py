"""Request and response bodies of the share links (`saddlescope.api.routers.share_links`)."""

from __future__ import annotations

import datetime as dt
from typing import Literal

from pydantic import BaseModel, Field, model_validator

from saddlescope.api.schemas import MAX_ID, _In
from saddlescope.services.accounts.share_links import DEFAULT_DAYS, MAX_DAYS

__all__ = ["ShareLinkCreated", "ShareLinkIn", "ShareLinkOut"]


class ShareLinkIn(_In):
    """A read-only link to one ride's report or one horse's page, for someone without an account."""

    ride_id: int | None = Field(None, ge=1, le=MAX_ID, description="the ride whose report the link shows")
    horse_id: int | None = Field(None, ge=1, le=MAX_ID, description="the horse whose page the link shows")
    days: int = Field(DEFAULT_DAYS, ge=1, le=MAX_DAYS, description="how many days the link works")

    @model_validator(mode="after")
    def _one_target(self) -> ShareLinkIn:
        if (self.ride_id is None) == (self.horse_id is None):
            raise ValueError("give either ride_id (a ride's report) or horse_id (a horse's page), not both")
        return self


class ShareLinkOut(BaseModel):
    """A share link as the club's list shows it (never its token)."""

    id: int
    kind: Literal["ride", "horse"]
    ride_id: int | None
    horse_id: int | None
    shows: str = Field(description="what the link shows, in words")
    created_by: str = Field(description="the member who made it")
    created_at: dt.datetime
    expires_at: dt.datetime
    revoked_at: dt.datetime | None = Field(description="when an admin withdrew it (None: not withdrawn)")
    state: Literal["active", "expired", "withdrawn"]


class ShareLinkCreated(ShareLinkOut):
    """A new link with its path: shown this once (only its hash is stored), to copy for the vet."""

    path: str = Field(description="the link's path on this server: /shared/<token>")
