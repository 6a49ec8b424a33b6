"""Clubs, users, passwords and access tokens (no web framework here).

Passwords are hashed with Argon2id (argon2-cffi's defaults, RFC 9106's low-memory parameters; a test
suite may choose the library's cheapest, `use_password_hashing`). An access token is a JWT (HS256, signed
with ``SADDLESCOPE_SECRET_KEY``) naming the user, their club and role, and carrying a random CSRF
token: the browser gets the same token as an HttpOnly session cookie and must echo the CSRF token in a
header on unsafe requests (`saddlescope.api.deps`).

A token also carries the user's session version (``sv``): signing out everywhere, changing the password
and an admin's password reset bump it, so every older token is refused from then on. And it carries its
sign-in's random id (``sid``): signing out (`end_sign_in`) keeps that id in ``ended_sign_ins`` until the
token would have expired, so that one token (cookie or bearer) is refused and other sign-ins go on.
"""

from __future__ import annotations

import datetime as dt
import hashlib
import re
import secrets
from dataclasses import dataclass, replace

import jwt
from argon2 import PasswordHasher, profiles
from argon2.exceptions import InvalidHashError, VerificationError, VerifyMismatchError
from sqlalchemy.orm import Session

from saddlescope.core.errors import InputError, SaddleScopeError
from saddlescope.db.enums import Role
from saddlescope.db.models import Club, EndedSignIn, User
from saddlescope.db.repositories import ClubRepository, Conflict, UserRepository
from saddlescope.settings import Settings

__all__ = [
    "AuthError", "Forbidden", "MIN_PASSWORD_LENGTH", "Principal", "RESET_LIFETIME", "TOKEN_ALGORITHM",
    "TOKEN_AUDIENCE", "WrongPassword", "add_user", "authenticate", "change_password", "check_email", "check_password",
    "consume_password_reset", "create_club", "current_principal", "end_sessions", "end_sign_in", "hash_password",
    "issue_token", "read_token", "require_admin", "start_password_reset", "update_user", "use_password_hashing",
    "verify_password", "PASSWORD_HASHING",
]

TOKEN_ALGORITHM = "HS256"
TOKEN_AUDIENCE = "saddlescope"
MIN_PASSWORD_LENGTH = 8
RESET_LIFETIME = dt.timedelta(hours=24)
_EMAIL = re.compile(r"^[^@\s]+@[^@\s]+\.[^@\s]+$")
# Settings.password_hashing -> Argon2id's parameters
PASSWORD_HASHING = {"rfc9106-low-memory": profiles.RFC_9106_LOW_MEMORY, "cheapest-for-tests": profiles.CHEAPEST}
_hasher = PasswordHasher.from_parameters(PASSWORD_HASHING["rfc9106-low-memory"])
# Verifying against this when the e-mail is unknown keeps sign-in time the same either way.
_DUMMY_HASH = _hasher.hash("not-a-real-password")


def use_password_hashing(name: str) -> None:
    """Hash and check passwords with the parameters `name` names (a key of `PASSWORD_HASHING`) from now on.

    The server sets it from its settings at start (`SADDLESCOPE_PASSWORD_HASHING`); stored hashes of
    the other parameters still verify, and are re-hashed at their next sign-in (`authenticate`).
    """
    global _hasher, _DUMMY_HASH
    parameters = PASSWORD_HASHING.get(name)
    if parameters is None:
        raise InputError(f"password hashing {name!r} is not one of {', '.join(PASSWORD_HASHING)}")
    if _hasher.time_cost != parameters.time_cost or _hasher.memory_cost != parameters.memory_cost:
        _hasher = PasswordHasher.from_parameters(parameters)
        _DUMMY_HASH = _hasher.hash("not-a-real-password")


class AuthError(SaddleScopeError):
    """Sign-in failed or a token is missing, expired or forged (HTTP 401)."""


class Forbidden(SaddleScopeError):
    """Signed in, but the role does not allow this (HTTP 403)."""


class WrongPassword(InputError):
    """The current password given to change it is wrong (HTTP 422)."""


@dataclass(frozen=True)
class Principal:
    """Who is calling: the signed-in user, their club and role (from a verified token)."""

    user_id: int
    club_id: int
    role: str
    csrf: str
    session_version: int = 0
    sign_in_id: str | None = None  # the token's ``sid`` (None: a token issued before sign-ins had ids)
    expires_at: dt.datetime | None = None

    @property
    def is_admin(self) -> bool:
        """True for a club admin."""
        return self.role == Role.ADMIN.value


def hash_password(password: str) -> str:
    """The Argon2 hash of `password` (with its own salt), to store."""
    return _hasher.hash(password)


def verify_password(password_hash: str, password: str) -> bool:
    """True when `password` matches the stored hash (False also for a damaged hash)."""
    try:
        return _hasher.verify(password_hash, password)
    except (VerifyMismatchError, VerificationError, InvalidHashError):
        return False


