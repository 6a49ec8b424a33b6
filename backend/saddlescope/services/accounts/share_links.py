"""Share links: a ride's report or a horse's page for someone without an account (a vet), read only.

A member makes a link for one ride or one horse of the club, valid for `DEFAULT_DAYS` days unless they
choose otherwise (at most `MAX_DAYS`); an admin lists the club's links and withdraws one. The link's
token is ``secrets.token_urlsafe(32)`` (256 random bits: not guessable), shown once to its maker; only
its SHA-256 is stored, so a copy of the database opens nothing. Opening a link answers the one ride or
horse it names and nothing else; a withdrawn or expired link is refused in plain words.
"""

from __future__ import annotations

import datetime as dt
import hashlib
import html
import secrets
from dataclasses import dataclass
from typing import Any

from sqlalchemy.orm import Session

from saddlescope.core.errors import InputError
from saddlescope.db.models import ShareLink, utcnow
from saddlescope.db.repositories import HorseRepository, NotFound, RideRepository, ShareLinkRepository

__all__ = [
    "DEFAULT_DAYS", "MAX_DAYS", "SHARE_PATH", "ShareRefused", "create_share_link", "link_state", "link_view",
    "list_share_links", "open_share_link", "refusal_html", "revoke_share_link", "ride_of_link", "token_hash",
]

DEFAULT_DAYS = 30
MAX_DAYS = 365
SHARE_PATH = "/shared/"  # a link is SHARE_PATH + token, on the club's own server
GAIT_WORDS = {"walk": "walk", "sitting_trot": "sitting trot", "rising_trot": "rising trot", "canter": "canter"}


class ShareRefused(Exception):
    """A link that opens nothing: unknown, withdrawn by the club or expired (`reason`, with a plain `title`)."""

    def __init__(self, reason: str, title: str, message: str) -> None:
        super().__init__(message)
        self.reason, self.title, self.message = reason, title, message


@dataclass(frozen=True)
class CreatedLink:
    """A new link and its token (the only time the token is known: it is not stored)."""

    link: ShareLink
    token: str

    @property
    def path(self) -> str:
        """The link's path on this server (the page adds the address it is served from)."""
        return SHARE_PATH + self.token


def token_hash(token: str) -> str:
    """The stored form of a token: SHA-256, hex (a 256-bit random token needs no slow hash)."""
    return hashlib.sha256(token.encode("utf-8")).hexdigest()


def create_share_link(session: Session, *, club_id: int, user_id: int | None, ride_id: int | None = None,
                      horse_id: int | None = None, days: int = DEFAULT_DAYS) -> CreatedLink:
    """A link to one ride's report or one horse's page of the club, valid `days` days (1 to `MAX_DAYS`)."""
    if (ride_id is None) == (horse_id is None):
        raise InputError("a share link shows one ride's report or one horse's page: give ride_id or horse_id")
    if not 1 <= days <= MAX_DAYS:
        raise InputError(f"a share link lasts 1 to {MAX_DAYS} days, not {days}")
    if ride_id is not None:
        RideRepository(session, club_id=club_id).get(ride_id)  # another club's ride: NotFound (404)
    elif horse_id is not None:
        HorseRepository(session, club_id=club_id).get(horse_id)
    token = secrets.token_urlsafe(32)
    link = ShareLinkRepository(session, club_id=club_id).add(
        token_hash=token_hash(token), expires_at=utcnow() + dt.timedelta(days=days), created_by=user_id,
        ride_id=ride_id, horse_id=horse_id)
    return CreatedLink(link, token)


def link_state(link: ShareLink, now: dt.datetime | None = None) -> str:
    """"active", "expired" or "withdrawn"."""
    if link.revoked_at is not None:
        return "withdrawn"
    return "expired" if link.expires_at <= (now or utcnow()) else "active"


