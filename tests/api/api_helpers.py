"""Helpers of the API tests: a signed-in client, a thread job queue, a fast stand-in analysis, zips.

The stand-in replaces `saddlescope.services.analysis.ride_bundle.analyze_bundle` and the rig calibration
(`saddlescope.services.rigs.calibration.calibrate_clips`): the real pipeline takes minutes per ride on a
2-core machine, these take milliseconds. The stand-in still opens and validates the bundle, reports
progress through the stage callback and returns a complete result document whose indicators come
from `saddlescope.core.vibration.ride_indicators` on an exact harmonic saddle motion (different
per horse and gait, so rankings are not trivial). ``STANDIN_DELAY_S`` in the environment (or
`STANDIN.delay_s`) makes the analysis stage last that long, reporting progress all the way (the
worker-kill test needs a slow stage).
"""

from __future__ import annotations

import contextlib
import io
import math
import os
import sys
import tempfile
import threading
import time
import types
import zipfile
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from integration_services import Api, add_member, free_box, new_club, poll_job, sign_in  # noqa: F401 (the signed-in client)

from saddlescope.core.types import CAMERA_ROLES
from saddlescope.core.vibration import ride_indicators
from saddlescope.settings import Settings, load_settings


def settings_for(tmp_path: Path, **overrides) -> Settings:
    """Embedded settings in `tmp_path` (SQLite, a folder store, a test secret), with `overrides`."""
    values = {
        "database_url": f"sqlite:///{tmp_path / 'db.sqlite'}",
        "storage_dir": str(tmp_path / "storage"),
        "secret_key": "a-test-secret-of-enough-length",
    }
    values.update(overrides)
    return load_settings(**values)


GAIT_F0_HZ = {"walk": 1.8, "sitting_trot": 2.6, "rising_trot": 2.6, "canter": 1.7}
GAIT_SPEED_KMH = {"walk": 6.0, "sitting_trot": 12.0, "rising_trot": 13.0, "canter": 19.0}


@dataclass
class _Standin:
    delay_s: float = 0.0
    calls: int = 0


STANDIN = _Standin(delay_s=float(os.environ.get("STANDIN_DELAY_S", "0") or 0))


def standin_result(meta: dict, *, fps: float = 30.0) -> dict:
    """A complete result document (CONTRACTS section 2) for ride.json `meta`, deterministic per horse+gait."""
    horse = (meta.get("horse") or {}).get("name") or "horse"
    gait = meta["gait"]
    rider = (meta.get("rider") or {}).get("name") or "rider"
    rng = np.random.default_rng(zlib.crc32(f"{horse}|{gait}|{rider}|{meta.get('direction')}".encode()))
    f0 = GAIT_F0_HZ[gait] * (1 + 0.05 * rng.random())
    amplitudes = np.array([rng.uniform(2.0, 6.0), rng.uniform(0.3, 1.5)])
    phases = np.array([0.0, rng.uniform(0, np.pi)])
    duration_s = 2.0 / f0  # two periods, as the thesis
    t = np.arange(int(round(duration_s * fps))) / fps
    k = np.arange(1, 3)[:, None]
    w = 2 * np.pi * f0 * k
    acc_y = (amplitudes[:, None] * np.cos(w * t + phases[:, None])).sum(axis=0)
    pos_y = (-amplitudes[:, None] / w**2 * np.cos(w * t + phases[:, None])).sum(axis=0)
    vel_y = (amplitudes[:, None] / w * np.sin(w * t + phases[:, None])).sum(axis=0)
    speed_m_s = GAIT_SPEED_KMH[gait] / 3.6 * (1 + 0.1 * rng.random())
    position = np.stack([speed_m_s * t, pos_y, np.zeros_like(t)], axis=1)
    velocity = np.stack([np.full_like(t, speed_m_s), vel_y, np.zeros_like(t)], axis=1)
    acceleration = np.stack([np.zeros_like(t), acc_y, np.zeros_like(t)], axis=1)
    markers = position[:, None, :] + np.array([[0.3, -0.2, 0.1], [-0.3, -0.2, 0.1], [0.0, -0.25, -0.2]])
    indicators = ride_indicators(
        f0_hz=f0,
        acc_y_amplitudes_m_s2=amplitudes,
        acc_y_phases_rad=phases,
        duration_s=duration_s,
        speed_kmh=speed_m_s * 3.6,
        amplitude_y_m=float(np.ptp(pos_y)),
        stride_frequency_hz=f0,
    )
    return {
        "format": "saddlescope.result/1",
        "fps": fps,
        "gait": gait,
        "direction": meta.get("direction"),
        "calibration": standin_calibration(),
        "sync": {"motion": {role: 0.0 for role in CAMERA_ROLES}},
        "period_s": 1.0 / f0,
        "window": {"start_s": 0.0, "duration_s": float(len(t) / fps)},
        "saddle": {
            "t_s": t.tolist(),
            "position_m": position.tolist(),
            "velocity_m_s": velocity.tolist(),
            "acceleration_m_s2": acceleration.tolist(),
        },
        "angular": {
            "omega_rad_s": np.zeros_like(position).tolist(),
            "alpha_rad_s2": np.zeros_like(position).tolist(),
            "singularity_index": 0.1,
        },
        "markers": {"names": ["M1", "M2", "M3"], "position_m": markers.tolist()},
        "indicators": {key: float(value) for key, value in indicators.items()},
        "quality": {"flags": [], "standin": True},
        "timings_s": {"total": 0.01},
    }


