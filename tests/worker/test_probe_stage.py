"""The probe stage reads a clip once: a clip probed and hashed before (at upload, or by an earlier job)
is not decoded or hashed again while its size is unchanged (issue 28)."""

from __future__ import annotations

from pathlib import Path

import integration_services
import pytest

from saddlescope.db.migrate import upgrade_to_head
from saddlescope.db.models import Job, Recording
from saddlescope.db.session import session_factory_for, session_scope
from saddlescope.services.jobs.lifecycle import create_job
from saddlescope.services.jobs.runner import run_job
from saddlescope.services.rides.registration import register_bundle
from saddlescope.settings import load_settings
from saddlescope.storage import FileStorage as Storage


@pytest.fixture
def probed_ride(tmp_path):
    settings = load_settings(database_url=f"sqlite:///{tmp_path / 'db.sqlite'}",
                             storage_dir=str(tmp_path / "storage"))
    upgrade_to_head(settings.database_url)
    sessions = session_factory_for(settings.database_url)
    bundle = integration_services.write_tiny_bundle(tmp_path / "bundle")
    ride_id = register_bundle(sessions, Storage(settings.storage_dir), bundle, club_name="Test club")
    first = _probe_job(sessions, ride_id)
    assert run_job(first, settings=settings) == "done"
    return settings, sessions, ride_id


def _probe_job(sessions, ride_id) -> int:
    with session_scope(sessions) as s:
        return create_job(s, kind="probe", ride_id=ride_id).id


def test_a_probed_clip_is_not_decoded_or_hashed_again(probed_ride, monkeypatch):
    settings, sessions, ride_id = probed_ride
    read: list[str] = []
    import saddlescope.io.video as video

    real_probe = video.probe_video
    monkeypatch.setattr(video, "probe_video", lambda path, **kw: read.append(str(path)) or real_probe(path, **kw))
    import saddlescope.services.jobs.stages as stages

    real_sha = stages.sha256_file
    monkeypatch.setattr(stages, "sha256_file", lambda path: read.append(str(path)) or real_sha(path))
    job_id = _probe_job(sessions, ride_id)
    assert run_job(job_id, settings=settings) == "done"
    with sessions() as s:
        videos = [r for r in s.query(Recording).filter_by(ride_id=ride_id).all() if r.clip_kind != "plumb"]
        plumb_folders = s.query(Recording).filter_by(ride_id=ride_id, clip_kind="plumb").count()
        assert s.get(Job, job_id).status == "done"
    # only the image folders (plumb: no upload checksum to reuse) are read again: no video file is
    # fetched, hashed or probed
    assert len(read) == plumb_folders and all(Path(p).suffix == "" for p in read)
    read.clear()
    # a clip whose bytes changed since (its size differs) is read again: hashed and probed
    storage = Storage(settings.storage_dir)
    changed = storage.path(videos[0].path)
    changed.write_bytes(changed.read_bytes() + b"\0" * 16)
    assert run_job(_probe_job(sessions, ride_id), settings=settings) in ("done", "failed")
    again = [p for p in read if Path(p).suffix]
    assert [Path(p).name for p in again] == [changed.name, changed.name]