def _what(link: ShareLink) -> str:
    """What the link shows, in words: "Report of Bella's canter of 2026-03-01" or "Page of the horse Bella"."""
    if link.ride is not None:
        ride = link.ride
        when = f" of {ride.ridden_on.isoformat()}" if ride.ridden_on else ""
        return f"Report of {ride.horse.name}'s {GAIT_WORDS.get(ride.gait, ride.gait)}{when} (ride #{ride.id})"
    if link.horse is not None:
        return f"Page of the horse {link.horse.name}"
    return "–"


def link_view(link: ShareLink) -> dict[str, Any]:
    """A link as the API lists it (never its token: only its maker saw that)."""
    maker = link.maker
    return {
        "id": link.id, "kind": "ride" if link.ride_id is not None else "horse", "ride_id": link.ride_id,
        "horse_id": link.horse_id, "shows": _what(link),
        "created_by": (maker.display_name or maker.email) if maker is not None else "a former member",
        "created_at": link.created_at, "expires_at": link.expires_at, "revoked_at": link.revoked_at,
        "state": link_state(link),
    }


def list_share_links(session: Session, *, club_id: int) -> list[dict[str, Any]]:
    """The club's links, newest first (at most 500)."""
    return [link_view(link) for link in ShareLinkRepository(session, club_id=club_id).all_links()]


def revoke_share_link(session: Session, *, club_id: int, link_id: int, user_id: int) -> dict[str, Any]:
    """Withdraw a link of the club (again: no change); it is refused from now on."""
    link = ShareLinkRepository(session, club_id=club_id).get(link_id)
    if link.revoked_at is None:
        link.revoked_at, link.revoked_by = utcnow(), user_id
        session.flush()
    return link_view(link)


def open_share_link(session: Session, token: str) -> ShareLink:
    """The active link of `token`; `ShareRefused` when unknown, withdrawn or expired."""
    link = ShareLinkRepository(session).by_token_hash(token_hash(token)) if 20 <= len(token) <= 100 else None
    if link is None:
        raise ShareRefused("unknown", "This link is not known",
                           "Check that the whole link was copied, or ask the club for a new one.")
    state = link_state(link)
    if state == "withdrawn":
        raise ShareRefused("withdrawn", "This link was withdrawn by the club",
                           "The club that shared it has withdrawn it. Ask the club for a new link if you still "
                           "need it.")
    if state == "expired":
        raise ShareRefused("expired", "This link has expired",
                           f"It worked until {link.expires_at:%Y-%m-%d}. Ask the club for a new link.")
    return link


def ride_of_link(session: Session, link: ShareLink, ride_id: int | None = None) -> int:
    """The ride a link may show: its own ride, or `ride_id` when it is one of the linked horse's rides."""
    if link.ride_id is not None:
        if ride_id is not None and ride_id != link.ride_id:
            raise NotFound("this link shows one ride only")
        return link.ride_id
    if ride_id is None:
        raise NotFound("this link shows a horse's page")
    ride = RideRepository(session, club_id=link.club_id).get(ride_id)
    if ride.horse_id != link.horse_id:
        raise NotFound(f"ride {ride_id} is not one of this horse's rides")
    return ride_id


def refusal_html(title: str, message: str) -> str:
    """A plain page for a link that opens nothing (no sign-in: the reader has no account)."""
    return (
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        '<meta name="viewport" content="width=device-width, initial-scale=1"><link rel="icon" href="data:,">'
        f"<title>{html.escape(title)}</title><style>{REFUSAL_CSS}</style></head><body><main>"
        f"<h1>{html.escape(title)}</h1><p>{html.escape(message)}</p>"
        "<p class=\"hint\">SaddleScope: saddle motion and rider comfort, shared read-only by a riding club.</p>"
        "</main></body></html>\n")


REFUSAL_CSS = ("body{font:11pt/1.5 \"DejaVu Sans\",Arial,sans-serif;color:#1d2630;background:#e9edf2;margin:0}"
               "main{max-width:34rem;margin:12vh auto;background:#fff;padding:1.5rem 2rem;"
               "box-shadow:0 1px 6px rgba(0,0,0,.15)}h1{font-size:1.4rem;margin:0 0 .8rem}"
               ".hint{color:#4a5563;font-size:.9rem}")
