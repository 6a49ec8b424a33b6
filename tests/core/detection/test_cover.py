"""Partly covered discs left out (issue 38): area against the marker's own frames and its neighbours', gap edges."""

from __future__ import annotations

import numpy as np
import pytest

from saddlescope.core.detection.cover import drop_partly_covered, partly_covered_samples
from saddlescope.core.findings import FINDING_KINDS
from saddlescope.core.types import ImageTracks


def _tracks(area: np.ndarray, gaps: tuple = ()) -> ImageTracks:
    n, m = area.shape
    rng = np.random.default_rng(0)
    xy = np.cumsum(np.full((n, m, 2), 3.0), axis=0) + rng.normal(0, 0.05, (n, m, 2))
    for f, k in gaps:
        xy[f, k] = np.nan
    return ImageTracks(camera="left", xy_px=xy, frame_index=np.arange(n), area_px=area.astype(float))


def test_a_disc_shrinking_alone_is_partly_covered_but_its_usual_scatter_is_not():
    rng = np.random.default_rng(1)
    area = np.clip(np.round(rng.normal(8.0, 1.0, (60, 3))), 5, None)
    area[30, 2] = 3.0  # a third of the disc left: the boot's edge over it
    covered = partly_covered_samples(_tracks(area))
    assert covered[30, 2]
    assert covered.sum() == 1  # 5-11 px scatter of a small disc is no cover


def test_a_dip_of_every_marker_at_once_is_not_a_cover():
    area = np.full((40, 3), 8.0)
    area[20] = 3.0  # the whole frame blurred or dimmed
    assert not partly_covered_samples(_tracks(area)).any()


def test_the_samples_next_to_a_gap_inside_a_track_are_left_out_but_not_a_track_s_ends():
    area = np.full((40, 3), 8.0)
    tracks = _tracks(area, gaps=[(f, 2) for f in range(18, 22)] + [(0, 1), (39, 0)])
    covered = partly_covered_samples(tracks)
    assert covered[17, 2] and covered[22, 2]
    assert covered.sum() == 2


def test_dropping_sets_the_covered_samples_to_gaps_and_counts_them():
    area = np.full((40, 3), 8.0)
    area[10, 1] = 2.0
    tracks = _tracks(area)
    out, n = drop_partly_covered(tracks)
    assert n == 1
    assert np.all(np.isnan(out.xy_px[10, 1])) and np.isnan(out.area_px[10, 1])
    assert np.isfinite(out.xy_px[10, [0, 2]]).all() and np.isfinite(tracks.xy_px[10, 1]).all()
    same, none = drop_partly_covered(_tracks(np.full((40, 3), 8.0)))
    assert none == 0


@pytest.mark.parametrize("code", ["tracking.partly_covered", "kinematics.stride_phase_unmeasured"])
def test_the_new_findings_are_registered(code):
    assert code in FINDING_KINDS
