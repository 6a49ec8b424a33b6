"""The board corners a calibration keeps for the rig page's coverage picture: every view's, thinned evenly."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from saddlescope.core.pipeline.setup import board_corner_sample


def test_corners_of_every_view_are_kept_evenly_thinned_and_finite():
    rng = np.random.default_rng(1)
    views = [SimpleNamespace(corners_px=rng.uniform(0, 640, size=(54, 2))) for _ in range(40)]
    views[3].corners_px[0] = np.nan  # a corner lost in one frame is left out
    sample = board_corner_sample(views, max_points=500)
    assert len(sample) == 500
    pts = np.array(sample)
    assert np.isfinite(pts).all()
    assert sample[0] == np.round(views[0].corners_px[0], 1).tolist()  # thinned evenly from the first view
    assert sample[-1] == np.round(views[-1].corners_px[-1], 1).tolist()  # ... to the last
    few = board_corner_sample(views[:2], max_points=500)
    assert len(few) == 108
