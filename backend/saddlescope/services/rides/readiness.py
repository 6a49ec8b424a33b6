"""Whether a ride can be analysed now, and if not, what is missing in sentences a club understands.

One answer for the upload form (before anything is sent), the ride page (an incomplete ride) and
the API (a ride that cannot run is refused with the same sentences instead of being queued).
"""

from __future__ import annotations

from collections.abc import Iterable

from sqlalchemy.orm import Session

from saddlescope.core.errors import InputError
from saddlescope.core.types import CAMERA_ROLES
from saddlescope.db.repositories import RecordingRepository, RideRepository, RigRepository

__all__ = ["CLIP_WORDS", "RideNotReady", "missing_for_ride", "require_ready"]

# What each clip set is, in the words the upload page uses: (name, what it shows).
CLIP_WORDS = {
    "calibration": ("calibration", "the board moved through the view"),
    "plumb": ("plumb-line", "the plumb line hanging still"),
    "static": ("static", "horse standing still, saddle marker visible"),
    "motion": ("motion", "the ride"),
}


def _clips(kind: str, *, plural: bool = False) -> str:
    name, what = CLIP_WORDS[kind]
    return f"{name} clip{'s' if plural else ''} ({what})"


class RideNotReady(InputError):
    """A ride that cannot be analysed yet (HTTP 422), with every missing clip or setting named."""

    def __init__(self, ride_id: int, missing: list[str]) -> None:
        self.missing = missing
        super().__init__(f"ride {ride_id} cannot be analysed yet: " + " ".join(missing))


def _and(names: list[str]) -> str:
    return names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]


def _cameras_by_kind(recordings: Iterable) -> dict[str, set[str]]:
    out: dict[str, set[str]] = {}
    for r in recordings:
        out.setdefault(r.clip_kind, set()).add(r.camera_role)
    return out


def _missing_cameras(have: set[str]) -> list[str]:
    return [c for c in CAMERA_ROLES if c not in have]


def _clip_sentences(kind: str, own: set[str], shared: set[str], *, where: str) -> list[str]:
    """Sentences for one clip set a ride needs: its own clips, else its rig's."""
    if not _missing_cameras(own) or not _missing_cameras(shared):
        return []
    have = own or shared
    lacking = _missing_cameras(have)
    if have:
        many = len(lacking) > 1
        return [f"The {_clips(kind, plural=many)} of the {_and(lacking)} camera{'s' if many else ''} "
                f"{'are' if many else 'is'} missing (there {'is' if len(have) == 1 else 'are'} only the "
                f"{_and(sorted(have))} one{'s' if len(have) > 1 else ''}); upload {'them' if many else 'it'} {where}."]
    return [f"The {_clips(kind, plural=True)} of the left, middle and right cameras are missing; upload them {where}."]


def _calibration_sentences(rig, own: set[str], shared: set[str]) -> list[str]:
    if rig is None:
        return ["No camera rig is chosen: choose the rig these clips were filmed with (its calibration "
                "board is needed; create one on the Rigs page)."]
    out = []
    if not rig.board:
        out.append(f"The rig \u201c{rig.name}\u201d has no calibration board described: set its board on "
                   "the rig page.")
    if rig.calibration or not _missing_cameras(own) or not _missing_cameras(shared):
        return out
    have = own or shared
    if have:
        lacking = _missing_cameras(have)
        whose, where = ("the ride's", "with the ride") if own else ("its", "on the rig page")
        out.append(f"The rig \u201c{rig.name}\u201d is not calibrated: {whose} calibration clips come from only "
                   f"{len(have)} camera{'s' if len(have) > 1 else ''} ({_and(sorted(have))}); upload the "
                   f"{_and(lacking)} camera's calibration clip {where}.")
    else:
        out.append(f"The rig \u201c{rig.name}\u201d is not calibrated and has no calibration clips: upload "
                   "the calibration clips of its three cameras on the rig page.")
    return out


def missing_for_ride(session: Session, ride_id: int, *, club_id: int | None = None) -> list[str]:
    """What ride `ride_id` still needs before it can be analysed (empty: it can run now).

    A ride from a bundle was checked whole when it was registered. A ride of clips needs a rig with
    its board, a calibration (the rig's, or calibration clips of all three cameras), the static and
    motion clips of all three cameras, and no plumb set from only some cameras (it would be ignored).
    """
    ride = RideRepository(session, club_id=club_id).get(ride_id)
    if ride.bundle_key is not None:
        return []
    recordings = RecordingRepository(session)
    rig = RigRepository(session).find(ride.rig_id) if ride.rig_id is not None else None
    own = _cameras_by_kind(recordings.for_ride(ride.id))
    shared = _cameras_by_kind(recordings.for_rig(rig.id)) if rig is not None else {}
    missing = _calibration_sentences(rig, own.get("calibration", set()), shared.get("calibration", set()))
    if rig is None and (ride.meta or {}).get("board"):
        # A ride of the API may describe its board itself; it then calibrates from its own clips (the
        # choice rests on there being no rig, not on the wording of the sentence saying so).
        missing = _clip_sentences("calibration", own.get("calibration", set()), set(), where="with the ride")
    where = "with the ride on the upload page" if rig is None else "with the ride, or on the rig page"
    missing += _clip_sentences("static", own.get("static", set()), shared.get("static", set()), where=where)
    missing += _clip_sentences("motion", own.get("motion", set()), set(), where="with the ride on the upload page")
    plumb_own, plumb_shared = own.get("plumb", set()), shared.get("plumb", set())
    if (plumb_own or plumb_shared) and _missing_cameras(plumb_own) and _missing_cameras(plumb_shared):
        missing += _clip_sentences("plumb", plumb_own, plumb_shared, where=where)
    return missing


def require_ready(session: Session, ride_id: int, *, club_id: int | None = None) -> None:
    """Raise `RideNotReady` (422, naming what is missing) unless ride `ride_id` can be analysed now."""
    missing = missing_for_ride(session, ride_id, club_id=club_id)
    if missing:
        raise RideNotReady(ride_id, missing)
