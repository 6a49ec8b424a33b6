"""The filesystem storage: safe keys, atomic writes with checksums, arrays, stage folders."""

from __future__ import annotations

import hashlib
import io

import pytest

from saddlescope.core.errors import InputError
from saddlescope.storage import Storage, stage_output_key, tree_digest


@pytest.fixture
def storage(tmp_path):
    return Storage(tmp_path / "store")


@pytest.mark.parametrize("key", ["../escape", "/etc/passwd", "a/../../b", "", "a//b", "a\\b"])
def test_keys_cannot_leave_the_root(storage, key):
    with pytest.raises(InputError, match="relative path"):
        storage.path(key)


def test_write_stream_returns_size_and_sha256(storage):
    data = b"saddle" * 100_000
    size, sha = storage.write_stream("rides/1/bundle/motion/left.mp4", io.BytesIO(data))
    assert (size, sha) == (len(data), hashlib.sha256(data).hexdigest())
    assert storage.read_bytes("rides/1/bundle/motion/left.mp4") == data
    assert storage.sha256("rides/1/bundle/motion/left.mp4") == sha


def test_upload_over_the_limit_keeps_nothing(storage):
    with pytest.raises(InputError, match="upload limit of 1000 bytes"):
        storage.write_stream("big.bin", io.BytesIO(b"x" * 5000), max_bytes=1000)
    assert not storage.exists("big.bin")
    assert list(storage.root.iterdir()) == []  # no temporary file left behind


def test_fresh_dir_replaces_an_earlier_stage_output(storage):
    key = stage_output_key(7, "triangulate")
    first = storage.fresh_dir(key)
    (first / "old.npz").write_bytes(b"old")
    second = storage.fresh_dir(key)
    assert first == second and list(second.iterdir()) == []


def test_import_file_copies_not_links(storage, tmp_path):
    source = tmp_path / "clip.mp4"
    source.write_bytes(b"first")
    storage.import_file("c/clip.mp4", source)
    source.write_bytes(b"changed")
    assert storage.read_bytes("c/clip.mp4") == b"first"


def test_tree_digest_depends_on_names_and_bytes(tmp_path):
    a = tmp_path / "a"
    a.mkdir()
    (a / "0001.png").write_bytes(b"one")
    (a / "0002.png").write_bytes(b"two")
    size, digest = tree_digest(a)
    assert size == 6
    (a / "0002.png").rename(a / "0003.png")
    assert tree_digest(a)[1] != digest


def test_iter_keys_and_delete(storage):
    storage.write_bytes("rides/1/a.txt", b"a")
    storage.write_bytes("rides/1/sub/b.txt", b"b")
    assert list(storage.iter_keys("rides/1")) == ["rides/1/a.txt", "rides/1/sub/b.txt"]
    storage.delete("rides/1")
    assert list(storage.iter_keys("rides/1")) == []


def test_check_reports_a_writable_root(storage):
    assert "writable" in storage.check()