def standin_calibration(size: tuple[int, int] = (640, 480)) -> dict:
    """A plausible three-camera calibration (result format) that `rig_from_dict` accepts."""
    K = [[800.0, 0.0, size[0] / 2], [0.0, 800.0, size[1] / 2], [0.0, 0.0, 1.0]]
    cameras = {
        role: {"K": K, "dist": [0.0] * 5, "image_size": list(size), "rms_px": 0.2} for role in CAMERA_ROLES
    }
    extrinsics = {
        role: {"R": np.eye(3).tolist(), "t_mm": [-1000.0 * (i + 1), 0.0, 0.0]}
        for i, role in enumerate(CAMERA_ROLES[1:])
    }
    return {
        "cameras": cameras,
        "extrinsics": extrinsics,
        "checks": {"board_square_error_mm": 0.2},
        "flags": [],
        "pairs": {},
    }


def standin_analyze_bundle(path, on_progress=None, rig=None, params=None, meta_overrides=None, rig_report=None):
    from saddlescope.io.bundle import open_bundle

    STANDIN.calls += 1
    with open_bundle(Path(path)) as bundle:
        meta = {**bundle.meta, **(meta_overrides or {})}
    steps = max(1, int(STANDIN.delay_s / 0.1))
    for i in range(steps):
        if STANDIN.delay_s:
            time.sleep(STANDIN.delay_s / steps)
        if on_progress is not None:
            on_progress((i + 1) / (steps + 1), "standin")
    if str((meta.get("horse") or {}).get("name", "")).startswith("Failing"):
        from saddlescope.core.errors import DetectionError

        raise DetectionError(
            "motion clip of the left camera: no marker found in any frame (stand-in failure)"
        )
    result = standin_result(meta)
    if rig is not None:
        result["quality"]["calibration_from_rig"] = True
    return result


def standin_calibrate_clips(paths, *, board, sync=None, params=None, on_progress=None):
    from saddlescope.io.video import probe_video

    info = probe_video(Path(paths["left"]))
    if on_progress is not None:
        on_progress(0.5, "standin calibration")
    return standin_calibration((info.width, info.height))


def install_standin() -> None:
    """Replace the analysis and the rig calibration by the stand-ins in this process (a worker's)."""
    module = types.ModuleType("saddlescope.services.analysis.ride_bundle")
    module.analyze_bundle = standin_analyze_bundle
    sys.modules["saddlescope.services.analysis.ride_bundle"] = module
    import saddlescope.services.rigs.calibration as calibration

    calibration.calibrate_clips = standin_calibrate_clips


@contextlib.contextmanager
def standin_installed():
    """The stand-ins for the duration of a block (a test module), then the real functions again."""
    import saddlescope.services.rigs.calibration as calibration

    saved_module = sys.modules.get("saddlescope.services.analysis.ride_bundle")
    saved_calibrate = calibration.calibrate_clips
    install_standin()
    try:
        yield STANDIN
    finally:
        if saved_module is None:
            sys.modules.pop("saddlescope.services.analysis.ride_bundle", None)
        else:
            sys.modules["saddlescope.services.analysis.ride_bundle"] = saved_module
        calibration.calibrate_clips = saved_calibrate


