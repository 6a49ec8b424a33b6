"""The job body shared by Celery and the embedded pool, run in-process on SQLite."""

from __future__ import annotations

import json
import sys
import threading
import time
import types

import integration_services
import numpy as np
import pytest

from saddlescope.core.errors import SaddleScopeError
from saddlescope.db.migrate import upgrade_to_head
from saddlescope.db.models import Job, Recording, Ride
from saddlescope.db.repositories import JobRepository, NotFound, ResultRepository
from saddlescope.db.session import session_factory_for, session_scope
from saddlescope.demo import DemoError, ensure_demo_bundle, run_demo
from saddlescope.services.jobs import stages
from saddlescope.services.jobs.lifecycle import create_job, submit_job
from saddlescope.services.jobs.queue import InlineQueue
from saddlescope.services.jobs.runner import run_job
from saddlescope.services.rides.registration import register_bundle
from saddlescope.settings import load_settings
from saddlescope.storage import open_storage

FAKE_INDICATORS = {
    "acc_y_wb_rms": 2.79,
    "acc_y_wk_rms": 2.9,
    "vdv_y_wb": 5.1,
    "vdv_y_wk": 5.3,
    "vel_x_avg_kmh": 19.7,
    "amplitude_y_m": 0.08,
    "stride_frequency_hz": 1.7,
}


@pytest.fixture
def settings(tmp_path):
    s = load_settings(
        database_url=f"sqlite:///{tmp_path / 'db.sqlite'}", storage_dir=str(tmp_path / "storage")
    )
    upgrade_to_head(s.database_url)
    return s


@pytest.fixture
def sessions(settings):
    return session_factory_for(settings.database_url)


@pytest.fixture
def ride_id(settings, sessions, tmp_path):
    bundle = integration_services.write_tiny_bundle(tmp_path / "bundle")
    return register_bundle(sessions, open_storage(settings), bundle, club_name="Test club")


@pytest.fixture
def fake_analysis(monkeypatch):
    """A stand-in for saddlescope.services.analysis.ride_bundle (the lead's pipeline), recording its calls."""
    calls = []

    def analyze_bundle(path, on_progress=None, rig=None, rig_report=None, meta_overrides=None):
        calls.append(path)
        assert (path / "ride.json").is_file()
        for stage_name in ("calibrate", "triangulate", "indicators"):
            on_progress(0.5, stage_name)
        return {
            "format": "saddlescope.result/1",
            "indicators": dict(FAKE_INDICATORS),
            "quality": {"ok": True},
            "saddle": {"t_s": [0.0, 0.1, 0.2], "position_m": [[0, 0, 0], [1, 0, 0], [2, 0, 0]]},
            "angular": {"omega_rad_s": [[0, 0, 1]] * 3},
        }

    module = types.ModuleType("saddlescope.services.analysis.ride_bundle")
    module.analyze_bundle = analyze_bundle
    monkeypatch.setitem(sys.modules, "saddlescope.services.analysis.ride_bundle", module)
    return calls


def add_job(sessions, **kwargs) -> int:
    with session_scope(sessions) as s:
        return create_job(s, **kwargs).id


def job_row(sessions, job_id) -> Job:
    with sessions() as s:
        return s.get(Job, job_id)


def test_selftest_job_records_progress_timings_and_provenance(settings, sessions):
    job_id = add_job(sessions, kind="selftest", payload={"steps": 3, "delay_s": 0.0})
    assert run_job(job_id, settings=settings) == "done"
    job = job_row(sessions, job_id)
    assert (job.status, job.progress, job.attempts, job.error) == ("done", 1.0, 1, None)
    assert set(job.timings) == {"selftest", "total"} and job.timings["total"] >= job.timings["selftest"] >= 0
    assert job.host and job.code_version.startswith("0.")
    assert job.started_at <= job.finished_at


