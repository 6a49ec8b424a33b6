"""The states and kinds the database stores as short strings, for every layer to name them.

The API reads these (a ride's status filter, an upload that takes no more bytes) without importing
the models; the models use them for their CHECK constraints.
"""

from __future__ import annotations

import enum

from saddlescope.core.calibration.wand import WAND_LENGTH_RANGE_M as CORE_WAND_LENGTH_RANGE_M

__all__ = ["RIDE_STATUSES", "RIDER_WEIGHT_RANGE_KG", "WAND_LENGTH_RANGE_M", "JobStatus", "RideStatus", "Role",
           "SaddleType", "UploadStatus",
           "UploadTarget"]

# A rider's weight in kg is believed between these (a child on a pony to a heavy adult); outside: a typo.
RIDER_WEIGHT_RANGE_KG = (20.0, 200.0)
# A calibration wand's length in m: the core's one range (core.calibration.wand).
WAND_LENGTH_RANGE_M = CORE_WAND_LENGTH_RANGE_M


class Role(enum.StrEnum):
    """A user's role in the club: members use the data, admins also manage users and delete things."""

    MEMBER = "member"
    ADMIN = "admin"


class JobStatus(enum.StrEnum):
    """Where a job stands: queued, running, then done, failed or cancelled."""

    QUEUED = "queued"
    RUNNING = "running"
    DONE = "done"
    FAILED = "failed"
    CANCELLED = "cancelled"

    @property
    def finished(self) -> bool:
        """True for done, failed and cancelled (nothing more will happen to the job)."""
        return self in (JobStatus.DONE, JobStatus.FAILED, JobStatus.CANCELLED)


class RideStatus(enum.StrEnum):
    """Where a ride stands, derived from its clips, its analysis jobs and its result."""

    NEW = "new"  # created, clips not all uploaded
    READY = "ready"  # all clips present
    PROCESSING = "processing"
    ANALYSED = "analysed"
    FAILED = "failed"


RIDE_STATUSES = tuple(s.value for s in RideStatus)


class UploadTarget(enum.StrEnum):
    """What a resumable upload becomes: a ride's clip, a rig's clip, or a whole ride bundle."""

    RIDE_CLIP = "ride_clip"
    RIG_CLIP = "rig_clip"
    BUNDLE = "bundle"


class UploadStatus(enum.StrEnum):
    """Where a resumable upload stands."""

    OPEN = "open"  # bytes still arriving
    FINALISING = "finalising"  # one finalise request holds it (claimed atomically) while making its clip or ride
    FINALISED = "finalised"  # turned into a recording or a ride
    FAILED = "failed"  # finalising refused it (the reason is in `error`)


class SaddleType(enum.StrEnum):
    """What kind of saddle it is, as a saddle fitter names it."""

    GP = "gp"  # general purpose
    DRESSAGE = "dressage"
    JUMP = "jump"
    TREELESS = "treeless"
    ENDURANCE = "endurance"
    WESTERN = "western"
    OTHER = "other"
