"""The whole pipeline on the wide rig (1920x1080, 60 fps, cameras metres apart), against its exact answer.

Issue 4: marker 3-D RMS error below 2 mm; issues 5 and 6: the saddle's vertical acceleration and the
rider's indicators, printed next to the floor that exact marker positions give (skin motion).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from saddlescope.arena import saddle_truth_at
from saddlescope.bench import exact_marker_floor
from saddlescope.core import pipeline as P
from saddlescope.core.kinematics.registration import register_rigid
from saddlescope.core.pipeline import run
from saddlescope.io.result_document import result_to_document

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def wide_ride(tmp_path_factory):
    from rendered_rides import cached_ride_bundle

    from saddlescope.io.bundle import open_bundle
    from saddlescope.io.clip_source import BundleClips

    out = tmp_path_factory.mktemp("wide") / "canter"
    cached_ride_bundle(out, gait="canter", seed=2, rig="wide", extras=False)
    captured = {}
    original = run.saddle_kinematics

    def keep_tracks(motion, *args, **kwargs):
        captured["motion"] = motion
        return original(motion, *args, **kwargs)

    mp = pytest.MonkeyPatch()
    mp.setattr(run, "saddle_kinematics", keep_tracks)
    try:
        with open_bundle(out) as bundle:
            result = result_to_document(P.analyze_ride(BundleClips(bundle.clip_paths), bundle.meta))
    finally:
        mp.undo()
    return result, captured["motion"], json.loads((out / "truth.json").read_text())


def _rigid_aligned_errors(ours: np.ndarray, exact: np.ndarray) -> np.ndarray:
    """Errors (K, 3) mm of our points after the best rigid motion onto the exact ones (the rig frame
    is the calibrated left camera's, which may sit a few mm and arc-seconds off the true one)."""
    return register_rigid(exact[None], ours).registered[0] - exact


def test_wide_rig_markers_within_two_millimetres(wide_ride):
    result, motion, truth = wide_ride
    exact_all = np.asarray(truth["truth"]["markers_3d_mm"]["motion"], dtype=float)[:, :3]
    exact = exact_all[np.round(motion.t_s * truth["fps"]).astype(int)]
    ours = motion.xyz_mm
    # our markers are numbered by the detector: pair each with the nearest exact marker
    order = [int(np.argmin([np.nanmedian(np.linalg.norm(ours[:, j] - exact[:, i], axis=1)) for i in range(3)]))
             for j in range(3)]
    assert sorted(order) == [0, 1, 2]
    seen = np.all(np.isfinite(ours), axis=2)
    err = _rigid_aligned_errors(ours[seen], exact[:, order][seen])
    per_axis = np.sqrt(np.mean(err ** 2, axis=0))
    rms = float(np.sqrt(np.mean(np.sum(err ** 2, axis=1))))
    print(f"wide rig: marker 3-D RMS error {rms:.2f} mm (x {per_axis[0]:.2f}, y {per_axis[1]:.2f}, "
          f"z {per_axis[2]:.2f}) over {int(seen.sum())} marker samples")
    assert rms < 2.0
    for cam, c in result["calibration"]["cameras"].items():
        f_true = truth["calibration"]["cameras"][cam]["K"][0][0]
        assert abs(c["K"][0][0] / f_true - 1) < 0.005, cam


def test_wide_rig_saddle_and_indicators_against_the_floor(wide_ride):
    result, _, truth = wide_ride
    ts = np.array(result["saddle"]["t_s"])
    exact = saddle_truth_at(truth, ts)["acceleration_m_s2"][:, 1]
    acc = np.array(result["saddle"]["acceleration_m_s2"], dtype=float)[:, 1]
    err_pct = 100 * np.sqrt(np.mean((acc - exact) ** 2)) / np.sqrt(np.mean(exact ** 2))
    floor = exact_marker_floor(truth)
    ind, ref = result["indicators"], truth["indicators"]
    wb = 100 * (ind["acc_y_wb_rms"] / ref["acc_y_wb_rms"] - 1)
    vdv = 100 * (ind["vdv_y_wb"] / ref["vdv_y_wb"] - 1)
    speed = 100 * (ind["vel_x_avg_kmh"] / ref["vel_x_avg_kmh"] - 1)
    print(f"wide rig canter: vertical acceleration error {err_pct:.1f} % (exact markers: "
          f"{floor['acc_y_rms_error_pct']:.1f} %), W_b rms {wb:+.1f} %, VDV {vdv:+.1f} %, speed {speed:+.2f} %")
    # the measurement adds little to what skin motion costs exact markers
    assert err_pct < floor["acc_y_rms_error_pct"] + 2.0
    assert abs(speed) < 1.0
    assert abs(wb) < 5.0 and abs(vdv) < 6.0
