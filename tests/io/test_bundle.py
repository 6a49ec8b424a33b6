"""Ride bundles: folders and zips, ride.json validation, unsafe archives."""

from __future__ import annotations

import json
import os
import stat
import zipfile
from pathlib import Path

import pytest

from saddlescope.core.errors import BundleError
from saddlescope.io import bundle as bundle_mod
from saddlescope.io.bundle import open_bundle, write_bundle_zip

ROLES = ("left", "middle", "right")
KINDS = ("calibration", "plumb", "static", "motion")


def _meta(kinds=KINDS):
    return {
        "format": "saddlescope.ride/1",
        "cameras": list(ROLES),
        "board": {"kind": "checkerboard", "inner_corners": [9, 6], "square_mm": 50.0},
        "sync": {"method": "flash"},
        "markers": {"horse": 3, "plumb": 2, "saddle": 1},
        "horse": {"name": "Horse 2", "breed": "Dutch", "birth_year": 1999, "height_m": 1.73},
        "rider": {"name": "Rider B"},
        "gait": "canter",
        "direction": "CCW",
        "clips": {kind: {r: f"{kind}/{r}.mp4" for r in ROLES} for kind in kinds},
    }


def make_bundle(root: Path, meta: dict | None = None, *, truth: dict | None = None) -> Path:
    """A bundle folder whose clips are tiny stand-in files (nothing here decodes them)."""
    meta = _meta() if meta is None else meta
    root.mkdir(parents=True, exist_ok=True)
    for per_camera in meta["clips"].values():
        for rel in per_camera.values():
            (root / rel).parent.mkdir(parents=True, exist_ok=True)
            (root / rel).write_bytes(b"\x00\x00\x00\x18ftypisom stand-in clip")
    (root / "ride.json").write_text(json.dumps(meta, indent=2))
    if truth is not None:
        (root / "truth.json").write_text(json.dumps(truth))
    return root


def _zip_with(path: Path, members: dict[str, bytes], infos: list[zipfile.ZipInfo] = ()) -> Path:
    with zipfile.ZipFile(path, "w") as zf:
        for name, data in members.items():
            zf.writestr(name, data)
        for info in infos:
            zf.writestr(info, b"x")
    return path


def _bundle_members(meta=None) -> dict[str, bytes]:
    meta = _meta() if meta is None else meta
    members = {"ride.json": json.dumps(meta).encode()}
    for per_camera in meta["clips"].values():
        for rel in per_camera.values():
            members[rel] = b"stand-in clip"
    return members


# ------------------------------------------------------------------------------------- good bundles


def test_folder_bundle(tmp_path):
    root = make_bundle(tmp_path / "ride", truth={"format": "saddlescope.result/1"})
    b = open_bundle(root)
    assert b.root == root and b.source == root
    assert b.gait == "canter" and b.direction == "CCW" and b.sync_method == "flash"
    assert b.board.kind == "checkerboard" and b.board.inner_corners == (9, 6) and b.board.square_mm == 50.0
    assert set(b.clip_paths) == set(KINDS)
    assert b.clip("motion", "middle") == root / "motion" / "middle.mp4"
    assert b.truth == {"format": "saddlescope.result/1"}
    assert b.warnings == () and b.sync_offsets("motion") is None
    # The ride.json path opens the same bundle.
    assert open_bundle(root / "ride.json").clip_paths == b.clip_paths
    b.close()
    assert root.exists()  # a folder bundle is never deleted


def test_zip_round_trip_and_cleanup(tmp_path):
    root = make_bundle(tmp_path / "ride")
    (root / "motion" / "left.mp4").write_bytes(os.urandom(4096))
    zip_path = write_bundle_zip(root, tmp_path / "out" / "ride.zip")
    with zipfile.ZipFile(zip_path) as zf:
        names = zf.namelist()
        assert "ride.json" in names and "motion/left.mp4" in names
        assert zf.getinfo("motion/left.mp4").compress_type == zipfile.ZIP_STORED
    with open_bundle(zip_path) as b:
        assert b.source == zip_path and b.temp_dir is not None
        assert b.meta == json.loads((root / "ride.json").read_text())
        assert b.clip("motion", "left").read_bytes() == (root / "motion" / "left.mp4").read_bytes()
        temp = b.temp_dir
    assert not temp.exists()


