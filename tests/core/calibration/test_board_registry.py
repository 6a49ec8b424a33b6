"""The board registry: a board kind is one module (or one register call), and every place that reads,
writes, validates, detects or renders a board finds it there."""

from __future__ import annotations

import json
import sys
import textwrap
from pathlib import Path

import cv2
import numpy as np
import pytest

from saddlescope.core.calibration import (
    BoardTracker,
    BoardView,
    boards,
    calibrate_rig,
    detect_board_views,
    find_board_corners,
    render_board,
    simulate_board_views,
)
from saddlescope.core.calibration.boards import (
    BOARD_KINDS,
    DEFAULT_BOARD_KIND,
    BoardOption,
    board_from_meta,
    board_to_meta,
    board_type,
    make_board,
    register,
    unregister,
)
from saddlescope.core.calibration.boards.checkerboard import CheckerboardType
from saddlescope.core.errors import InputError
from saddlescope.core.types import Camera, Rig

KIND = "test_plain_board"  # a checkerboard variant under another name, registered by this module only


class _PlainBoardType(CheckerboardType):
    kind = KIND
    label = "plain test board"


CAM = Camera("a", np.array([[600.0, 0, 320], [0, 600, 240], [0, 0, 1]]), np.array([-0.2, 0.05, 0, 0, 0]),
             (640, 480))


@pytest.fixture
def plain_kind():
    register(_PlainBoardType())
    yield board_type(KIND)
    unregister(KIND)


def test_a_registered_kind_is_known_by_name(plain_kind):
    assert KIND in BOARD_KINDS and BOARD_KINDS[0] == DEFAULT_BOARD_KIND
    assert isinstance(plain_kind, _PlainBoardType)
    with pytest.raises(InputError, match="registered already"):
        register(_PlainBoardType())
    register(plain_kind)  # the same type again: nothing changes
    assert BOARD_KINDS.count(KIND) == 1


def test_meta_parsing_picks_up_a_registered_kind(plain_kind):
    board = board_from_meta({"kind": KIND, "inner_corners": [7, 6], "square_mm": 30})
    assert (board.kind, board.inner_corners, board.square_mm) == (KIND, (7, 6), 30.0)
    assert board_to_meta(board) == {"kind": KIND, "inner_corners": [7, 6], "square_mm": 30.0}
    assert make_board(KIND, (7, 6), 30.0) == board


def test_corner_detection_and_tracking_pick_up_a_registered_kind(plain_kind):
    board = make_board(KIND, (7, 6), 30.0)
    rv, t = np.array([0.3, -0.2, 0.1]), np.array([-90.0, -60.0, 500.0])
    img = render_board(board, CAM, rv, t)  # drawn with its kind's texture
    truth = CAM.project(board.object_points_mm() @ cv2.Rodrigues(rv)[0].T + t)
    corners, ids = find_board_corners(img, board)
    assert np.array_equal(ids, np.arange(42)) and np.sqrt(np.mean((corners - truth) ** 2)) < 0.1
    tracker = BoardTracker(board)  # trackable, as the checkerboard it derives from
    assert [v.frame for v in tracker.views([(0, img), (1, img)])] == [0, 1] and tracker.counts["tracked"] == 1
    views, size = detect_board_views(iter([(0, img), (1, img)]), board)
    assert size == (640, 480) and np.abs(views[1].corners_px - truth).max() < 0.3


def test_the_calibration_relabels_a_half_turned_view_of_a_registered_symmetric_kind(plain_kind):
    board = make_board(KIND, (8, 6), 30.0)  # cols + rows even: alike after a half turn
    assert np.array_equal(plain_kind.half_turn_ids(board, np.array([0, 1, 47])), [47, 46, 0])
    assert plain_kind.half_turn_ids(make_board(KIND, (7, 6), 30.0), np.arange(3)) is None
    rng = np.random.default_rng(3)
    rig = Rig({n: Camera(n, CAM.K, np.zeros(5), (640, 480), R=cv2.Rodrigues(np.array([0, np.radians(8 * i), 0]))[0],
                         t_mm=np.array([-150.0 * i, 0, 0])) for i, n in enumerate(("c0", "c1"))})
    rvecs = np.radians(rng.uniform(-30, 30, (24, 3))) * [1, 1, 0.5]
    ts = np.column_stack([rng.uniform(-80, 20, 24), rng.uniform(-80, 0, 24), rng.uniform(650, 800, 24)])
    views = simulate_board_views(rig, board, rvecs, ts, noise_px=0.05, rng=rng)
    c1 = views["c1"]
    views["c1"] = [BoardView(v.frame, v.corners_px, 47 - v.ids) if k == 3 else v for k, v in enumerate(c1)]
    _, report = calibrate_rig(views, board, {"c0": (640, 480), "c1": (640, 480)})
    assert report["n_relabelled_views"] == 1 and report["n_dropped_views"] == 0


def test_an_unregistered_kind_is_refused_naming_the_known_ones():
    assert KIND not in BOARD_KINDS
    with pytest.raises(InputError, match="board kind 'test_plain_board' is not one of checkerboard, charuco"):
        board_from_meta({"kind": KIND, "inner_corners": [7, 6], "square_mm": 30})


# A grid every kind accepts (5 a row, an odd number of rows: the asymmetric circle grid's rule).
GRID = {"inner_corners": [5, 7], "square_mm": 40.0}


@pytest.mark.parametrize("kind", list(BOARD_KINDS))
def test_every_registered_kind_round_trips_through_meta(kind):
    board = board_from_meta({"kind": kind, **GRID})
    meta = board_to_meta(board)
    assert meta["kind"] == kind
    assert board_from_meta(json.loads(json.dumps(meta))) == board  # JSON types only
    assert board_type(kind).to_meta(board_type(kind).from_meta(meta)) == meta


