"""Walking every API route with a request that would succeed for the club that owns the things named.

`api_routes` lists them from the app; `fill` puts the owning club's ids into a path; `call_kwargs` is a
valid body or query for each route. Used by the authorisation matrix (test_api_authz.py) and the fault
drill (test_api_fault_drill.py).
"""

from __future__ import annotations

from api_helpers import zip_folder

__all__ = ["api_routes", "call_kwargs", "fill"]


def api_routes(app) -> list[tuple[str, str]]:
    """(method, path) of every route under /api (FastAPI includes routers lazily: walk them)."""
    out = []
    for route in app.routes:
        if hasattr(route, "original_router"):
            prefix = route.include_context.prefix
            out += [(m, prefix + r.path) for r in route.original_router.routes for m in r.methods]
        elif getattr(route, "path", "").startswith("/api"):
            out += [(m, route.path) for m in route.methods]
    # /shared/<token> is outside /api: the token is its credential (tests/api/test_share_links.py)
    return sorted((m, p) for m, p in out if p.startswith("/api") and (m != "HEAD" or p.startswith("/api/uploads")))


def call_kwargs(method: str, path: str, ids: dict, tiny) -> dict:
    """A request that would succeed for club A itself (valid body), pointing at club A's things."""
    body: dict | None = None
    if path == "/api/rides" and method == "POST":
        body = {"horse_id": ids["horse_id"], "rider_id": ids["rider_id"], "gait": "walk", "direction": "CW"}
    elif path == "/api/grades" and method == "POST":
        body = {"ride_id": ids["ride_id"], "rider_id": ids["rider_id"], "grade": 4}
    elif path == "/api/jobs" and method == "POST":
        body = {"kind": "probe", "ride_id": ids["ride_id"]}
    elif path == "/api/uploads" and method == "POST":
        body = {
            "target": "ride_clip",
            "ride_id": ids["ride_id"],
            "clip_kind": "motion",
            "camera": "left",
            "length_bytes": 10,
        }
    elif path == "/api/uploads/{upload_id}/parts" and method == "POST":
        body = {"numbers": [1]}
    elif path == "/api/share-links" and method == "POST":
        body = {"ride_id": ids["ride_id"]}
    elif path == "/api/riders" and method == "POST":
        body = {"name": "Someone", "user_id": ids["user_id"]}
    elif (
        path in ("/api/horses/{horse_id}", "/api/riders/{rider_id}", "/api/rigs/{rig_id}", "/api/saddles/{saddle_id}")
        and method == "PATCH"
    ):
        body = {"name": "Renamed"}
    elif path == "/api/rides/{ride_id}" and method == "PATCH":
        body = {"notes": "changed"}
    elif path == "/api/grades/{grade_id}" and method == "PATCH":
        body = {"grade": 1}
    elif path == "/api/users/{user_id}" and method == "PATCH":
        body = {"display_name": "Renamed"}
    elif path == "/api/users" and method == "POST":
        body = {"email": "intruder@b.example", "password": "password 123"}
    kwargs: dict = {"json": body} if body is not None else {}
    if path.endswith("/clips/{clip_kind}/{camera}"):
        kwargs = {"files": {"file": ("left.avi", (tiny / "motion/left.avi").read_bytes(), "video/x-msvideo")}}
    if path == "/api/rides/bundle":
        kwargs = {
            "files": {"file": ("ride.zip", zip_folder(tiny), "application/zip")},
            "params": {"rig_id": ids["rig_id"]},
        }
    if path == "/api/uploads/{upload_id}" and method == "PATCH":
        kwargs = {
            "content": b"0123456789",
            "headers": {"Upload-Offset": "0", "Content-Type": "application/offset+octet-stream"},
        }
    if path.startswith("/api/rides/export/"):
        kwargs = {"params": {"horse_id": ids["horse_id"]}}
    if path == "/api/horses/{horse_id}/saddles":
        kwargs = {"params": {"gait": "walk"}}
    if path == "/api/comparison":
        kwargs = {"params": {"gait": "walk", "horses": str(ids["horse_id"])}}
    if path == "/api/mocap":
        kwargs = {"params": {"horse_id": ids["horse_id"], "rider_id": ids["rider_id"], "markers": "A,B,C",
                             "filename": "lab.trc"},
                  "content": b"PathFileType\t4\t(X/Y/Z)\tlab.trc\n"}
    if path == "/api/horses/{horse_id}/ride-pair":
        kwargs = {"params": {"a": ids["ride_id"], "b": ids["ride_id"]}}
    if path == "/api/horses/{horse_id}/trend":
        kwargs = {"params": {"gait": "walk"}}
    if path in ("/api/leaderboard",):
        kwargs = {"params": {"gait": "walk"}}
    if path in ("/api/rides", "/api/grades", "/api/jobs") and method == "GET":
        kwargs = {
            "params": {"ride_id": ids["ride_id"]} if path != "/api/rides" else {"horse_id": ids["horse_id"]}
        }
    return kwargs


def fill(path: str, ids: dict) -> str:
    """The route's path with club A's ids, relative to /api (as `Api` calls take them)."""
    return path.format(**ids).removeprefix("/api")
