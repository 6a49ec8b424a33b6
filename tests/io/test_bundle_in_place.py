"""A bundle zip read in place (`open_zip_stream`, what the API does with a zip in a bucket) says exactly what
unpacking it (`open_bundle`) says: the same refusals in the same words, the same clips, the same bytes."""

from __future__ import annotations

import hashlib
import io
import json
import stat
import zipfile
from pathlib import Path

import pytest
from integration_services import zip_with_a_flipped_byte

from saddlescope.core.errors import BundleError
from saddlescope.io.bundle import open_bundle, open_zip_stream, zip_bundle_files
from saddlescope.storage import sha256_file, tree_digest

ROLES = ("left", "middle", "right")


def _meta(**changes) -> dict:
    clips = {kind: {r: f"{kind}/{r}.mp4" for r in ROLES} for kind in ("calibration", "static", "motion")}
    clips["plumb"] = {r: f"plumb/{r}" for r in ROLES}  # numbered images
    return {"format": "saddlescope.ride/1", "cameras": list(ROLES),
            "board": {"kind": "checkerboard", "inner_corners": [9, 6], "square_mm": 50.0},
            "sync": {"method": "flash"}, "markers": {"horse": 3, "plumb": 2, "saddle": 1},
            "horse": {"name": "Horse 2"}, "rider": {"name": "Rider B"}, "gait": "canter", "direction": "CCW",
            "clips": clips, **changes}


def _members(meta: dict | None = None, top: str = "") -> dict[str, bytes]:
    meta = _meta() if meta is None else meta
    out = {f"{top}ride.json": json.dumps(meta).encode()}
    for kind, cams in meta["clips"].items():
        for role, rel in cams.items():
            if kind == "plumb":
                for i in range(3):
                    out[f"{top}{rel}/{i + 1:04d}.png"] = f"{role} frame {i}".encode() * 50
            else:
                out[f"{top}{rel}"] = f"{kind} {role} clip ".encode() * 500
    return out


def _zip(members: dict[str, bytes], infos: tuple[zipfile.ZipInfo, ...] = ()) -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as zf:
        for name, data in members.items():
            zf.writestr(name, data)
        for info in infos:
            zf.writestr(info, b"x")
    return buffer.getvalue()


def _link() -> zipfile.ZipInfo:
    info = zipfile.ZipInfo("motion/evil.mp4")
    info.create_system, info.external_attr = 3, (stat.S_IFLNK | 0o777) << 16
    return info


def _bomb() -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, data in _members().items():
            zf.writestr(name, data)
        zf.writestr("padding.bin", b"\0" * (4 * 1024**2))
    return buffer.getvalue()


