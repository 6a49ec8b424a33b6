"""`saddlescope bench --only SECTION[,SECTION]`: a part of the benchmark measured alone gives the keys it
gives in a whole run (issue 34: the whole bench takes half an hour here)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

import saddlescope.bench as bench


def _fake_sections(monkeypatch, ran):
    fakes = []
    for section in bench.SECTIONS:
        def run(tmp, quick, name=section.name):
            ran.append((name, quick))
            return {f"{name}_key": 1.0}
        fakes.append(bench.BenchSection(section.name, section.summary, run))
    monkeypatch.setattr(bench, "SECTIONS", tuple(fakes))


def test_only_runs_the_named_sections_in_a_whole_runs_order(monkeypatch):
    ran = []
    _fake_sections(monkeypatch, ran)
    out = bench.run_benchmarks(quick=True, only="similarity, speed")
    assert ran == [("speed", True), ("similarity", True)]
    assert out["speed_key"] == out["similarity_key"] == 1.0 and "detection_key" not in out
    assert out["machine"]["sections"] == ["speed", "similarity"]


def test_a_whole_run_is_every_section(monkeypatch):
    ran = []
    _fake_sections(monkeypatch, ran)
    out = bench.run_benchmarks(quick=False)
    assert [name for name, _ in ran] == list(bench.SECTION_NAMES)
    assert all(out[f"{name}_key"] == 1.0 for name in bench.SECTION_NAMES)


def test_the_command_names_the_sections_the_bench_has():
    from saddlescope import cli

    assert cli._BENCH_SECTIONS == bench.SECTION_NAMES


def test_an_unknown_section_is_refused_naming_the_sections():
    with pytest.raises(ValueError, match="no benchmark section 'sped': choose from detection, calibration"):
        bench.sections_named("speed,sped")
    proc = subprocess.run([sys.executable, "-m", "saddlescope.cli", "bench", "--only", "sped"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and "choose from detection" in proc.stderr and "Traceback" not in proc.stderr


def test_the_floor_alone_from_the_command_line(tmp_path):
    """A real section, quick, through the command: its keys are those of a whole run."""
    out = tmp_path / "bench.json"
    proc = subprocess.run([sys.executable, "-m", "saddlescope.cli", "bench", "--quick", "--only", "floor",
                           "--json", str(out)], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(out.read_text())
    assert set(doc) == {"machine", "kinematics_floor_thesis"}
    assert set(doc["kinematics_floor_thesis"]) == {"walk", "sitting_trot", "rising_trot", "canter"}
