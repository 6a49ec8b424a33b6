"""Many readers at once never wait on each other for database connections (issue 25: p95 1.4 s under 50).

A request holds its database session across several hops onto the shared request threads. When more
requests than pooled connections started at once, the threads blocked waiting for connections that
requests waiting for a thread held: the server stalled until SQLAlchemy's 30 s pool timeout. Requests
now wait for a session slot on the event loop, and the pool has a connection for every slot.
"""

from __future__ import annotations

import asyncio
import time

import anyio.to_thread
import httpx
import pytest
from api_helpers import ThreadQueue, standin_installed

from saddlescope.api import create_app
from saddlescope.settings import load_settings, with_embedded_secret


@pytest.fixture
def app(tmp_path):
    settings = with_embedded_secret(
        load_settings(
            database_url=f"sqlite:///{tmp_path / 'db.sqlite'}", storage_dir=str(tmp_path / "storage")
        )
    )
    with standin_installed():
        yield create_app(settings, queue=ThreadQueue(settings), open_registration=True)


def test_the_connection_pool_covers_every_session_slot(app):
    from saddlescope.api.app import REQUEST_SESSIONS

    pool = app.state.engine.pool
    assert pool.size() >= REQUEST_SESSIONS + app.state.settings.hash_workers
    assert app.state.db_slots._value == REQUEST_SESSIONS


def test_more_readers_than_threads_and_connections_do_not_stall(app):
    clients, threads = 40, 4  # 40 requests in flight, 4 request threads: the old pool (15) starved them

    async def run() -> tuple[list[int], float]:
        async with app.router.lifespan_context(app):
            anyio.to_thread.current_default_thread_limiter().total_tokens = threads
            transport = httpx.ASGITransport(app=app)
            async with httpx.AsyncClient(transport=transport, base_url="http://club") as client:
                await client.post(
                    "/api/clubs",
                    json={"club_name": "Busy", "email": "busy@club.example", "password": "busy password 1"},
                )
                login = await client.post(
                    "/api/auth/login", data={"username": "busy@club.example", "password": "busy password 1"}
                )
                headers = {"Authorization": f"Bearer {login.json()['access_token']}"}
                t0 = time.monotonic()
                answers = await asyncio.gather(
                    *(
                        asyncio.wait_for(client.get("/api/auth/me", headers=headers), 20)
                        for _ in range(clients)
                    )
                )
                return [a.status_code for a in answers], time.monotonic() - t0

    statuses, seconds = asyncio.run(run())
    assert statuses == [200] * clients
    assert seconds < 20  # before: every request waited out the pool's 30 s timeout, then 500
