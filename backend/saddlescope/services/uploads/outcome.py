"""What finalising a resumable upload made: a clip's recording, or a bundle's ride, and the job it started.

The same outcome is kept on the upload's row (its ``outcome`` JSON), so a finalise asked again answers it again:
`as_json` writes it there and `outcome_from_json` reads it back.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

__all__ = ["BundleFinalised", "ClipFinalised", "UploadOutcome", "outcome_from_json"]


@dataclass(frozen=True)
class ClipFinalised:
    """A clip's upload finalised: its recording, and the job the clip let start."""

    recording_id: int
    job_id: int | None  # None: nothing to start yet (or a job already queued or running)
    # A ride's clip that started no job: what the ride still needs (None for a rig's clip, or when a job started).
    missing: tuple[str, ...] | None = None

    def as_json(self) -> dict[str, Any]:
        """The outcome as the upload's row keeps it (``missing`` only when there is one)."""
        kept: dict[str, Any] = {"recording_id": self.recording_id, "job_id": self.job_id}
        if self.missing is not None:
            kept["missing"] = list(self.missing)
        return kept


@dataclass(frozen=True)
class BundleFinalised:
    """A ride bundle's upload finalised: the new ride, and its analysis job."""

    ride_id: int
    job_id: int

    def as_json(self) -> dict[str, Any]:
        """The outcome as the upload's row keeps it."""
        return {"ride_id": self.ride_id, "job_id": self.job_id}


UploadOutcome = ClipFinalised | BundleFinalised


def outcome_from_json(kept: Mapping[str, Any]) -> UploadOutcome:
    """The outcome a finalised upload's row keeps (`as_json`)."""
    if "ride_id" in kept:
        return BundleFinalised(ride_id=int(kept["ride_id"]), job_id=int(kept["job_id"]))
    missing = kept.get("missing")
    return ClipFinalised(recording_id=int(kept["recording_id"]), job_id=kept.get("job_id"),
                         missing=tuple(missing) if missing is not None else None)
