"""Share links of the club: a member makes one for a ride's report or a horse's page; admins list and withdraw.

The pages a link opens, for someone without an account, are `routers.shared`'s.
"""

from __future__ import annotations

from fastapi import APIRouter, status

from saddlescope.api.deps import ClubDep
from saddlescope.api.routers.common import ERRORS, Id
from saddlescope.api.share_schemas import ShareLinkCreated, ShareLinkIn, ShareLinkOut
from saddlescope.services.accounts.share_links import (
    create_share_link,
    link_view,
    list_share_links,
    revoke_share_link,
)

__all__ = ["router"]

router = APIRouter(prefix="/share-links", tags=["share links"])
RESPONSES = ERRORS


@router.post("", status_code=status.HTTP_201_CREATED, response_model=ShareLinkCreated, responses=RESPONSES)
def create(body: ShareLinkIn, club: ClubDep) -> dict:
    """Make a read-only link to one ride's report or one horse's page (default 30 days, at most a year).

    The answer's ``path`` holds the link's token: it is shown only now (the club keeps only its hash).
    """
    club.require("share.create")
    made = create_share_link(club.session, club_id=club.club_id, user_id=club.principal.user_id,
                             ride_id=body.ride_id, horse_id=body.horse_id, days=body.days)
    club.session.refresh(made.link)
    return {**link_view(made.link), "path": made.path}


@router.get("", response_model=list[ShareLinkOut], responses=RESPONSES)
def list_links(club: ClubDep) -> list[dict]:
    """The club's share links, newest first: what each shows, who made it, until when, withdrawn or not."""
    club.require("share.manage")
    return list_share_links(club.session, club_id=club.club_id)


@router.post("/{link_id}/revoke", response_model=ShareLinkOut, responses=RESPONSES)
def revoke(link_id: Id, club: ClubDep) -> dict:
    """Withdraw a link: whoever opens it from now on reads "This link was withdrawn by the club"."""
    club.require("share.manage")
    return revoke_share_link(club.session, club_id=club.club_id, link_id=link_id, user_id=club.principal.user_id)
