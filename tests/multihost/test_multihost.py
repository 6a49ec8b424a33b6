"""Several hosts on one machine (issue 26, parts 5 and 6): the flow across hosts, and the drills.

A club uploads small rides to the API host; workers on two other hosts analyse them through the bucket
on the object-store host; the results are served. Counts are printed: rides submitted, results stored,
duplicates (0), lost rides (0). The set-up is `hosts.cluster` (network namespaces; see netns.py).
"""

from __future__ import annotations

import io
import json
import os
import signal
import threading
import time
import zipfile
from pathlib import Path

import hosts
import httpx
import integration_services
import netns
import pytest

cluster = hosts.cluster

pytestmark = [pytest.mark.integration, pytest.mark.slow]

JOB_TIMEOUT_S = 120.0
REAL_PIPELINE_TIMEOUT_S = 900.0  # the real analysis of a 2.5 s ride with its calibration, on a loaded machine
tiny_ride = integration_services.tiny_ride  # the session fixture: a 2.5 s canter bundle folder


def _upload(api, bundle_zip: bytes) -> tuple[int, int]:
    created = api.ok("POST", "/rides/bundle", 201, files={"file": ("ride.zip", bundle_zip, "application/zip")})
    return created["ride"]["id"], created["job_id"]


def _counts(cluster, ride_ids: list[int]) -> dict[str, int]:
    """Rides submitted, results stored, duplicates and lost rides (no result), read from the primary."""
    rows = cluster.sql("SELECT ride_id, count(*) FROM results WHERE ride_id = ANY(:ids) GROUP BY ride_id",
                       ids=ride_ids)
    per_ride = dict(rows)
    return {"rides submitted": len(ride_ids), "results stored": sum(per_ride.values()),
            "duplicates": sum(n - 1 for n in per_ride.values() if n > 1),
            "lost rides": sum(1 for ride_id in ride_ids if ride_id not in per_ride)}


def _print_counts(what: str, counts: dict[str, int]) -> None:
    print(f"\nmulti-host {what}: " + ", ".join(f"{name} {n}" for name, n in counts.items()))


def _every_ride_once(cluster, what: str, ride_ids: list[int]) -> None:
    """Print the counts, then require one result per ride: no duplicate, no ride lost."""
    counts = _counts(cluster, ride_ids)
    _print_counts(what, counts)
    n = len(ride_ids)
    assert counts == {"rides submitted": n, "results stored": n, "duplicates": 0, "lost rides": 0}, counts


def zip_folder(folder: Path) -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_STORED) as archive:
        for file in sorted(p for p in folder.rglob("*") if p.is_file()):
            archive.write(file, file.relative_to(folder).as_posix())
    return buffer.getvalue()


@pytest.fixture(scope="module")
def new_bundle(tmp_path_factory):
    """`new_bundle()`: the zip of a tiny ride bundle unlike any other (an upload of the same bytes is refused)."""
    made = iter(range(10**6))

    def make(padding_bytes: int = 0) -> bytes:
        n = next(made)
        folder = tmp_path_factory.mktemp("bundle") / "ride"
        integration_services.write_tiny_bundle(folder)
        meta = json.loads((folder / "ride.json").read_text())
        meta["rider"]["name"] = f"Rider {n}"  # another rider: other bytes, another ride
        (folder / "ride.json").write_text(json.dumps(meta))
        if padding_bytes:  # a file ride.json does not name, to make the zip span several upload parts
            (folder / "padding.bin").write_bytes(os.urandom(padding_bytes))
        return zip_folder(folder)

    return make


def test_rides_uploaded_to_the_api_host_are_analysed_by_workers_on_two_other_hosts(cluster, new_bundle):
    for host in ("w1", "w2"):
        if host not in cluster.workers or cluster.workers[host].proc.poll() is not None:
            cluster.start_worker(host, delay_s=0.5)
    http = cluster.http()
    api, _ = integration_services.new_club(http)
    rides = [_upload(api, new_bundle()) for _ in range(4)]
    jobs = [api.wait_job(job_id, timeout_s=JOB_TIMEOUT_S)[0] for _, job_id in rides]
    assert all(job["status"] == "done" for job in jobs), [(job["id"], job["status"], job["error"]) for job in jobs]
    for ride_id, _ in rides:
        result = api.ok("GET", f"/rides/{ride_id}/result")
        assert result["indicators"], result
    pids = {job["host"].rpartition(":")[2] for job in jobs}
    worker_pids = {str(cluster.workers[host].proc.pid) for host in ("w1", "w2")}
    _every_ride_once(cluster, "flow", [ride_id for ride_id, _ in rides])
    # `ip netns exec` execs the worker, so its pid is the one recorded on the job (host:pid).
    assert pids <= worker_pids, (pids, worker_pids)
    http.close()


