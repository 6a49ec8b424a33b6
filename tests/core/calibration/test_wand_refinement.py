"""A board calibration refined by a wand pass, kept only where the checks it did not fit say so (issue 35).

The decision's rules on made-up checks, then one geometric ride: the arena's ``wide_partial`` rig, its board
carried through the middle band of the volume (exact corner projections), a wand walked along the track
(exact end projections with noise). The rendered pipeline path is ``tests/core/pipeline/test_board_wand_ride.py``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from saddlescope.core.calibration.wand import WandView
from saddlescope.core.calibration.wand_refinement import held_out_split, refine_board_rig, refinement_verdict
from saddlescope.core.errors import InputError
from saddlescope.core.types import WandCheck, WandRefinement
from saddlescope.io.result_schema import RESULT_SCHEMA
from saddlescope.io.rig_document import rig_from_dict, rig_to_dict

GOOD = WandCheck(wand_length_rms_mm=15.0, board_square_error_pct=0.025, board_rms_px=0.15,
                 reach_px={"left": 570.0, "middle": 210.0, "right": 505.0})


def _check(**changes) -> WandCheck:
    values = {"wand_length_rms_mm": 3.3, "board_square_error_pct": 0.05, "board_rms_px": 0.16,
              "reach_px": {"left": 630.0, "middle": 650.0, "right": 650.0}, **changes}
    return WandCheck(**values)


def test_every_fifth_run_of_ten_frames_is_held_out_and_never_fitted():
    views = {"left": [WandView(f, np.zeros((2, 2))) for f in range(100)],
             "middle": [WandView(f, np.zeros((2, 2))) for f in range(0, 100, 3)]}
    fit, held = held_out_split(views)
    assert [v.frame for v in held["left"]] == [*range(40, 50), *range(90, 100)]
    for cam in views:
        assert {v.frame for v in fit[cam]}.isdisjoint(v.frame for v in held[cam])
        assert len(fit[cam]) + len(held[cam]) == len(views[cam])
    with pytest.raises(InputError, match="every must be 2 or more"):
        held_out_split(views, every=1)


def test_a_refinement_no_check_says_is_worse_is_kept():
    keep, reason = refinement_verdict(GOOD, _check())
    assert keep and "no worse" in reason
    # within the tolerances: the squares' floor (0.1 % of the square) and the corners' 25 % + 0.05 px
    assert refinement_verdict(GOOD, _check(board_square_error_pct=0.12, board_rms_px=0.23))[0]
    # a check that could not be made (no held-out frame two cameras saw) counts as not worse, and is said
    keep, reason = refinement_verdict(GOOD, _check(wand_length_rms_mm=math.nan))
    assert keep and "no wand frame was held out" in reason


@pytest.mark.parametrize(("changes", "says"), [
    ({"wand_length_rms_mm": 16.0}, "the wand's length on frames it did not fit came out 16.0 mm r.m.s. off, 15.0 mm"),
    ({"board_square_error_pct": 0.34}, "the board's squares came out 0.34 % r.m.s. off, 0.03 % with the board's "
                                       "calibration alone (is the wand's length right?)"),
    ({"board_rms_px": 0.25}, "the board's corners triangulated 0.25 px r.m.s., 0.15 px"),
])
def test_a_refinement_any_check_says_is_worse_is_refused_with_the_reason(changes, says):
    keep, reason = refinement_verdict(GOOD, _check(**changes))
    assert not keep and says in reason
    refusal = WandRefinement(False, reason, 1000.0, 30, GOOD, _check(**changes))
    assert refusal.sentence.startswith("Not refined by the wand: with the wand ")
    assert refusal.sentence.endswith("The board's calibration is kept.")


def test_a_kept_refinement_says_how_far_the_lens_is_now_known():
    kept = WandRefinement(True, "no worse", 1000.0, 38, GOOD, _check())
    assert kept.sentence == ("Refined by the wand: the middle camera's lens is now known to 650 px from the centre "
                             "of its image, was 210 px; the wand's length on 38 frames it did not fit is off by "
                             "3.3 mm r.m.s., was 15.0 mm.")


@pytest.fixture(scope="module")
def band_ride():
    """The arena's wide_partial rig calibrated from a board through the middle 60 % of the volume, and a wand
    walked along the track the horse takes (geometry: exact projections with noise, nothing rendered)."""
    from saddlescope.arena import build_scene
    from saddlescope.arena.content import BOARD
    from saddlescope.arena.wand import wand_path
    from saddlescope.bench.calibration import _scene_board_views, _wand_views_exact
    from saddlescope.core.calibration import calibrate_rig
    from saddlescope.core.pipeline.setup import board_coverage

    rng = np.random.default_rng(8013)
    scene = build_scene(gait="canter", seed=1013, rig="wide_partial", board_band=0.6, speed_range_m_s=(4.0, 6.0),
                        calibration_poses=30, extras=False)
    board_views = _scene_board_views(scene, 0.15, rng)
    sizes = {r: c.image_size for r, c in scene.rig.cameras.items()}
    rig, _ = calibrate_rig(board_views, BOARD, sizes)
    x = scene.contents["motion"].markers_w(scene.timings["motion"].frame_times("left"))[..., 0]
    path = wand_path(scene.rig, rng, n_frames=480, length_m=1.0, track_x_m=(float(np.nanmin(x)), float(np.nanmax(x))))
    wand = _wand_views_exact(scene.rig, path, 0.2, rng)
    hulls = {r: board_coverage(v, sizes[r])["hull_px"] for r, v in board_views.items()}
    return rig, board_views, BOARD, wand, hulls


def test_a_middle_band_board_is_refined_by_a_wand_along_the_track(band_ride):
    rig, board_views, board, wand, hulls = band_ride
    refined, report = refine_board_rig(rig, board_views, board, wand, 1000.0, board_hull_px=hulls)
    choice = refined.wand_refinement
    assert choice is not None and choice.kept, choice
    assert choice.held_out_frames >= 10
    # the middle camera's lens, known to about 210 px from the band, is known to the image's edge (734 px corner)
    assert choice.board.reach_px["middle"] < 260 and choice.refined.reach_px["middle"] > 600
    assert choice.refined.wand_length_rms_mm < choice.board.wand_length_rms_mm
    assert set(report["lens_coverage"]) == set(rig.cameras)
    assert refined.checks["board_square_error_pct"] == pytest.approx(choice.refined.board_square_error_pct)
    assert refined.checks["wand_length_mm"] == 1000.0
    # the choice travels with the calibration document and back, and the result's schema takes it
    doc = rig_to_dict(refined)
    assert doc["wand_refinement"]["kept"] is True and doc["wand_refinement"]["sentence"] == choice.sentence
    assert rig_from_dict(doc).wand_refinement == choice
    import jsonschema

    jsonschema.validate(doc, RESULT_SCHEMA["properties"]["calibration"])


def test_a_wand_whose_length_disagrees_with_the_board_leaves_the_boards_rig(band_ride):
    rig, board_views, board, wand, hulls = band_ride
    # told 1 % long: the refined rig rebuilds the board's squares 1 % long, which the board's check sees
    kept, report = refine_board_rig(rig, board_views, board, wand, 1010.0, board_hull_px=hulls)
    choice = kept.wand_refinement
    assert choice is not None and not choice.kept
    assert "is the wand's length right?" in choice.reason
    assert kept.cameras is rig.cameras and kept.checks == rig.checks  # the board's rig, unchanged
    assert "lens_coverage" not in report
    # too few frames to refine on: the board's rig, and why
    few = {cam: views[:5] for cam, views in wand.items()}
    kept, _ = refine_board_rig(rig, board_views, board, few, 1000.0, board_hull_px=hulls)
    assert not kept.wand_refinement.kept and "the wand could not refine it" in kept.wand_refinement.reason
    # the wand's two ends seen by one camera only (the others' clips never showed both): nothing to refine with
    alone = {cam: views if cam == "middle" else [] for cam, views in wand.items()}
    kept, _ = refine_board_rig(rig, board_views, board, alone, 1000.0, board_hull_px=hulls)
    assert not kept.wand_refinement.kept and "seen by two or more cameras" in kept.wand_refinement.reason
    assert math.isnan(kept.wand_refinement.board.wand_length_rms_mm)  # no held-out frame two cameras saw