def test_charuco_fields_round_trip_through_meta():
    meta = {"kind": "charuco", "inner_corners": [4, 3], "square_mm": 54.0, "dictionary": "DICT_5X5_100",
            "marker_mm": 40.5, "legacy": True}
    board = board_from_meta(meta)
    assert board.options == (("dictionary", "DICT_5X5_100"), ("marker_mm", 40.5), ("legacy", True))
    assert board_to_meta(board) == meta
    with pytest.raises(InputError, match="incomplete or wrong"):
        board_from_meta({"kind": "charuco", "square_mm": 54.0})


def test_ride_json_the_api_and_the_cli_accept_a_registered_kind(plain_kind):
    from saddlescope.api.schemas import BoardIn
    from saddlescope.cli import build_parser
    from saddlescope.io.result_schema import ride_problems

    meta = {"format": "saddlescope.ride/1", "board": {"kind": KIND, "inner_corners": [7, 6], "square_mm": 30}}
    assert not [p for p in ride_problems(meta) if p.startswith("board")]
    assert BoardIn(kind=KIND, inner_corners=(7, 6), square_mm=30).kind == KIND
    args = build_parser().parse_args(["calibrate", "--pattern", "7x6", "--square", "30", "--board", KIND,
                                      "--camera", "a=a.mp4"])
    assert args.board == KIND
    unregister(KIND)
    assert any(p.startswith("board.kind") for p in ride_problems(meta))
    with pytest.raises(ValueError, match="not one of"):
        BoardIn(kind=KIND, inner_corners=(7, 6), square_mm=30)


def test_a_module_in_the_boards_package_registers_its_kind(tmp_path, monkeypatch):
    (tmp_path / "test_dotted_board.py").write_text(textwrap.dedent('''
        from saddlescope.core.calibration.boards.checkerboard import CheckerboardType

        class DottedType(CheckerboardType):
            kind = "test_dotted"
            label = "dotted test board"

        BOARD_TYPE = DottedType()
    '''))
    monkeypatch.setattr(boards, "__path__", [*boards.__path__, str(tmp_path)])
    before = list(BOARD_KINDS)
    try:
        boards._register_package_board_types()  # as when the package is imported
        assert "test_dotted" in BOARD_KINDS and board_type("test_dotted").label == "dotted test board"
    finally:
        unregister("test_dotted")
        sys.modules.pop("saddlescope.core.calibration.boards.test_dotted_board", None)
    assert BOARD_KINDS == [kind for kind in before if kind != "test_dotted"]


@pytest.mark.parametrize("kind", list(BOARD_KINDS))
def test_every_registered_kind_is_offered_taken_printed_and_described_from_its_own_module(kind):
    from saddlescope.api.routers.comparisons import calibration_board_types
    from saddlescope.api.schemas import BoardIn
    from saddlescope.services.rigs.board_print import board_advice, board_print_html, camera_view
    from saddlescope.services.rigs.views import board_svg, board_words

    meta = board_to_meta(board_from_meta({"kind": kind, **GRID}))  # every field of its kind, at its default
    assert BoardIn(**meta).model_dump(exclude_none=True) == {**meta, "inner_corners": (5, 7)}
    offered = {t.kind: t for t in calibration_board_types()}[kind]  # GET /api/board-types: the rig page's form
    assert offered.label == board_type(kind).label and offered.min_square_px == board_type(kind).min_square_px
    assert [o.name for o in offered.options] == [o.name for o in board_type(kind).options]
    words = board_type(kind).describe(board_from_meta(meta))
    assert words.startswith(board_type(kind).label) and board_words(meta) == words
    assert words in board_svg(meta) and words[1:] in board_print_html(meta, "a4-tiles")
    assert board_advice(meta, camera_view(None, [])).min_square_px == board_type(kind).min_square_px


def test_a_kind_may_not_declare_a_field_another_kind_declares_otherwise():
    class _Clash(CheckerboardType):
        kind = "test_clash"
        options = (BoardOption("marker_mm", "text", "Marker"),)  # ChArUco's marker_mm is a number

    with pytest.raises(InputError, match="declares board.marker_mm otherwise"):
        register(_Clash())
    assert "test_clash" not in BOARD_KINDS


def test_the_cli_types_a_board_option_as_its_kind_declares_it():
    from saddlescope.cli import _board_options, build_parser

    def options(*extra):
        return _board_options(build_parser().parse_args(["calibrate", "--pattern", "4x3", "--square", "40",
                                                         "--camera", "a=a.mp4", *extra]))

    assert options("--marker", "30", "--board-option", "legacy=yes") == {"marker_mm": 30.0, "legacy": True}
    with pytest.raises(InputError, match="board option 'marker' is not one of dictionary, marker_mm"):
        options("--board-option", "marker=30")
    with pytest.raises(InputError, match="board option marker_mm is a number, not 'big'"):
        options("--board-option", "marker_mm=big")


def test_outside_the_boards_package_a_boards_points_come_from_its_type():
    """``Board.object_points_mm()`` is the checkerboard-like grid; any kind's points are its type's."""
    backend = Path(boards.__file__).resolve().parents[3]
    allowed = {"core/calibration/boards", "arena", "bench"}  # the types themselves; the arena's own checkerboard
    callers = [str(path.relative_to(backend)) for path in backend.rglob("*.py")
               if not any(part in str(path.relative_to(backend)) for part in allowed)
               and ".object_points_mm()" in path.read_text(encoding="utf-8")]
    assert callers == []