def test_a_real_ride_is_analysed_by_the_real_pipeline_on_a_worker_host(cluster, tiny_ride):
    """The drills run a stand-in analysis (they time their faults on it); this one ride goes through
    SaddleScope's own worker and every stage, its clips only in the bucket on the store's host."""
    cluster.stop_workers()
    worker = cluster.start_worker("w1", real=True)
    http = cluster.http()
    api, _ = integration_services.new_club(http)
    ride_id, job_id = _upload(api, zip_folder(tiny_ride))
    job, _ = api.wait_job(job_id, timeout_s=REAL_PIPELINE_TIMEOUT_S)
    assert job["status"] == "done", job["error"]
    assert job["host"] == f"w1:{worker.proc.pid}", job
    result = api.ok("GET", f"/rides/{ride_id}/result")
    truth = json.loads((tiny_ride / "truth.json").read_text())
    speed_kmh = result["indicators"]["vel_x_avg_kmh"]
    assert speed_kmh == pytest.approx(truth["indicators"]["vel_x_avg_kmh"], rel=0.02), (speed_kmh, truth)
    _every_ride_once(cluster, "real pipeline", [ride_id])
    cluster.stop_workers()
    http.close()


def _wait_running_in_analyze(api, job_id: int, timeout_s: float = 60.0) -> dict:
    deadline = time.monotonic() + timeout_s
    while True:
        job = api.ok("GET", f"/jobs/{job_id}")
        if job["status"] == "running" and (job["stage"] or "").startswith("analyze") and job["progress"] > 0.3:
            return job
        assert job["status"] in ("queued", "running") and time.monotonic() < deadline, (
            f"job {job_id} did not reach the middle of its analyze stage in {timeout_s:.0f} s: {job}")
        time.sleep(0.1)


def test_drill_a_worker_killed_mid_stage_its_job_completes_on_the_other_host(cluster, new_bundle):
    cluster.stop_workers()
    first = cluster.start_worker("w1", delay_s=8.0)
    http = cluster.http()
    api, _ = integration_services.new_club(http)
    ride_id, job_id = _upload(api, new_bundle())
    _wait_running_in_analyze(api, job_id)
    first.stop(kill=True)  # SIGKILL, mid-stage: no chance to report or clean up
    assert first.proc.returncode == -signal.SIGKILL
    stuck = api.ok("GET", f"/jobs/{job_id}")
    assert stuck["status"] == "running" and stuck["host"].endswith(f":{first.proc.pid}") and stuck["attempts"] == 1
    second = cluster.start_worker("w2", delay_s=1.0)
    job, _ = api.wait_job(job_id, timeout_s=JOB_TIMEOUT_S)
    assert job["status"] == "done", job["error"]
    assert job["attempts"] == 2 and job["host"].endswith(f":{second.proc.pid}"), job
    assert api.ok("GET", f"/rides/{ride_id}/result")["indicators"]
    _every_ride_once(cluster, "drill (a) worker killed", [ride_id])
    assert "queued again" in second.log_path.read_text()
    http.close()


