"""`saddlescope sweep`: what an operator runs by hand (or cron) to remove abandoned uploads and partial
writes, as every worker does hourly (`saddlescope_worker.app.sweep_once`)."""

from __future__ import annotations

import os
import time

from saddlescope.cli import main
from saddlescope.db.migrate import upgrade_to_head
from saddlescope.settings import get_settings
from saddlescope.storage import FileStorage


def test_the_sweep_command_removes_old_leftovers_and_says_how_many(tmp_path, monkeypatch, capsys):
    database_url = f"sqlite:///{tmp_path / 'db.sqlite'}"
    upgrade_to_head(database_url)
    storage = FileStorage(tmp_path / "storage")
    storage.write_bytes("incoming/1/forgotten.mp4", b"staged by a request that never finished")
    storage.write_bytes("incoming/1/fresh.mp4", b"being checked right now")
    writer = storage.writer("rides/7/clips/motion/left.mp4")
    writer.write(b"half")
    writer._out.close()  # a process killed mid-write
    old = time.time() - 3 * 3600
    for path in storage.root.rglob("*"):
        if path.name != "fresh.mp4":
            os.utime(path, (old, old))
    monkeypatch.setenv("SADDLESCOPE_DATABASE_URL", database_url)
    monkeypatch.setenv("SADDLESCOPE_STORAGE_DIR", str(storage.root))
    monkeypatch.delenv("SADDLESCOPE_STORAGE_URL", raising=False)
    monkeypatch.delenv("SADDLESCOPE_BROKER_URL", raising=False)
    get_settings.cache_clear()
    try:
        assert main(["sweep", "--older-than-h", "2"]) == 0
    finally:
        get_settings.cache_clear()
    assert capsys.readouterr().out.strip() == "expired uploads: 0, staged files: 1, partial writes: 1"
    assert list(storage.iter_keys("incoming")) == ["incoming/1/fresh.mp4"]
    assert not list(storage.root.rglob(".part-*"))