def check_email(email: str) -> str:
    """The address lower-cased and stripped; `InputError` when it is not an e-mail address."""
    email = email.strip().lower()
    if not _EMAIL.match(email) or len(email) > 320:
        raise InputError(f"{email!r} is not an e-mail address")
    return email


def check_password(password: str) -> str:
    """The password, if long enough (and not absurdly long); `InputError` otherwise."""
    if len(password) < MIN_PASSWORD_LENGTH:
        raise InputError(f"the password must have at least {MIN_PASSWORD_LENGTH} characters")
    if len(password) > 1024:
        raise InputError("the password is longer than 1024 characters")
    return password


def create_club(
    session: Session, *, club_name: str, email: str, password: str, display_name: str = ""
) -> tuple[Club, User]:
    """A new club and its first user, an admin (not committed)."""
    club_name = club_name.strip()
    if not club_name:
        raise InputError("the club needs a name")
    club = ClubRepository(session).add(club_name)
    user = UserRepository(session, club_id=club.id).add(
        email=check_email(email),
        password_hash=hash_password(check_password(password)),
        display_name=display_name.strip(),
        role=Role.ADMIN.value,
    )
    return club, user


def add_user(
    session: Session,
    *,
    club_id: int,
    email: str,
    password: str,
    display_name: str = "",
    role: str = Role.MEMBER.value,
) -> User:
    """A new user of the club (admins call this through the API)."""
    if role not in {r.value for r in Role}:
        raise InputError(f"role must be one of {', '.join(r.value for r in Role)}, got {role!r}")
    return UserRepository(session, club_id=club_id).add(
        email=check_email(email),
        password_hash=hash_password(check_password(password)),
        display_name=display_name.strip(),
        role=role,
    )


def authenticate(session: Session, email: str, password: str) -> User:
    """The active user with this e-mail and password; `AuthError` (one message for every failure)."""
    user = UserRepository(session).by_email(email or "")
    if user is None:
        verify_password(_DUMMY_HASH, password or "")
        raise AuthError("wrong e-mail address or password")
    if not verify_password(user.password_hash, password or "") or not user.is_active:
        raise AuthError("wrong e-mail address or password")
    if _hasher.check_needs_rehash(user.password_hash):
        user.password_hash = hash_password(password)
    return user


def _signing_key(settings: Settings) -> bytes:
    """The token key: derived from the secret for this one purpose (and always 256 bits long)."""
    return hashlib.sha256(
        b"saddlescope-access-token-v1\0" + settings.secret_key.get_secret_value().encode()
    ).digest()


def issue_token(user: User, settings: Settings, *, now: dt.datetime | None = None) -> tuple[str, str, int]:
    """(token, csrf token, lifetime in s) for a signed-in user."""
    now = now or dt.datetime.now(dt.UTC)
    csrf = secrets.token_urlsafe(24)
    lifetime_s = settings.token_lifetime_s
    claims = {
        "sub": str(user.id),
        "club": user.club_id,
        "role": user.role,
        "csrf": csrf,
        "sv": int(user.session_version or 0),
        "sid": secrets.token_urlsafe(24),
        "aud": TOKEN_AUDIENCE,
        "iat": now,
        "exp": now + dt.timedelta(seconds=lifetime_s),
    }
    token = jwt.encode(claims, _signing_key(settings), algorithm=TOKEN_ALGORITHM)
    return token, csrf, lifetime_s


def read_token(token: str, settings: Settings) -> Principal:
    """Verify a token's signature and expiry; `AuthError` saying why it is refused."""
    try:
        claims = jwt.decode(
            token,
            _signing_key(settings),
            algorithms=[TOKEN_ALGORITHM],
            audience=TOKEN_AUDIENCE,
            options={"require": ["exp", "sub", "club", "csrf"]},
        )
    except jwt.ExpiredSignatureError:
        raise AuthError("the sign-in has expired; sign in again") from None
    except jwt.InvalidTokenError:
        raise AuthError("invalid access token; sign in again") from None
    try:
        return Principal(
            user_id=int(claims["sub"]),
            club_id=int(claims["club"]),
            role=str(claims["role"]),
            csrf=str(claims["csrf"]),
            session_version=int(claims.get("sv", 0)),
            sign_in_id=str(claims["sid"]) if claims.get("sid") is not None else None,
            expires_at=dt.datetime.fromtimestamp(int(claims["exp"]), dt.UTC),
        )
    except (KeyError, TypeError, ValueError):
        raise AuthError("invalid access token; sign in again") from None


def current_principal(session: Session, principal: Principal) -> Principal:
    """The principal re-checked against the database: the user still exists, is active, same club.

    The role is read afresh, so demoting an admin takes effect at once, not when the token expires.
    """
    user = session.get(User, principal.user_id)
    if user is None or not user.is_active or user.club_id != principal.club_id:
        raise AuthError("this account no longer exists or was deactivated; sign in again")
    if (user.session_version or 0) != principal.session_version:
        raise AuthError("this sign-in was ended (signed out everywhere, or the password was changed or "
                        "reset); sign in again")
    if principal.sign_in_id is not None and session.get(EndedSignIn, principal.sign_in_id) is not None:
        raise AuthError("this sign-in was ended (signed out); sign in again")
    return replace(principal, role=user.role)


