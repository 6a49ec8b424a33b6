"""Share links: read-only links for someone without an account (`models.ShareLink`)."""

from __future__ import annotations

import datetime as dt

from sqlalchemy import select
from sqlalchemy.orm import selectinload

from saddlescope.db.models import ShareLink
from saddlescope.db.repositories.base import Repository

__all__ = ["ShareLinkRepository"]


class ShareLinkRepository(Repository):
    """A club's share links; looking one up by its token's hash needs no club (the vet has none)."""

    model = ShareLink

    def add(self, *, token_hash: str, expires_at: dt.datetime, created_by: int | None,
            ride_id: int | None = None, horse_id: int | None = None) -> ShareLink:
        """Add a link to one ride or one horse of this club (the caller checked it is the club's)."""
        if (ride_id is None) == (horse_id is None):
            raise ValueError("a share link shows one ride or one horse")
        return self._add(ShareLink(club_id=self._club_for_new(None), token_hash=token_hash, ride_id=ride_id,
                                   horse_id=horse_id, created_by=created_by, expires_at=expires_at))

    def by_token_hash(self, token_hash: str) -> ShareLink | None:
        """The link whose token hashes to `token_hash` (any club, unless scoped), or None."""
        return self.session.scalars(self._scoped(select(ShareLink).where(ShareLink.token_hash == token_hash))).first()

    def all_links(self, *, limit: int = 500) -> list[ShareLink]:
        """The club's links, newest first, with their ride, horse and maker loaded."""
        stmt = (self._scoped(select(ShareLink))
                .options(selectinload(ShareLink.ride), selectinload(ShareLink.horse), selectinload(ShareLink.maker))
                .order_by(ShareLink.id.desc()).limit(limit))
        return list(self.session.scalars(stmt))
