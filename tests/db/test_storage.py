"""Storage on both back ends (a folder tree; an S3 bucket on a real SeaweedFS): safe keys, whole-or-nothing
writes with checksums, folders of keys, fetching to a local path, the health probe; the storage URL."""

from __future__ import annotations

import hashlib
import io

import pytest
import s3_server as s3_server_module

from saddlescope.core.errors import InputError
from saddlescope.settings import load_settings
from saddlescope.storage import (
    FileStorage,
    S3Storage,
    Storage,
    open_storage,
    parse_s3_url,
    storage_for_url,
    tree_digest,
)
from saddlescope.storage.s3 import PART_BYTES

s3_server = s3_server_module.s3_server  # one SeaweedFS for the session (tests/s3_server.py)

BACK_ENDS = ["file", "s3"]


@pytest.fixture(params=BACK_ENDS)
def storage(request, tmp_path, monkeypatch) -> Storage:
    if request.param == "file":
        return FileStorage(tmp_path / "store")
    server = request.getfixturevalue("s3_server")
    for name, value in server.environ().items():
        monkeypatch.setenv(name, value)
    return S3Storage(server.new_bucket("storage"), "club-data", endpoint_url=server.endpoint_url)


def _no_leftovers(storage: Storage) -> bool:
    """Nothing stored at all: no file (file), no object and no unfinished multipart upload (s3)."""
    if isinstance(storage, FileStorage):
        return not storage.root.exists() or not any(p.is_file() for p in storage.root.rglob("*"))
    s3 = storage.client
    objects = s3.list_objects_v2(Bucket=storage.bucket).get("Contents", [])
    return not objects and not s3.list_multipart_uploads(Bucket=storage.bucket).get("Uploads", [])


def test_both_back_ends_are_storages(storage):
    assert isinstance(storage, Storage)


@pytest.mark.parametrize("key", ["../escape", "/etc/passwd", "a/../../b", "", "a//b", "a\\b"])
def test_keys_cannot_leave_the_root(storage, key):
    with pytest.raises(InputError, match="relative path"):
        storage.write_bytes(key, b"x")


def test_write_stream_returns_size_and_sha256(storage):
    data = b"saddle" * 100_000
    size, sha = storage.write_stream("rides/1/bundle/motion/left.mp4", io.BytesIO(data))
    assert (size, sha) == (len(data), hashlib.sha256(data).hexdigest())
    assert storage.read_bytes("rides/1/bundle/motion/left.mp4") == data
    assert storage.sha256("rides/1/bundle/motion/left.mp4") == sha
    assert storage.size("rides/1/bundle/motion/left.mp4") == len(data)


def test_a_file_larger_than_a_part_is_written_in_parts_and_read_back_whole(storage):
    data = bytes(range(256)) * ((2 * PART_BYTES + 12345) // 256)  # three parts on S3, the last short
    with storage.writer("clips/big.mp4") as out:
        for start in range(0, len(data), 1_000_000):
            out.write(data[start:start + 1_000_000])
        assert not storage.exists("clips/big.mp4")  # nothing visible before the commit
        size, sha = out.commit()
    assert (size, sha) == (len(data), hashlib.sha256(data).hexdigest())
    assert storage.sha256("clips/big.mp4") == sha


def test_upload_over_the_limit_keeps_nothing(storage):
    with pytest.raises(InputError, match="upload limit of 1000 bytes"):
        storage.write_stream("big.bin", io.BytesIO(b"x" * 5000), max_bytes=1000)
    assert not storage.exists("big.bin")
    assert _no_leftovers(storage)  # no temporary file, no unfinished multipart upload


def test_an_aborted_writer_keeps_nothing(storage):
    with pytest.raises(RuntimeError), storage.writer("clips/half.mp4") as out:
        out.write(b"y" * (PART_BYTES + 10))  # one part already sent on S3
        raise RuntimeError("the client went away")
    assert not storage.exists("clips/half.mp4")
    assert _no_leftovers(storage)


def test_import_file_copies_not_links(storage, tmp_path):
    source = tmp_path / "clip.mp4"
    source.write_bytes(b"first")
    storage.import_file("c/clip.mp4", source)
    source.write_bytes(b"changed")
    assert storage.read_bytes("c/clip.mp4") == b"first"


def test_fetch_puts_a_file_or_a_folder_on_local_disk(storage, tmp_path):
    storage.write_bytes("rides/3/bundle/ride.json", b"{}")
    storage.write_bytes("rides/3/bundle/motion/left/0001.png", b"png")
    clip = storage.fetch("rides/3/bundle/ride.json", tmp_path / "scratch" / "ride.json")
    assert clip.read_bytes() == b"{}"
    folder = storage.fetch("rides/3/bundle", tmp_path / "scratch" / "bundle")
    assert sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*") if p.is_file()) == [
        "motion/left/0001.png", "ride.json"]
    with pytest.raises(FileNotFoundError, match="rides/3/nothing is not in storage"):
        storage.fetch("rides/3/nothing", tmp_path / "scratch" / "nothing")


