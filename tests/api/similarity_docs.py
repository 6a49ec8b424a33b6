"""Result documents of rides whose motion is known: one saddle-point stride shape per horse and gait.

Each document has several whole strides of the saddle point S (a horse-specific Fourier series of the
stride in x, y, z on top of the travel), three markers moving rigidly with it plus a small rotation, and
per recording its own noise, start phase and speed. Stored as the analyse stage stores a result (the
result JSON in storage, the row in the database), so the similarity routes can be tested without the
pipeline.
"""

from __future__ import annotations

import zlib
from pathlib import Path

import numpy as np

STRIDE_HZ = {"walk": 0.95, "sitting_trot": 1.45, "rising_trot": 1.45, "canter": 1.7}
SPEED_M_S = {"walk": 1.6, "sitting_trot": 3.3, "rising_trot": 3.5, "canter": 5.2}


def motion_document(horse: str, gait: str, *, recording: int = 0, strides: int = 8, fps: float = 60.0) -> dict:
    """A result document (the parts the similarity reads, plus indicators) of `horse` in `gait`."""
    shape = np.random.default_rng(zlib.crc32(f"{horse}|{gait}".encode()))
    amplitudes_m = shape.uniform(0.004, 0.03, (3, 3)) * np.array([[1.0], [0.6], [0.3]])  # harmonic x axis
    phases = shape.uniform(0, 2 * np.pi, (3, 3))
    noise = np.random.default_rng(zlib.crc32(f"{horse}|{gait}|{recording}".encode()))
    f0 = STRIDE_HZ[gait] * noise.uniform(0.97, 1.03)
    start = noise.uniform(0, 2 * np.pi)
    t = np.arange(int(round(strides / f0 * fps))) / fps
    arg = 2 * np.pi * f0 * t + start
    k = np.arange(1, 4)[:, None, None]
    stride = (amplitudes_m[:, :, None] * np.cos(k * arg[None, None, :] + phases[:, :, None])).sum(axis=0).T
    speed = SPEED_M_S[gait] * noise.uniform(0.95, 1.05)
    position = stride + np.column_stack([speed * t, np.zeros_like(t), np.zeros_like(t)])
    position += noise.normal(0.0, 0.0003, position.shape)
    offsets = np.array([[0.3, -0.2, 0.1], [-0.3, -0.2, 0.1], [0.0, -0.25, -0.2]])
    markers = position[:, None, :] + offsets[None] * (1 + 0.02 * np.sin(arg))[:, None, None]
    return {
        "format": "saddlescope.result/1", "fps": fps, "gait": gait, "direction": "CCW",
        "period_s": 1.0 / f0, "window": {"start_s": 0.0, "duration_s": float(t.size / fps)},
        "saddle": {"t_s": t.tolist(), "position_m": position.tolist()},
        "markers": {"names": ["M1", "M2", "M3"], "position_m": markers.tolist()},
        "indicators": {"stride_frequency_hz": f0, "vel_x_avg_kmh": speed * 3.6},
        "quality": {"flags": []},
    }


def store_document(database_url: str, storage_dir: Path | str, ride_id: int, doc: dict, *,
                   code_version: str = "test") -> None:
    """Put a finished analysis in as the analyse stage does: result JSON in storage, row in the database."""
    from saddlescope.db.repositories import RideRepository
    from saddlescope.db.session import make_engine, make_session_factory, session_scope
    from saddlescope.services.results.documents import commit_result
    from saddlescope.storage import FileStorage

    engine = make_engine(database_url)
    try:
        sessions = make_session_factory(engine)
        with session_scope(sessions) as session:
            club_id = RideRepository(session).get(ride_id).club_id
        commit_result(sessions, FileStorage(storage_dir), club_id=club_id, ride_id=ride_id, job_id=None,
                      document=doc, code_version=code_version)
    finally:
        engine.dispose()
