"""Synchronisation from the markers' own motion (no flash), on synthetic tracks with known offsets."""

from __future__ import annotations

import numpy as np
import pytest

from saddlescope.core.camera_model import project_points
from saddlescope.core.errors import SyncError
from saddlescope.core.sync_motion import image_speed, motion_offsets, speed_correlation
from saddlescope.core.types import Camera, ImageTracks, Rig

FPS = 30.0


def _rig(spacing_mm: float = 2500.0) -> Rig:
    """Three cameras in a row 8 m from the track, turned in towards its middle."""
    cams = {}
    for i, name in enumerate(("left", "middle", "right")):
        x = (i - 1) * spacing_mm
        yaw = np.arctan2(-x, 8000.0)  # turn towards (0, 0, 8000)
        R = np.array([[np.cos(yaw), 0, -np.sin(yaw)], [0, 1, 0], [np.sin(yaw), 0, np.cos(yaw)]])
        centre = np.array([x, 0.0, 0.0])
        K = np.array([[1400.0, 0, 960], [0, 1400.0, 540], [0, 0, 1]])
        cams[name] = Camera(name, K, np.array([-0.05, 0.01, 0, 0, 0]), (1920, 1080), R=R, t_mm=-R @ centre)
    # express every camera in the left camera's frame (the rig's coordinates)
    R0, t0 = cams["left"].R, cams["left"].t_mm
    for name, c in cams.items():
        R = c.R @ R0.T
        cams[name] = Camera(name, c.K, c.dist, c.image_size, R=R, t_mm=c.t_mm - R @ t0)
    return Rig(cams)


def _markers_mm(t_s: np.ndarray, seed: int = 0, vertical: float = 1.0) -> np.ndarray:
    """Three markers of a cantering horse crossing the view: (T, 3, 3) mm in world = rig-ish coordinates.

    ``vertical`` scales their up-and-down motion (0: they stay in the cameras' epipolar planes).
    """
    rng = np.random.default_rng(seed)
    f = 1.7  # strides per second
    phase = rng.uniform(0, 2 * np.pi)
    x = -4000.0 + 5000.0 * t_s + 60.0 * np.sin(2 * np.pi * f * t_s + phase)  # speed varies over the stride
    y = vertical * (80.0 * np.sin(2 * np.pi * f * t_s + phase + 1.0) + 25.0 * np.sin(4 * np.pi * f * t_s))
    base = np.stack([x, y, np.full_like(t_s, 8000.0)], axis=-1)
    layout = np.array([[-300.0, 0, 0], [0, 60, 0], [300, 0, 0]])
    pitch = vertical * 0.05 * np.sin(2 * np.pi * f * t_s + phase)
    out = base[:, None, :] + layout[None]
    out[..., 1] += pitch[:, None] * layout[None, :, 0]
    return out


def _tracks(rig: Rig, offsets: dict, *, n_frames: int = 75, noise_px: float = 0.15, seed: int = 1,
            speed_scale: float = 1.0, clocks: dict | None = None, vertical: float = 1.0) -> dict[str, ImageTracks]:
    """Each camera's tracks: its frame k shows the instant of the reference's frame k - offset."""
    rng = np.random.default_rng(seed)
    R0 = rig.cameras["left"]
    out = {}
    for name, cam in rig.cameras.items():
        k = np.arange(n_frames, dtype=np.float64)
        t = (k - offsets[name]) / FPS if clocks is None or name not in clocks else clocks[name][0] - offsets[name] / FPS
        pts_world = _markers_mm(t * speed_scale, vertical=vertical)
        pts_rig = pts_world @ R0.R.T + R0.t_mm  # world -> rig (left camera) coordinates
        xy = project_points(cam, pts_rig) + rng.normal(0, noise_px, (n_frames, 3, 2))
        xy[(xy[..., 0] < 0) | (xy[..., 0] > 1920)] = np.nan  # out of view
        # each camera labels its markers its own way
        perm = rng.permutation(3)
        out[name] = ImageTracks(name, xy[:, perm], np.arange(n_frames))
    return out


