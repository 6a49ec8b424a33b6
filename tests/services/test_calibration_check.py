"""The calibration check on rendered arena clips (issue 35): the wide_partial rig's board carried only
through the middle band of the volume never reaches the side thirds of the images, and the check says
"film that part again", on the command line (exit status 1) as in the service; a board carried through
the whole volume reaches more of each view."""

from __future__ import annotations

import json

import pytest
from rendered_rides import cached_ride_bundle

from saddlescope.cli import main
from saddlescope.core.errors import InputError
from saddlescope.services.rigs.calibration_check import check_calibration_clips, check_document, sample_step

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def middle_band(tmp_path_factory):
    """The board carried only through the central 30 % of the volume (left to right)."""
    return cached_ride_bundle(tmp_path_factory.mktemp("band") / "ride", rig="wide_partial", size=(640, 360),
                              calibration_poses=20, duration_s=2.0, extras=False, board_band=0.3, seed=3)


def test_sampling_is_a_few_frames_a_second_but_enough_of_a_short_clip():
    assert sample_step(60.0, 1800) == 20  # 3 a second of a 30 s clip at 60 fps: 90 frames
    assert sample_step(50.0, 112) == 2  # a 2 s clip: every other frame, at least 40 looked at
    assert sample_step(30.0, 20) == 1


def test_a_board_in_the_middle_band_never_reached_a_third_film_again(middle_band, tmp_path, capsys):
    board = json.loads((middle_band / "ride.json").read_text())["board"]
    clips = {c: middle_band / "calibration" / f"{c}.mp4" for c in ("middle", "right")}
    check = check_calibration_clips(clips, board)
    assert check.film_again
    middle = check.cameras["middle"]
    assert middle.views >= 12
    assert {"left third", "right third"} <= set(middle.bands_missed)
    third = next(f for f in middle.findings if f.code == "calibration_check.third_missed")
    assert third.detail.endswith("of the middle camera's view: film that part again.")
    document = check_document(check)
    assert document["verdict"].startswith("Film again")
    assert document["cameras"]["middle"]["grid"] == middle.grid.tolist()

    out = tmp_path / "check.json"
    assert main(["check-calibration", "--ride", str(middle_band), "--json", str(out)]) == 1
    printed = capsys.readouterr().out
    assert "never reached the" in printed and "of the middle camera's view: film that part again." in printed
    assert printed.strip().splitlines()[-1].startswith("Film again")
    assert set(json.loads(out.read_text())["cameras"]) == {"left", "middle", "right"}


def test_the_command_says_what_is_missing(tmp_path, capsys):
    assert main(["check-calibration", str(tmp_path / "left.mp4")]) == 2
    assert "--pattern CxR and --square MM" in capsys.readouterr().err


def test_a_wand_waved_only_in_the_middle_says_film_the_sides_again(tmp_path, capsys):
    """The wand's clips checked like the board's (issue 35): rendered by the arena's wide_partial rig, a wand
    waved only 0.6 m either side of the middle misses the middle camera's side thirds."""
    import numpy as np

    from saddlescope.arena.rig import make_rig
    from saddlescope.arena.wand import render_wand_frames, wand_path
    from saddlescope.io.video_writer import write_h264
    from saddlescope.services.rigs.calibration_check import check_wand_clips

    rng = np.random.default_rng(5)
    rig = make_rig("wide_partial", rng, size=(640, 360))
    path = wand_path(rig, rng, n_frames=120, fps=10.0, track_x_m=(-0.6, 0.6))
    clips = {}
    for role in ("middle", "right"):
        clips[role] = tmp_path / f"{role}.mp4"
        write_h264(clips[role], (g for _, g in render_wand_frames(rig, path, role, rng=rng)), fps=10.0)
    check = check_wand_clips(clips, 1.0)
    middle = check.cameras["middle"]
    assert middle.views >= 40
    assert {"left third", "right third"} <= set(middle.bands_missed)
    third = next(f for f in middle.findings if f.code == "calibration_check.wand_third_missed")
    assert third.detail.startswith("The wand never reached the ") and "left third" in third.detail
    assert third.detail.endswith("of the middle camera's view: film that part again.")
    assert check.verdict().startswith("Film again: the middle")
    assert "wand clip" in check.verdict()
    with pytest.raises(InputError, match=r"outside 0.05-5 m \(in centimetres\? 100 cm is 1.00 m\): measure"):
        check_wand_clips(clips, 100.0)
    # the same on the command line: no board to name, the wand's length instead; exit status 1
    assert main(["check-calibration", "--wand", "1.0", *(f"{r}={p}" for r, p in clips.items())]) == 1
    printed = capsys.readouterr().out
    assert f"middle: wand in {middle.views} of {middle.frames_sampled} frames looked at" in printed
    assert printed.strip().splitlines()[-1].startswith("Film again: the middle")
