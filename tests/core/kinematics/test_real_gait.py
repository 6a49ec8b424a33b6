"""The kinematics stages on a real recording: a person walking in a motion-capture lab (BTK's
Gait.c3d, 100 Hz, ../shared/data/real/c3d). The pelvis markers (both anterior iliac spines and the
sacrum) stand in for the three horse markers: a real skin-mounted triad whose motion nobody on this
project shaped. The references come from other markers of the same recording: the left heel's two
stance phases give the stride time and the stride length."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import find_peaks

from conftest import real_data_path
from saddlescope.core.errors import KinematicsError
from saddlescope.core.kinematics.fitting import fit_marker_kinematics
from saddlescope.core.kinematics.frames import motion_frame, to_motion_frame
from saddlescope.core.kinematics.period import analysis_window, estimate_period
from saddlescope.core.kinematics.registration import marker_model, register_rigid
from saddlescope.io.mocap import read_mocap

pytestmark = pytest.mark.realdata
PELVIS = ("RASI", "LASI", "VSAC")


@pytest.fixture(scope="module")
def gait():
    data = read_mocap(real_data_path("c3d", "Gait.c3d"))
    pelvis_mm = np.stack([data.marker(name) for name in PELVIS], axis=1)
    seen = np.flatnonzero(np.isfinite(pelvis_mm).all(axis=(1, 2)))  # the walk through the volume
    t_s = seen / data.rate_hz
    heel_m = data.marker("LHEE")[seen] / 1000.0
    stance, _ = find_peaks(-heel_m[:, 2], prominence=0.03)  # the heel at rest on the floor
    assert stance.size == 2, "the recording holds one whole stride of the left foot"
    period_s, period_info = estimate_period(t_s, pelvis_mm[seen] / 1000.0)
    return {"t_s": t_s, "pelvis_mm": pelvis_mm[seen], "period_s": period_s, "period_info": period_info,
            "stride_s": float(np.diff(t_s[stance])[0]),
            "stride_m": float(np.linalg.norm(np.diff(heel_m[stance, :2], axis=0)))}


def test_the_stride_period_found_in_the_pelvis_is_the_heels(gait):
    # a person's pelvis bobs twice per stride, as a horse's back at walk and trot
    assert gait["period_info"]["harmonic"] == 2
    assert gait["period_s"] == pytest.approx(gait["stride_s"], rel=0.03)  # measured: 0.985 s against 1.00 s


def test_fits_of_the_pelvis_give_the_heels_speed_and_stride(gait):
    t, period_s = gait["t_s"], gait["period_s"]
    frame = motion_frame(gait["pelvis_mm"][:, 2], rig_down_hint=np.array([0.0, 0.0, -1.0]),
                         hint_name="the lab's vertical", t_s=t, period_s=period_s)
    pelvis_m = np.stack([to_motion_frame(gait["pelvis_mm"][:, k], frame) for k in range(3)], axis=1)
    kin = fit_marker_kinematics(t, pelvis_m, period_s=period_s, x_model="fourier", trend_degree=1)
    speed_m_s = gait["stride_m"] / gait["stride_s"]  # 1.43 m/s
    assert kin.average_speed_m_s == pytest.approx(speed_m_s, rel=0.03)  # measured: 1.46 m/s
    assert 2 * np.pi / kin.omega_rad_s == pytest.approx(gait["stride_s"], rel=0.04)  # measured: 0.973 s
    for fit in kin.fits_x:  # the speed's 95 % interval is a few centimetres per second wide
        lo, hi = fit.ci["trend"][0]
        assert lo < fit.trend[0] < hi and hi - lo < 0.05
    # the pelvis's vertical motion is smooth: a few harmonics of the stride, not the noise's
    assert all(2 <= f.order <= 4 for f in kin.fits_y)


def test_the_pelvis_triad_is_rigid_to_a_few_millimetres_of_skin_motion(gait):
    pelvis = gait["pelvis_mm"]
    reg = register_rigid(pelvis, marker_model(pelvis[0]))
    assert np.median(reg.rms_residual) < 4.0  # measured: 2.8 mm (skin over the iliac spines)
    assert np.max(reg.rms_residual) < 8.0  # measured: 5.3 mm
    # the pelvis turns about the vertical with the swinging leg (gait texts: about 8-10 degrees peak
    # to peak); the registration's rotation, from the first frame's pose, shows it
    yaw_deg = np.degrees(np.arctan2(reg.R[:, 1, 0], reg.R[:, 0, 0]))
    assert 4.0 < np.ptp(yaw_deg) < 20.0  # measured: 9.8 degrees


def test_a_real_walk_shorter_than_two_strides_is_refused_with_the_reason(gait):
    t, period_s = gait["t_s"], gait["period_s"]
    with pytest.raises(KinematicsError, match=r"shorter than 2 periods .*record a longer ride"):
        analysis_window(t, np.ones(t.size, dtype=bool), period_s, n_periods=2)
    start, stop = analysis_window(t, np.ones(t.size, dtype=bool), period_s, n_periods=1)
    assert (stop - start) == round(period_s * 100)
