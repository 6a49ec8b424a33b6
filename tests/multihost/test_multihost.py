"""Several hosts on one machine (issue 26, parts 5 and 6): the flow across hosts, and the drills.

A club uploads small rides to the API host; workers on two other hosts analyse them through the bucket
on the object-store host; the results are served. Counts are printed: rides submitted, results stored,
duplicates (0), lost rides (0). The set-up is `hosts.cluster` (network namespaces; see netns.py).
"""

from __future__ import annotations

import io
import zipfile
from pathlib import Path

import hosts
import integration_services
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
        return zip_folder(integration_services.write_tiny_bundle(folder, frames=5 + n))

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
