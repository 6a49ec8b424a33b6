"""The calibration board as the API takes it and the kinds of board it offers, both made from the board registry.

``BoardIn`` (ride.json's "board", a rig's board) holds kind, inner_corners and square_mm and, as optional
fields, every field a registered kind declares (:class:`~saddlescope.core.calibration.boards.BoardOption`:
ChArUco's ``dictionary``, ``marker_mm``, ``legacy`` ...), each with its declared bounds; the kind's own
checks (a dictionary OpenCV knows, markers inside their squares) run when the board is made. A new kind
of board is one module in ``core/calibration/boards/``: its fields appear here, in the OpenAPI and in
``GET /api/board-types`` (the rig page's form) without a line changed.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, StringConstraints, create_model, field_validator, model_validator

from saddlescope.core.calibration.boards import (
    BOARD_KINDS,
    DEFAULT_BOARD_KIND,
    BoardOption,
    BoardType,
    board_from_meta,
    board_options,
)
from saddlescope.core.errors import InputError

__all__ = ["BoardIn", "BoardOptionOut", "BoardTypeOut", "board_type_out"]


class _BoardGrid(BaseModel):
    """ride.json's "board" (CONTRACTS section 1): its kind and grid; ``BoardIn`` adds the kinds' fields."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    kind: str = Field(default=DEFAULT_BOARD_KIND, json_schema_extra=lambda s: s.update(enum=list(BOARD_KINDS)))
    inner_corners: tuple[Annotated[int, Field(ge=2, le=100)], Annotated[int, Field(ge=2, le=100)]]
    square_mm: float = Field(gt=0, le=10_000)

    @field_validator("kind")
    @classmethod
    def _registered_kind(cls, kind: str) -> str:
        if kind not in BOARD_KINDS:
            raise ValueError(f"board kind {kind!r} is not one of {', '.join(BOARD_KINDS)}")
        return kind

    @model_validator(mode="after")
    def _a_board_its_type_can_make(self) -> _BoardGrid:
        # The board type's own checks (a ChArUco dictionary OpenCV knows, markers inside their squares) at
        # creation, not first when board.svg or a calibration job reads it.
        try:
            board_from_meta(self.model_dump(exclude_none=True))
        except InputError as exc:
            raise ValueError(str(exc)) from None
        return self


def _option_field(option: BoardOption) -> tuple[Any, Any]:
    """The pydantic field of a board option: its JSON type and bounds, None when not given."""
    if option.value == "flag":
        return bool | None, Field(default=None, description=option.label)
    if option.value == "text":
        text = Annotated[str, StringConstraints(pattern=option.pattern, max_length=option.max_length)]
        return text | None, Field(default=None, description=option.label)
    return float | None, Field(default=None, gt=option.greater_than, le=option.at_most, description=option.label)


if TYPE_CHECKING:
    BoardIn = _BoardGrid
else:
    # Built once the board modules have registered: a kind registered later (a test's) is accepted by its
    # name, with only the fields the kinds registered by then declare.
    BoardIn = create_model("BoardIn", __base__=_BoardGrid, __module__=__name__,
                           __doc__="ride.json's \"board\" (CONTRACTS section 1): kind, grid and the kind's own fields.",
                           **{option.name: _option_field(option) for option in board_options()})


class BoardOptionOut(BaseModel):
    """A field a kind of board adds, and how the rig page asks for it."""

    name: str = Field(description="its key in the board (e.g. marker_mm)")
    value: Literal["number", "text", "flag"]
    label: str = Field(description="the form's words for it, with its unit")
    unset: str = Field(description="what leaving it out means (e.g. 0.75 × square); empty: its default is none")
    greater_than: float | None = None
    at_most: float | None = None
    offered: list[str] = Field(description="a text's values to offer, the default first")


class BoardTypeOut(BaseModel):
    """A kind of calibration board a rig may use."""

    kind: str
    label: str
    short: str = Field(description="what it is and when to choose it")
    min_square_px: int = Field(description="pixels one square must cover in a frame for the board to be found")
    options: list[BoardOptionOut]


def board_type_out(board_type: BoardType) -> BoardTypeOut:
    """A registered board type as the API serves it."""
    return BoardTypeOut(
        kind=board_type.kind, label=board_type.label, short=board_type.short, min_square_px=board_type.min_square_px,
        options=[BoardOptionOut(name=o.name, value=o.value, label=o.label, unset=o.unset, greater_than=o.greater_than,
                                at_most=o.at_most, offered=list(o.offered)) for o in board_type.options])
