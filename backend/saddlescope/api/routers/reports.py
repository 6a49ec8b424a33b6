"""The one-page ride report: HTML for the browser (prints to one A4 sheet) and the same as PDF."""

from __future__ import annotations

from fastapi import APIRouter
from fastapi.responses import HTMLResponse, Response

from saddlescope.api.deps import ClubDep, StorageDep
from saddlescope.api.routers.common import ERRORS, Id, download
from saddlescope.api.security_headers import inline_style_hashes, report_csp
from saddlescope.services.results.report import ride_report_html, ride_report_pdf

__all__ = ["router"]

router = APIRouter(prefix="/rides", tags=["reports"])


@router.get("/{ride_id}/report", response_class=HTMLResponse,
            responses={**ERRORS, 200: {"content": {"text/html": {}}}})
def report_html(ride_id: Id, club: ClubDep, storage: StorageDep) -> HTMLResponse:
    """The ride's one-page report for a vet or a trainer (HTML with print CSS: one A4 page).

    Horse, rider, date, gait, the main indicators against the horse's normal band, one chart, the
    quality in plain words and the analysis version. 404 until the ride is analysed.
    """
    page = ride_report_html(club.session, storage, ride_id, club_id=club.club_id)
    return HTMLResponse(page, headers={"Cache-Control": "private, no-cache",
                                       "Content-Security-Policy": report_csp(inline_style_hashes(page))})


@router.get("/{ride_id}/report.pdf", responses={**ERRORS, 200: {"content": {"application/pdf": {}}}})
def report_pdf(ride_id: Id, club: ClubDep, storage: StorageDep) -> Response:
    """The same report as an A4 PDF (one page), made on the server."""
    data = ride_report_pdf(club.session, storage, ride_id, club_id=club.club_id)
    return download(data, f"ride-{ride_id}-report.pdf", "application/pdf")