def test_a_finished_job_is_not_run_again(settings, sessions):
    job_id = add_job(sessions, kind="selftest", payload={"steps": 1, "delay_s": 0.0})
    run_job(job_id, settings=settings)
    finished_at = job_row(sessions, job_id).finished_at
    assert run_job(job_id, settings=settings) == "done"  # a redelivered task
    job = job_row(sessions, job_id)
    assert (job.attempts, job.finished_at) == (1, finished_at)


def test_a_failing_stage_fails_the_job_with_its_message(settings, sessions):
    job_id = add_job(sessions, kind="selftest", payload={"steps": 1, "delay_s": 0.0, "fail": True})
    assert run_job(job_id, settings=settings) == "failed"
    job = job_row(sessions, job_id)
    assert job.status == "failed"
    assert job.error == f"selftest: selftest job {job_id} failed on request (payload fail=true)"
    assert "selftest" in job.timings


def test_bad_payloads_and_kinds_are_refused_before_queueing(sessions):
    with pytest.raises(SaddleScopeError, match="steps must be an integer from 1 to 1000"):
        add_job(sessions, kind="selftest", payload={"steps": "many"})
    with pytest.raises(
        SaddleScopeError,
        match="unknown job kind 'fly'; known kinds: analyze, calibrate_rig, check_calibration, probe, selftest",
    ):
        add_job(sessions, kind="fly")
    with pytest.raises(NotFound, match="ride 12345 not found"):
        add_job(sessions, kind="probe", ride_id=12345)
    with pytest.raises(SaddleScopeError, match="needs a ride_id"):
        add_job(sessions, kind="analyze")


def test_a_job_of_a_kind_this_worker_does_not_know_fails_clearly(settings, sessions):
    with session_scope(sessions) as s:
        job_id = JobRepository(s).add(kind="from-the-future").id
    assert run_job(job_id, settings=settings) == "failed"
    assert "unknown job kind 'from-the-future'" in job_row(sessions, job_id).error


def test_cancelling_stops_a_running_job_at_its_next_progress_report(settings, sessions, monkeypatch):
    monkeypatch.setattr("saddlescope.services.jobs.runner.PROGRESS_INTERVAL_S", 0.0)
    job_id = add_job(sessions, kind="selftest", payload={"steps": 200, "delay_s": 0.01})
    outcome = {}
    thread = threading.Thread(target=lambda: outcome.update(status=run_job(job_id, settings=settings)))
    thread.start()
    deadline = time.monotonic() + 20
    while job_row(sessions, job_id).progress < 0.05 and time.monotonic() < deadline:
        time.sleep(0.02)
    with session_scope(sessions) as s:
        assert JobRepository(s).request_cancel(job_id)
    thread.join(timeout=20)
    job = job_row(sessions, job_id)
    assert outcome["status"] == "cancelled" and job.status == "cancelled"
    assert 0.05 <= job.progress < 0.9


def test_probe_records_each_clips_size_checksum_and_format(settings, sessions, ride_id):
    storage = open_storage(settings)
    job_id = add_job(sessions, kind="probe", ride_id=ride_id)
    assert run_job(job_id, settings=settings) == "done", job_row(sessions, job_id).error
    with sessions() as s:
        recordings = s.query(Recording).filter_by(ride_id=ride_id).all()
    assert len(recordings) == 12
    for rec in recordings:
        assert (rec.fps, rec.frame_count, rec.width, rec.height) == (30.0, 5, 64, 48), rec.path
        assert rec.probed_at is not None and rec.size_bytes > 0
        if rec.clip_kind != "plumb":  # plumb clips are image folders: a digest of the tree
            assert rec.sha256 == storage.sha256(rec.path)
    assert job_row(sessions, job_id).timings["probe"] > 0


def test_probe_names_a_clip_missing_from_storage(settings, sessions, ride_id):
    with sessions() as s:
        key = (
            s.query(Recording).filter_by(ride_id=ride_id, clip_kind="static", camera_role="middle").one().path
        )
    open_storage(settings).delete(key)
    job_id = add_job(sessions, kind="probe", ride_id=ride_id)
    assert run_job(job_id, settings=settings) == "failed"
    assert job_row(sessions, job_id).error == (
        f"probe: ride {ride_id}: static clip of the middle camera is missing from storage ({key})"
    )