def test_zip_with_one_top_folder_and_extract_to(tmp_path):
    members = {f"myride/{k}": v for k, v in _bundle_members().items()}
    zip_path = _zip_with(tmp_path / "ride.zip", members)
    b = open_bundle(zip_path, extract_to=tmp_path / "x")
    assert b.root == tmp_path / "x" / "myride" and b.temp_dir is None
    assert b.clip("static", "right").is_file()


def test_image_folder_clip_extra_clips_and_offsets(tmp_path):
    meta = _meta()
    meta["clips"]["calibration"] = {r: f"calibration/{r}" for r in ROLES}
    meta["extra_clips"] = {"warmup": {"left": "warmup/left.mp4"}}
    meta["sync"] = {"method": "offsets",
                    "offsets": {k: {"left": 0, "middle": 53, "right": 126.5} for k in KINDS}}
    root = tmp_path / "ride"
    root.mkdir()
    for r in ROLES:
        (root / "calibration" / r).mkdir(parents=True)
        (root / "calibration" / r / "0001.png").write_bytes(b"png")
    (root / "warmup").mkdir()
    (root / "warmup" / "left.mp4").write_bytes(b"clip")
    meta_files = {k: v for k, v in meta["clips"].items() if k != "calibration"}
    make_bundle(root, {**meta, "clips": meta_files})  # writes the video stand-ins
    (root / "ride.json").write_text(json.dumps(meta))
    b = open_bundle(root)
    assert b.clip("calibration", "left").is_dir()
    assert b.clip("warmup", "left") == root / "warmup" / "left.mp4"
    assert b.sync_offsets("motion") == {"left": 0.0, "middle": 53.0, "right": 126.5}
    with pytest.raises(BundleError, match="the warmup clips have no 'right' camera"):
        b.clip("warmup", "right")


def test_plumb_optional_with_warning_and_calibration_file(tmp_path):
    meta = _meta(kinds=("static", "motion"))
    meta["calibration_file"] = "rig.toml"
    root = make_bundle(tmp_path / "ride", meta)
    with pytest.raises(BundleError, match="calibration_file 'rig.toml' does not exist"):
        open_bundle(root)
    (root / "rig.toml").write_text("[cam_0]\n")
    b = open_bundle(root)
    assert b.calibration_file == root / "rig.toml"
    assert [w.code for w in b.warnings] == ["plumb.missing"]
    with pytest.raises(BundleError, match="no plumb clips"):
        b.clip("plumb", "left")


def test_charuco_board(tmp_path):
    meta = _meta()
    meta["board"] = {"kind": "charuco", "inner_corners": [4, 3], "square_mm": 54.0,
                     "dictionary": "DICT_4X4_1000", "marker_mm": 40.5}
    b = open_bundle(make_bundle(tmp_path / "ride", meta))
    assert (b.board.option("dictionary"), b.board.option("marker_mm")) == ("DICT_4X4_1000", 40.5)
    meta["board"]["dictionary"] = "DICT_9X9_7"
    make_bundle(tmp_path / "ride", meta)
    with pytest.raises(BundleError, match="'DICT_9X9_7' is not an OpenCV ArUco dictionary"):
        open_bundle(tmp_path / "ride")


# -------------------------------------------------------------------------------------- bad ride.json


def test_unknown_gait_message(tmp_path):
    meta = _meta()
    meta["gait"] = "gallop"
    with pytest.raises(BundleError) as info:
        open_bundle(make_bundle(tmp_path / "ride", meta))
    assert str(info.value) == "ride.json: gait 'gallop' is not one of walk, sitting_trot, rising_trot, canter"


