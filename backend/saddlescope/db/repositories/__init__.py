"""All SQL lives here: one small repository per aggregate.

A repository wraps a `Session` and, optionally, a ``club_id``: when given, every read and write is
confined to that club (the API builds club-scoped repositories from the signed-in user; the job
runner and the command line use unscoped ones). Repositories flush but never commit: the caller
owns the transaction (`saddlescope.db.session.session_scope`).

Layers above build no queries: they pass plain values (``name_like=``, a `RideFilter`) and read the
rows returned. The row classes are re-exported here as the repositories' return types, for
annotations.
"""

from saddlescope.db.models import Job, Ride, Rig, Saddle, Upload
from saddlescope.db.repositories.accounts import ClubRepository, UserRepository
from saddlescope.db.repositories.analytics import AnalyticsRepository
from saddlescope.db.repositories.base import BadQuery, Conflict, NotFound, Page, Repository, like_pattern
from saddlescope.db.repositories.catalogue import HorseRepository, RiderRepository, RigRepository, SaddleRepository
from saddlescope.db.repositories.jobs import JobRepository, UploadRepository
from saddlescope.db.repositories.rides import (
    GradeRepository,
    RecordingRepository,
    ResultRepository,
    RideFilter,
    RideRepository,
)
from saddlescope.db.repositories.sharing import ShareLinkRepository
from saddlescope.db.repositories.similarity import (
    AnalysedRide,
    SimilarityRepository,
    analysis_version,
    ordered_pair,
)

__all__ = [
    "AnalysedRide",
    "AnalyticsRepository",
    "BadQuery",
    "ClubRepository",
    "Conflict",
    "GradeRepository",
    "HorseRepository",
    "Job",
    "JobRepository",
    "NotFound",
    "Page",
    "RecordingRepository",
    "Repository",
    "ResultRepository",
    "Ride",
    "RideFilter",
    "RideRepository",
    "RiderRepository",
    "Rig",
    "Saddle",
    "RigRepository",
    "SaddleRepository",
    "ShareLinkRepository",
    "SimilarityRepository",
    "Upload",
    "UploadRepository",
    "UserRepository",
    "analysis_version",
    "like_pattern",
    "ordered_pair",
]