def test_drill_b_a_worker_cut_off_and_healed_is_fenced_out_and_the_ride_keeps_one_result(cluster, new_bundle):
    cluster.stop_workers()
    w1_log = cluster.root / "w1" / "worker.log"
    log_from = w1_log.stat().st_size if w1_log.exists() else 0  # this test's part of w1's log
    first = cluster.start_worker("w1", delay_s=8.0)
    http = cluster.http()
    api, _ = integration_services.new_club(http)
    ride_id, job_id = _upload(api, new_bundle())
    _wait_running_in_analyze(api, job_id)
    cluster.network.link("w1", up=False)  # cut off mid-stage: its heartbeats and writes reach nobody
    try:
        second = cluster.start_worker("w2", delay_s=1.0)
        job, _ = api.wait_job(job_id, timeout_s=JOB_TIMEOUT_S)  # w2 finds it silent past the stale time
    finally:
        cluster.network.link("w1", up=True)  # healed: w1 carries on where it stood
    assert job["status"] == "done", job["error"]
    assert job["attempts"] == 2 and job["host"] == f"w2:{second.proc.pid}", job
    # Healed, w1's pending write reaches the database: either it is refused by the fence (logged), or its
    # connection was ended meanwhile (the server's idle-in-transaction timeout) and Celery retries the
    # task, whose claim finds the job done. Either way the checks below must hold.
    # TCP's retransmission back-off (up to 2 min between tries after a long cut) decides when that comes.
    refused = f"of attempt 1 on w1:{first.proc.pid} refused"
    retried = "Retry in"  # Celery's line for a task retried after the OperationalError

    def w1_says() -> str:
        return w1_log.read_bytes()[log_from:].decode(errors="replace")

    # Give it a minute; a write still held back then is fenced all the same (the checks below).
    deadline = time.monotonic() + 60
    while not any(line in w1_says() for line in (refused, retried)) and time.monotonic() < deadline:
        time.sleep(0.5)
    fenced_by = ("refused" if refused in w1_says() else "retried, claim refused" if retried in w1_says()
                 else "still held back by TCP after a minute")
    assert first.proc.poll() is None  # fenced out, not crashed: it takes other jobs again
    after = api.ok("GET", f"/jobs/{job_id}")
    assert (after["status"], after["attempts"], after["host"], after["error"]) == ("done", 2, job["host"], None)
    assert cluster.sql("SELECT job_attempt FROM results WHERE ride_id = :r", r=ride_id) == [(2,)]
    # w2's document is where its result row points, and w1 left no document of its own beside it
    listed = cluster.s3("list_objects_v2", Prefix=f"club-data/rides/{ride_id}/results/").get("Contents", [])
    # one result: its document, and the series and page derived from it beside it
    assert {o["Key"].rpartition("/")[2][:len(f"{job_id}-2-")] for o in listed} == {f"{job_id}-2-"}, listed
    assert len(listed) == 3, listed
    assert api.ok("GET", f"/rides/{ride_id}/result")["indicators"]
    print(f"the healed worker's late write: {fenced_by} (the job was taken over by another attempt)")
    _every_ride_once(cluster, "drill (b) worker cut off and healed", [ride_id])
    http.close()


def test_drill_c_the_broker_restarted_new_rides_get_503_and_nothing_is_lost(cluster, new_bundle):
    cluster.stop_workers()
    cluster.start_worker("w1", delay_s=2.0)
    cluster.start_worker("w2", delay_s=2.0)
    http = cluster.http()
    api, _ = integration_services.new_club(http)
    rides = [_upload(api, new_bundle()) for _ in range(4)]
    _wait_running_in_analyze(api, rides[0][1])
    redis = cluster.services["redis"]
    redis.stop()  # SIGTERM: Redis writes its append-only file and exits
    refused = api.request("POST", "/rides/bundle", files={"file": ("ride.zip", new_bundle(), "application/zip")})
    assert refused.status_code == 503, refused.text
    reason = refused.json()["detail"]
    assert "broker" in reason and "unreachable" in reason, reason
    assert api.ok("GET", "/rides")["total"] == len(rides)  # the refused bundle left no ride behind
    cluster.services["redis"] = netns.start_redis(cluster.network, "redis", cluster.root / "redis")
    jobs = [api.wait_job(job_id, timeout_s=JOB_TIMEOUT_S)[0] for _, job_id in rides]
    assert all(job["status"] == "done" for job in jobs), [(job["id"], job["status"], job["error"]) for job in jobs]
    after = _upload(api, new_bundle())  # the broker back: submissions are taken again
    assert api.wait_job(after[1], timeout_s=JOB_TIMEOUT_S)[0]["status"] == "done"
    print(f"refused while the broker was down: 503 {reason!r}")
    _every_ride_once(cluster, "drill (c) broker restarted", [ride_id for ride_id, _ in [*rides, after]])
    http.close()


def _wait(condition, timeout_s: float, what: str, interval_s: float = 0.3):
    deadline = time.monotonic() + timeout_s
    while not (value := condition()):
        assert time.monotonic() < deadline, f"{what}: not within {timeout_s:.0f} s"
        time.sleep(interval_s)
    return value


def _put(cluster, url: str, data: bytes) -> int:
    """PUT a part straight to the store (a pre-signed URL), from the client host."""
    return cluster.client.call(httpx.put, url, content=data, timeout=60).status_code


def _store_down_answer(response) -> str:
    """The reason of a 503 the API answers while the store is down (checked: 503, Retry-After)."""
    assert response.status_code == 503, response.text
    assert response.headers.get("Retry-After") == "10", response.headers
    reason = response.json()["detail"]
    assert reason.startswith("the file store is not answering") and "try again" in reason, reason
    return reason