def test_unknown_camera_role(tmp_path):
    meta = _meta()
    meta["clips"]["motion"]["centre"] = meta["clips"]["motion"].pop("middle")
    expected = r"clips.motion has unknown 'centre' \(expected left, middle, right\)"
    with pytest.raises(BundleError, match=expected):
        open_bundle(make_bundle(tmp_path / "ride", meta))
    meta = _meta()
    meta["cameras"] = ["left", "middle", "top"]
    with pytest.raises(BundleError, match=r"cameras\[2\] 'top' is not one of left, middle, right"):
        open_bundle(make_bundle(tmp_path / "ride2", meta))


def test_missing_clip_file(tmp_path):
    root = make_bundle(tmp_path / "ride")
    (root / "motion" / "right.mp4").unlink()
    expected = "clips.motion.right 'motion/right.mp4' does not exist in the bundle"
    with pytest.raises(BundleError, match=expected):
        open_bundle(root)


def test_empty_clip_and_empty_image_folder(tmp_path):
    root = make_bundle(tmp_path / "ride")
    (root / "static" / "left.mp4").write_bytes(b"")
    with pytest.raises(BundleError, match="clips.static.left 'static/left.mp4' is an empty file"):
        open_bundle(root)
    meta = _meta()
    meta["clips"]["static"]["left"] = "static/left"
    (root / "ride.json").write_text(json.dumps(meta))
    (root / "static" / "left").mkdir()
    (root / "static" / "left" / "notes.txt").write_text("no images")
    with pytest.raises(BundleError, match="a folder without numbered images"):
        open_bundle(root)


@pytest.mark.parametrize("rel", ["../outside.mp4", "/etc/hostname", "C:/clips/left.mp4"])
def test_clip_paths_must_stay_inside(tmp_path, rel):
    (tmp_path / "outside.mp4").write_bytes(b"clip")
    meta = _meta()
    meta["clips"]["motion"]["left"] = rel
    root = make_bundle(tmp_path / "ride", {**meta, "clips": {k: v for k, v in meta["clips"].items()
                                                            if k != "motion"}})
    (root / "ride.json").write_text(json.dumps(meta))
    for r in ("middle", "right"):
        (root / "motion").mkdir(exist_ok=True)
        (root / "motion" / f"{r}.mp4").write_bytes(b"clip")
    with pytest.raises(BundleError, match="must be a relative path inside the bundle"):
        open_bundle(root)


def test_symlinked_clip_leading_outside(tmp_path):
    root = make_bundle(tmp_path / "ride")
    secret = tmp_path / "secret.mp4"
    secret.write_bytes(b"secret")
    (root / "motion" / "left.mp4").unlink()
    (root / "motion" / "left.mp4").symlink_to(secret)
    with pytest.raises(BundleError, match="points outside the bundle"):
        open_bundle(root)


def test_missing_or_broken_ride_json(tmp_path):
    with pytest.raises(BundleError, match="no such ride bundle"):
        open_bundle(tmp_path / "nothing")
    (tmp_path / "empty").mkdir()
    with pytest.raises(BundleError, match="no ride.json"):
        open_bundle(tmp_path / "empty")
    root = make_bundle(tmp_path / "ride")
    (root / "ride.json").write_text('{"format": "saddlescope.ride/1",\n "gait": }')
    with pytest.raises(BundleError, match="ride.json: not valid JSON .* line 2"):
        open_bundle(root)
    (root / "ride.json").write_text("[]")
    with pytest.raises(BundleError, match="ride.json: must be object"):
        open_bundle(root)


def test_not_a_zip(tmp_path):
    odd = tmp_path / "ride.zip"
    odd.write_bytes(b"this is not an archive")
    with pytest.raises(BundleError, match="must be a folder or a .zip"):
        open_bundle(odd)
    good = _zip_with(tmp_path / "good.zip", _bundle_members())
    raw = good.read_bytes()
    # Damage a member's data but keep the central directory: the CRC check must catch it.
    start = raw.index(b"stand-in clip")
    broken = tmp_path / "broken.zip"
    broken.write_bytes(raw[:start] + b"STAND-IN CLIP" + raw[start + 13:])
    with pytest.raises(BundleError, match="broken.zip: corrupt"):
        open_bundle(broken)