def test_image_speed_is_the_mean_step_of_the_markers_seen():
    xy = np.zeros((4, 2, 2))
    xy[:, 0, 0] = [0, 3, 6, 9]
    xy[:, 1, 1] = [0, 1, 2, 3]
    xy[2, 1] = np.nan
    np.testing.assert_allclose(image_speed(xy), [2.0, 3.0, 3.0])


def test_speed_correlation_peaks_at_the_shift():
    rng = np.random.default_rng(3)
    s = rng.normal(size=200)
    lags = np.arange(-10, 11)
    ncc = speed_correlation(s[:150], s[7:157], lags)  # camera sample k + L = reference k when L = -7
    assert lags[int(np.nanargmax(ncc))] == -7
    assert np.nanmax(ncc) == pytest.approx(1.0)


@pytest.mark.parametrize("true", [{"middle": 4.37, "right": -2.81}, {"middle": 9.62, "right": 0.18}])
def test_sub_frame_offsets_from_motion(true):
    rig = _rig()
    offsets = {"left": 0.0, **true}
    found = motion_offsets(_tracks(rig, offsets), FPS, rig=rig)
    for cam, o in true.items():
        assert abs(found.offsets[cam] - o) < 0.05, (cam, found.offsets, found.candidates)
        assert 0 < found.sigma_frames[cam] < 0.1
    assert found.offsets["left"] == 0.0 and found.method == "motion"
    assert found.rms_px < 0.5


@pytest.mark.slow
def test_reported_uncertainty_grows_with_tracking_noise():
    rig = _rig()
    offsets = {"left": 0.0, "middle": 3.3, "right": 6.6}
    quiet = motion_offsets(_tracks(rig, offsets, noise_px=0.1), FPS, rig=rig)
    noisy = motion_offsets(_tracks(rig, offsets, noise_px=0.8), FPS, rig=rig)
    assert noisy.sigma_frames["middle"] > 3 * quiet.sigma_frames["middle"]
    for cam in ("middle", "right"):  # and the error stays within a few of those sigmas
        assert abs(noisy.offsets[cam] - offsets[cam]) < max(4 * noisy.sigma_frames[cam], 0.1)


def _board_centroid(t_s: np.ndarray, seed: int = 2) -> np.ndarray:
    """A board carried from pose to pose: held still three frame periods, moved in one; (T, 1, 2) px."""
    rng = np.random.default_rng(seed)
    poses = np.cumsum(rng.normal(0, 40, (200, 2)), axis=0) + 500
    period = 4 / FPS
    j = np.clip(np.floor(t_s / period).astype(int), 0, 198)
    moving = np.clip((t_s / period - j - 0.75) / 0.25, 0, 1)  # the last quarter of each period
    return (poses[j] + moving[:, None] * (poses[j + 1] - poses[j]))[:, None, :]


def test_whole_frames_without_a_rig():
    """The calibration clip: the board's own (unperiodic) motion places the cameras to a frame."""
    offsets = {"left": 0.0, "middle": 5.3, "right": -3.0}
    rng = np.random.default_rng(4)
    tracks = {}
    for i, (cam, o) in enumerate(offsets.items()):
        xy = (1.0 + 0.2 * i) * _board_centroid((np.arange(200) - o) / FPS) + rng.normal(0, 0.2, (200, 1, 2))
        tracks[cam] = ImageTracks(cam, xy, np.arange(200))
    found = motion_offsets(tracks, FPS)
    assert abs(found.offsets["middle"] - 5.3) < 0.5 and abs(found.offsets["right"] + 3.0) < 0.5, found.offsets
    assert found.rms_px is None