GOOD = _zip(_members())
CASES = {
    "good": GOOD,
    "one top folder": _zip({**_members(top="ride/"), "__MACOSX/._ride.json": b"x"}),
    "extras and truth.json": _zip({**_members(), "truth.json": b'{"format": "saddlescope.result/1"}',
                                   "notes/readme.txt": b"hello"}),
    "not a zip": b"not a zip at all\n" * 100,
    "truncated": GOOD[:len(GOOD) // 2],
    "no ride.json": _zip({k: v for k, v in _members().items() if k != "ride.json"}),
    "dot-dot member": _zip({**_members(), "../escape.mp4": b"x"}),
    "absolute member": _zip({**_members(), "/etc/evil": b"x"}),
    "symlink member": _zip(_members(), (_link(),)),
    "broken ride.json": _zip({**_members(), "ride.json": b"{nope"}),
    "unknown gait": _zip(_members(_meta(gait="gallop"))),
    "missing clip": _zip({k: v for k, v in _members().items() if k != "motion/left.mp4"}),
    "empty clip": _zip({**_members(), "motion/left.mp4": b""}),
    "image folder without numbers": _zip({**{k: v for k, v in _members().items() if not k.startswith("plumb/left/")},
                                          "plumb/left/cover.png": b"x" * 100}),
    "corrupt member": zip_with_a_flipped_byte(GOOD, "motion/left.mp4"),
    "zip bomb": _bomb(),
}


def _local_digest(source: Path) -> tuple[int, str]:
    return tree_digest(source) if source.is_dir() else (source.stat().st_size, sha256_file(source))


def _unpacked(path: Path):
    try:
        with open_bundle(path) as bundle:
            clips = {(kind, role): source for kind, cams in bundle.clip_paths.items() for role, source in cams.items()}
            return "ok", {key: (source.relative_to(bundle.root).as_posix(), _local_digest(source))
                          for key, source in clips.items()}
    except BundleError as exc:
        return "refused", str(exc).replace(str(path), path.name)


def _in_place(data: bytes, name: str):
    try:
        with open_zip_stream(io.BytesIO(data), name) as bundle:
            clips = {(kind, role): source.relative_to(bundle.root).as_posix()
                     for kind, cams in bundle.clip_paths.items() for role, source in cams.items()}
            files = {}
            for member, chunks in zip_bundle_files(bundle):
                digest, size = hashlib.sha256(), 0
                for chunk in chunks:
                    digest.update(chunk)
                    size += len(chunk)
                files[member.relative_to(bundle.root).as_posix()] = (size, digest.hexdigest())
            return "ok", {key: (rel, _digest_of(rel, files, data, bundle)) for key, rel in clips.items()}
    except BundleError as exc:
        return "refused", str(exc)


def _digest_of(rel: str, files: dict, data: bytes, bundle) -> tuple[int, str]:
    """A clip's (size, sha256) as `tree_digest` / `sha256_file` make them, from the zip's own bytes."""
    if rel in files:
        return files[rel]
    digest, size = hashlib.sha256(), 0
    with zipfile.ZipFile(io.BytesIO(data)) as zf:
        prefix = "/".join((*bundle.root.parts, rel)) + "/"
        for name in sorted((n for n in zf.namelist() if n.startswith(prefix)), key=lambda n: n.split("/")):
            body = zf.read(name)
            digest.update(name[len(prefix):].encode() + b"\0" + body)
            size += len(body)
    return size, digest.hexdigest()


@pytest.mark.parametrize("case", list(CASES))
def test_a_zip_read_in_place_says_what_unpacking_it_says(tmp_path, case):
    path = tmp_path / "ride.zip"
    path.write_bytes(CASES[case])
    unpacked, in_place = _unpacked(path), _in_place(CASES[case], "ride.zip")
    assert in_place == unpacked
    assert unpacked[0] == ("ok" if case in ("good", "one top folder", "extras and truth.json") else "refused")


def test_the_copy_in_path_order_gives_each_image_folder_its_tree_digest(tmp_path):
    """What the API records for an image-folder clip (hashed as its files stream past) is `tree_digest`."""
    from saddlescope.services.rides.registration import _store_files
    from saddlescope.storage import FileStorage

    with open_zip_stream(io.BytesIO(CASES["one top folder"]), "ride.zip") as bundle:
        digests = _store_files(FileStorage(tmp_path / "store"), bundle, "rides/1/bundle")
    stored = tmp_path / "store" / "rides" / "1" / "bundle"
    assert digests["plumb/left"] == tree_digest(stored / "plumb" / "left")
    clip = stored / "motion" / "left.mp4"
    assert digests["motion/left.mp4"] == (clip.stat().st_size, sha256_file(clip))
    assert not (stored / "__MACOSX").exists() and (stored / "ride.json").is_file()


def test_a_member_that_is_also_a_folder_is_refused_both_ways(tmp_path):
    data = _zip({**_members(), "motion": b"x"})
    (tmp_path / "ride.zip").write_bytes(data)
    with pytest.raises(BundleError, match="ride.zip: cannot be extracted"):
        open_bundle(tmp_path / "ride.zip")
    with pytest.raises(BundleError, match="ride.zip: cannot be extracted .member 'motion' is both a file and a folder"):
        open_zip_stream(io.BytesIO(data), "ride.zip")

