"""The real pipeline end to end through the API, once per engine, on a tiny synthetic ride: the indicators
served equal those of `saddlescope analyze` on the same bundle.

Embedded: SQLite and the server's own process pool, the ride uploaded as a zip bundle.
Celery: PostgreSQL, Redis and a real worker; the ride uploaded clip by clip with a rig whose calibration
is computed once from the rig's calibration clips and handed to the analysis as ``rig=``.

Should `saddlescope analyze` itself fail on the tiny ride, both tests fail with its message.
"""

from __future__ import annotations

import datetime as dt
import json
import subprocess
import types
import typing

import integration_services
import pytest
from api_helpers import new_club, zip_folder
from fastapi.testclient import TestClient
from pydantic import BaseModel

from conftest import PROJECT_ROOT
from saddlescope.api import create_app
from saddlescope.api.schemas import ResultOut
from saddlescope.db.migrate import upgrade_to_head
from saddlescope.services.results.documents import view_of_document
from saddlescope.settings import load_settings

pg_database_url = integration_services.pg_database_url
redis_url = integration_services.redis_url
tiny_ride = integration_services.tiny_ride

pytestmark = pytest.mark.slow
PIPELINE_TIMEOUT_S = 900.0


@pytest.fixture(scope="module")
def reference(tiny_ride, tmp_path_factory) -> dict:
    """``saddlescope analyze RIDE --json OUT`` on the tiny ride (the command line, as a user runs it)."""
    out = tmp_path_factory.mktemp("reference") / "result.json"
    done = subprocess.run(
        [str(integration_services.VENV_BIN / "saddlescope"), "analyze", str(tiny_ride), "--json", str(out)],
        capture_output=True,
        text=True,
        timeout=PIPELINE_TIMEOUT_S,
        cwd=PROJECT_ROOT,
    )
    if done.returncode != 0:
        reason = (done.stderr.strip().splitlines() or ["no message"])[-1]
        pytest.fail(f"`saddlescope analyze` fails on the tiny ride: {reason}")
    return json.loads(out.read_text())


def same_indicators(served: dict, expected: dict) -> None:
    assert set(served) == set(expected)
    for key, value in expected.items():
        # rel 1e-5: two runs of `saddlescope analyze` on one bundle differ by ~4e-7 (not bit for bit)
        assert served[key] == pytest.approx(value, rel=1e-5, abs=1e-9), key


def _nested_model(annotation) -> type[BaseModel] | None:
    """The pydantic model a field holds (also inside ``Model | None``), or None."""
    for candidate in (annotation, *typing.get_args(annotation)):
        if isinstance(candidate, type) and not typing.get_args(candidate) and issubclass(candidate, BaseModel):
            return candidate
    return None


def shape_mismatches(view: dict, model: type[BaseModel], where: str) -> list[str]:
    """Keys of `view` that `model` does not declare and fields of `model` that `view` lacks, recursively
    into the nested objects the model declares as models."""
    fields = model.model_fields
    problems = [f"{where}.{key}: in the view, not in {model.__name__}" for key in sorted(set(view) - set(fields))]
    problems += [f"{where}.{key}: in {model.__name__}, not in the view" for key in sorted(set(fields) - set(view))]
    for name, field in fields.items():
        nested = _nested_model(field.annotation)
        if nested is not None and isinstance(view.get(name), dict):
            problems += shape_mismatches(view[name], nested, f"{where}.{name}")
    return problems


def test_the_view_of_a_real_result_has_exactly_the_schemas_fields(reference):
    """The view is built in services/results/documents.py, its schema declared in api/schemas.py: adding a key to one
    and not the other fails here (the real document has every optional series)."""
    row = types.SimpleNamespace(job_id=7, code_version="test", created_at=dt.datetime.now(dt.UTC))
    view = view_of_document(reference, row, ride_id=3, max_points=50)
    assert shape_mismatches(view, ResultOut, "ResultOut") == []
    ResultOut.model_validate(view)  # and the values have the declared types


def test_embedded_bundle_upload_with_the_real_pipeline(reference, tiny_ride, tmp_path):
    settings = load_settings(
        database_url=f"sqlite:///{tmp_path / 'db.sqlite'}", storage_dir=str(tmp_path / "storage")
    )
    with TestClient(create_app(settings)) as client:  # the real embedded process pool
        api, _ = new_club(client)
        created = api.ok(
            "POST",
            "/rides/bundle",
            201,
            files={"file": ("ride.zip", zip_folder(tiny_ride), "application/zip")},
        )
        job, _ = api.wait_job(created["job_id"], timeout_s=PIPELINE_TIMEOUT_S)
        assert job["status"] == "done", job["error"]
        result = api.ok("GET", f"/rides/{created['ride']['id']}/result")
    same_indicators(result["indicators"], reference["indicators"])
    assert result["period_s"] == pytest.approx(reference["period_s"])


@pytest.mark.integration
def test_celery_clip_uploads_with_a_rig_calibrated_once(
    request, reference, tiny_ride, tmp_path, pg_database_url, redis_url
):
    upgrade_to_head(pg_database_url)
    settings = load_settings(
        database_url=pg_database_url,
        broker_url=redis_url,
        storage_dir=str(tmp_path / "storage"),
        secret_key=integration_services.TEST_SECRET,
    )
    meta = json.loads((tiny_ride / "ride.json").read_text())
    with (
        integration_services.run_celery_worker(
            database_url=pg_database_url,
            broker_url=redis_url,
            storage_dir=tmp_path / "storage",
            log_path=tmp_path / "worker.log",
            config=request.config,
        ),
        TestClient(create_app(settings, open_registration=True)) as client,
    ):
        api, _ = new_club(client)
        rig = api.ok("POST", "/rigs", 201, json={"name": "Tiny rig", "board": meta["board"]})

        def put(owner: str, owner_id: int, kind: str, camera: str) -> dict:
            path = tiny_ride / meta["clips"][kind][camera]
            return api.ok(
                "PUT",
                f"/{owner}/{owner_id}/clips/{kind}/{camera}",
                files={"file": (path.name, path.read_bytes())},
            )

        calibrate_job = [
            put("rigs", rig["id"], "calibration", c)["job_id"] for c in ("left", "middle", "right")
        ][-1]
        job, _ = api.wait_job(calibrate_job, timeout_s=PIPELINE_TIMEOUT_S)
        assert job["status"] == "done", job["error"]
        for kind in ("plumb", "static"):
            for camera in ("left", "middle", "right"):
                put("rigs", rig["id"], kind, camera)
        horse = api.ok("POST", "/horses", 201, json={"name": meta["horse"]["name"]})
        rider = api.ok("POST", "/riders", 201, json={"name": meta["rider"]["name"]})
        ride = api.ok(
            "POST",
            "/rides",
            201,
            json={
                "horse_id": horse["id"],
                "rider_id": rider["id"],
                "rig_id": rig["id"],
                "gait": meta["gait"],
                "direction": meta["direction"],
                "meta": {"markers": meta.get("markers")},
            },
        )
        analyze_job = [put("rides", ride["id"], "motion", c)["job_id"] for c in ("left", "middle", "right")][
            -1
        ]
        job, _ = api.wait_job(analyze_job, timeout_s=PIPELINE_TIMEOUT_S)
        assert job["status"] == "done", job["error"]
        assert job["timings_s"]["calibrate"] < 5  # reused: the rig was calibrated by its own job
        result = api.ok("GET", f"/rides/{ride['id']}/result")
    same_indicators(result["indicators"], reference["indicators"])
