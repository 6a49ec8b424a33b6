"""A job reads its ride's (rig's) rows once, into `RideJobInputs` / `RigInputs` (issue 34, part 3)."""

from __future__ import annotations

import json
import sys
import types
from pathlib import Path

import integration_services
import pytest
from sqlalchemy import event

from saddlescope.db.migrate import upgrade_to_head
from saddlescope.db.models import Job, Ride
from saddlescope.db.repositories import (
    ClubRepository,
    HorseRepository,
    RecordingRepository,
    ResultRepository,
    RideRepository,
    RiderRepository,
    RigRepository,
)
from saddlescope.db.session import session_factory_for, session_scope
from saddlescope.services.jobs import stages
from saddlescope.services.jobs.inputs import (
    ClipInput,
    HorseDetails,
    RideGone,
    RigGone,
    read_ride_job_inputs,
    read_rig_inputs,
)
from saddlescope.services.jobs.lifecycle import create_job
from saddlescope.services.jobs.runner import run_job
from saddlescope.services.rides.registration import register_bundle
from saddlescope.settings import load_settings
from saddlescope.storage import open_storage

BOARD = {"kind": "checkerboard", "inner_corners": [9, 6], "square_mm": 50.0}
CALIBRATION = {"cameras": {"left": {}, "middle": {}, "right": {}}, "n_views": 40, "board_coverage": 0.7}
ROLES = ("left", "middle", "right")


@pytest.fixture
def settings(tmp_path):
    s = load_settings(database_url=f"sqlite:///{tmp_path / 'db.sqlite'}", storage_dir=str(tmp_path / "storage"))
    upgrade_to_head(s.database_url)
    return s


@pytest.fixture
def sessions(settings):
    return session_factory_for(settings.database_url)


def _ride_of_clips(sessions, storage, *, calibrated: bool) -> tuple[int, int]:
    """A ride of uploaded motion and static clips on a rig with its calibration clips; (ride id, rig id)."""
    with session_scope(sessions) as s:
        club = ClubRepository(s).get_or_create("Clips club").id
        horse = HorseRepository(s, club_id=club).add(name="Bella", breed="KWPN", birth_year=2012,
                                                      height_withers_m=1.68).id
        rider = RiderRepository(s, club_id=club).add(name="Anna").id
        rigs = RigRepository(s, club_id=club)
        rig = rigs.add(name="Arena rig", board=dict(BOARD)).id
        if calibrated:
            rigs.set_calibration(rig, dict(CALIBRATION), {})
        ride = RideRepository(s, club_id=club).add(horse_id=horse, rider_id=rider, gait="rising_trot", direction="CW",
                                                   rig_id=rig, meta={"sync": {"method": "flash", "frames": 3}})
        recordings = RecordingRepository(s, club_id=club)
        for owner, kinds in (({"ride_id": ride.id}, ("static", "motion")), ({"rig_id": rig}, ("calibration",))):
            for kind in kinds:
                for role in ROLES:
                    key = f"clips/{kind}/{role}.avi"
                    storage.write_bytes(key, f"{kind} {role}".encode())
                    recordings.add(clip_kind=kind, camera_role=role, path=key, **owner)
        return ride.id, rig


def test_inputs_of_a_ride_of_clips(settings, sessions):
    ride_id, rig_id = _ride_of_clips(sessions, open_storage(settings), calibrated=True)
    inputs = read_ride_job_inputs(sessions, ride_id, job_id=7)
    assert (inputs.ride_id, inputs.gait, inputs.direction, inputs.bundle_key) == (ride_id, "rising_trot", "CW", None)
    assert inputs.analysed_settings == {"gait": "rising_trot", "direction": "CW"}
    assert inputs.horse == HorseDetails("Bella", "KWPN", 2012, 1.68) and inputs.rider_name == "Anna"
    assert inputs.sync == {"method": "flash", "frames": 3} and inputs.board is None and inputs.markers is None
    assert inputs.rig is not None and (inputs.rig.rig_id, inputs.rig.board) == (rig_id, BOARD)
    assert inputs.calibration == CALIBRATION
    assert inputs.rig.calibration_clips == {role: f"clips/calibration/{role}.avi" for role in ROLES}
    # the rig's calibration is stored: its clips are not carried into the ride
    assert inputs.clip_plan == {kind: {role: f"clips/{kind}/{role}.avi" for role in ROLES}
                                for kind in ("static", "motion")}
    assert [(c.clip_kind, c.camera_role) for c in inputs.clips] == [(k, r) for k in ("static", "motion") for r in ROLES]
    assert all(isinstance(c, ClipInput) and not c.probed for c in inputs.clips)
    with pytest.raises(AttributeError):
        inputs.gait = "walk"  # frozen