def test_analyze_stores_the_result_and_rerunning_replaces_it(settings, sessions, ride_id, fake_analysis):
    storage = open_storage(settings)
    first = add_job(sessions, kind="analyze", ride_id=ride_id)
    assert run_job(first, settings=settings) == "done", job_row(sessions, first).error
    assert set(job_row(sessions, first).timings) == {"probe", "assemble", "calibrate", "analyze", "total"}
    with sessions() as s:
        result = ResultRepository(s).for_ride(ride_id)
        assert s.get(Ride, ride_id).status == "analysed"
    assert result.acc_y_wb_rms == pytest.approx(2.79) and result.vel_x_avg_kmh == pytest.approx(19.7)
    assert json.loads(storage.read_bytes(result.result_key))["indicators"] == FAKE_INDICATORS
    served = json.loads(storage.read_bytes(result.result_key))["saddle"]["position_m"]
    np.testing.assert_array_equal(np.asarray(served)[:, 0], [0, 1, 2])
    assert not list(storage.root.rglob("*.npz"))  # arrays.npz is not written: nothing reads it
    second = add_job(sessions, kind="analyze", ride_id=ride_id)
    assert run_job(second, settings=settings) == "done"
    with sessions() as s:
        again = ResultRepository(s).for_ride(ride_id)
    assert (again.id, again.job_id) == (result.id, second)
    assert len(fake_analysis) == 2


def test_analyze_without_the_pipeline_fails_clearly(settings, sessions, ride_id, monkeypatch):
    monkeypatch.setitem(sys.modules, "saddlescope.services.analysis.ride_bundle", None)
    job_id = add_job(sessions, kind="analyze", ride_id=ride_id)
    assert run_job(job_id, settings=settings) == "failed"
    assert (
        "analysis pipeline (saddlescope.services.analysis.ride_bundle) is not part of this installation"
        in job_row(sessions, job_id).error
    )
    with sessions() as s:
        assert s.get(Ride, ride_id).status == "failed"


def test_an_internal_error_is_recorded_and_reraised(settings, sessions, monkeypatch):
    def broken(ctx):
        raise ZeroDivisionError("a bug")

    monkeypatch.setitem(stages.STAGES, "broken", stages.Stage("broken", broken))
    monkeypatch.setitem(stages.JOB_KINDS, "broken", stages.JobKind("broken", ("broken",)))
    job_id = add_job(sessions, kind="broken")
    with pytest.raises(ZeroDivisionError):
        run_job(job_id, settings=settings)
    assert job_row(sessions, job_id).error == "broken: internal error (ZeroDivisionError: a bug)"


def test_stage_registry_refuses_unknown_stages():
    with pytest.raises(ValueError, match="unregistered stage"):
        stages.define_job_kind(stages.JobKind("nope", ("selftest", "no-such-stage")))


def test_inline_queue_runs_a_submitted_job(settings, sessions):
    job_id = submit_job(sessions, InlineQueue(settings), kind="selftest", payload={"steps": 2, "delay_s": 0})
    assert job_row(sessions, job_id).status == "done"


def test_demo_prints_the_indicators(settings, tmp_path, fake_analysis, capsys):
    bundle = integration_services.write_tiny_bundle(tmp_path / "demo-ride")
    status = run_demo(serve=False, settings=settings, bundle=bundle, queue=InlineQueue(settings))
    captured = capsys.readouterr()
    assert status == 0, captured.err
    assert json.loads(captured.out) == FAKE_INDICATORS
    # a second demo reuses the registered ride instead of copying the bundle again
    assert run_demo(serve=False, settings=settings, bundle=bundle, queue=InlineQueue(settings)) == 0
    with session_factory_for(settings.database_url)() as s:
        assert s.query(Ride).count() == 1


def test_demo_explains_a_missing_synthetic_ride_writer(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "saddlescope.io.synth_writer", None)
    with pytest.raises(DemoError, match="synth_writer .* is not part of this installation"):
        ensure_demo_bundle(tmp_path / "no-ride")
