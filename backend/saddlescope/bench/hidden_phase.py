"""How the phase-deletion test's factor was set (issue 38): exact-marker rides with a fifth of the stride hidden.

For each gait and seed, the arena's exact markers (thesis rig, skin motion, 0.5 mm noise, no cameras) are
analysed twice through :func:`~saddlescope.core.saddle.saddle_kinematics` and
:func:`~saddlescope.core.saddle.kinematics_indicators`: as they are, and with the rear marker hidden for a fifth
of every stride from a phase drawn per seed. The hidden part's cost (the largest relative change over W_b and W_k
r.m.s., VDV and the displacement) is set beside the test's median change on the hidden ride;
:func:`factor_table` then says, per candidate factor, how many costs fall inside an interval made of the gait's
skin floor and the test's part, and how many trots and canters that interval marks too uncertain.

``python -m saddlescope.bench.hidden_phase`` (about 2 minutes of CPU for 60 rides) prints both.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from saddlescope.core.kinematics.hidden_phase import DELETION_KEYS

__all__ = ["factor_table", "hidden_fifth_rows"]

GAITS = ("sitting_trot", "rising_trot", "canter", "walk")
HIDDEN_SHARE = 0.2


def _exact_markers(gait: str, seed: int):
    """(motion tracks with 0.5 mm noise, static, plumb, the seed's random generator) of an arena ride."""
    from saddlescope.arena import RenderOptions, build_scene, build_truth
    from saddlescope.core.types import MarkerTracks

    scene = build_scene(gait=gait, seed=seed, rig="thesis", extras=False, calibration_poses=4,
                        options=RenderOptions(textured_background=False))
    truth = build_truth(scene)
    marks = {k: np.asarray(truth["truth"]["markers_3d_mm"][k], float) for k in ("motion", "static", "plumb")}
    first, last = truth["truth"]["clips"]["motion"]["markers_in_view_left_frames"]
    frames = np.arange(first, last + 1)
    fps = float(truth["fps"])
    rng = np.random.default_rng(seed)

    def tracks(xyz, idx):
        return MarkerTracks(tuple(f"M{i + 1}" for i in range(xyz.shape[1])), np.asarray(idx) / fps, xyz)

    motion = tracks(marks["motion"][frames, :3] + rng.normal(0, 0.5, (len(frames), 3, 3)), frames)
    return motion, tracks(marks["static"], np.arange(len(marks["static"]))), \
        tracks(marks["plumb"], np.arange(len(marks["plumb"]))), rng


def hidden_fifth_rows(gaits: Sequence[str] = GAITS, seeds: Sequence[int] = tuple(range(11, 26))) -> list[dict]:
    """Per ride: gait, seed, the hidden fifth's cost and the test's median change (None where not done)."""
    from dataclasses import replace

    from saddlescope.core.params import PipelineParams
    from saddlescope.core.saddle import kinematics_indicators, saddle_kinematics

    params = PipelineParams()
    rows = []
    for gait in gaits:
        for seed in seeds:
            motion, static, plumb, rng = _exact_markers(gait, seed)

            def run(tracks, gait=gait, static=static, plumb=plumb):
                kin = saddle_kinematics(tracks, static, plumb, params, horse_idx=[0, 1, 2], saddle_idx=3, gait=gait)
                return kin, kinematics_indicators(kin, params)[1]

            kin, whole = run(motion)
            xyz, t = motion.xyz_mm.copy(), motion.t_s
            phase = ((t - t[0]) / kin.period_s - rng.uniform()) % 1.0
            along = np.nanmean(xyz[:, :, 0], axis=0) * np.sign(np.nanmean(np.diff(xyz[:, 0, 0])))
            xyz[phase < HIDDEN_SHARE, int(np.argmin(along))] = np.nan  # the rear marker, hidden
            hidden_kin, hidden = run(replace(motion, xyz_mm=xyz))
            test = (hidden_kin.unmeasured_phase or {}).get("deletion") or {}
            rows.append({"gait": gait, "seed": seed,
                         "cost": max(abs(hidden[k] / whole[k] - 1.0) for k in DELETION_KEYS),
                         "median_change": test.get("median_change")})
    return rows


def factor_table(rows: Sequence[dict], factors: Sequence[float] = (1.0, 1.5, 2.0, 3.0)) -> list[dict]:
    """Per candidate factor, the costs inside the interval and the trots and canters it marks.

    The interval: 1.96 sigma of the gait's skin floor (common gain) and the factor times the test's median
    change; marked where that half-width passes ±10 % (``MAX_HALF_WIDTH_FRACTION``).
    """
    from saddlescope.core.vibration.intervals import MAX_HALF_WIDTH_FRACTION, SKIN_FLOORS

    tested = [r for r in rows if r["median_change"] is not None]
    out = []
    for factor in factors:
        half = [1.96 * math.hypot(SKIN_FLOORS[r["gait"]][0], factor * r["median_change"]) for r in tested]
        out.append({"factor": factor, "rides": len(tested),
                    "covered": sum(r["cost"] <= h for r, h in zip(tested, half, strict=True)),
                    "trots_and_canters": sum(r["gait"] != "walk" for r in tested),
                    "marked": sum(r["gait"] != "walk" and h > MAX_HALF_WIDTH_FRACTION
                                  for r, h in zip(tested, half, strict=True))})
    return out


if __name__ == "__main__":
    found = hidden_fifth_rows()
    ratios = np.array([r["cost"] / r["median_change"] for r in found if r["median_change"]])
    print(f"cost / median change: median {np.median(ratios):.2f}, 90th percentile {np.percentile(ratios, 90):.2f}, "
          f"largest {ratios.max():.2f}")
    for line in factor_table(found):
        print(line)
