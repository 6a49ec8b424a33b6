"""A bundle's calibration_file read in its own unit: caliscope's TOML (metres, 3x3 rotations) and
Pose2Sim's Calib.toml (metres, no unit stated) no longer refused or read 1000x too small."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import real_data_path
from saddlescope.io.bundle import read_bundle_calibration
from saddlescope.io.calibration_files import rig_from_caliscope_toml, write_anipose_toml
from saddlescope.services.analysis.ride_bundle import load_calibration_file


@pytest.mark.realdata
def test_caliscope_camera_array_is_read_in_metres():
    path = real_data_path("caliscope_4cam", "camera_array.toml")
    rig, notes = read_bundle_calibration(path)
    assert notes == [] and len(rig.cameras) == 4
    expected = rig_from_caliscope_toml(path)
    for name, cam in rig.cameras.items():
        np.testing.assert_allclose(cam.t_mm, expected.cameras[name].t_mm)
    # four cameras around a desk: centres 0.5-2 m apart, in mm
    spread = max(np.linalg.norm(c.t_mm) for c in rig.cameras.values())
    assert 300 < spread < 3000


def _pose2sim_toml(tmp_path, rig, *, keep_units: bool):
    path = write_anipose_toml(rig, tmp_path / "Calib.toml", units="m")
    if not keep_units:  # Pose2Sim states no unit
        path.write_text("\n".join(ln for ln in path.read_text().splitlines() if not ln.startswith("units")))
    return path


@pytest.mark.realdata
@pytest.mark.parametrize("keep_units", [True, False])
def test_pose2sim_calib_toml_is_read_in_metres(tmp_path, keep_units):
    rig = rig_from_caliscope_toml(real_data_path("caliscope_4cam", "camera_array.toml"))
    path = _pose2sim_toml(tmp_path, rig, keep_units=keep_units)
    back, notes = read_bundle_calibration(path)
    for name, cam in rig.cameras.items():
        np.testing.assert_allclose(back.cameras[name].t_mm, cam.t_mm, atol=1e-6)
    assert bool(notes) is not keep_units
    if notes:
        assert notes[0].code == "calibration.units_guessed" and "read as metres" in notes[0].detail
    np.testing.assert_allclose(load_calibration_file(path).cameras["cam_1"].t_mm, rig.cameras["cam_1"].t_mm,
                               atol=1e-6)


@pytest.mark.realdata
def test_anipose_toml_in_mm_without_units_stays_mm(tmp_path):
    rig = rig_from_caliscope_toml(real_data_path("caliscope_4cam", "camera_array.toml"))
    path = write_anipose_toml(rig, tmp_path / "calibration.toml", units="mm")
    path.write_text("\n".join(ln for ln in path.read_text().splitlines() if not ln.startswith("units")))
    back, notes = read_bundle_calibration(path)
    np.testing.assert_allclose(back.cameras["cam_2"].t_mm, rig.cameras["cam_2"].t_mm, atol=1e-6)
    assert notes[0].code == "calibration.units_guessed" and "read as mm" in notes[0].detail