def test_inputs_of_an_uncalibrated_rig_plan_its_calibration_clips(settings, sessions):
    ride_id, _ = _ride_of_clips(sessions, open_storage(settings), calibrated=False)
    inputs = read_ride_job_inputs(sessions, ride_id, job_id=7)
    assert inputs.calibration is None
    assert inputs.require_clip_plan()["calibration"] == {role: f"clips/calibration/{role}.avi" for role in ROLES}


def test_inputs_of_a_bundle_ride(settings, sessions, tmp_path):
    bundle = integration_services.write_tiny_bundle(tmp_path / "bundle", gait="canter")
    ride_id = register_bundle(sessions, open_storage(settings), bundle, club_name="Bundle club",
                              chosen={"direction": "CW"})
    inputs = read_ride_job_inputs(sessions, ride_id, job_id=3)
    assert inputs.bundle_key == f"rides/{ride_id}/bundle" and inputs.rig is None and inputs.calibration is None
    assert inputs.analysed_settings == {"gait": "canter", "direction": "CW"}  # chosen at upload wins over ride.json
    assert inputs.horse == HorseDetails("Horse 2", "Dutch", 1999, 1.73) and inputs.rider_name == "Rider B"
    assert (inputs.board, inputs.sync, inputs.markers) == (BOARD, {"method": "flash"}, stages.DEFAULT_MARKERS)
    assert inputs.clip_plan is None and inputs.missing_clips is None
    assert len(inputs.clips) == 12 and all(c.key.startswith(f"{inputs.bundle_key}/") for c in inputs.clips)
    assert inputs.replaced_bundle_clips() == {}


def test_a_ride_or_rig_deleted_before_its_job_ran_is_named(settings, sessions):
    ride_id, rig_id = _ride_of_clips(sessions, open_storage(settings), calibrated=True)
    with session_scope(sessions) as s:
        RideRepository(s).delete(ride_id)
        RigRepository(s).delete(rig_id)
    with pytest.raises(RideGone, match=f"ride {ride_id} of job 9 no longer exists"):
        read_ride_job_inputs(sessions, ride_id, job_id=9)
    with pytest.raises(RigGone, match=f"rig {rig_id} of job 9 no longer exists"):
        read_rig_inputs(sessions, rig_id, job_id=9)


def test_a_job_whose_ride_is_gone_fails_with_the_reason(settings, sessions, monkeypatch):
    """The job row outlives its ride here (a stand-in reader): the stage's error names the ride."""
    ride_id, _ = _ride_of_clips(sessions, open_storage(settings), calibrated=True)
    with session_scope(sessions) as s:
        job_id = create_job(s, kind="probe", ride_id=ride_id).id
    real = read_ride_job_inputs
    monkeypatch.setattr("saddlescope.services.jobs.runner.read_ride_job_inputs",
                        lambda sessions, _ride_id, job_id: real(sessions, 10_000, job_id=job_id))
    assert run_job(job_id, settings=settings) == "failed"
    with sessions() as s:
        error = s.get(Job, job_id).error
    assert error == f"probe: ride 10000 of job {job_id} no longer exists (deleted after the job was queued)"


class _NoDatabase:
    """A sessionmaker a stage must not call: it reads its ride from the inputs it was given."""

    def __call__(self, *args, **kwargs):
        raise AssertionError("the stage opened a database session")


def _context(settings, inputs, stage: str, scratch: Path, sessions=None) -> stages.StageContext:
    return stages.StageContext(
        job_id=1, attempt=1, host="test:1", kind="analyze", stage=stage, club_id=inputs.club_id,
        ride_id=inputs.ride_id, rig_id=None, payload={}, settings=settings, storage=open_storage(settings),
        sessions=sessions or _NoDatabase(), report=lambda f, s=None: None, scratch=scratch,
        read_inputs=lambda: inputs)


def test_assemble_and_calibrate_read_only_their_inputs(settings, sessions, tmp_path):
    ride_id, _ = _ride_of_clips(sessions, open_storage(settings), calibrated=True)
    inputs = read_ride_job_inputs(sessions, ride_id, job_id=1)
    for stage in ("assemble", "calibrate"):
        stages.STAGES[stage].run(_context(settings, inputs, stage, tmp_path / "run"))
    folder = tmp_path / "run" / "stages" / "assemble" / stages.ASSEMBLED_BUNDLE
    doc = json.loads((folder / "ride.json").read_text())
    assert (doc["gait"], doc["direction"], doc["board"], doc["sync"]) == ("rising_trot", "CW", BOARD,
                                                                         {"method": "flash", "frames": 3})
    assert doc["horse"] == {"name": "Bella", "breed": "KWPN", "birth_year": 2012, "height_m": 1.68}
    assert doc["rider"] == {"name": "Anna"} and doc["markers"] == stages.DEFAULT_MARKERS
    assert doc["calibration_file"] == "calibration.json" and set(doc["clips"]) == {"static", "motion"}
    assert json.loads((folder / "calibration.json").read_text()) == CALIBRATION
    assert (folder / "motion" / "left.avi").read_bytes() == b"motion left"
    assert json.loads((tmp_path / "run" / "stages" / "calibrate" / "source.json").read_text())["reused"] is True