# ----------------------------------------------------------------------------------- unsafe archives


def test_zip_slip_is_refused_and_nothing_escapes(tmp_path):
    members = _bundle_members()
    members["../evil.txt"] = b"pwned"
    (tmp_path / "sub").mkdir()
    zip_path = _zip_with(tmp_path / "sub" / "ride.zip", members)
    dest = tmp_path / "sub" / "x"
    with pytest.raises(BundleError, match=r"member '../evil.txt' has a '..' component"):
        open_bundle(zip_path, extract_to=dest)
    assert not (tmp_path / "sub" / "evil.txt").exists() and not (tmp_path / "evil.txt").exists()
    assert not any(dest.rglob("*"))  # refused before anything was written


def test_absolute_member_and_symlink_member(tmp_path):
    absolute = zipfile.ZipInfo("/etc/cron.d/evil")
    with pytest.raises(BundleError, match="has an absolute path"):
        open_bundle(_zip_with(tmp_path / "a.zip", _bundle_members(), [absolute]))
    link = zipfile.ZipInfo("motion/link.mp4")
    link.create_system = 3
    link.external_attr = (stat.S_IFLNK | 0o777) << 16
    with pytest.raises(BundleError, match="'motion/link.mp4' is a symbolic link"):
        open_bundle(_zip_with(tmp_path / "b.zip", _bundle_members(), [link]))


def test_too_many_members(tmp_path):
    zip_path = _zip_with(tmp_path / "ride.zip", _bundle_members())
    with pytest.raises(BundleError, match="13 members, more than the limit of 5"):
        open_bundle(zip_path, max_files=5)