@pytest.mark.slow
def test_variable_frame_clocks():
    """Phones: camera frames at jittered instants, tracks placed by their stamps."""
    rig = _rig()
    rng = np.random.default_rng(5)
    n = 75
    # the nominal clock is tied to the clip's stamps at frame 0 (no flash: the anchor is the first frame)
    late = {c: np.r_[0.0, rng.uniform(-0.2, 0.2, n - 1)] / FPS if c != "left" else 0.0 for c in rig.cameras}
    stamps = {c: np.arange(n) / FPS + late[c] for c in rig.cameras}
    offsets = {"left": 0.0, "middle": 2.45, "right": 7.8}
    tracks = _tracks(rig, offsets, clocks={c: (stamps[c],) for c in rig.cameras}, n_frames=n)
    clocks = {c: (stamps[c], 0.0) for c in rig.cameras}
    found = motion_offsets(tracks, FPS, rig=rig, clocks=clocks)
    for cam in ("middle", "right"):
        assert abs(found.offsets[cam] - offsets[cam]) < 0.1, found.offsets
    # ignoring the stamps costs accuracy: the check above is not met by chance
    plain = motion_offsets(tracks, FPS, rig=rig)
    assert max(abs(plain.offsets[c] - offsets[c]) for c in ("middle", "right")) > \
        max(abs(found.offsets[c] - offsets[c]) for c in ("middle", "right"))


def test_standing_still_is_refused_with_a_reason():
    rig = _rig()
    tracks = _tracks(rig, {"left": 0.0, "middle": 1.0, "right": 2.0}, speed_scale=0.0, noise_px=0.05)
    with pytest.raises(SyncError, match="not enough motion"):
        motion_offsets(tracks, FPS, rig=rig)


def test_unrelated_motion_is_refused_with_a_reason():
    rig = _rig()
    tracks = _tracks(rig, {"left": 0.0, "middle": 1.0, "right": 2.0})
    rng = np.random.default_rng(9)
    walk = np.cumsum(rng.normal(0, 3, (75, 3, 2)), axis=0) + 900  # the right camera followed something else
    tracks["right"] = ImageTracks("right", walk, np.arange(75))
    with pytest.raises(SyncError, match="matches|half a frame|other offsets"):
        motion_offsets(tracks, FPS, rig=rig)


def test_two_cameras_a_stride_apart_are_refused_not_guessed():
    """Two cameras check only the epipolar constraint: markers that stay in the epipolar planes meet it
    nearly at every offset. Refused, or said to be uncertain by as much as it is wrong; never silently wrong."""
    rig = _rig()
    tracks = _tracks(rig, {"left": 0.0, "middle": 4.37, "right": -2.81}, vertical=0.0)
    try:
        found = motion_offsets({c: tracks[c] for c in ("left", "right")}, FPS, rig=rig)
    except SyncError as exc:
        assert "about as well at other offsets" in str(exc) or "half a frame" in str(exc)
    else:
        error = abs(found.offsets["right"] + 2.81)
        assert found.sigma_frames["right"] > 0.1 and error < 3 * found.sigma_frames["right"], found


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_two_cameras_are_right_or_refused(seed):
    """With the markers' vertical motion two cameras may tell the strides apart: never a wrong offset."""
    rig = _rig()
    tracks = _tracks(rig, {"left": 0.0, "middle": 4.37, "right": -2.81}, seed=seed)
    try:
        found = motion_offsets({c: tracks[c] for c in ("left", "right")}, FPS, rig=rig)
    except SyncError as exc:
        assert "about as well at other offsets" in str(exc)
    else:
        assert abs(found.offsets["right"] + 2.81) < 0.1, found.offsets


def test_one_camera_is_refused():
    rig = _rig()
    tracks = _tracks(rig, {"left": 0.0, "middle": 1.0, "right": 2.0})
    with pytest.raises(SyncError, match="two cameras"):
        motion_offsets({"left": tracks["left"]}, FPS, rig=rig)


class _Clips:
    """A ClipReader of brightness curves only: a flash in the clip sets named in ``flashed``."""

    def __init__(self, flashed=(), fps=None, decode=True):
        self.flashed, self.fps_of, self.decode = set(flashed), dict(fps or {}), decode

    def cameras(self, kind):
        return ["left", "middle", "right"]

    def fps(self, kind, camera):
        return self.fps_of.get(camera, 30.0)

    def frame_times(self, kind, camera):
        return None

    def brightness(self, kind, camera):
        assert self.decode, "a ride synchronised from motion decodes no brightness"
        rng = np.random.default_rng(len(kind) + len(camera))
        b = 80 + rng.normal(0, 0.3, 120)
        if kind in self.flashed:
            b[40 + len(camera): 45 + len(camera)] += 40
        return b


