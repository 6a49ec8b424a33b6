"""A clip's sync pass hands its open decoder and the frames after the flash to the next pass (issue 28)."""

from __future__ import annotations

import numpy as np
from integration_services import write_noise_clip

from saddlescope.io.clip_source import BundleClips
from saddlescope.io.video import iter_gray_frames


def _frames(it):
    return [(i, img.copy()) for i, img in it]


def _same(a, b) -> bool:
    if [i for i, _ in a] != [i for i, _ in b]:
        return False
    return all(np.array_equal(x, y) for (_, x), (_, y) in zip(a, b, strict=True))


def test_the_next_pass_gets_the_same_frames_without_decoding_the_start_again(tmp_path):
    path = tmp_path / "flash.mp4"
    write_noise_clip(path, 150, flash=(20, 24))
    truth = _frames(iter_gray_frames(path, threads=1))
    with BundleClips({"motion": {"left": path}}, threads=1) as clips:
        values = clips.brightness("motion", "left")
        handoff = clips._handoffs[("motion", "left")]
        first, last = handoff.frames[0][0], handoff.frames[-1][0]
        assert first == 24 and last == len(values) - 1  # from the flash's end to where the sync pass stopped
        # a peek at the first frame after the flash leaves the hand-over for the pass that follows
        assert _same(_frames(clips.gray_frames("motion", "left", start=24, stop=25)), truth[24:25])
        assert ("motion", "left") in clips._handoffs
        opened = clips._open_decoders
        got = _frames(clips.gray_frames("motion", "left", start=26, step=3))
        assert _same(got, truth[26::3])
        assert not clips._handoffs and clips._handoff_bytes == 0 and clips._open_decoders == opened - 1


def test_an_earlier_start_a_budget_of_none_and_close_decode_as_before(tmp_path):
    path = tmp_path / "flash.mp4"
    write_noise_clip(path, 90, flash=(10, 13))
    truth = _frames(iter_gray_frames(path, threads=1))
    with BundleClips({"motion": {"left": path}}) as clips:
        clips.brightness("motion", "left")
        assert _same(_frames(clips.gray_frames("motion", "left", start=2, stop=40)), truth[2:40])
        assert not clips._handoffs and clips._handoff_bytes == 0  # dropped: the next pass starts before it
    with BundleClips({"motion": {"left": path}}, handoff_budget_mb=0) as clips:
        clips.brightness("motion", "left")
        assert not clips._handoffs and clips._handoff_bytes == 0
    clips = BundleClips({"motion": {"left": path}})
    clips.brightness("motion", "left")
    assert clips._handoffs and clips._open_decoders == 1
    clips.close()  # a hand-over not taken up: its decoder is closed and its frames dropped
    assert not clips._handoffs and clips._open_decoders == 0 and clips._handoff_bytes == 0


def test_the_budget_bounds_what_the_sync_passes_keep(tmp_path):
    paths = {}
    for cam in ("left", "middle", "right"):
        paths[cam] = tmp_path / f"{cam}.mp4"
        write_noise_clip(paths[cam], 90, flash=(10, 13))
    frame_mb = 64 * 48 / 1e6
    # room for the reservation of one pass (a second of frames at 30 fps and two more), not of two
    with BundleClips({"motion": paths}, handoff_budget_mb=33 * frame_mb) as clips:
        for cam in paths:
            clips.brightness("motion", cam)
        assert list(clips._handoffs) == [("motion", "left")]
        assert clips._handoff_bytes <= 33 * frame_mb * 1e6
    # no flash (the whole clip read): nothing to hand over
    dark = tmp_path / "dark.mp4"
    write_noise_clip(dark, 40)
    with BundleClips({"motion": {"left": dark}}) as clips:
        assert len(clips.brightness("motion", "left")) == 40 and not clips._handoffs


def test_close_during_a_sync_pass_leaves_that_pass_its_reservation_and_nothing_open(tmp_path):
    paths = {cam: tmp_path / f"{cam}.mp4" for cam in ("left", "middle")}
    for path in paths.values():
        write_noise_clip(path, 90, flash=(10, 13))
    clips = BundleClips({"motion": paths})
    clips.brightness("motion", "left")
    decoded = clips._decoded

    def closed_midway(kind, camera, start, stop, step):  # the analysis ends while the middle clip is read
        for n, frame in enumerate(decoded(kind, camera, start, stop, step)):
            if n == 5:
                clips.close()
            yield frame

    clips._decoded = closed_midway
    values = clips.brightness("motion", "middle")  # the pass ends after close(): it hands nothing over
    assert not clips._handoffs and clips._handoff_bytes == 0 and clips._open_decoders == 0
    clips._decoded = decoded  # a closed source still reads, decoding from the start
    assert len(values) < 90 and len(_frames(clips.gray_frames("motion", "middle", start=20))) == 70