@pytest.fixture
def overrides_seen(monkeypatch):
    """A stand-in pipeline recording what it is given."""
    seen: list[dict] = []

    def analyze_bundle(path, on_progress=None, rig=None, rig_report=None, meta_overrides=None):
        seen.append({"path": path, "rig_report": rig_report, "meta_overrides": meta_overrides})
        return {"format": "saddlescope.result/1", "indicators": {"acc_y_wb_rms": 1.0}, "quality": {"ok": True}}

    module = types.ModuleType("saddlescope.services.analysis.ride_bundle")
    module.analyze_bundle = analyze_bundle
    monkeypatch.setitem(sys.modules, "saddlescope.services.analysis.ride_bundle", module)
    monkeypatch.setattr("saddlescope.services.rigs.calibration.rig_from_calibration", lambda c: "a rig")
    monkeypatch.setattr("saddlescope.services.results.documents.commit_result", lambda *a, **k: None)
    return seen


def _selects_of(sessions, tables: tuple[str, ...]) -> list[str]:
    """The SELECTs of `tables` this sessionmaker's engine runs from now on."""
    seen: list[str] = []

    def note(conn, cursor, statement, *args):
        words = statement.lower()
        if words.lstrip().startswith("select") and any(f"from {t}" in words for t in tables):
            seen.append(statement)

    event.listen(sessions.kw["bind"], "before_cursor_execute", note)
    return seen


def test_analyze_reads_no_ride_rig_or_recording_rows(settings, sessions, tmp_path, overrides_seen):
    bundle = integration_services.write_tiny_bundle(tmp_path / "bundle")
    ride_id = register_bundle(sessions, open_storage(settings), bundle, club_name="Bundle club")
    with session_scope(sessions) as s:  # edited after the upload: the ride's own settings go to the pipeline
        s.get(Ride, ride_id).gait = "rising_trot"
    inputs = read_ride_job_inputs(sessions, ride_id, job_id=1)
    selects = _selects_of(sessions, ("rides", "rigs", "recordings"))
    ctx = _context(settings, inputs, "analyze", tmp_path / "run", sessions=sessions)
    stages.run_analyze(ctx)
    # only the write of what the result was computed with reads the ride's row (to update its meta)
    assert len(selects) == 1, selects
    assert overrides_seen[0]["meta_overrides"] == {"gait": "rising_trot", "direction": "CCW"}
    with sessions() as s:
        assert dict(s.get(Ride, ride_id).meta)["_analysed_as"] == {"gait": "rising_trot", "direction": "CCW"}
        assert ResultRepository(s).for_ride(ride_id) is None  # commit_result was a stand-in


def test_analyze_uses_the_calibration_this_runs_calibrate_stage_stored(settings, sessions, tmp_path, overrides_seen):
    ride_id, rig_id = _ride_of_clips(sessions, open_storage(settings), calibrated=False)
    inputs = read_ride_job_inputs(sessions, ride_id, job_id=1)
    run = tmp_path / "run"
    (run / "stages" / "assemble" / stages.ASSEMBLED_BUNDLE).mkdir(parents=True)
    (run / "stages" / "assemble" / stages.ASSEMBLED_BUNDLE / "ride.json").write_text("{}")
    (run / "stages" / "calibrate").mkdir(parents=True)
    (run / "stages" / "calibrate" / "calibration.json").write_text(json.dumps(CALIBRATION))
    stages.run_analyze(_context(settings, inputs, "analyze", run, sessions=sessions))
    assert overrides_seen[0]["rig_report"] == {"n_views": 40, "board_coverage": 0.7}
    assert overrides_seen[0]["meta_overrides"] == {"gait": "rising_trot", "direction": "CW"}


def test_the_ride_shows_processing_from_the_transaction_that_starts_its_job(settings, sessions, monkeypatch):
    ride_id, _ = _ride_of_clips(sessions, open_storage(settings), calibrated=True)
    seen: list[str] = []

    def peek(ctx):
        with sessions() as s:
            seen.append(s.get(Ride, ride_id).status)

    monkeypatch.setitem(stages.STAGES, "peek", stages.Stage("peek", peek))
    monkeypatch.setitem(stages.JOB_KINDS, "analyze", stages.JobKind("analyze", ("peek",), needs_ride=True))
    with session_scope(sessions) as s:
        job_id = create_job(s, kind="analyze", ride_id=ride_id).id
    with sessions() as s:
        assert s.get(Ride, ride_id).status == "ready"
    assert run_job(job_id, settings=settings) == "done"
    assert seen == ["processing"]
    with sessions() as s:
        assert s.get(Ride, ride_id).status == "ready"  # done without a result: back to its clips' status
