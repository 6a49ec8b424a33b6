"""Small pieces every router uses: id path parameters, paging and sorting, file responses."""

from __future__ import annotations

import inspect
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from enum import StrEnum
from typing import Annotated, Any, cast

from fastapi import Depends, Path, Query
from fastapi.responses import Response

from saddlescope.api.schemas import MAX_ID, ErrorOut
from saddlescope.core.vibration import INDICATORS

__all__ = [
    "CONFLICT", "ERRORS", "Id", "IndicatorKey", "MAX_OFFSET", "Paging", "PagingDep", "QueryId", "changes",
    "download", "page_of", "paging_sorted_by", "sort_enum",
]

Id = Annotated[int, Path(ge=1, le=MAX_ID, description="the id (within your club)")]
QueryId = Annotated[int | None, Query(ge=1, le=MAX_ID)]
MAX_OFFSET = 10_000_000

# Responses every club route may give, for the OpenAPI.
ERRORS: dict[int | str, dict[str, Any]] = {
    401: {"model": ErrorOut, "description": "not signed in"},
    403: {"model": ErrorOut, "description": "not allowed (role, CSRF)"},
    404: {"model": ErrorOut, "description": "no such thing in your club"},
    422: {"model": ErrorOut, "description": "invalid input, with the reason"},
}
CONFLICT: dict[int | str, dict[str, Any]] = {409: {"model": ErrorOut, "description": "conflicts with existing data"}}


@dataclass(frozen=True)
class Paging:
    """A list request's page (`limit` rows from `offset`) and sort field (``-`` first: descending)."""

    limit: int
    offset: int
    sort: str | None


def _paging(
    limit: Annotated[int, Query(ge=1, le=500, description="rows per page")] = 50,
    offset: Annotated[int, Query(ge=0, le=MAX_OFFSET, description="rows to skip")] = 0,
    sort: Annotated[
        str | None,
        Query(
            max_length=40, pattern=r"^-?[a-z0-9_]+$", description="field to sort by; '-field' for descending"
        ),
    ] = None,
) -> Paging:
    return Paging(limit, offset, sort)


PagingDep = Annotated[Paging, Depends(_paging)]

# Every indicator key of the result (CONTRACTS section 2 and more): the OpenAPI lists them.
IndicatorKey = StrEnum("IndicatorKey", [(key, key) for key in INDICATORS])  # type: ignore[misc]  # members from data


def sort_enum(name: str, fields: Iterable[str]) -> type[StrEnum]:
    """The sort values of a list: each field ascending and, with ``-`` first, descending."""
    members = []
    for field in dict.fromkeys(["id", *fields]):
        members += [(field, field), (f"desc_{field}", f"-{field}")]
    return cast("type[StrEnum]", StrEnum(name, members))  # the functional API makes a class, not a member


def paging_sorted_by(sort_values: type[StrEnum], default: str) -> Callable[..., Paging]:
    """A paging dependency whose `sort` is one of `sort_values` (an enum the OpenAPI shows).

    A route takes it as ``Annotated[Paging, Depends(paging_sorted_by(...))]``.
    """

    def dependency(limit: int, offset: int, sort: StrEnum | None) -> Paging:
        return Paging(limit, offset, sort.value if sort is not None else None)

    # Annotations built here, not written (this module's annotations are strings FastAPI resolves by name).
    sort_type = Annotated[
        sort_values | None,  # type: ignore[valid-type]
        Query(description=f"field to sort by, '-field' for descending (default {default})"),
    ]
    keyword = inspect.Parameter.KEYWORD_ONLY
    dependency.__signature__ = inspect.Signature([  # type: ignore[attr-defined]
        inspect.Parameter("limit", keyword, default=50,
                          annotation=Annotated[int, Query(ge=1, le=500, description="rows per page")]),
        inspect.Parameter("offset", keyword, default=0,
                          annotation=Annotated[int, Query(ge=0, le=MAX_OFFSET, description="rows to skip")]),
        inspect.Parameter("sort", keyword, default=None, annotation=sort_type),
    ])
    return dependency


def page_of(page, convert) -> dict:
    """A repository `Page` as the JSON list envelope."""
    return {
        "items": [convert(row) for row in page.items],
        "total": page.total,
        "limit": page.limit,
        "offset": page.offset,
    }


def download(data: bytes, filename: str, media_type: str) -> Response:
    """A response that browsers save as file `filename`."""
    return Response(
        data, media_type=media_type, headers={"Content-Disposition": f'attachment; filename="{filename}"'}
    )


def changes(body, *, nullable: tuple[str, ...] = ()) -> dict:
    """The fields a PATCH body sets; an explicit null clears only the fields in `nullable`."""
    return {k: v for k, v in body.model_dump(exclude_unset=True).items() if v is not None or k in nullable}