def _zeros_member(zip_path: Path, n_mib: int, members: dict[str, bytes]) -> Path:
    with zipfile.ZipFile(zip_path, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, data in members.items():
            zf.writestr(name, data)
        with zf.open("motion/huge.mp4", "w", force_zip64=True) as out:
            block = bytes(1024**2)
            for _ in range(n_mib):
                out.write(block)
    return zip_path


def test_zip_bomb_over_the_size_limit(tmp_path, monkeypatch):
    zip_path = _zeros_member(tmp_path / "bomb.zip", 200, _bundle_members())
    assert zip_path.stat().st_size < 1024**2  # 200 MiB of zeros, small on disk
    # a temporary folder of this test's own: the other test workers unpack bundles into the shared one meanwhile
    private = tmp_path / "tmp"
    private.mkdir()
    monkeypatch.setattr(bundle_mod.tempfile, "tempdir", str(private))
    with pytest.raises(BundleError, match="unpacks to more than the limit of 100 MB"):
        open_bundle(zip_path, max_bytes=100 * 10**6)
    assert not list(private.iterdir())  # the temporary folder was removed


def test_zip_bomb_by_compression_ratio(tmp_path):
    zip_path = _zeros_member(tmp_path / "bomb.zip", 8, _bundle_members())
    with pytest.raises(BundleError, match=r"'motion/huge.mp4' compresses \d+:1, over the limit of 200:1"):
        open_bundle(zip_path)


def test_lying_header_is_caught_while_extracting(tmp_path, monkeypatch):
    members = _bundle_members()
    clip = _meta()["clips"]["motion"]["left"]  # a member ride.json names: it is unpacked
    zip_path = _zip_with(tmp_path / "ride.zip", {**members, clip: b"y" * 5000})
    real_check = bundle_mod._check_zip

    def shrink_sizes(zf, *args, **kwargs):
        members = real_check(zf, *args, **kwargs)
        for info, _ in members:
            if info.filename == clip:
                info.file_size = 10  # what a forged header would claim
        return members

    monkeypatch.setattr(bundle_mod, "_check_zip", shrink_sizes)
    with pytest.raises(BundleError, match="corrupt|more than its header says"):
        open_bundle(zip_path)


def test_write_bundle_zip_refuses_invalid_or_non_bundles(tmp_path):
    with pytest.raises(BundleError, match="no ride.json"):
        write_bundle_zip(tmp_path, tmp_path / "x.zip")
    meta = _meta()
    meta["direction"] = "sideways"
    root = make_bundle(tmp_path / "ride", meta)
    with pytest.raises(BundleError, match="direction 'sideways'"):
        write_bundle_zip(root, tmp_path / "x.zip")
    assert not (tmp_path / "x.zip").exists()


def _padded(zip_path: Path, count: int, size: int, members: dict[str, bytes]) -> Path:
    """Many members each just under the per-member ratio check (1 MiB) of zeros: padding, not a video."""
    with zipfile.ZipFile(zip_path, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, data in members.items():
            zf.writestr(name, data)
        for i in range(count):
            zf.writestr(f"padding/{i:05d}.png", bytes(size))
    return zip_path


def test_a_padded_bundle_is_refused_by_its_total_against_the_archive_size(tmp_path):
    zip_path = _padded(tmp_path / "padded.zip", 300, 1024**2 - 1, _bundle_members())
    assert zip_path.stat().st_size < 2 * 1024**2  # ~300 MB unpacked from well under 2 MB
    out = tmp_path / "out"
    with pytest.raises(BundleError, match=r"padded.zip: unpacks to \d+ MB, \d+ times its [\d.]+ MB compressed size"):
        open_bundle(zip_path, extract_to=out)
    assert not any(out.rglob("*.png"))  # refused before a member was written


def test_a_bundle_of_many_empty_members_is_refused_by_count_against_the_archive_size(tmp_path):
    zip_path = _padded(tmp_path / "many.zip", 3000, 0, _bundle_members())
    with pytest.raises(BundleError, match=r"many.zip: 30\d\d members in a \d+ kB archive"):
        open_bundle(zip_path)


def test_an_ordinary_bundle_with_small_members_still_opens(tmp_path):
    zip_path = _zip_with(tmp_path / "ride.zip", _bundle_members())
    with open_bundle(zip_path) as bundle:
        assert bundle.meta


def test_only_the_members_ride_json_names_are_unpacked(tmp_path):
    # Issue 39 item 9: members the bundle does not use (padding, notes, an older take) were unpacked anyway.
    import io

    from saddlescope.io.bundle import open_zip_stream, zip_bundle_files

    members = {**_bundle_members(), "truth.json": b'{"format": "saddlescope.result/1"}',
               "notes/readme.txt": b"hello", "padding/000.bin": bytes(1024**2), "motion/left-old.mp4": b"older take"}
    zip_path = _zip_with(tmp_path / "ride.zip", members)
    named = sorted(["ride.json", "truth.json", *(rel for cams in _meta()["clips"].values() for rel in cams.values())])
    out = tmp_path / "out"
    with open_bundle(zip_path, extract_to=out) as bundle:
        assert bundle.truth is not None
        assert sorted(p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file()) == named
    with open_zip_stream(io.BytesIO(zip_path.read_bytes()), "ride.zip") as bundle:  # a bucket's zip read in place
        assert sorted(member.relative_to(bundle.root).as_posix() for member, _ in zip_bundle_files(bundle)) == named


def test_clip_images_of_zeros_are_refused_by_the_ratio_of_what_would_be_unpacked(tmp_path):
    """Padding inside a clip folder ride.json names: numbered "images" of zeros, each under the per-member
    check, with an unnamed incompressible member so the archive-wide ratio passes."""
    meta = _meta(kinds=("calibration", "static", "motion"))
    meta["clips"]["plumb"] = {role: f"plumb/{role}" for role in ROLES}
    zip_path = tmp_path / "padded clips.zip"
    with zipfile.ZipFile(zip_path, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, data in _bundle_members(meta).items():
            if not name.startswith("plumb/"):
                zf.writestr(name, data)
        for role in ROLES:
            for i in range(24):
                zf.writestr(f"plumb/{role}/{i + 1:04d}.png", bytes(1024**2 - 1))
        zf.writestr("notes/filler.bin", os.urandom(4 * 1024**2), compress_type=zipfile.ZIP_STORED)
    out = tmp_path / "out"
    with pytest.raises(BundleError, match=r"padded clips.zip: the clips ride.json names unpack to \d+ MB, \d+ times"):
        open_bundle(zip_path, extract_to=out)
    assert not any(p.is_file() for p in out.rglob("*"))  # refused before a member was written


# --- a wand calibration (issue 35 item 3): ride.json's ``calibration`` and its clip sets ----------------


def _wand_meta(**calibration):
    meta = _meta(kinds=("plumb", "static", "motion", "wand", "close_up"))
    meta["calibration"] = {"method": "wand", "wand_length_m": 1.0, **calibration}
    return meta


def test_a_wand_bundle_opens_with_its_wand_and_close_up_clips(tmp_path):
    with open_bundle(make_bundle(tmp_path / "ride", _wand_meta())) as bundle:
        assert bundle.calibration_method == "wand"
        assert set(bundle.clip_paths) == {"plumb", "static", "motion", "wand", "close_up"}
        assert bundle.clip("close_up", "middle").name == "middle.mp4"
    with open_bundle(make_bundle(tmp_path / "board", _meta())) as bundle:
        assert bundle.calibration_method == "board"


@pytest.mark.parametrize(("change", "says"), [
    (lambda m: m["calibration"].pop("wand_length_m"), "needs calibration.wand_length_m"),
    (lambda m: m["clips"].pop("close_up"), "needs clips.close_up: the board filmed close to each camera"),
    (lambda m: m["clips"].pop("wand"), "needs clips.wand: the wand waved through the riding area"),
    (lambda m: m["calibration"].update(wand_length_m=12.0), "calibration.wand_length_m"),
    (lambda m: m["clips"].update(calibration={r: f"calibration/{r}.mp4" for r in ROLES}),
     "and clips.calibration (a board walk) contradict each other"),
    (lambda m: m.pop("calibration"), "clips.wand is a wand's clip set"),
    (lambda m: m["calibration"].update(method="stick"), "'stick' is not one of board, wand"),
])
def test_a_wrong_wand_bundle_is_refused_in_words(tmp_path, change, says):
    meta = _wand_meta()
    change(meta)
    with pytest.raises(BundleError, match="ride.json") as err:
        open_bundle(make_bundle(tmp_path / "ride", meta))
    assert says in str(err.value)


# --- the board walk refined by a wand (issue 35): ride.json's "board+wand" ------------------------------


def _board_wand_meta():
    meta = _meta(kinds=("calibration", "plumb", "static", "motion", "wand"))
    meta["calibration"] = {"method": "board+wand", "wand_length_m": 1.0}
    return meta


def test_a_board_and_wand_bundle_opens_with_its_board_walk_and_wand_clips(tmp_path):
    with open_bundle(make_bundle(tmp_path / "ride", _board_wand_meta())) as bundle:
        assert bundle.calibration_method == "board+wand"
        assert {"calibration", "wand"} <= set(bundle.clip_paths) and "close_up" not in bundle.clip_paths


@pytest.mark.parametrize(("change", "says"), [
    (lambda m: m["calibration"].pop("wand_length_m"), "'board+wand' needs calibration.wand_length_m"),
    (lambda m: m["clips"].pop("wand"), "'board+wand' needs clips.wand: the wand waved through the riding area by "
                                       "the three cameras at once, along the track the horse takes"),
    (lambda m: m["clips"].pop("calibration"), "'board+wand' needs clips.calibration: the board walk the wand refines"),
    (lambda m: m["clips"].update(close_up={r: f"close_up/{r}.mp4" for r in ROLES}),
     "'board+wand' takes each lens from the board walk: clips.close_up is not used"),
    (lambda m: m["calibration"].update(method="wand+board"), "'wand+board' is not one of board, wand, board+wand"),
    (lambda m: m["calibration"].update(method="board"), "clips.wand is a wand's clip set: add"),
])
def test_a_wrong_board_and_wand_bundle_is_refused_in_words(tmp_path, change, says):
    meta = _board_wand_meta()
    change(meta)
    with pytest.raises(BundleError, match="ride.json") as err:
        open_bundle(make_bundle(tmp_path / "ride", meta))
    assert says in str(err.value)
