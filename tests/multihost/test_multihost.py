"""Several hosts on one machine (issue 26, parts 5 and 6): the flow across hosts, and the drills.

A club uploads small rides to the API host; workers on two other hosts analyse them through the bucket
on the object-store host; the results are served. Counts are printed: rides submitted, results stored,
duplicates (0), lost rides (0). The set-up is `hosts.cluster` (network namespaces; see netns.py).
"""

from __future__ import annotations

import io
import json
import signal
import time
import zipfile
from pathlib import Path

import hosts
import integration_services
import netns
import pytest

cluster = hosts.cluster

pytestmark = [pytest.mark.integration, pytest.mark.slow]

JOB_TIMEOUT_S = 120.0


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

    def make() -> bytes:
        n = next(made)
        folder = tmp_path_factory.mktemp("bundle") / "ride"
        integration_services.write_tiny_bundle(folder)
        meta = json.loads((folder / "ride.json").read_text())
        meta["rider"]["name"] = f"Rider {n}"  # another rider: other bytes, another ride
        (folder / "ride.json").write_text(json.dumps(meta))
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
    counts = _counts(cluster, [ride_id for ride_id, _ in rides])
    _print_counts("flow", counts)
    # `ip netns exec` execs the worker, so its pid is the one recorded on the job (host:pid).
    assert pids <= worker_pids, (pids, worker_pids)
    assert counts["results stored"] == 4 and counts["duplicates"] == 0 and counts["lost rides"] == 0
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
    counts = _counts(cluster, [ride_id])
    _print_counts("drill (a) worker killed", counts)
    assert counts == {"rides submitted": 1, "results stored": 1, "duplicates": 0, "lost rides": 0}
    assert "queued again" in second.log_path.read_text()
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
    cluster.services["redis"] = netns.start_redis(cluster.network, "redis", cluster.root / "redis")
    jobs = [api.wait_job(job_id, timeout_s=JOB_TIMEOUT_S)[0] for _, job_id in rides]
    assert all(job["status"] == "done" for job in jobs), [(job["id"], job["status"], job["error"]) for job in jobs]
    after = _upload(api, new_bundle())  # the broker back: submissions are taken again
    assert api.wait_job(after[1], timeout_s=JOB_TIMEOUT_S)[0]["status"] == "done"
    counts = _counts(cluster, [ride_id for ride_id, _ in [*rides, after]])
    _print_counts("drill (c) broker restarted", counts)
    print(f"refused while the broker was down: 503 {reason!r}")
    assert counts == {"rides submitted": 5, "results stored": 5, "duplicates": 0, "lost rides": 0}
    http.close()


def _wait(condition, timeout_s: float, what: str, interval_s: float = 0.3):
    deadline = time.monotonic() + timeout_s
    while not (value := condition()):
        assert time.monotonic() < deadline, f"{what}: not within {timeout_s:.0f} s"
        time.sleep(interval_s)
    return value


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
    counts = _counts(cluster, rides)
    _print_counts("drill (e) PostgreSQL fail-over", counts)
    assert counts == {"rides submitted": 4, "results stored": 4, "duplicates": 0, "lost rides": 0}
    http.close()
