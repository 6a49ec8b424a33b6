"""Dependencies of the routes, as ``Annotated`` aliases (one place to change how each is made).

Authentication and the club scope live here and nowhere else: `ClubDep` is the signed-in user's
club with every repository already confined to it, so a route cannot reach another club's rows
(another club's id is simply not found: 404).
"""

from __future__ import annotations

import hmac
import ipaddress
from collections.abc import AsyncIterator
from dataclasses import dataclass
from functools import cached_property
from typing import Annotated

from fastapi import Depends, Request
from fastapi.security import OAuth2PasswordBearer
from sqlalchemy import Engine
from sqlalchemy.orm import Session, sessionmaker
from starlette.concurrency import run_in_threadpool

from saddlescope.db.repositories import (
    AnalyticsRepository,
    GradeRepository,
    HorseRepository,
    JobRepository,
    RecordingRepository,
    ResultRepository,
    RideRepository,
    RiderRepository,
    RigRepository,
    SaddleRepository,
    UploadRepository,
    UserRepository,
)
from saddlescope.services.accounts.permissions import require as require_permission
from saddlescope.services.accounts.users import (
    AuthError,
    Forbidden,
    Principal,
    current_principal,
    read_token,
    require_admin,
)
from saddlescope.services.jobs.queue import JobQueue
from saddlescope.settings import Settings
from saddlescope.storage import Storage

__all__ = [
    "AdminClubDep", "CSRF_COOKIE", "CSRF_HEADER", "ClubDep", "ClubScope", "EngineDep", "PrincipalDep",
    "OptionalBearerDep", "QueueDep", "SAFE_METHODS", "SESSION_COOKIE", "SessionDep", "SessionFactoryDep", "SettingsDep",
    "StorageDep", "check_csrf", "client_address",
]

SESSION_COOKIE = "saddlescope_session"
CSRF_COOKIE = "saddlescope_csrf"
CSRF_HEADER = "X-CSRF-Token"
SAFE_METHODS = frozenset({"GET", "HEAD", "OPTIONS"})

oauth2_scheme = OAuth2PasswordBearer(
    tokenUrl="/api/auth/login", auto_error=False, description="the access token of POST /api/auth/login"
)


def _settings(request: Request) -> Settings:
    return request.app.state.settings


def _engine(request: Request) -> Engine:
    return request.app.state.engine


def _sessions(request: Request) -> sessionmaker[Session]:
    return request.app.state.sessions


def _finish(session: Session, ok: bool) -> None:
    try:
        if ok:
            session.commit()
        else:
            session.rollback()
    finally:
        session.close()


async def _session(request: Request) -> AsyncIterator[Session]:
    # Commits when the route returns normally (before the response is sent: scope="function" below,
    # so a failed commit is an error response and a client's next request sees the change); routes
    # that enqueue work commit first themselves.
    # A request holds its database connection across several hops onto the shared thread pool. Without
    # a bound, more requests than pooled connections start at once, and the threads then block waiting
    # for connections held by requests that are themselves waiting for a thread (p95 of seconds under
    # 50 clients). So requests wait for a session slot here, on the event loop, where waiting is free;
    # the engine's pool has a connection for every slot.
    async with request.app.state.db_slots:
        session = request.app.state.sessions()
        try:
            yield session
        except BaseException:
            await run_in_threadpool(_finish, session, False)
            raise
        await run_in_threadpool(_finish, session, True)


def _trusted(address: str, trusted: str) -> bool:
    """Whether `address` is one of the proxies `trusted` names (comma-separated addresses or networks, or *)."""
    entries = [entry.strip() for entry in trusted.split(",") if entry.strip()]
    if "*" in entries:
        return True
    try:
        ip = ipaddress.ip_address(address)
    except ValueError:
        return address in entries  # a name such as "testclient" or a unix socket path
    for entry in entries:
        try:
            if ip in ipaddress.ip_network(entry, strict=False):
                return True
        except ValueError:
            continue
    return False


def client_address(request: Request) -> str:
    """The caller's address, for counting failed sign-ins.

    The peer, or when the peer is a trusted proxy (``SADDLESCOPE_FORWARDED_ALLOW_IPS``) the nearest
    address in ``X-Forwarded-For`` that is not itself a trusted proxy. Behind uvicorn (`saddlescope
    serve`) the peer is already that address; this keeps the counting right under any other server too.
    The header from an untrusted peer is ignored (anyone can send it).
    """
    peer = request.client.host if request.client else ""
    trusted = request.app.state.settings.forwarded_allow_ips
    if not peer or not _trusted(peer, trusted):
        return peer
    hops = [hop.strip() for hop in request.headers.get("x-forwarded-for", "").split(",") if hop.strip()]
    for hop in reversed(hops):  # the proxies append: read from the nearest back
        if not _trusted(hop, trusted):
            return hop
    return hops[0] if hops else peer


