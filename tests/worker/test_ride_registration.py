"""Registering a ride bundle (folder or zip): rows, stored copy, and no half-registered rides."""

from __future__ import annotations

import integration_services
import pytest

from saddlescope.core.errors import BundleError
from saddlescope.db.migrate import upgrade_to_head
from saddlescope.db.models import Horse, Recording, Ride
from saddlescope.db.session import session_factory_for
from saddlescope.io.bundle import open_bundle, write_bundle_zip
from saddlescope.services.rides.registration import register_bundle
from saddlescope.storage import FileStorage


@pytest.fixture
def env(tmp_path):
    url = f"sqlite:///{tmp_path / 'db.sqlite'}"
    upgrade_to_head(url)
    bundle = integration_services.write_tiny_bundle(tmp_path / "bundle", gait="sitting_trot")
    (bundle / "truth.json").write_text("{}")
    return session_factory_for(url), FileStorage(tmp_path / "storage"), bundle


def test_folder_bundle_becomes_a_ride_with_twelve_recordings(env):
    sessions, storage, bundle = env
    ride_id = register_bundle(sessions, storage, bundle, club_name="Club")
    with sessions() as s:
        ride = s.get(Ride, ride_id)
        recordings = s.query(Recording).filter_by(ride_id=ride_id).all()
        horse = s.get(Horse, ride.horse_id)
    assert (ride.gait, ride.direction, ride.status, ride.bundle_key) == (
        "sitting_trot",
        "CCW",
        "ready",
        f"rides/{ride_id}/bundle",
    )
    assert (horse.name, horse.birth_year, horse.height_withers_m) == ("Horse 2", 1999, 1.73)
    assert len(recordings) == 12 and all(r.sha256 and r.size_bytes > 0 for r in recordings)
    assert storage.exists(f"{ride.bundle_key}/truth.json")
    # the stored copy is itself a valid bundle
    with open_bundle(storage.path(ride.bundle_key)) as stored:
        assert stored.gait == "sitting_trot"


def test_zip_bundle_is_accepted(env, tmp_path):
    sessions, storage, bundle = env
    zipped = write_bundle_zip(bundle, tmp_path / "ride.zip")
    ride_id = register_bundle(sessions, storage, zipped)
    with sessions() as s:
        assert s.query(Recording).filter_by(ride_id=ride_id).count() == 12


def test_invalid_bundle_registers_nothing(env):
    sessions, storage, bundle = env
    (bundle / "motion" / "right.avi").unlink()
    with pytest.raises(BundleError, match="right.avi"):
        register_bundle(sessions, storage, bundle)
    with sessions() as s:
        assert s.query(Ride).count() == 0


def test_a_failed_copy_leaves_no_half_registered_ride(env, monkeypatch):
    sessions, storage, bundle = env

    def disk_full(key, source):
        storage.write_bytes(f"{key}/partial.bin", b"x")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(storage, "import_tree", disk_full)
    with pytest.raises(OSError, match="No space left"):
        register_bundle(sessions, storage, bundle)
    with sessions() as s:
        assert s.query(Ride).count() == 0
    assert list(storage.iter_keys("rides")) == []


def test_a_wand_calibrated_bundle_is_refused_in_words_and_registers_nothing(env):
    import json

    sessions, storage, bundle = env
    meta = json.loads((bundle / "ride.json").read_text())
    meta["clips"]["wand"] = meta["clips"].pop("calibration")
    meta["clips"]["close_up"] = dict(meta["clips"]["wand"])
    meta["calibration"] = {"method": "wand", "wand_length_m": 1.0}
    (bundle / "ride.json").write_text(json.dumps(meta))
    with pytest.raises(BundleError, match="calibrated with a wand .* is analysed with `saddlescope analyze` for now"):
        register_bundle(sessions, storage, bundle)
    with sessions() as s:
        assert s.query(Ride).count() == 0
