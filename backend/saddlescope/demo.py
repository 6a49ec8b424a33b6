"""`saddlescope demo`: the main job on the embedded default, from nothing to indicators.

1. make a synthetic ride under ``./var/demo/ride`` if none exists,
2. register it as a ride (club "Demo club") unless it already is,
3. submit an ``analyze`` job through `saddlescope.services.jobs.queue.submit` and wait for it,
4. print the indicators as JSON (``--no-serve``) or serve the dashboard.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import TextIO

from saddlescope.core.errors import SaddleScopeError
from saddlescope.db.migrate import upgrade_to_head
from saddlescope.db.repositories import ClubRepository, ResultRepository, RideRepository
from saddlescope.db.session import session_factory_for, session_scope
from saddlescope.services.jobs.lifecycle import submit_job, wait_for_job
from saddlescope.services.jobs.queue import JobQueue, make_queue
from saddlescope.services.rides.registration import register_bundle
from saddlescope.settings import Settings, get_settings
from saddlescope.storage import Storage, open_storage

DEMO_BUNDLE = Path("var/demo/ride")
DEMO_CLUB = "Demo club"
# The embedded demo's sign-in, printed when the dashboard starts (never created with a broker set).
DEMO_EMAIL = "demo@saddlescope.example"
DEMO_PASSWORD = "saddlescope-demo"


class DemoError(SaddleScopeError):
    """The demo cannot run (a part of SaddleScope is missing, or the job failed)."""


def ensure_demo_bundle(path: Path = DEMO_BUNDLE) -> Path:
    """The synthetic demo ride at `path`, written on first use (canter, seed 1, thesis rig)."""
    if (path / "ride.json").is_file():
        return path
    try:
        from saddlescope.io.synth_writer import write_ride_bundle
    except ImportError as exc:
        if exc.name not in ("saddlescope.io.synth_writer",):
            raise
        raise DemoError("cannot make the demo ride: saddlescope.io.synth_writer (the synthetic ride "
                        "writer) is not part of this installation yet") from None
    path.parent.mkdir(parents=True, exist_ok=True)
    written = write_ride_bundle(path, gait="canter", seed=1, rig="thesis", size=None, fps=None,
                                duration_s=None)
    return Path(written) if written is not None else path


def ensure_demo_user(sessions) -> bool:
    """An admin of the demo club to sign in to the dashboard with; True if it exists now."""
    from saddlescope.db.repositories import UserRepository
    from saddlescope.services.accounts.users import add_user

    with session_scope(sessions) as session:
        club = ClubRepository(session).get_or_create(DEMO_CLUB)
        if UserRepository(session).by_email(DEMO_EMAIL) is None:
            add_user(session, club_id=club.id, email=DEMO_EMAIL, password=DEMO_PASSWORD,
                     display_name="Demo", role="admin")
    return True


def _demo_ride_id(sessions, storage: Storage, bundle: Path) -> int:
    """The demo club's ride registered from `bundle` earlier, or a newly registered one."""
    with session_scope(sessions) as session:
        club = ClubRepository(session).get_or_create(DEMO_CLUB)
        ride_id = RideRepository(session).latest_with_bundle(club.id)
    if ride_id is not None and storage.exists(f"rides/{ride_id}/bundle/ride.json"):
        return ride_id
    return register_bundle(sessions, storage, bundle, club_name=DEMO_CLUB)


def run_demo(serve: bool = True, host: str = "127.0.0.1", port: int = 8000, *,
             settings: Settings | None = None, bundle: Path = DEMO_BUNDLE, queue: JobQueue | None = None,
             stdout: TextIO | None = None, stderr: TextIO | None = None) -> int:
    """Process the demo ride; then print its indicators (``serve=False``) or serve the dashboard.

    Returns the exit status (0 on success, 1 when the analysis job failed). `queue` defaults to the
    one the settings ask for (`saddlescope.services.jobs.queue.make_queue`).
    """
    stdout = stdout or sys.stdout
    stderr = stderr or sys.stderr
    if serve:  # before minutes of analysis: a taken port is said at once
        from saddlescope.server import check_port_free

        check_port_free(host, port, hint="make demo PORT={port} (or saddlescope demo --port {port})")
    settings = settings or get_settings()
    upgrade_to_head(settings.database_url)
    sessions = session_factory_for(settings.database_url)
    storage = open_storage(settings)

    bundle = ensure_demo_bundle(bundle)
    ride_id = _demo_ride_id(sessions, storage, bundle)
    print(f"demo: ride {ride_id} from {bundle}, analysing ({'embedded' if settings.embedded else 'celery'} "
          "mode)", file=stderr, flush=True)

    def show(view: dict) -> None:
        print(f"[{view['progress'] * 100:5.1f} %] {view['status']} {view['stage'] or ''}".rstrip(),
              file=stderr, flush=True)

    own_queue = queue is None
    queue = queue or make_queue(settings)
    try:
        job_id = submit_job(sessions, queue, kind="analyze", ride_id=ride_id)
        view = wait_for_job(sessions, job_id, on_update=show)
    finally:
        if own_queue:
            queue.close()
    if view["status"] != "done":
        print(f"demo: job {job_id} {view['status']}: {view['error'] or 'no detail'}", file=stderr)
        return 1
    with session_scope(sessions) as session:
        result = ResultRepository(session).for_ride(ride_id)
        indicators = dict(result.indicators) if result is not None else {}
    timings = ", ".join(f"{k} {v:.1f} s" for k, v in view["timings_s"].items())
    print(f"demo: done ({timings})", file=stderr, flush=True)
    if not serve:
        print(json.dumps(indicators, indent=2, allow_nan=False), file=stdout)
        return 0
    from saddlescope.server import serve as serve_forever

    if settings.embedded and ensure_demo_user(sessions):
        print(f"demo: sign in as {DEMO_EMAIL} with password {DEMO_PASSWORD}", file=stderr, flush=True)
    print(f"demo: dashboard at http://{host}:{port}/", file=stderr, flush=True)
    serve_forever(host, port, settings=settings)
    return 0