def test_move_renames_a_stored_file(storage):
    storage.write_bytes("incoming/a.part", b"clip")
    storage.move("incoming/a.part", "rides/1/clips/a.mp4")
    assert not storage.exists("incoming/a.part")
    assert storage.read_bytes("rides/1/clips/a.mp4") == b"clip"


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
    storage.write_bytes("rides/10/c.txt", b"c")  # a neighbour whose name starts alike
    assert list(storage.iter_keys("rides/1")) == ["rides/1/a.txt", "rides/1/sub/b.txt"]
    assert list(storage.iter_keys("rides/1/a.txt")) == ["rides/1/a.txt"]
    assert storage.exists("rides/1") and storage.exists("rides/1/sub/b.txt")
    storage.delete("rides/1")
    assert list(storage.iter_keys("rides/1")) == [] and not storage.exists("rides/1")
    assert storage.read_bytes("rides/10/c.txt") == b"c"
    storage.delete("rides/1")  # absent: no error


def test_check_reports_a_writable_store(storage):
    assert "writable" in storage.check()
    assert _no_leftovers(storage)  # the probe is removed


def test_check_of_a_missing_bucket_says_so(s3_server, monkeypatch):
    for name, value in s3_server.environ().items():
        monkeypatch.setenv(name, value)
    storage = S3Storage("no-such-bucket-here", endpoint_url=s3_server.endpoint_url)
    with pytest.raises(OSError, match="Not ?Found|NoSuchBucket|404"):
        storage.check()


def test_fresh_dir_replaces_an_earlier_output_in_a_folder_tree(tmp_path):
    storage = FileStorage(tmp_path / "store")
    first = storage.fresh_dir("rides/7/scratch")
    (first / "old.npz").write_bytes(b"old")
    second = storage.fresh_dir("rides/7/scratch")
    assert first == second and list(second.iterdir()) == []


@pytest.mark.parametrize(("url", "expected"), [
    ("s3://rides", ("rides", "")), ("s3://rides/club-a/", ("rides", "club-a")), ("s3://b/x/y", ("b", "x/y"))])
def test_s3_urls_name_a_bucket_and_a_prefix(url, expected):
    assert parse_s3_url(url) == expected


def test_the_storage_url_chooses_the_back_end(tmp_path):
    assert isinstance(open_storage(load_settings(storage_dir=str(tmp_path / "s"))), FileStorage)
    chosen = open_storage(load_settings(storage_url=f"file://{tmp_path / 'f'}"))
    assert isinstance(chosen, FileStorage) and chosen.root == (tmp_path / "f").resolve()
    assert isinstance(storage_for_url(str(tmp_path / "plain")), FileStorage)
    s3 = open_storage(load_settings(storage_url="s3://club-rides/prod", s3_endpoint_url="http://127.0.0.1:1"))
    assert isinstance(s3, S3Storage) and (s3.bucket, s3.prefix) == ("club-rides", "prod")
    for bad in ("s3://", "ftp://host/x"):
        with pytest.raises((InputError, ValueError), match="s3://BUCKET"):
            storage_for_url(bad)


def _start_partial_write(storage: Storage, key: str) -> None:
    """A write begun and never finished (a process killed mid-write): a folder's temporary file, or a
    multipart upload with one part in the bucket."""
    if isinstance(storage, FileStorage):
        writer = storage.writer(key)
        writer.write(b"half a clip")
        writer._out.close()  # the process "dies": neither commit nor abort
        return
    name = storage.object_name(key)
    upload_id = storage.client.create_multipart_upload(Bucket=storage.bucket, Key=name)["UploadId"]
    storage.client.upload_part(Bucket=storage.bucket, Key=name, UploadId=upload_id, PartNumber=1,
                               Body=b"half a clip")


def _age(storage: Storage, seconds: float) -> None:
    """Make every file of a folder store look `seconds` old (a bucket's clock cannot be wound back: its
    tests wait instead)."""
    import os
    import time

    if isinstance(storage, FileStorage):
        then = time.time() - seconds
        for path in storage.root.rglob("*"):
            os.utime(path, (then, then))
    else:
        time.sleep(2.0)


def test_partial_writes_and_stale_staged_files_are_swept_by_age_only(storage):
    storage.write_bytes("incoming/1/old.mp4", b"staged and forgotten")
    _start_partial_write(storage, "rides/1/clips/motion/left.mp4")
    # Younger than the limit: a write still going on, a request still being checked, all kept.
    assert storage.sweep_partial_writes(older_than_s=3600) == 0
    assert storage.stale_keys("incoming", older_than_s=3600) == []
    _age(storage, 7200)
    limit_s = 3600 if isinstance(storage, FileStorage) else 1.0
    assert storage.stale_keys("incoming", older_than_s=limit_s) == ["incoming/1/old.mp4"]
    assert storage.sweep_partial_writes(older_than_s=limit_s) == 1
    storage.delete("incoming/1/old.mp4")
    assert _no_leftovers(storage)
    assert storage.sweep_partial_writes(older_than_s=limit_s) == 0  # nothing left to sweep, no error


def test_a_committed_file_is_never_swept(storage):
    storage.write_bytes("rides/1/clips/motion/left.mp4", b"a whole clip")
    _age(storage, 7200)
    limit_s = 3600 if isinstance(storage, FileStorage) else 1.0
    assert storage.sweep_partial_writes(older_than_s=limit_s) == 0
    assert storage.read_bytes("rides/1/clips/motion/left.mp4") == b"a whole clip"