def test_clip_sets_without_a_flash_are_left_to_their_motion():
    from saddlescope.core.pipeline.setup import synchronise, synchronise_clips

    kinds = ["calibration", "plumb", "static", "motion"]
    offsets, first, methods = synchronise_clips(_Clips(flashed=["calibration"]), {"sync": {"method": "flash"}}, kinds)
    assert methods["calibration"] == "flash" and first["calibration"]["left"] > 40
    assert methods["plumb"] == methods["static"] == "still" and methods["motion"] == "motion"
    assert "no sync flash found in the motion clip" in methods["reasons"]["motion"]
    assert offsets["motion"] == {"left": 0.0, "middle": 0.0, "right": 0.0} and first["motion"]["right"] == 0
    with pytest.raises(SyncError, match="no sync flash found in the motion clip"):
        synchronise(_Clips(flashed=["calibration"]), {"sync": {"method": "flash"}}, kinds)  # callers without motion


def test_sync_by_choice_decodes_no_brightness_and_checks_frame_rates():
    from saddlescope.core.pipeline.setup import synchronise_clips

    _, _, methods = synchronise_clips(_Clips(decode=False), {"sync": {"method": "motion"}}, ["static", "motion"])
    assert methods["static"] == "still" and methods["motion"] == "motion"
    with pytest.raises(SyncError, match="equal frame rates"):
        synchronise_clips(_Clips(decode=False, fps={"right": 25.0}), {"sync": {"method": "motion"}}, ["motion"])


# --------------------------------------------------------------------------------------------------
# The whole pipeline on arena rides: one filmed without a flash, one with a flash analysed both ways
# --------------------------------------------------------------------------------------------------

def _ride(tmp_path_factory, name: str, *, flash: bool):
    from rendered_rides import cached_ride_bundle

    from saddlescope.arena import RenderOptions

    out = tmp_path_factory.mktemp(name) / "canter"
    # 30 calibration poses (120 frames) rather than the thesis's 90: the board's motion still places the
    # calibration clips to a frame and calibrates the rig for the 1 % checks, at a third of the rendering
    # and board detection (two rides, each analysed once)
    cached_ride_bundle(out, gait="canter", seed=23, rig="thesis", duration_s=3.0, extras=False,
                       calibration_poses=30, options=RenderOptions(flash=flash))
    return out


@pytest.fixture(scope="module")
def no_flash_ride(tmp_path_factory):
    import json

    from saddlescope.services.analysis.ride_bundle import analyze_bundle

    ride = _ride(tmp_path_factory, "no_flash", flash=False)
    # ride.json says "flash" as a club's default would: no flash is found, and the motion takes over
    result = analyze_bundle(ride, meta_overrides={"sync": {"method": "flash"}})
    return result, json.loads((ride / "truth.json").read_text())


@pytest.fixture(scope="module")
def by_flash(tmp_path_factory):
    from saddlescope.services.analysis.ride_bundle import analyze_bundle

    return analyze_bundle(_ride(tmp_path_factory, "flash", flash=True))


@pytest.mark.slow
def test_a_ride_without_a_flash_is_synchronised_from_its_motion(no_flash_ride):
    result, truth = no_flash_ride
    sync = result["quality"]["sync"]
    assert sync["motion"]["method"] == "motion" and "no sync flash found" in sync["motion"]["reason"]
    assert sync["calibration"]["method"] == "motion" and sync["static"]["method"] == "still"
    for cam, off in truth["sync"]["motion"].items():
        assert abs(result["sync"]["motion"][cam] - off) < 0.1, (cam, result["sync"]["motion"], truth["sync"]["motion"])
        assert sync["motion"]["sigma_frames"][cam] < 0.1
    for cam, off in truth["sync"]["calibration"].items():  # the board's: to the nearest frame
        assert abs(result["sync"]["calibration"][cam] - off) < 1.0
    assert any(f["code"] == "sync.motion" and f["detail"].startswith("the motion clip was synchronised from the "
                                                                       "markers' motion")
               for f in result["quality"]["findings"])
    assert abs(result["indicators"]["vel_x_avg_kmh"] / truth["truth"]["speed_kmh"] - 1) < 0.01
    assert abs(result["indicators"]["stride_frequency_hz"] * truth["period_s"] - 1) < 0.01