def test_drill_d_the_store_stopped_during_an_upload_the_client_resumes_and_finishes(cluster, new_bundle):
    cluster.stop_workers()
    cluster.start_worker("w1", delay_s=0.5)
    http = cluster.http()
    api, _ = integration_services.new_club(http)
    data = new_bundle(padding_bytes=17 * 1024**2)  # two parts of the 16 MiB the API asks for
    upload = api.ok("POST", "/uploads", 201, json={"target": "bundle", "length_bytes": len(data),
                                                   "filename": "ride.zip"})
    assert (upload["transport"], upload["parts_total"]) == ("s3-parts", 2), upload
    upload_id, part = upload["id"], upload["part_bytes"]
    urls = api.ok("POST", f"/uploads/{upload_id}/parts", json={"numbers": [1, 2]})["urls"]
    assert _put(cluster, urls["1"], data[:part]) == 200
    cluster.services["s3"].stop()
    with pytest.raises(httpx.TransportError):  # the second part does not reach the store
        _put(cluster, urls["2"], data[part:])
    reason = _store_down_answer(api.get(f"/uploads/{upload_id}/parts"))  # "what arrived?": 503, the reason
    _store_down_answer(api.post(f"/uploads/{upload_id}/finalize"))
    cluster.restart_store()
    state = api.ok("GET", f"/uploads/{upload_id}/parts")
    assert [p["number"] for p in state["parts"]] == [1], state  # nothing lost: part 1 is still there
    assert _put(cluster, urls["2"], data[part:]) == 200  # resumed: only the missing part is sent
    outcome = api.ok("POST", f"/uploads/{upload_id}/finalize")
    job, _ = api.wait_job(outcome["job_id"], timeout_s=JOB_TIMEOUT_S)
    assert job["status"] == "done", job["error"]
    assert api.ok("GET", f"/rides/{outcome['ride_id']}/result")["indicators"]
    print(f"asked while the store was down: 503, Retry-After 10, {reason!r}")
    _every_ride_once(cluster, "drill (d) store stopped during an upload", [outcome["ride_id"]])
    http.close()


def test_drill_d_the_store_stopped_during_a_job_it_waits_with_the_reason_then_succeeds(cluster, new_bundle):
    cluster.stop_workers()
    cluster.start_worker("w1", delay_s=4.0)
    http = cluster.http()
    api, _ = integration_services.new_club(http)
    ride_id, job_id = _upload(api, new_bundle())
    _wait_running_in_analyze(api, job_id)  # its bundle fetched; its result not yet stored
    cluster.services["s3"].stop()
    try:
        waiting = _wait(lambda: (job := api.ok("GET", f"/jobs/{job_id}"))["status"] == "queued" and job, 60,
                        "the job put back in the queue while the store is down")
    finally:
        cluster.restart_store()
    assert waiting["error"].startswith("waiting to try again: analyze: the file store is not answering"), waiting
    job, _ = api.wait_job(job_id, timeout_s=JOB_TIMEOUT_S)
    assert job["status"] == "done" and job["error"] is None, job
    assert job["attempts"] >= 2, job
    assert api.ok("GET", f"/rides/{ride_id}/result")["indicators"]
    print(f"the job while the store was down: {waiting['status']}, {waiting['error']!r}; "
          f"done after {job['attempts']} attempts")
    _every_ride_once(cluster, "drill (d) store stopped during a job", [ride_id])
    http.close()


def _patch(api, upload_id: str, offset: int, content):
    return api.patch(f"/uploads/{upload_id}", content=content,
                     headers={"Upload-Offset": str(offset), "Content-Type": "application/offset+octet-stream"})


def test_an_api_replica_killed_mid_upload_the_client_resumes_on_the_other(cluster, new_bundle):
    cluster.stop_workers()
    cluster.start_worker("w1", delay_s=0.5)
    streamed = {"SADDLESCOPE_DIRECT_UPLOADS": "false"}  # the bytes pass through the replicas
    replicas = [cluster.start_api("api2", **streamed), cluster.start_api("api3", **streamed)]
    sender = netns.NetnsThread(cluster.network.ns("client"))  # sends the chunk that is cut short
    try:
        api1, _ = integration_services.new_club(cluster.http("api2", thread=sender))
        api2 = integration_services.Api(cluster.http("api3"))
        api2.headers = dict(api1.headers)  # one secret: a token of one replica is good on the other
        ride_id, job_id = _upload_across_a_killed_replica(api1, api2, replicas[0], new_bundle())
        job, _ = api2.wait_job(job_id, timeout_s=JOB_TIMEOUT_S)
        assert job["status"] == "done", job["error"]
        assert api2.ok("GET", f"/rides/{ride_id}/result")["indicators"]
    finally:
        for service in replicas:
            service.stop(kill=True)
            cluster.services.pop(service.host, None)
        sender.close()
    _every_ride_once(cluster, "replica killed mid-upload", [ride_id])


