"""Sub-frame sync on lamps that ramp up over frames, seen through short exposures (the common case)."""

import numpy as np
import pytest

from saddlescope.arena import flash_fraction
from saddlescope.core.sync import clip_offsets


@pytest.mark.parametrize(("ramp_frames", "exposure_s", "plateau_frames"),
                         [(2.0, 1 / 250, 1.5), (1.0, 1 / 60, 1.5), (3.0, 1 / 30, 1.5), (2.0, 1 / 60, 4.0)])
def test_ramp_lamp_offsets_within_a_tenth_of_a_frame(ramp_frames, exposure_s, plateau_frames):
    fps, on = 30.0, 0.5
    ramp = ramp_frames / fps
    off = on + ramp + plateau_frames / fps
    rng = np.random.default_rng(1)
    worst = 0.0
    for offset in np.linspace(0.0, 1.0, 11):
        truth = {"left": 0.0, "middle": offset + 2.0, "right": -1.7 * offset}
        curves = {cam: 90 + 95 * flash_fraction((np.arange(40) - o) / fps, exposure_s, on + 0.3, off + 0.3, ramp)
                  + rng.normal(0, 0.05, 40) for cam, o in truth.items()}
        found = clip_offsets(curves, dict.fromkeys(truth, fps), clip="motion")
        worst = max(worst, max(abs(found[c] - truth[c]) for c in truth))
    assert worst < 0.1