def require_admin(principal: Principal) -> None:
    """Raise `Forbidden` unless the caller is a club admin."""
    if not principal.is_admin:
        raise Forbidden("only a club admin may do this")


def update_user(
    session: Session,
    *,
    club_id: int,
    user_id: int,
    role: str | None = None,
    is_active: bool | None = None,
    password: str | None = None,
    display_name: str | None = None,
) -> User:
    """Change a user of the club; the club always keeps at least one active admin."""
    users = UserRepository(session, club_id=club_id)
    user = users.get(user_id)
    if role is not None and role not in {r.value for r in Role}:
        raise InputError(f"role must be one of {', '.join(r.value for r in Role)}, got {role!r}")
    losing_admin = (
        user.role == Role.ADMIN.value
        and user.is_active
        and ((role is not None and role != Role.ADMIN.value) or is_active is False)
    )
    if losing_admin and users.count_admins() <= 1:
        # 409: the request is well formed, the club's state refuses it (a club without an admin could
        # never add a member or reset a password again).
        raise Conflict(f"{user.display_name or user.email} is the club's last active admin and cannot be "
                       "made a member or disabled: the club must keep at least one active admin; make "
                       "another member an admin first")
    if role is not None:
        user.role = role
    if is_active is not None:
        user.is_active = is_active
    if password is not None:
        user.password_hash = hash_password(check_password(password))
        end_sessions(user)
    if display_name is not None:
        user.display_name = display_name.strip()
    session.flush()
    return user


def end_sign_in(session: Session, principal: Principal, *, now: dt.datetime | None = None) -> None:
    """Sign out this one sign-in: its token is refused from now on (others of the user go on).

    Ended sign-ins whose tokens have expired anyway are forgotten on the way.
    """
    now = now or dt.datetime.now(dt.UTC)
    session.query(EndedSignIn).filter(EndedSignIn.expires_at < now).delete(synchronize_session=False)
    if principal.sign_in_id is None or principal.expires_at is None:
        return  # a token from before sign-ins had ids: it expires as before
    if session.get(EndedSignIn, principal.sign_in_id) is None:
        session.add(EndedSignIn(sign_in_id=principal.sign_in_id, user_id=principal.user_id,
                                expires_at=principal.expires_at))
    session.flush()


def end_sessions(user: User) -> None:
    """Make every token issued to `user` so far invalid (bumps the session version)."""
    user.session_version = (user.session_version or 0) + 1


def change_password(session: Session, *, user_id: int, current_password: str, new_password: str) -> User:
    """The signed-in user's own change: the current password must match; every session ends."""
    user = UserRepository(session).get(user_id)
    if not verify_password(user.password_hash, current_password):
        raise WrongPassword("the current password is wrong")
    user.password_hash = hash_password(check_password(new_password))
    end_sessions(user)
    session.flush()
    return user


def _reset_hash(token: str) -> str:
    return hashlib.sha256(b"saddlescope-password-reset-v1\0" + token.encode()).hexdigest()


def start_password_reset(
    session: Session, *, club_id: int, user_id: int, now: dt.datetime | None = None
) -> tuple[str, dt.datetime]:
    """An admin resets a user of the club: (one-time token, its expiry).

    The user's sessions end and the old password stops working at once; the token (shown once to the
    admin, stored only as a hash) sets a new one through `consume_password_reset`.
    """
    now = now or dt.datetime.now(dt.UTC)
    users = UserRepository(session, club_id=club_id)
    user = users.get(user_id)
    token = secrets.token_urlsafe(32)
    expires_at = now + RESET_LIFETIME
    users.end_resets(user.id, now)  # an earlier token of this user stops working
    users.add_reset(user, token_hash=_reset_hash(token), expires_at=expires_at)
    user.password_hash = "!reset:" + secrets.token_hex(16)  # matches no password
    end_sessions(user)
    session.flush()
    return token, expires_at


def consume_password_reset(
    session: Session, *, token: str, new_password: str, now: dt.datetime | None = None
) -> User:
    """Set a new password with a reset token (once, before it expires); `AuthError` otherwise."""
    now = now or dt.datetime.now(dt.UTC)
    check_password(new_password)
    reset = UserRepository(session).reset_by_hash(_reset_hash(token or ""))
    if reset is None or reset.used_at is not None or reset.expires_at <= now or not reset.user.is_active:
        raise AuthError("this password reset link is invalid, already used or expired; ask a club admin "
                        "for a new one")
    user = reset.user
    UserRepository(session).end_resets(user.id, now)  # this one and any other outstanding
    user.password_hash = hash_password(new_password)
    end_sessions(user)
    session.flush()
    return user