def _upload_across_a_killed_replica(api1, api2, first, data: bytes) -> tuple[int, int]:
    """A third of the bundle to replica 1; SIGKILL it while the next chunk arrives; the rest to replica 2."""
    upload = api1.ok("POST", "/uploads", 201, json={"target": "bundle", "length_bytes": len(data),
                                                    "filename": "ride.zip"})
    assert upload["transport"] == "stream", upload
    upload_id, third = upload["id"], len(data) // 3
    assert _patch(api1, upload_id, 0, data[:third]).status_code == 204
    arriving, killed = threading.Event(), threading.Event()

    def chunk():
        yield data[third:third + 4096]
        arriving.set()
        killed.wait(30)
        yield data[third + 4096:2 * third]

    # Sent on the client host's second thread (the httpx client itself, not `api1`, whose calls wait on it).
    headers = {**api1.headers, "Upload-Offset": str(third), "Content-Type": "application/offset+octet-stream"}
    in_flight = api1.client.thread.submit(api1.client.http.request, "PATCH", f"/api/uploads/{upload_id}",
                                          content=chunk(), headers=headers)
    assert arriving.wait(30)
    first.stop(kill=True)  # SIGKILL with the chunk half sent
    killed.set()
    with pytest.raises(httpx.TransportError):
        in_flight.result(timeout=60)
    resume = api2.request("HEAD", f"/uploads/{upload_id}")
    assert resume.status_code == 200 and int(resume.headers["Upload-Offset"]) == third  # the cut chunk: not kept
    assert _patch(api2, upload_id, third, data[third:]).status_code == 204
    outcome = api2.ok("POST", f"/uploads/{upload_id}/finalize")
    print(f"\nreplica 1 killed at byte {third + 4096} of {len(data)}; replica 2 resumed from {third}")
    return outcome["ride_id"], outcome["job_id"]


def test_drill_e_postgresql_primary_stopped_and_a_replica_promoted_loses_no_ride(cluster, new_bundle):
    """The last drill of the module: from here on the primary is `pg2`."""
    cluster.stop_workers()
    cluster.services["pg2"] = netns.start_replica(cluster.network, "pg2", cluster.pg_root / "pg2", "pg")
    cluster.start_worker("w1", delay_s=0.5)
    http = cluster.http()
    api, _ = integration_services.new_club(http)
    done = [_upload(api, new_bundle()) for _ in range(2)]
    for _, job_id in done:
        assert api.wait_job(job_id, timeout_s=JOB_TIMEOUT_S)[0]["status"] == "done"
    cluster.stop_workers()
    waiting = _upload(api, new_bundle())  # queued, no worker: it must survive the fail-over
    _wait(lambda: cluster.sql("SELECT count(*) FROM pg_stat_replication WHERE replay_lsn >= pg_current_wal_lsn()")
          == [(1,)], 60, "the replica catching up with the primary")
    cluster.services["pg"].stop()  # the primary goes away (fast shutdown)
    netns.promote(cluster.pg_root / "pg2")
    assert cluster.sql("SELECT pg_is_in_recovery()", host="pg2") == [(False,)]
    cluster.pg_host = "pg2"
    cluster.services["api"].stop()
    cluster.start_api()  # the API pointed at the new primary
    cluster.start_worker("w1", delay_s=0.5)
    cluster.start_worker("w2", delay_s=0.5)
    assert api.wait_job(waiting[1], timeout_s=JOB_TIMEOUT_S)[0]["status"] == "done"
    after = _upload(api, new_bundle())  # a token signed before the fail-over still works: same secret, same rows
    assert api.wait_job(after[1], timeout_s=JOB_TIMEOUT_S)[0]["status"] == "done"
    rides = [ride_id for ride_id, _ in [*done, waiting, after]]
    for ride_id in rides:
        assert api.ok("GET", f"/rides/{ride_id}/result")["indicators"]
    _every_ride_once(cluster, "drill (e) PostgreSQL fail-over", rides)
    http.close()
