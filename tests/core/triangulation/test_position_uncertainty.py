"""The rig's position uncertainty: how well a narrow and a wide rig fix a point's depth."""

from __future__ import annotations

import numpy as np
import pytest

from saddlescope.arena import make_rig
from saddlescope.core.errors import TriangulationError
from saddlescope.core.triangulation import position_uncertainty
from saddlescope.core.types import Rig


def _rig(name: str) -> Rig:
    scene = make_rig(name, np.random.default_rng(3))
    return Rig(scene.cameras)


def test_thesis_rig_fixes_depth_far_worse_than_a_wide_rig():
    point = np.array([0.0, 0.0, 7500.0])
    narrow = position_uncertainty(_rig("thesis"), point)
    wide = position_uncertainty(_rig("wide"), point)
    assert narrow["anisotropy"] > 15, narrow
    assert wide["anisotropy"] < 5, wide
    # the worst direction is the viewing direction (rig z) for cameras side by side
    assert abs(narrow["worst_axis"][2]) > 0.99
    assert narrow["std_mm"][0] > narrow["std_mm"][1] >= narrow["std_mm"][2] > 0


def test_uncertainty_needs_two_cameras():
    rig = _rig("thesis")
    with pytest.raises(TriangulationError):
        position_uncertainty(rig, np.array([0.0, 0.0, -7500.0]))  # behind every camera