@pytest.fixture
def standin(monkeypatch):
    """The stand-ins for one test (restored after it)."""
    module = types.ModuleType("saddlescope.services.analysis.ride_bundle")
    module.analyze_bundle = standin_analyze_bundle
    monkeypatch.setitem(sys.modules, "saddlescope.services.analysis.ride_bundle", module)
    import saddlescope.services.rigs.calibration as calibration

    monkeypatch.setattr(calibration, "calibrate_clips", standin_calibrate_clips)
    return STANDIN


class ThreadQueue:
    """Runs each job in a thread of the test process (so the stand-ins apply); embedded mode."""

    mode = "embedded"

    def __init__(self, settings) -> None:
        self.settings = settings
        self.threads: list[threading.Thread] = []

    def submit(self, job_id: int) -> None:
        from saddlescope.services.jobs.runner import run_job

        thread = threading.Thread(
            target=run_job, args=(job_id,), kwargs={"settings": self.settings}, daemon=True
        )
        thread.start()
        self.threads.append(thread)

    def health(self) -> tuple[bool, str]:
        return True, "embedded: test threads"

    def close(self) -> None:
        for thread in self.threads:
            thread.join(timeout=30)


# --- bundles and zips ------------------------------------------------------------------------------


def zip_folder(folder: Path, *, rewrite: dict | None = None, extra: dict | None = None) -> bytes:
    """A ride bundle folder as zip bytes; `rewrite` replaces members' bytes, `extra` adds members."""
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_STORED) as zf:
        for file in sorted(p for p in folder.rglob("*") if p.is_file()):
            name = file.relative_to(folder).as_posix()
            data = (rewrite or {}).get(name, file.read_bytes())
            zf.writestr(name, data)
        for name, data in (extra or {}).items():
            zf.writestr(name, data)
    return buffer.getvalue()


def another_take(folder: Path, note: str) -> dict[str, bytes]:
    """`zip_folder` rewrites giving the bundle's MP4 motion clips other bytes (a trailing ISO BMFF ``free``
    box holding `note`; every reader skips it): the same ride, filmed "again", since the same clips never
    make two rides of a club.
    """
    return {path.relative_to(folder).as_posix(): path.read_bytes() + free_box(note)
            for path in sorted((folder / "motion").glob("*.mp4"))}


def zip_members(members: dict[str, bytes], *, deflate: bool = True) -> bytes:
    """A zip of the given members (name -> bytes)."""
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED if deflate else zipfile.ZIP_STORED) as zf:
        for name, data in members.items():
            zf.writestr(name, data)
    return buffer.getvalue()


def zip_bomb() -> bytes:
    """A small zip whose one clip inflates to 20 MiB of zeros (a compression ratio no video has)."""
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("ride.json", b"{}")
        with zf.open("motion/left.mp4", "w", force_zip64=True) as member:
            for _ in range(20):
                member.write(b"\x00" * (1 << 20))
    return buffer.getvalue()


def ride_json_with(folder: Path, **changes) -> bytes:
    import json

    meta = json.loads((folder / "ride.json").read_text())
    for key, value in changes.items():
        meta[key] = value
    return json.dumps(meta).encode()


def finite(value) -> bool:
    return isinstance(value, int | float) and math.isfinite(value)


class FullDisk:
    """While `full`, every file the folder store's writer opens is /dev/full: writes fail with ENOSPC."""

    def __init__(self) -> None:
        self.full = False

    def install(self, monkeypatch) -> FullDisk:
        """Make the folder store's writers open their files through `mkstemp` (undone by `monkeypatch`)."""
        from saddlescope.storage import files

        monkeypatch.setattr(files, "tempfile", types.SimpleNamespace(mkstemp=self.mkstemp))
        return self

    def mkstemp(self, *args, **kwargs):
        fd, name = tempfile.mkstemp(*args, **kwargs)
        if self.full:
            full = os.open("/dev/full", os.O_WRONLY)
            os.dup2(full, fd)  # the temporary file exists (and must be removed); its bytes go nowhere
            os.close(full)
        return fd, name


def job_outcome(api, job_id: int, timeout_s: float = 60.0) -> dict:
    """The job once it is done, failed or cancelled (polled through the API)."""
    return poll_job(lambda: api.ok("GET", f"/jobs/{job_id}"), job_id, timeout_s=timeout_s)[0]
