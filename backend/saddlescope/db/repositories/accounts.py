"""Clubs and their users."""

from __future__ import annotations

import datetime as dt

from sqlalchemy import Select, func, select, update

from saddlescope.db.models import Club, PasswordReset, User
from saddlescope.db.repositories.base import Conflict, Repository

__all__ = ["ClubRepository", "UserRepository"]


class ClubRepository(Repository):
    """Clubs; scoped to one club, it sees only that club."""

    model = Club

    def _scoped(self, stmt: Select) -> Select:
        return stmt.where(Club.id == self.club_id) if self.club_id is not None else stmt

    def get_or_create(self, name: str) -> Club:
        """Return the club named `name`, created if new."""
        club = self.session.scalars(select(Club).where(Club.name == name)).first()
        return club or self._add(Club(name=name))

    def add(self, name: str) -> Club:
        """Add a club; `Conflict` when the name is taken (in any letter case)."""
        if self.session.scalar(select(Club.id).where(func.lower(Club.name) == name.lower())) is not None:
            raise Conflict(f"a club named {name!r} already exists")
        return self._add(Club(name=name))

    def count(self) -> int:
        """Return the number of clubs (all of them, whatever the scope)."""
        return int(self.session.scalar(select(func.count(Club.id))) or 0)


class UserRepository(Repository):
    """Users (accounts) of a club; e-mail addresses are unique over all clubs, stored lower-case."""

    model = User
    sort_fields = {"email": User.email, "display_name": User.display_name, "role": User.role,
                   "created_at": User.created_at}
    default_sort = "email"

    def by_email(self, email: str) -> User | None:
        """Return the user with this e-mail address (any club: sign-in comes before the club is known)."""
        return self.session.scalars(select(User).where(User.email == email.strip().lower())).first()

    def add(self, *, club_id: int | None = None, email: str, password_hash: str, display_name: str = "",
            role: str) -> User:
        """Add an active user; `Conflict` when the e-mail address is taken."""
        email = email.strip().lower()
        if self.by_email(email) is not None:
            # One answer whether the address is in this club or another: it names no other club's user.
            raise Conflict("this e-mail address cannot be used for a new account; choose another one")
        return self._add(User(club_id=self._club_for_new(club_id), email=email, password_hash=password_hash,
                              display_name=display_name, role=role, is_active=True))

    def count_admins(self) -> int:
        """Return the number of active admins (of this club)."""
        stmt = self._scoped(select(func.count(User.id)).where(User.role == "admin", User.is_active.is_(True)))
        return int(self.session.scalar(stmt) or 0)

    def add_reset(self, user: User, *, token_hash: str, expires_at: dt.datetime) -> PasswordReset:
        """Record a one-time password reset for `user` (of this club), by the SHA-256 of its token."""
        return self._add(PasswordReset(user_id=user.id, token_hash=token_hash, expires_at=expires_at))

    def reset_by_hash(self, token_hash: str) -> PasswordReset | None:
        """Return the password reset with this token hash (any club: the token is the credential)."""
        return self.session.scalars(select(PasswordReset).where(PasswordReset.token_hash == token_hash)).first()

    def end_resets(self, user_id: int, now: dt.datetime) -> None:
        """Mark every unused password reset of the user as used (a newer one, or a new password, wins)."""
        self.session.execute(update(PasswordReset).where(PasswordReset.user_id == user_id,
                                                         PasswordReset.used_at.is_(None)).values(used_at=now))
