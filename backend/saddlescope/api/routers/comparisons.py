"""Comparisons across the club: horses within a gait, the leaderboard, and what the codes mean.

What the codes mean: the glossary, the indicators and the kinds of calibration board.
"""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query

from saddlescope.api.board_schemas import BoardTypeOut, board_type_out
from saddlescope.api.deps import ClubDep
from saddlescope.api.routers.common import ERRORS, IndicatorKey, QueryId
from saddlescope.api.schemas import MAX_ID, ComparisonOut, Gait, GlossaryEntryOut, IndicatorOut, LeaderboardOut
from saddlescope.core.calibration.boards import board_types
from saddlescope.core.errors import InputError
from saddlescope.core.vibration import COMFORT_INDICATORS, INDICATORS
from saddlescope.services.comparisons.analytics import club_leaderboard, horses_comparison
from saddlescope.services.glossary import glossary

__all__ = ["router"]

router = APIRouter(tags=["comparisons"])


def _horse_ids(horses: str | None) -> list[int] | None:
    if not horses:
        return None
    try:
        ids = [int(part) for part in horses.split(",") if part.strip()]
    except ValueError:
        raise InputError(f"horses must be comma-separated horse ids (e.g. 1,2,5), got {horses!r}") from None
    if any(not 1 <= i <= MAX_ID for i in ids):
        raise InputError(f"horses: ids are between 1 and {MAX_ID}")
    return ids or None


@router.get("/comparison", response_model=ComparisonOut, responses=ERRORS)
def compare_horses(
    club: ClubDep,
    gait: Gait,
    horses: Annotated[
        str | None,
        Query(max_length=2000, pattern=r"^[0-9, ]*$", description="comma-separated horse ids; default all"),
    ] = None,
    indicator: Annotated[
        list[IndicatorKey] | None,
        Query(description="indicator keys (repeat); default the eight comfort indicators"),
    ] = None,
    saddle_id: QueryId = None,
    include_uncertain: Annotated[
        bool, Query(description="average rides too uncertain for a decision too (left out and counted otherwise)")
    ] = False,
) -> dict:
    """Horses within one gait (thesis 8.5.2): per indicator and horse n, mean, std, min and max.

    Rides too uncertain for a decision are left out unless ``include_uncertain`` (``uncertain_left_out``
    counts them); ``saddle_id`` keeps the rides in that saddle.
    """
    keys = [str(key) for key in indicator] if indicator else None
    return horses_comparison(
        club.session, club_id=club.club_id, gait=gait, horse_ids=_horse_ids(horses), indicators=keys,
        saddle_id=saddle_id, include_uncertain=include_uncertain,
    )


@router.get("/leaderboard", response_model=LeaderboardOut, responses=ERRORS)
def leaderboard(
    club: ClubDep,
    gait: Gait,
    indicator: IndicatorKey = IndicatorKey("acc_y_wb_rms"),
    lower_is_better: bool | None = None,
    include_uncertain: Annotated[
        bool, Query(description="rank rides too uncertain for a decision too (they are marked either way)")
    ] = False,
    saddle_id: QueryId = None,
) -> dict:
    """The club's horses ranked in a gait by an indicator, most comfortable first.

    With the number of rides behind each horse and their spread (max - min); ties share a rank. Rides
    too uncertain for a decision are left out unless ``include_uncertain``, and listed with the reason.
    """
    return club_leaderboard(
        club.session, club_id=club.club_id, gait=gait, indicator=str(indicator), lower_is_better=lower_is_better,
        include_uncertain=include_uncertain, saddle_id=saddle_id,
    )


@router.get("/glossary", response_model=list[GlossaryEntryOut], responses=ERRORS)
def glossary_entries() -> list[GlossaryEntryOut]:
    """Every code a page may meet (indicators, gaits, job kinds, ...) with its label, unit and meaning.

    Open without signing in: a shared report's reader needs the words too, and they hold no club data.
    """
    return [GlossaryEntryOut(kind=e.kind, code=e.code, label=e.label, unit=e.unit, short=e.short,  # type: ignore[arg-type]
                             expert=e.expert) for e in glossary()]


@router.get("/indicators", response_model=list[IndicatorOut], responses=ERRORS)
def indicators() -> list[IndicatorOut]:
    """Every indicator key: unit, label, its name in thesis Table 8.7, and which way is more comfortable.

    Open without signing in, as the glossary: the dashboard loads both before its first page (the
    sign-in page too), and they hold no club data.
    """
    return [
        IndicatorOut(
            key=key,
            unit=info.unit,
            label=info.label,
            thesis_name=info.thesis_name,
            better=info.better,
            comfort=key in COMFORT_INDICATORS,
        )
        for key, info in INDICATORS.items()
    ]


@router.get("/board-types", response_model=list[BoardTypeOut], responses=ERRORS)
def calibration_board_types() -> list[BoardTypeOut]:
    """The kinds of calibration board (the board registry's), the default first, with the fields each adds.

    The rig page's choice of board and its fields come from here. Open without signing in, as the glossary:
    the same for everyone, no club data.
    """
    return [board_type_out(kind) for kind in board_types()]