def _storage(request: Request) -> Storage:
    return request.app.state.storage


def _queue(request: Request) -> JobQueue:
    return request.app.state.queue


SettingsDep = Annotated[Settings, Depends(_settings)]
EngineDep = Annotated[Engine, Depends(_engine)]
SessionFactoryDep = Annotated[sessionmaker[Session], Depends(_sessions)]
SessionDep = Annotated[Session, Depends(_session, scope="function")]
StorageDep = Annotated[Storage, Depends(_storage)]
QueueDep = Annotated[JobQueue, Depends(_queue)]


def _principal(
    request: Request,
    settings: SettingsDep,
    session: SessionDep,
    bearer: Annotated[str | None, Depends(oauth2_scheme)],
) -> Principal:
    """The caller, from a bearer token or the session cookie (then CSRF-checked on unsafe methods)."""
    if bearer:
        principal = read_token(bearer, settings)
    else:
        cookie = request.cookies.get(SESSION_COOKIE)
        if not cookie:
            raise AuthError(
                "not signed in: send 'Authorization: Bearer <token>' from POST /api/auth/login, or "
                "sign in with the browser"
            )
        principal = read_token(cookie, settings)
        check_csrf(request, principal)
    return current_principal(session, principal)


def check_csrf(request: Request, principal: Principal) -> None:
    """For a caller signed in by the cookie: an unsafe method needs the CSRF header (`Forbidden`)."""
    if request.method in SAFE_METHODS:
        return
    # Double submit: a page on another site can make the browser send the cookie, but it cannot
    # read our CSRF cookie to copy it into the header. Comparing with the token signed into the
    # session also defeats a CSRF cookie planted by a sibling domain.
    header = request.headers.get(CSRF_HEADER, "")
    if not header or not hmac.compare_digest(header, principal.csrf):
        raise Forbidden(
            f"missing or wrong {CSRF_HEADER} header (copy the {CSRF_COOKIE} cookie into it "
            "on every POST, PUT, PATCH and DELETE)"
        )


PrincipalDep = Annotated[Principal, Depends(_principal)]
OptionalBearerDep = Annotated[str | None, Depends(oauth2_scheme)]


@dataclass
class ClubScope:
    """The signed-in user's club: its id, the caller, and repositories confined to it."""

    session: Session
    principal: Principal

    @property
    def club_id(self) -> int:
        """The id of the signed-in user's club."""
        return self.principal.club_id

    def require_admin(self) -> None:
        """Raise `Forbidden` unless the caller is an admin of the club."""
        require_admin(self.principal)

    def require(self, action: str, *, owner_id: int | None = None) -> None:
        """Raise `Forbidden` unless the caller may do `action` (the table in services/accounts/permissions.py)."""
        require_permission(self.principal, action, owner_id=owner_id)

    def _repo(self, cls):
        return cls(self.session, club_id=self.club_id)

    @cached_property
    def users(self) -> UserRepository:
        """The club's users."""
        return self._repo(UserRepository)

    @cached_property
    def horses(self) -> HorseRepository:
        """The club's horses."""
        return self._repo(HorseRepository)

    @cached_property
    def riders(self) -> RiderRepository:
        """The club's riders."""
        return self._repo(RiderRepository)

    @cached_property
    def saddles(self) -> SaddleRepository:
        """The club's saddles."""
        return self._repo(SaddleRepository)

    @cached_property
    def rigs(self) -> RigRepository:
        """The club's rigs."""
        return self._repo(RigRepository)

    @cached_property
    def rides(self) -> RideRepository:
        """The club's rides."""
        return self._repo(RideRepository)

    @cached_property
    def recordings(self) -> RecordingRepository:
        """The club's clips (recordings)."""
        return self._repo(RecordingRepository)

    @cached_property
    def jobs(self) -> JobRepository:
        """The club's jobs."""
        return self._repo(JobRepository)

    @cached_property
    def results(self) -> ResultRepository:
        """The club's results."""
        return self._repo(ResultRepository)

    @cached_property
    def grades(self) -> GradeRepository:
        """The club's grades."""
        return self._repo(GradeRepository)

    @cached_property
    def uploads(self) -> UploadRepository:
        """The club's resumable uploads."""
        return self._repo(UploadRepository)

    @cached_property
    def analytics(self) -> AnalyticsRepository:
        """The club's read-only analytics queries."""
        return AnalyticsRepository(self.session, club_id=self.club_id)


def _club(session: SessionDep, principal: PrincipalDep) -> ClubScope:
    return ClubScope(session, principal)


def _admin_club(club: Annotated[ClubScope, Depends(_club)]) -> ClubScope:
    club.require_admin()
    return club


ClubDep = Annotated[ClubScope, Depends(_club)]
AdminClubDep = Annotated[ClubScope, Depends(_admin_club)]
