"""Issue 39 item 5: a ride's result is swapped atomically: during a re-analysis readers get the old or the
new result, never "not analysed" (the old document is deleted after the row points at the new one, and a
reader that read the row just before reads it again)."""

from __future__ import annotations

import threading

import integration_services
import pytest
from api_helpers import new_club, zip_folder
from engines import ENGINES, open_env
from integration_services import write_tiny_bundle

from saddlescope.db.repositories import ResultRepository
from saddlescope.db.session import session_factory_for
from saddlescope.services.results.documents import commit_result
from saddlescope.storage import open_storage

pg_database_url = integration_services.pg_database_url
redis_url = integration_services.redis_url

# Scaled down from the 10,000 reads over 20 re-analyses to keep the test short (same mechanism).
RE_ANALYSES = 20
READERS = 3


@pytest.fixture(scope="module", params=ENGINES)
def env(request, tmp_path_factory):
    yield from open_env(request, tmp_path_factory)


@pytest.fixture(scope="module")
def analysed(env, tmp_path_factory):
    api, account = new_club(env.client)
    data = zip_folder(write_tiny_bundle(tmp_path_factory.mktemp("swap") / "bundle"))
    created = api.ok("POST", "/rides/bundle", 201, files={"file": ("swap.zip", data, "application/zip")})
    assert api.wait_job(created["job_id"])[0]["status"] == "done"
    return api, created["ride"]["id"], account["club"]["id"]


def test_a_read_that_straddles_the_swap_answers_the_new_result(env, analysed, monkeypatch):
    """The interleaving of the 404, forced: a re-analysis commits (and deletes the old document) between
    the reader's read of the result row and its read of the document."""
    api, ride_id, club_id = analysed
    document = api.ok("GET", f"/rides/{ride_id}/export/json")
    sessions, storage = session_factory_for(env.settings.database_url), open_storage(env.settings)
    real_for_ride = ResultRepository.for_ride

    for path in (f"/rides/{ride_id}/result", f"/rides/{ride_id}/export/json"):
        marker = f"swapped under {path}"
        swapped: list[str] = []

        def for_ride_then_swap(self, ride, marker=marker, swapped=swapped):
            row = real_for_ride(self, ride)
            if not swapped and row is not None:
                swapped.append(row.result_key)  # before the swap: commit_result reads the row too
                commit_result(sessions, storage, club_id=club_id, ride_id=ride_id, job_id=None,
                              document={**document, "code_version": marker}, code_version=marker)
            return row

        monkeypatch.setattr(ResultRepository, "for_ride", for_ride_then_swap)
        response = api.get(path)
        monkeypatch.setattr(ResultRepository, "for_ride", real_for_ride)
        assert swapped and not storage.exists(swapped[0])  # the reader's key was deleted under it
        assert response.status_code == 200, response.text
    assert api.ok("GET", f"/rides/{ride_id}/export/json")["code_version"] == marker  # the newest one


def test_result_reads_during_repeated_re_analyses_never_miss(env, analysed):
    api, ride_id, _ = analysed
    answers: dict[int, int] = {}
    lock, finished = threading.Lock(), threading.Event()

    def read_until_finished() -> None:
        while not finished.is_set():
            code = api.get(f"/rides/{ride_id}/result").status_code
            with lock:
                answers[code] = answers.get(code, 0) + 1

    readers = [threading.Thread(target=read_until_finished) for _ in range(READERS)]
    for reader in readers:
        reader.start()
    try:
        for _ in range(RE_ANALYSES):
            job = api.ok("POST", f"/rides/{ride_id}/analyze", 201)
            assert api.wait_job(job["id"])[0]["status"] == "done"
    finally:
        finished.set()
        for reader in readers:
            reader.join()
    assert set(answers) == {200}, answers  # not one "ride has no result yet" (404) nor 500
    assert answers[200] >= RE_ANALYSES * 10, answers
