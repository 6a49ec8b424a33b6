"""What a share link opens, without an account: one ride's report, or one horse's page and its rides' reports.

Mounted at ``/shared`` (not under ``/api``): a vet opens ``/shared/<token>`` in a browser. Only GET; the
token decides everything a request may read, so no route here takes a club, a horse or a list. A link
that opens nothing (unknown, withdrawn, expired) and anything outside it answer a plain page in words,
never a sign-in page: the reader has no account to sign in with.
"""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Path, status
from fastapi.responses import HTMLResponse, Response

from saddlescope.api.deps import SessionDep, StorageDep
from saddlescope.api.routers.common import Id
from saddlescope.api.security_headers import inline_style_hashes, report_csp
from saddlescope.db.repositories import NotFound
from saddlescope.services.accounts.share_links import ShareRefused, open_share_link, refusal_html, ride_of_link
from saddlescope.services.horses.shared_page import shared_horse_html
from saddlescope.services.results.report import ride_report_html, ride_report_pdf

__all__ = ["router"]

router = APIRouter(prefix="/shared", tags=["shared"])
Token = Annotated[str, Path(min_length=1, max_length=200, description="the share link's token")]
PRIVATE = {"Cache-Control": "private, no-store", "X-Robots-Tag": "noindex, nofollow", "Referrer-Policy": "no-referrer"}
HTML: dict[str, Any] = {"content": {"text/html": {}}}
PAGE: dict[int | str, dict[str, Any]] = {200: HTML, 404: HTML, 410: HTML}
PDF_PAGE: dict[int | str, dict[str, Any]] = {**PAGE, 200: {"content": {"application/pdf": {}}}}
REFUSED_STATUS = {"unknown": status.HTTP_404_NOT_FOUND, "withdrawn": status.HTTP_410_GONE,
                  "expired": status.HTTP_410_GONE}


def _page(page: str, code: int = status.HTTP_200_OK) -> HTMLResponse:
    return HTMLResponse(page, status_code=code,
                        headers={**PRIVATE, "Content-Security-Policy": report_csp(inline_style_hashes(page))})


def _refused(title: str, message: str, code: int) -> HTMLResponse:
    return _page(refusal_html(title, message), code)


def _shared(render):
    """Run `render`, answering a refused link or a thing outside it with a plain page."""
    try:
        return render()
    except ShareRefused as refused:
        return _refused(refused.title, refused.message, REFUSED_STATUS[refused.reason])
    except NotFound as missing:
        detail = str(missing)
        if "not been analysed" in detail:
            return _refused("No report yet", "This ride has not been analysed yet: its report is not ready. "
                            "Try again later.", status.HTTP_404_NOT_FOUND)
        return _refused("Not part of this link", "This link does not show that page.", status.HTTP_404_NOT_FOUND)


def _report_links(pdf_href: str, back: str | None) -> str:
    back_link = f'<a href="{back}">&larr; Back to the horse</a> &middot; ' if back else ""
    return f'{back_link}<a href="{pdf_href}">Download as PDF</a>'


@router.get("/{token}", response_class=HTMLResponse, responses=PAGE)
def shared_page(token: Token, session: SessionDep, storage: StorageDep) -> HTMLResponse:
    """The page a link shows: the ride's one-page report, or the horse's page with its rides."""

    def render() -> HTMLResponse:
        link = open_share_link(session, token)
        if link.horse_id is not None:
            return _page(shared_horse_html(session, link, ride_href=lambda ride_id: f"{token}/rides/{ride_id}"))
        ride_id = ride_of_link(session, link)
        return _page(ride_report_html(session, storage, ride_id, club_id=link.club_id,
                                      screen_links=_report_links(f"{token}/report.pdf", None)))

    return _shared(render)


@router.get("/{token}/report.pdf", responses=PDF_PAGE)
def shared_pdf(token: Token, session: SessionDep, storage: StorageDep) -> Response:
    """A ride link's report as an A4 PDF."""

    def render() -> Response:
        link = open_share_link(session, token)
        ride_id = ride_of_link(session, link)
        return _pdf(ride_report_pdf(session, storage, ride_id, club_id=link.club_id), ride_id)

    return _shared(render)


def _pdf(data: bytes, ride_id: int) -> Response:
    return Response(data, media_type="application/pdf",
                    headers={**PRIVATE, "Content-Disposition": f'inline; filename="ride-{ride_id}-report.pdf"'})


@router.get("/{token}/rides/{ride_id}", response_class=HTMLResponse, responses=PAGE)
def shared_ride_of_horse(token: Token, ride_id: Id, session: SessionDep, storage: StorageDep) -> HTMLResponse:
    """A horse link: the report of one of that horse's rides."""

    def render() -> HTMLResponse:
        link = open_share_link(session, token)
        ride = ride_of_link(session, link, ride_id) if link.horse_id is not None else _outside()
        links = _report_links(f"{ride}/report.pdf", f"../../{token}")
        return _page(ride_report_html(session, storage, ride, club_id=link.club_id, screen_links=links))

    return _shared(render)


@router.get("/{token}/rides/{ride_id}/report.pdf", responses=PDF_PAGE)
def shared_ride_of_horse_pdf(token: Token, ride_id: Id, session: SessionDep, storage: StorageDep) -> Response:
    """A horse link: one of that horse's rides' report as an A4 PDF."""

    def render() -> Response:
        link = open_share_link(session, token)
        ride = ride_of_link(session, link, ride_id) if link.horse_id is not None else _outside()
        return _pdf(ride_report_pdf(session, storage, ride, club_id=link.club_id), ride)

    return _shared(render)


def _outside() -> int:
    raise NotFound("this link shows one ride only")
