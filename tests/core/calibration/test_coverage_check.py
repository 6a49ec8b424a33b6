"""The calibration clip's check (issue 35) on board corners projected by a known camera: the thirds of the
image the board never reached are named ("film that part again"), the distances it was held at are
recovered from the views alone, and a clip without the board, with few views or at one distance only
is said so with its own finding code."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from saddlescope.core.calibration.coverage_check import check_camera_coverage
from saddlescope.core.findings import FINDING_KINDS
from saddlescope.core.types import Board

BOARD = Board("checkerboard", (9, 6), 40.0)
SIZE = (1280, 720)
K = np.array([[900.0, 0, 640], [0, 900.0, 360], [0, 0, 1]])


def sightings(centres_px, distances_m, *, seed=0):
    """The board's corners seen with its centre at each image point and distance, tilted a little at random."""
    rng = np.random.default_rng(seed)
    obj = BOARD.object_points_mm()
    obj = obj - obj.mean(axis=0)
    out = []
    for (u, v), d in zip(centres_px, distances_m, strict=True):
        ray = np.linalg.solve(K, [u, v, 1.0])
        t = ray / ray[2] * d * 1000.0
        rvec = rng.uniform(-0.35, 0.35, 3)
        px, _ = cv2.projectPoints(obj, rvec, t, K, np.zeros(5))
        px = px.reshape(-1, 2)
        inside = (px[:, 0] >= 0) & (px[:, 0] < SIZE[0]) & (px[:, 1] >= 0) & (px[:, 1] < SIZE[1])
        if inside.all():
            out.append((px + rng.normal(0, 0.2, px.shape), np.arange(len(px))))
    return out


def grid_centres(xs, ys):
    return [(x, y) for x in xs for y in ys]


def test_a_board_carried_everywhere_and_at_several_distances_is_ready():
    centres = grid_centres(np.linspace(150, 1130, 6), np.linspace(110, 610, 4))
    distances = np.resize([2.5, 3.5, 4.5], len(centres))
    check = check_camera_coverage("left", sightings(centres, distances), BOARD, SIZE, frames_sampled=40)
    assert check.views == 24 and not check.bands_missed and not check.film_again
    assert [f.code for f in check.findings] == ["calibration_check.covered"]
    assert check.grid.shape == (7, 12) and (check.grid > 0).mean() > 0.6
    assert check.reach_x[0] < 0.1 and check.reach_x[1] > 0.9
    # the views' distances come back from the quick lens fit of the same views
    assert np.nanmedian(check.distances_m) == pytest.approx(3.5, rel=0.08)
    assert np.nanmin(check.distances_m) == pytest.approx(2.5, rel=0.1)


def test_a_board_only_in_the_middle_band_says_film_the_sides_again():
    centres = grid_centres(np.linspace(560, 720, 4), np.linspace(110, 610, 5))
    distances = np.resize([3.0, 4.0, 5.0], len(centres))
    check = check_camera_coverage("right", sightings(centres, distances, seed=1), BOARD, SIZE, frames_sampled=30)
    assert check.film_again
    assert set(check.bands_missed) == {"left third", "right third"}
    third = next(f for f in check.findings if f.code == "calibration_check.third_missed")
    assert third.severity == "problem"
    assert third.detail == ("The board never reached the left third and right third of the right camera's view: "
                            "film that part again.")
    # the coverage map: no view in the image's outer columns
    assert check.grid[:, :3].sum() == 0 and check.grid[:, -3:].sum() == 0


def test_one_stray_view_does_not_make_a_third_reached():
    centres = grid_centres(np.linspace(300, 980, 5), np.linspace(110, 300, 3)) + [(640, 600)]
    check = check_camera_coverage("middle", sightings(centres, np.full(len(centres), 4.0)), BOARD, SIZE,
                                  frames_sampled=20)
    assert "lower third" in check.bands_missed
    assert "The board never reached the lower third of the middle camera's view" in " ".join(
        f.detail for f in check.findings)


def test_no_board_few_views_and_one_distance_have_their_own_findings():
    nothing = check_camera_coverage("left", [], BOARD, SIZE, frames_sampled=90)
    assert [f.code for f in nothing.findings] == ["calibration_check.board_not_seen"] and nothing.film_again
    assert nothing.grid.sum() == 0 and nothing.bands_missed == ()

    few = check_camera_coverage("left", sightings(grid_centres([150, 640, 1130], [110, 360, 610])[:8],
                                                  np.full(8, 3.0)), BOARD, SIZE, frames_sampled=90)
    assert "calibration_check.few_views" in [f.code for f in few.findings] and few.film_again

    centres = grid_centres(np.linspace(150, 1130, 5), np.linspace(110, 610, 4))
    flat = check_camera_coverage("left", sightings(centres, np.full(len(centres), 4.0), seed=2), BOARD, SIZE,
                                 frames_sampled=30)
    codes = [f.code for f in flat.findings]
    assert "calibration_check.narrow_depth" in codes and not flat.film_again  # worth a word, not a re-film
    for code in codes:
        assert code in FINDING_KINDS


# --- a wand calibration's clip (check_wand_coverage) -----------------------------------------------------

def _wand_ends(centres_px, length_px):
    """The wand's two ends about each centre, turning from frame to frame."""
    out = []
    for i, (x, y) in enumerate(centres_px):
        a = 0.7 * i
        d = 0.5 * length_px * np.array([np.cos(a), np.sin(a)])
        out.append(np.array([[x, y] - d, [x, y] + d]))
    return out


def test_a_wand_waved_only_through_the_middle_band_says_film_the_sides_again():
    from saddlescope.core.calibration.coverage_check import check_wand_coverage

    rng = np.random.default_rng(3)
    middle = _wand_ends(np.column_stack([rng.uniform(500, 780, 80), rng.uniform(60, 660, 80)]), 80)
    check = check_wand_coverage("right", middle, SIZE, frames_sampled=90, wand_length_mm=1000.0)
    assert check.film_again
    assert check.views == 80
    third = next(f for f in check.findings if f.code == "calibration_check.wand_third_missed")
    assert third.detail == ("The wand never reached the left third and right third of the right camera's view: "
                            "film that part again.")
    # the wand everywhere, at 60 to 200 px (4.5 to 15 m at a 60-degree lens): ready, its distances spread
    every = _wand_ends(np.column_stack([rng.uniform(60, 1220, 120), rng.uniform(60, 660, 120)]), 0)
    every = [e + (0.5 * rng.uniform(60, 200) * np.array([[-1, 0], [1, 0]])) for e in every]
    ready = check_wand_coverage("left", every, SIZE, frames_sampled=130, wand_length_mm=1000.0)
    assert [f.code for f in ready.findings] == ["calibration_check.wand_covered"]
    assert 3.0 < np.nanmin(ready.distances_m) < np.nanmax(ready.distances_m) < 20.0


def test_a_wand_never_seen_or_seldom_seen_has_its_own_findings():
    from saddlescope.core.calibration.coverage_check import check_wand_coverage

    none = check_wand_coverage("left", [], SIZE, frames_sampled=50, wand_length_mm=1000.0)
    assert [f.code for f in none.findings] == ["calibration_check.wand_not_seen"]
    few = check_wand_coverage("left", _wand_ends([(100, 100), (1200, 650)] * 5, 60), SIZE, frames_sampled=50,
                              wand_length_mm=1000.0)
    assert "calibration_check.wand_few_frames" in [f.code for f in few.findings]
    assert all(f.code in FINDING_KINDS for f in few.findings + none.findings)
