"""The bad-input corpus (`bad_input_corpus.CORPUS`, one line per case) against SQLite and PostgreSQL.

Every case is refused with its 4xx and a reason a club understands, never a 5xx; and another club's
complete ride (rows of every table and files in storage) is byte-for-byte the same after the whole
corpus as before it.
"""

from __future__ import annotations

import hashlib
import json

import integration_services
import pytest
from api_helpers import zip_bomb, zip_folder, zip_members
from bad_input_corpus import CORPUS, LONG
from engines import ENGINES, MAX_UPLOAD_BYTES, open_env
from integration_services import add_member, new_club, write_tiny_bundle, write_tiny_clip
from sqlalchemy import select

from saddlescope.db.models import Base
from saddlescope.db.session import make_engine
from saddlescope.storage import open_storage

pg_database_url = integration_services.pg_database_url
redis_url = integration_services.redis_url


@pytest.fixture(scope="module", params=ENGINES)
def env(request, tmp_path_factory):
    yield from open_env(request, tmp_path_factory)


# --- the files the cases upload ---------------------------------------------------------------------


def _clip(folder, name, **kw) -> bytes:
    return write_tiny_clip(folder / name, **kw).read_bytes()


def _padded(bundle) -> bytes:
    """Members of exactly 1 MiB each: every one passes the ratio check, their total is over the limit."""
    pads = {f"pad/{i:03d}.bin": bytes(range(256)) * 4096 for i in range(MAX_UPLOAD_BYTES // (1 << 20) + 2)}
    return zip_folder(bundle, extra=pads)


def _clip_images_of_zeros(bundle) -> bytes:
    """Issue 39 item 9: padding inside clip folders ride.json names (numbered "images" of zeros, deflated, each
    under the per-member ratio check), and an unnamed incompressible member so the archive-wide ratio passes."""
    import io
    import os
    import zipfile

    buffer = io.BytesIO(zip_folder(bundle))
    with zipfile.ZipFile(buffer, "a", zipfile.ZIP_DEFLATED) as zf:
        for role in ("left", "middle", "right"):
            for i in range(24):
                zf.writestr(f"plumb/{role}/{100 + i:04d}.png", bytes(1024**2 - 1))
        zf.writestr("notes/filler.bin", os.urandom(4 * 1024**2), compress_type=zipfile.ZIP_STORED)
    return buffer.getvalue()


def _meta_bundle(bundle, change) -> bytes:
    meta = json.loads((bundle / "ride.json").read_text())
    change(meta)
    return zip_folder(bundle, rewrite={"ride.json": json.dumps(meta).encode()})


def _set(**values):
    return lambda meta: meta.update(values)


def _horse(**values):
    return lambda meta: meta["horse"].update(values)


def _missing(meta):
    meta["clips"]["motion"]["right"] = "motion/missing.avi"


CLIPS = {
    "good": lambda f: _clip(f, "good.avi", frames=6),
    "empty": lambda f: b"",
    "text": lambda f: b"these are my notes, not a video\n" * 100,
    "cut": lambda f: _clip(f, "whole.avi", frames=20)[:3000],
    "fps25": lambda f: _clip(f, "slow.avi", frames=6, fps=25.0),
    "big": lambda f: _clip(f, "big.avi", frames=6, size=(80, 60)),
    "zeros": lambda f: b"\x00" * 5000,
    "huge": lambda f: b"\x00" * (MAX_UPLOAD_BYTES + 1),
    "one_frame": lambda f: _clip(f, "still.avi", frames=1),
}
BUNDLES = {
    "zip_slip": lambda b: zip_folder(b, extra={"../../evil.txt": b"owned"}),
    "bomb": lambda b: zip_bomb(),
    "padded": lambda b: _padded(b),
    "not_zip": lambda b: b"PK\x03\x04 this is not really a zip",
    "no_ride_json": lambda b: zip_members({"notes.txt": b"hello"}),
    "ride_json_broken": lambda b: zip_folder(b, rewrite={"ride.json": b'{"format": "saddlescope.ride/1", '}),
    "gait_gallop": lambda b: _meta_bundle(b, _set(gait="gallop")),
    "camera_top": lambda b: _meta_bundle(b, _set(cameras=["left", "middle", "top"])),
    "two_cameras": lambda b: _meta_bundle(b, _set(cameras=["left", "middle"])),
    "gait_number": lambda b: _meta_bundle(b, _set(gait=5)),
    "horse_name_long": lambda b: _meta_bundle(b, _horse(name=LONG)),
    "horse_name_surrogate": lambda b: _meta_bundle(b, _horse(name="\ud800")),
    "height_negative": lambda b: _meta_bundle(b, _horse(height_m=-1.7)),
    "missing_clip": lambda b: _meta_bundle(b, _missing),
    "clip_images_zeros": _clip_images_of_zeros,
}


# --- the world the corpus runs in ---------------------------------------------------------------------


@pytest.fixture(scope="module")
def world(env, tmp_path_factory):
    """The attacker's club (an admin) and another club with one complete ride (clips, result, job, grade)."""
    folder = tmp_path_factory.mktemp("corpus")
    other, other_account = new_club(env.client)
    add_member(other)
    bundle = write_tiny_bundle(folder / "other-bundle")
    created = other.ok(
        "POST", "/rides/bundle", 201, files={"file": ("ride.zip", zip_folder(bundle), "application/zip")}
    )
    job, _ = other.wait_job(created["job_id"], timeout_s=120)
    assert job["status"] == "done", job
    ride = other.ok("GET", f"/rides/{created['ride']['id']}")
    grade = other.ok(
        "POST", "/grades", 201, json={"ride_id": ride["id"], "rider_id": ride["rider_id"], "grade": 4}
    )
    rig = other.ok("POST", "/rigs", 201, json={"name": "Other rig"})
    users = other.ok("GET", "/users")["items"]

    api, _ = new_club(env.client)
    horse = api.ok("POST", "/horses", 201, json={"name": "Steady"})
    rider = api.ok("POST", "/riders", 201, json={"name": "Careful"})
    mine = api.ok(
        "POST",
        "/rides",
        201,
        json={"horse_id": horse["id"], "rider_id": rider["id"], "gait": "walk", "direction": "CW"},
    )
    api.ok(
        "PUT", f"/rides/{mine['id']}/clips/motion/left", files={"file": ("good.avi", CLIPS["good"](folder))}
    )
    ids = {
        "ride": mine["id"],
        "horse": horse["id"],
        "rider": rider["id"],
        "rig": api.ok("POST", "/rigs", 201, json={"name": "My rig"})["id"],
        "other_ride": ride["id"],
        "other_horse": ride["horse_id"],
        "other_rider": ride["rider_id"],
        "other_rig": rig["id"],
        "other_job": job["id"],
        "other_grade": grade["id"],
        "other_user": users[0]["id"],
    }
    return {
        "api": api,
        "ids": ids,
        "folder": folder,
        "bundle": write_tiny_bundle(folder / "bundle"),
        "club_id": other_account["club"]["id"] if "club" in other_account else None,
    }


def fingerprint(env, world) -> dict[str, str]:
    """A hash of every row (all columns) of the other club in every table, and of every file of its ride."""
    engine = make_engine(env.settings.database_url)
    other_ride = world["ids"]["other_ride"]
    out: dict[str, str] = {}
    try:
        with engine.connect() as conn:
            club_id = conn.execute(
                select(Base.metadata.tables["rides"].c.club_id).where(
                    Base.metadata.tables["rides"].c.id == other_ride
                )
            ).scalar_one()
            for name, table in sorted(Base.metadata.tables.items()):
                if "club_id" in table.c:
                    where = table.c.club_id == club_id
                elif name == "clubs":
                    where = table.c.id == club_id
                else:
                    continue
                rows = conn.execute(select(table).where(where).order_by(*table.primary_key.columns)).all()
                out[f"table {name}"] = hashlib.sha256(repr([tuple(r) for r in rows]).encode()).hexdigest()
                out[f"rows {name}"] = str(len(rows))
    finally:
        engine.dispose()
    root = open_storage(env.settings).path("rides") / str(other_ride)
    for path in sorted(p for p in root.rglob("*") if p.is_file()):
        out[f"file {path.relative_to(root)}"] = hashlib.sha256(path.read_bytes()).hexdigest()
    return out


def _fill(value, ids):
    if isinstance(value, str) and value.startswith("{") and value.endswith("}") and value[1:-1] in ids:
        return ids[value[1:-1]]
    if isinstance(value, dict):
        return {k: _fill(v, ids) for k, v in value.items()}
    if isinstance(value, list):
        return [_fill(v, ids) for v in value]
    return value


def send(world, method: str, path: str, spec):
    api, ids = world["api"], world["ids"]
    path = path.format(**ids)
    if spec is None:
        return api.request(method, path)
    if isinstance(spec, dict):
        return api.request(method, path, json=_fill(spec["json"], ids))
    kind = spec[0]
    if kind == "raw":
        return api.request(method, path, content=spec[1], headers={"Content-Type": spec[2]})
    if kind == "form":
        return api.request(method, path, data=spec[1])
    if kind == "clip":
        return api.request(method, path, files={"file": (spec[2], CLIPS[spec[1]](world["folder"]))})
    if kind == "bundle":
        return api.request(
            method, path, files={"file": ("ride.zip", BUNDLES[spec[1]](world["bundle"]), "application/zip")}
        )
    raise ValueError(f"unknown input kind {kind!r}")


def test_the_corpus_is_refused_with_reasons_and_the_other_clubs_ride_is_intact(env, world):
    assert len(CORPUS) >= 60
    before = fingerprint(env, world)
    assert (
        int(before["rows rides"]) == 1 and int(before["rows results"]) == 1 and int(before["rows jobs"]) >= 1
    )
    assert int(before["rows recordings"]) == 12 and int(before["rows grades"]) == 1
    assert any(k.startswith("file ") for k in before)
    wrong = []
    for case_id, method, path, spec, status, reason in CORPUS:
        response = send(world, method, path, spec)
        try:
            detail = response.json().get("detail")
        except ValueError:
            detail = response.text[:200]
        text = detail if isinstance(detail, str) else json.dumps(detail)
        ok = (
            response.status_code == status
            and reason.lower() in text.lower()
            and "Traceback" not in text
            and str(env.settings.storage_dir) not in text
        )
        if not ok or response.status_code >= 500:
            wrong.append(
                f"{case_id}: {method} {path} -> {response.status_code} {text[:300]!r} "
                f"(wanted {status} with {reason!r})"
            )
    assert not wrong, f"{len(wrong)} of {len(CORPUS)} cases:\n" + "\n".join(wrong)
    assert fingerprint(env, world) == before


def test_a_bundle_whose_video_is_broken_fails_its_job_with_the_reason(env, world):
    """A bundle is registered without decoding its clips; the analysis job's probe then refuses the clip."""
    before = fingerprint(env, world)
    broken = zip_folder(world["bundle"], rewrite={"motion/left.avi": b"not a video at all\n" * 200})
    api = world["api"]
    created = api.ok("POST", "/rides/bundle", 201, files={"file": ("broken.zip", broken, "application/zip")})
    job, _ = api.wait_job(created["job_id"], timeout_s=120)
    assert job["status"] == "failed", job
    assert "not a usable video" in job["error"] and "Traceback" not in job["error"], job["error"]
    assert fingerprint(env, world) == before
