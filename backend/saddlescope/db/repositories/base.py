"""What every repository shares: a session, an optional club scope, lookups by id and paged lists."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, TypeVar, cast

from sqlalchemy import ColumnElement, CursorResult, Result, Select, exists, func, select
from sqlalchemy.orm import Session

from saddlescope.db.models import Base

__all__ = ["BadQuery", "Conflict", "NotFound", "Page", "Repository", "changed_rows", "like_pattern"]

M = TypeVar("M", bound=Base)


class NotFound(LookupError):
    """No row with that id (or not in this club)."""


class Conflict(ValueError):
    """The change would break a rule of the data (a duplicate name, a horse that rides still use)."""


class BadQuery(ValueError):
    """A list query asks for something unknown (a sort field, a filter value)."""


@dataclass(frozen=True)
class Page:
    """One page of a list: the rows and the total number of rows matching the filters."""

    items: Sequence[Any]
    total: int
    limit: int
    offset: int


def like_pattern(text: str) -> str:
    """A LIKE pattern matching `text` anywhere, with LIKE's wildcards taken literally."""
    escaped = text.replace("\\", "\\\\").replace("%", "\\%").replace("_", "\\_")
    return f"%{escaped}%"


def changed_rows(result: Result[Any]) -> int:
    """How many rows an UPDATE or DELETE changed (``Session.execute`` is typed as a plain ``Result``)."""
    return int(cast(CursorResult[Any], result).rowcount or 0)


class Repository:
    """Base: a session and an optional club scope."""

    # The mapped class: its columns (id, club_id, name, ...) are read by name, which a type checker cannot
    # follow through a class attribute shared by every repository.
    model: Any
    # Sortable fields of `list_page`: public name -> column (override per repository).
    sort_fields: dict[str, Any] = {}
    default_sort = "id"

    def __init__(self, session: Session, *, club_id: int | None = None) -> None:
        self.session = session
        self.club_id = club_id

    def _scoped(self, stmt: Select) -> Select:
        if self.club_id is not None and hasattr(self.model, "club_id"):
            stmt = stmt.where(self.model.club_id == self.club_id)
        return stmt

    def _club_for_new(self, club_id: int | None) -> int | None:
        if self.club_id is not None and club_id is not None and club_id != self.club_id:
            raise PermissionError(f"cannot create a row in club {club_id} from a repository scoped to "
                                  f"club {self.club_id}")
        return self.club_id if club_id is None else club_id

    def find(self, id_: int | str) -> Any:
        """Return the row with primary key `id_` (in this club), or None."""
        return self.session.scalars(self._scoped(select(self.model).where(self.model.id == id_))).first()

    def get(self, id_: int | str) -> Any:
        """Return the row with primary key `id_` (in this club); `NotFound` otherwise."""
        row = self.find(id_)
        if row is None:
            raise NotFound(f"{self.model.__tablename__[:-1]} {id_} not found")
        return row

    def _add(self, row: M) -> M:
        self.session.add(row)
        self.session.flush()
        return row

    def _in_use(self, column, id_: int) -> bool:
        """True when some row has `id_` in `column` (a ride still using a horse, ...)."""
        return bool(self.session.scalar(select(exists().where(column == id_))))

    def _order(self, sort: str | None):
        sort = sort or self.default_sort
        name = sort.removeprefix("-")
        column = self.sort_fields.get(name) if name != "id" else self.model.id
        if column is None:
            known = ", ".join(sorted({"id", *self.sort_fields}))
            raise BadQuery(f"cannot sort by {name!r}; sort by one of {known} (prefix '-' for descending)")
        ordered = column.desc() if sort.startswith("-") else column.asc()
        # Ties (and NULLs) in a stable order, so pages never overlap.
        return [ordered.nulls_last(), self.model.id.desc() if sort.startswith("-") else self.model.id.asc()]

    def _page(self, where: Sequence[ColumnElement[bool]] = (), *, sort: str | None, limit: int, offset: int,
              stmt: Select | None = None, count_stmt: Select | None = None) -> Page:
        """Rows of `stmt` matching `where` (in this club), `limit` of them from `offset`, and their total.

        `count_stmt` (default `stmt`) is counted instead, when it matches the same rows more cheaply.
        """
        stmt = self._scoped(stmt if stmt is not None else select(self.model)).where(*where)
        counted = self._scoped(count_stmt).where(*where) if count_stmt is not None else stmt
        total = self.session.scalar(
            select(func.count()).select_from(counted.order_by(None).with_only_columns(self.model.id).subquery()))
        rows = self.session.scalars(stmt.order_by(*self._order(sort)).limit(limit).offset(offset)).all()
        return Page(rows, int(total or 0), limit, offset)

    def list_page(self, *, sort: str | None = None, limit: int = 50, offset: int = 0) -> Page:
        """Return the rows (of this club) sorted by `sort`, `limit` of them from `offset`, and their total.

        Repositories with filters take them as further keywords.
        """
        return self._page(sort=sort, limit=limit, offset=offset)

    def update_fields(self, id_: int, **values: Any):
        """Set columns of one row (in this club); returns the row."""
        row = self.get(id_)
        for name, value in values.items():
            setattr(row, name, value)
        self.session.flush()
        return row
