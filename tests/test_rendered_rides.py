"""The tests' render cache (tests/rendered_rides.py): a bundle is rendered once for the same arguments and
renderer, each test gets its own copy, and anything that makes a bundle different renders it again."""

from __future__ import annotations

import json

import pytest
import rendered_rides
from rendered_rides import bundle_key, cached_ride_bundle, renderer_modules

from saddlescope.arena import RenderOptions


@pytest.fixture
def renders(monkeypatch, tmp_path):
    """A stand-in for write_ride_bundle that counts its renders (the cache's logic, not the arena, is under test)."""
    made = []

    def write_ride_bundle(out_dir, **arguments):
        out_dir.mkdir(parents=True)
        (out_dir / "motion").mkdir()
        (out_dir / "motion" / "left.mp4").write_bytes(b"clip %d" % len(made))
        (out_dir / "ride.json").write_text(json.dumps({"seed": arguments.get("seed")}))
        made.append(arguments)
        return out_dir

    monkeypatch.setattr("saddlescope.io.synth_writer.write_ride_bundle", write_ride_bundle)
    monkeypatch.setenv(rendered_rides.CACHE_ENV, str(tmp_path / "cache"))
    return made


def test_the_key_follows_every_argument_and_render_option():
    base = bundle_key({"gait": "canter", "seed": 4, "size": (640, 480)})
    assert base == bundle_key({"seed": 4, "size": [640, 480], "gait": "canter"})  # order and tuple-or-list alike
    assert base != bundle_key({"gait": "canter", "seed": 5, "size": (640, 480)})
    assert base != bundle_key({"gait": "canter", "seed": 4, "size": (640, 480), "crf": 28})
    plain = bundle_key({"seed": 4, "options": RenderOptions()})
    assert plain != bundle_key({"seed": 4, "options": RenderOptions(boot_share=0.2)})
    assert plain == bundle_key({"seed": 4, "options": RenderOptions()})
    with pytest.raises(TypeError, match="cannot key an argument of type builtin_function_or_method"):
        bundle_key({"on_progress": print})


def test_the_renderer_is_every_module_the_writer_imports():
    modules = renderer_modules()
    for name in ("saddlescope.io.synth_writer", "saddlescope.io.video_writer", "saddlescope.arena.render",
                 "saddlescope.arena.truth", "saddlescope.core.vibration.weighting", "saddlescope", "saddlescope.arena"):
        assert name in modules
    assert not any(m.startswith(("saddlescope.api", "saddlescope.services", "saddlescope.db")) for m in modules)


def test_a_bundle_is_rendered_once_and_each_test_gets_its_own_copy(renders, tmp_path):
    a = cached_ride_bundle(tmp_path / "a" / "ride", gait="walk", seed=3)
    (a / "ride.json").write_text("changed by the first test")
    b = cached_ride_bundle(tmp_path / "b" / "ride", gait="walk", seed=3)
    assert len(renders) == 1
    assert json.loads((b / "ride.json").read_text()) == {"seed": 3}  # the first copy's change stays in it
    assert (b / "motion" / "left.mp4").read_bytes() == b"clip 0"
    assert not (b / "arguments.json").exists()
    cached_ride_bundle(tmp_path / "c" / "ride", gait="walk", seed=4)
    assert [r["seed"] for r in renders] == [3, 4]
    stored = json.loads(next((tmp_path / "cache").glob("*/arguments.json")).read_text())
    assert stored["gait"] == "walk"


def test_a_render_stopped_half_way_is_rendered_again(renders, tmp_path):
    key = bundle_key({"gait": "walk", "seed": 3})
    half = tmp_path / "cache" / key  # no <key>.built beside it: the render stopped before it finished
    half.mkdir(parents=True)
    (half / "ride.json").write_text("half")
    out = cached_ride_bundle(tmp_path / "a", gait="walk", seed=3)
    assert len(renders) == 1 and json.loads((out / "ride.json").read_text()) == {"seed": 3}
    assert json.loads((half / "ride.json").read_text()) == {"seed": 3}  # the half render was replaced


def test_off_renders_every_time(renders, tmp_path, monkeypatch):
    monkeypatch.setenv(rendered_rides.CACHE_ENV, "off")
    cached_ride_bundle(tmp_path / "a", gait="walk", seed=3)
    cached_ride_bundle(tmp_path / "b", gait="walk", seed=3)
    assert len(renders) == 2 and not (tmp_path / "cache").exists()


def test_the_least_recently_used_bundles_go_beyond_the_limit(renders, tmp_path, monkeypatch):
    import os

    for seed in (1, 2, 3):
        cached_ride_bundle(tmp_path / f"s{seed}", gait="walk", seed=seed)
    cache = tmp_path / "cache"
    folders = {json.loads((f / "ride.json").read_text())["seed"]: f for f in cache.iterdir() if f.is_dir()}
    for age, seed in enumerate((2, 1, 3)):  # seed 2 used longest ago, then 1, then 3
        os.utime(folders[seed], (1_000_000 + age, 1_000_000 + age))
    one = sum(f.stat().st_size for f in folders[1].rglob("*") if f.is_file())
    monkeypatch.setattr(rendered_rides, "CACHE_LIMIT_BYTES", 2 * one + one // 2)  # room for two of them
    cached_ride_bundle(tmp_path / "s4", gait="walk", seed=4)
    left = sorted(json.loads((f / "ride.json").read_text())["seed"] for f in cache.iterdir() if f.is_dir())
    assert left == [3, 4]
