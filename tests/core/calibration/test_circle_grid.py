"""The asymmetric circle grid board type: its circles found and numbered alike in rendered frames at any
turn of the board, a lens calibrated from them, its board section checked, the board printable, and the
API, ride.json and the CLI taking its own field (circle_mm) from its declaration."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from saddlescope.core.calibration import calibrate_intrinsics, detect_board_views, find_board_corners, render_board
from saddlescope.core.calibration.boards import board_from_meta, board_to_meta, board_type, make_board
from saddlescope.core.calibration.boards.circlegrid import KIND, circle_centres_mm
from saddlescope.core.errors import InputError
from saddlescope.core.types import Camera

CAM = Camera("a", np.array([[1000.0, 0, 640], [0, 1000, 360], [0, 0, 1]]), np.array([-0.1, 0.02, 0, 0, 0]),
             (1280, 720))
BOARD = make_board(KIND, (4, 11), 20.0)  # OpenCV's acircles pattern: 4 circles a row, 11 rows


def _pose(rng: np.random.Generator, board, *, distance_mm: float, tilt_deg: float = 40.0):
    """A board pose (rvec, t) facing the camera at any turn in its plane, tilted up to ``tilt_deg``."""
    turn = cv2.Rodrigues(np.array([0.0, 0.0, np.radians(rng.uniform(-180, 180))]))[0]
    tilt = cv2.Rodrigues(np.append(np.radians(rng.uniform(-tilt_deg, tilt_deg, 2)), 0.0))[0]
    rot = tilt @ turn
    centre = circle_centres_mm(board).mean(axis=0)
    t = np.array([rng.uniform(-60, 60), rng.uniform(-40, 40), distance_mm]) - rot @ centre
    return cv2.Rodrigues(rot)[0].ravel(), t


def _truth_px(board, rvec, t):
    return CAM.project(circle_centres_mm(board) @ cv2.Rodrigues(rvec)[0].T + t)


def test_the_circles_are_found_and_numbered_as_on_the_board_at_any_turn():
    rng = np.random.default_rng(7)
    errors = []
    for _ in range(8):
        rvec, t = _pose(rng, BOARD, distance_mm=rng.uniform(550, 850))
        found = find_board_corners(render_board(BOARD, CAM, rvec, t), BOARD)
        assert found is not None
        centres, ids = found
        assert np.array_equal(ids, np.arange(44))  # every circle, numbered as circle_centres_mm
        errors.append(np.abs(centres - _truth_px(BOARD, rvec, t)).max())
    assert max(errors) < 0.2, errors  # px: a dot's centre survives the tilt's perspective


def test_a_far_board_of_dots_six_pixels_apart_is_still_found():
    rvec, t = _pose(np.random.default_rng(3), BOARD, distance_mm=1000 * 20.0 / 6, tilt_deg=20)
    found = find_board_corners(render_board(BOARD, CAM, rvec, t, supersample=4), BOARD)
    assert found is not None and np.abs(found[0] - _truth_px(BOARD, rvec, t)).max() < 0.3


def test_no_grid_is_found_where_the_board_is_cut_by_the_frame_or_absent():
    rvec, t = _pose(np.random.default_rng(5), BOARD, distance_mm=700)
    img = render_board(BOARD, CAM, rvec, t)
    truth = _truth_px(BOARD, rvec, t)
    left = int(truth[:, 0].min()) + 2  # the frame's edge through the leftmost circle
    assert find_board_corners(np.ascontiguousarray(img[:, left:]), BOARD) is None
    assert find_board_corners(np.full((720, 1280), 128, np.uint8), BOARD) is None


def test_a_lens_is_calibrated_from_rendered_views_of_the_grid():
    rng = np.random.default_rng(11)
    frames = [(k, render_board(BOARD, CAM, *_pose(rng, BOARD, distance_mm=rng.uniform(500, 800))))
              for k in range(14)]
    views, size = detect_board_views(iter(frames), BOARD, track=False)
    assert size == (1280, 720) and len(views) >= 12
    lens, report = calibrate_intrinsics(views, BOARD, size)
    assert lens.K[0, 0] == pytest.approx(1000.0, rel=0.01) and report["rms_px"] < 0.2


def test_the_board_section_round_trips_and_its_mistakes_are_named():
    meta = board_to_meta(BOARD)
    assert meta == {"kind": "acircles", "inner_corners": [4, 11], "square_mm": 20.0, "circle_mm": 10.0}
    assert board_from_meta(meta) == BOARD
    with pytest.raises(InputError, match="odd number of rows"):
        make_board(KIND, (4, 10), 20.0)
    with pytest.raises(InputError, match="circle diameter 25 mm must be between 0 and the spacing"):
        make_board(KIND, (4, 11), 20.0, circle_mm=25.0)
    assert board_type(KIND).meta_problems({"square_mm": 20, "circle_mm": 20}) == [
        "board.circle_mm (20) must be smaller than board.square_mm (20)"]


def test_the_texture_draws_each_circle_where_the_board_says():
    tex, px_per_mm, origin = board_type(KIND).texture(BOARD, px_per_square=40)
    assert tex.shape == ((11 - 1 + 4) * 40, (2 * 4 - 1 + 4) * 40)
    for x, y, _ in circle_centres_mm(BOARD)[[0, 5, 43]]:
        u, v = np.round(origin + np.array([x, y]) * px_per_mm).astype(int)
        assert tex[v, u] == 0 and tex[v, u + 12] == 255  # dark centre, white 0.6 spacings across


def test_the_api_ride_json_and_the_cli_take_its_field_from_its_declaration():
    from saddlescope.api.schemas import BoardIn
    from saddlescope.cli import _board_options, build_parser
    from saddlescope.io.result_schema import ride_problems

    board = BoardIn(kind=KIND, inner_corners=(4, 11), square_mm=20, circle_mm=9).model_dump(exclude_none=True)
    assert board_from_meta(board).option("circle_mm") == 9.0
    with pytest.raises(ValueError, match="circle_mm"):
        BoardIn(kind=KIND, inner_corners=(4, 11), square_mm=20, circle_mm=-1)  # its declared bound
    with pytest.raises(ValueError, match="odd number of rows"):
        BoardIn(kind=KIND, inner_corners=(4, 10), square_mm=20)
    meta = {"format": "saddlescope.ride/1", "board": {**board_to_meta(BOARD), "circle_mm": "big"}}
    assert any(p.startswith("board.circle_mm") for p in ride_problems(meta))
    args = build_parser().parse_args(["calibrate", "--pattern", "4x11", "--square", "20", "--board", KIND,
                                      "--board-option", "circle_mm=9", "--camera", "a=a.mp4"])
    assert make_board(args.board, args.pattern, args.square, **_board_options(args)).option("circle_mm") == 9.0


def test_the_board_prints_at_its_size_with_its_words():
    from saddlescope.services.rigs.board_print import board_print_html, board_size_mm

    assert board_size_mm(BOARD) == ((2 * 4 - 1 + 4) * 20.0, (11 - 1 + 4) * 20.0)  # 220 x 280 mm
    page = board_print_html(board_to_meta(BOARD), "a3")
    assert "Asymmetric circle grid, 4 \u00d7 11 circles" in page and page.count("<rect") > 44