@pytest.mark.slow
def test_motion_sync_gives_the_flash_syncs_result(no_flash_ride, by_flash):
    """The same ride filmed with a flash and without one (the arena's seed fixes the motion and the
    cameras' offsets): synchronised from the markers' motion, it gives the flash sync's offsets and
    indicators (one analysis each; the flash ride is not analysed a second time by its motion)."""
    by_motion, _ = no_flash_ride
    assert by_flash["quality"]["sync"]["motion"]["method"] == "flash"
    assert by_motion["quality"]["sync"]["motion"]["method"] == "motion"
    for cam, off in by_flash["sync"]["motion"].items():
        assert abs(by_motion["sync"]["motion"][cam] - off) < 0.1
    for key in ("acc_y_wb_rms", "vel_x_avg_kmh", "stride_frequency_hz"):
        a, b = by_motion["indicators"][key], by_flash["indicators"][key]
        assert abs(a / b - 1) < 0.02, (key, a, b)


@pytest.mark.slow
def test_a_wide_rig_walk_without_a_flash_is_synchronised_to_a_tenth_of_a_frame(tmp_path):
    """The wide rig's cameras stand at the markers' height and a walk hardly moves them up and down:
    the offsets' weakest combination. With the arena's own rig (the calibration is not under test),
    the motion clip's offsets come within a tenth of a frame of the arena's, and say so."""
    import json

    from rendered_rides import cached_ride_bundle

    from saddlescope.arena import RenderOptions
    from saddlescope.core.params import PipelineParams
    from saddlescope.core.pipeline.setup import motion_sync
    from saddlescope.io.bundle import open_bundle
    from saddlescope.io.clip_source import BundleClips
    from saddlescope.services.rigs.calibration import rig_from_calibration

    ride = cached_ride_bundle(tmp_path / "walk", gait="walk", seed=3, rig="wide", size=(960, 540), fps=60.0,
                              calibration_poses=1, extras=False, options=RenderOptions(flash=False))
    truth = json.loads((ride / "truth.json").read_text())
    with open_bundle(ride) as bundle:
        clips = BundleClips(bundle.clip_paths, threads=1)
        found = motion_sync(clips, rig_from_calibration(truth["calibration"]), "motion", 3, PipelineParams())
    true = truth["sync"]["motion"]
    for cam in ("middle", "right"):
        error = (found.offsets[cam] - found.offsets["left"]) - (true[cam] - true["left"])
        assert abs(error) < 0.1, (cam, found.offsets, true)
        assert found.sigma_frames[cam] < 0.1, found.sigma_frames


def test_a_board_moved_by_equal_steps_is_placed_by_the_moves_directions():
    """Held three frame periods and moved in one by steps of one size: its speed repeats every four
    frames, so only the moves' directions (the same in cameras side by side) place the cameras."""
    rng = np.random.default_rng(8)
    angle = rng.uniform(0, 2 * np.pi, 60)
    poses = 500 + np.cumsum(40.0 * np.stack([np.cos(angle), np.sin(angle)], axis=1), axis=0)
    offsets = {"left": 0.0, "middle": 5.3, "right": -3.0}
    tracks = {}
    for i, (cam, o) in enumerate(offsets.items()):
        t = (np.arange(200) - o) / FPS
        period = 4 / FPS
        j = np.clip(np.floor(t / period).astype(int), 0, 58)
        moving = np.clip((t / period - j - 0.75) / 0.25, 0, 1)
        xy = (1.0 + 0.2 * i) * (poses[j] + moving[:, None] * (poses[j + 1] - poses[j]))[:, None, :]
        tracks[cam] = ImageTracks(cam, xy + rng.normal(0, 0.2, xy.shape), np.arange(200))
    found = motion_offsets(tracks, FPS)
    assert abs(found.offsets["middle"] - 5.3) < 0.5 and abs(found.offsets["right"] + 3.0) < 0.5, found.offsets
