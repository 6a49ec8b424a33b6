"""The embedded demo prints a sign-in that opens the demo club in the dashboard."""

from fastapi.testclient import TestClient

from saddlescope.api.app import create_app
from saddlescope.db.migrate import upgrade_to_head
from saddlescope.db.session import session_factory_for
from saddlescope.demo import DEMO_CLUB, DEMO_EMAIL, DEMO_PASSWORD, ensure_demo_user
from saddlescope.settings import load_settings


def test_demo_user_signs_in_to_the_demo_club(tmp_path):
    settings = load_settings(database_url=f"sqlite:///{tmp_path / 'db.sqlite'}", storage_dir=str(tmp_path / "s"))
    upgrade_to_head(settings.database_url)
    sessions = session_factory_for(settings.database_url)
    assert ensure_demo_user(sessions)
    assert ensure_demo_user(sessions)  # idempotent: a second demo run keeps the same user
    with TestClient(create_app(settings)) as client:
        r = client.post("/api/auth/login", json={"email": DEMO_EMAIL, "password": DEMO_PASSWORD})
        assert r.status_code == 200, r.text
        assert r.json()["user"]["role"] == "admin"
        token = r.json()["access_token"]
        me = client.get("/api/auth/me", headers={"Authorization": f"Bearer {token}"})
        assert me.status_code == 200 and me.json()["club"]["name"] == DEMO_CLUB, me.text
        bad = client.post("/api/auth/login", json={"email": DEMO_EMAIL, "password": "wrong-password"})
        assert bad.status_code == 401
