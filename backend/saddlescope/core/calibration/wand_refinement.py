"""A board calibration refined by a wand pass, kept only where the checks it did not fit say so (issue 35).

A board carried through the middle band of the volume fixes each lens only where it went (the lens reach,
:mod:`saddlescope.core.triangulation.lens_reach`); a wand walked along the track reaches the image edges.
:func:`refine_board_rig` refines the board's rig with the wand's ends on most of the wand's frames
(:func:`~saddlescope.core.calibration.board_wand_bundle.refine_board_and_wand`: the poses and each lens's k1,
k2 from the board's views and the wand's ends together, the wand's length held, the ends taken in outward
from the board's reach), then checks both rigs on what neither fitted to (:func:`check_rig`):

- the wand's length on the wand frames held out of the refinement (every fifth run of
  :data:`HELD_OUT_RUN_FRAMES` frames), each rig triangulating with its own lens reach, as the ride does;
- the board walk's square check and its corners' triangulation r.m.s. on the board's views (the board's
  rig was fitted to them: this asks the refined rig not to undo what the board fixed).

The refined rig is kept only where none of these is worse (:func:`refinement_verdict`); the rig says
which, and why, in :class:`~saddlescope.core.types.WandRefinement`. A kept refinement's lens is known
where the board's corners and the wand's ends went: its report's ``lens_coverage`` is that region, which
the ride's lens reach and coverage checks then use.
"""

from __future__ import annotations

from collections.abc import Mapping

import cv2
import numpy as np

from saddlescope.core.calibration.board_wand_bundle import refine_board_and_wand
from saddlescope.core.calibration.checks import metric_checks
from saddlescope.core.calibration.views import BoardView
from saddlescope.core.calibration.wand import (
    WAND_LENGTH_LIMIT_PCT,
    WandView,
    relabel_with_rig,
)
from saddlescope.core.errors import CalibrationError, InputError
from saddlescope.core.findings import Finding
from saddlescope.core.triangulation.lens_reach import board_reach_px
from saddlescope.core.triangulation.nview import triangulate_nview
from saddlescope.core.types import Board, Rig, WandCheck, WandRefinement

__all__ = ["HELD_OUT_EVERY", "HELD_OUT_RUN_FRAMES", "check_rig", "held_out_split", "lens_coverage",
           "refine_board_rig", "refinement_verdict"]

# Every fifth run of 10 frames (on the first camera's clock) is held out of the refinement: runs, not single
# frames, since neighbouring frames show the wand at nearly the same place; interleaved along the pass, so the
# held-out ends go where the fitted ones went (the horse's markers pass there too).
HELD_OUT_EVERY = 5
HELD_OUT_RUN_FRAMES = 10
# How much worse a check may come out and still count as "not worse": (ratio, floor). On the arena's four band
# rides (docs/accuracy.md, "A middle-band board refined by a wand") a good refinement rebuilt the board's squares
# 0.022-0.026 % -> 0.025-0.047 % off and its corners 0.152 -> 0.152-0.155 px; a wand told 1 % long gave 0.22 %
# (refused), 0.3 % long 0.08 % (kept: the board's squares and the wand share the scale). The floor of 0.1 % of
# the square is what a tape measure gives on a 1 m wand (1 mm).
SQUARE_TOLERANCE = (0.25, 0.1)  # of board_square_error_pct: ratio, percent of the square
BOARD_PX_TOLERANCE = (0.25, 0.05)  # of board_rms_px: ratio, px
LENGTH_TOLERANCE = (0.0, 0.5)  # of the held-out wand length r.m.s.: ratio, mm
_Views = dict[str, list[WandView]]
_METRIC_CODES = ("calibration.square_error", "calibration.corner_distances", "calibration.no_shared_view",
                 "calibration.wand_length")


def held_out_split(views_by_camera: Mapping[str, list[WandView]], *, every: int = HELD_OUT_EVERY,
                   run_frames: int = HELD_OUT_RUN_FRAMES) -> tuple[_Views, _Views]:
    """The wand views to fit and the ones held out: every ``every``-th run of ``run_frames`` frames held out."""
    if every < 2 or run_frames < 1:
        raise InputError(f"hold out every {every}-th run of {run_frames} frames: every must be 2 or more, "
                         "runs 1 frame or more")
    held = {n: [v for v in vs if (v.frame // run_frames) % every == every - 1] for n, vs in views_by_camera.items()}
    fit = {n: [v for v in vs if (v.frame // run_frames) % every != every - 1] for n, vs in views_by_camera.items()}
    return fit, held


def _seen_twice(views_by_camera: Mapping[str, list[WandView]]) -> dict[str, list[WandView]]:
    """Only the views of frames two cameras or more saw (a frame one camera saw fixes no point)."""
    count: dict[int, int] = {}
    for vs in views_by_camera.values():
        for v in vs:
            count[v.frame] = count.get(v.frame, 0) + 1
    return {n: [v for v in vs if count[v.frame] >= 2] for n, vs in views_by_camera.items()}


def lens_coverage(rig: Rig, board_hull_px: Mapping[str, list], wand_views: Mapping[str, list[WandView]]
                  ) -> dict[str, dict]:
    """Per camera, the image region the board's corners and the wand's ends reached: hull and share of the image.

    As :func:`~saddlescope.core.pipeline.setup.board_coverage`; only the wand's ends of frames two cameras saw.
    """
    wand = _seen_twice(wand_views)
    out = {}
    for name, cam in rig.cameras.items():
        pts = [np.asarray(board_hull_px.get(name) or np.empty((0, 2)), np.float64).reshape(-1, 2)]
        pts += [v.ends_px for v in wand.get(name, [])]
        allpts = np.concatenate(pts).astype(np.float32)
        allpts = allpts[np.all(np.isfinite(allpts), axis=1)]
        if len(allpts) < 3:
            continue
        hull = cv2.convexHull(allpts).reshape(-1, 2)
        out[name] = {"hull_px": hull.astype(float).round(1).tolist(),
                     "area_fraction": float(cv2.contourArea(hull) / (cam.image_size[0] * cam.image_size[1]))}
    return out


def _wand_length_rms_mm(rig: Rig, views: Mapping[str, list[WandView]], length_mm: float,
                        reach_px: Mapping[str, float]) -> tuple[float, int]:
    """The wand's length r.m.s. error (mm) over the frames two cameras saw, and how many; each rig's lens reach."""
    names = [n for n in rig.names if n in views]
    by_cam = {n: {v.frame: v.ends_px for v in views[n]} for n in names}
    frames = sorted({f for n in names for f in by_cam[n] if sum(f in by_cam[m] for m in names) >= 2})
    if not frames:
        return float("nan"), 0
    xy = {n: np.full((len(frames), 2, 2), np.nan) for n in names}
    for n in names:
        for i, f in enumerate(frames):
            if f in by_cam[n]:
                xy[n][i] = by_cam[n][f]
    X, _, _ = triangulate_nview(rig, xy, lens_reach_px=dict(reach_px))
    err = np.linalg.norm(X[:, 0] - X[:, 1], axis=1) - length_mm
    err = err[np.isfinite(err)]
    return (float(np.sqrt(np.mean(err ** 2))) if err.size else float("nan")), int(err.size)


def check_rig(rig: Rig, board_views: Mapping[str, list[BoardView]], board: Board,
              held_out: Mapping[str, list[WandView]], wand_length_mm: float,
              hull_px: Mapping[str, list]) -> tuple[WandCheck, int]:
    """A rig's :class:`~saddlescope.core.types.WandCheck`, and the held-out wand frames it was checked on.

    ``hull_px``: per camera the region the rig's lens is known in (the board's coverage, or the board's and
    the wand's), whose farthest point from the principal point is the lens reach.
    """
    reach = {n: board_reach_px(rig.cameras[n], hull_px[n]) for n in rig.names if hull_px.get(n)}
    length_rms, n_frames = _wand_length_rms_mm(rig, held_out, wand_length_mm, reach)
    checks, _, _ = metric_checks(rig, board_views, board)
    return WandCheck(wand_length_rms_mm=length_rms,
                     board_square_error_pct=float(checks.get("board_square_error_pct", np.nan)),
                     board_rms_px=float(checks.get("triangulation_rms_px", np.nan)),
                     reach_px={n: round(r, 1) for n, r in reach.items()}), n_frames


def _worse(after: float, before: float, tolerance: tuple[float, float]) -> bool:
    """Whether ``after`` exceeds ``before`` by more than the tolerance (ratio, floor); unknown is not worse."""
    if not (np.isfinite(after) and np.isfinite(before)):
        return False
    ratio, floor = tolerance
    return after > before * (1 + ratio) + floor


def refinement_verdict(board: WandCheck, refined: WandCheck) -> tuple[bool, str]:
    """Keep the refined rig? Only where no check it did not fit is worse than the board's rig's; why, in words."""
    worse = []
    if _worse(refined.wand_length_rms_mm, board.wand_length_rms_mm, LENGTH_TOLERANCE):
        worse.append(f"the wand's length on frames it did not fit came out {refined.wand_length_rms_mm:.1f} mm "
                     f"r.m.s. off, {board.wand_length_rms_mm:.1f} mm with the board's calibration alone")
    if _worse(refined.board_square_error_pct, board.board_square_error_pct, SQUARE_TOLERANCE):
        worse.append(f"the board's squares came out {refined.board_square_error_pct:.2f} % r.m.s. off, "
                     f"{board.board_square_error_pct:.2f} % with the board's calibration alone (is the wand's "
                     "length right?)")
    if _worse(refined.board_rms_px, board.board_rms_px, BOARD_PX_TOLERANCE):
        worse.append(f"the board's corners triangulated {refined.board_rms_px:.2f} px r.m.s., "
                     f"{board.board_rms_px:.2f} px with the board's calibration alone")
    if worse:
        return False, "with the wand " + "; ".join(worse)
    if not np.isfinite(refined.wand_length_rms_mm):
        return True, "the board's checks are no worse (no wand frame was held out to check the length on)"
    return True, "the wand's length on frames it did not fit and the board's checks are no worse"


def _refined_findings(board_rig: Rig, checks: dict, flags: list[Finding], length_mm: float) -> tuple[Finding, ...]:
    """The board rig's findings with its metric ones replaced by the refined rig's, and the wand's length flag."""
    kept = [f for f in board_rig.flags if f.code not in _METRIC_CODES]
    limit_mm = length_mm * WAND_LENGTH_LIMIT_PCT / 100.0
    rms = checks.get("wand_length_rms_mm", np.nan)
    if np.isfinite(rms) and rms > limit_mm:
        flags = [*flags, Finding("calibration.wand_length", (
            f"the wand's length, measured from the refined cameras, scatters by {rms:.1f} mm r.m.s. about its "
            f"{length_mm:.0f} mm (limit {limit_mm:.1f} mm): distances in the ride may be off by as much"),
            {"rms_mm": rms, "limit_mm": limit_mm})]
    return tuple(kept) + tuple(flags)


def refine_board_rig(rig: Rig, board_views: Mapping[str, list[BoardView]], board: Board,
                     wand_views: Mapping[str, list[WandView]], wand_length_mm: float, *,
                     board_hull_px: Mapping[str, list], max_square_error_pct: float = 1.0,
                     loss: str = "soft_l1") -> tuple[Rig, dict]:
    """The board's rig refined by the wand where that helps, else the board's rig; each with its choice.

    Parameters
    ----------
    rig, board_views, board : the board walk's rig, the views it was fitted to and its board.
    wand_views : dict name -> list of WandView
        The wand's ends on the first camera's clock, each camera's labels its own tracker's (they are made to
        agree between cameras with the rig's epipolar geometry, :func:`relabel_with_rig`).
    board_hull_px : dict name -> (H, 2) list
        Where the board's corners went in each image (the board coverage's hull): the board's lens reach.

    Returns
    -------
    rig : Rig
        Its ``wand_refinement`` says whether it is the refined rig and why. A refined rig's checks are the
        board's metric checks recomputed with it and the wand's (``wand_length_rms_mm`` over every frame).
    report : dict
        ``refinement`` (:func:`refine_board_and_wand`'s report, where it ran) and, where the refined rig is kept,
        ``lens_coverage`` (:func:`lens_coverage`: where its lens is known, for the ride's lens reach).
    """
    # each camera's tracker named the ends by itself: end A made the same marker in every camera first
    fit, held = held_out_split(relabel_with_rig(rig, wand_views))
    board_check, n_held = check_rig(rig, board_views, board, held, wand_length_mm, board_hull_px)

    def board_kept(reason: str, refined_check: WandCheck | None = None) -> Rig:
        choice = WandRefinement(False, reason, float(wand_length_mm), n_held, board_check, refined_check)
        return Rig(rig.cameras, rig.checks, rig.flags, rig.pairs, rig.lens_models, wand_refinement=choice)

    try:  # the board's views and the wand's ends together: the poses stay consistent with the board's lenses
        refined, report = refine_board_and_wand(rig, board_views, board, fit, wand_length_mm,
                                                reach_px=board_check.reach_px, loss=loss)
    except (CalibrationError, InputError) as exc:
        return board_kept(f"the wand could not refine it ({exc})"), {}
    coverage = lens_coverage(refined, board_hull_px, fit)
    refined_check, _ = check_rig(refined, board_views, board, held, wand_length_mm,
                                 {n: c["hull_px"] for n, c in coverage.items()})
    keep, reason = refinement_verdict(board_check, refined_check)
    if not keep:
        return board_kept(reason, refined_check), {"refinement": report}
    checks, flags, _ = metric_checks(refined, board_views, board, max_square_error_pct=max_square_error_pct)
    checks = {**rig.checks, **checks, **{k: v for k, v in refined.checks.items() if k.startswith("wand_")}}
    choice = WandRefinement(True, reason, float(wand_length_mm), n_held, board_check, refined_check)
    out = Rig(refined.cameras, checks, _refined_findings(rig, checks, flags, wand_length_mm),
              lens_models=rig.lens_models, wand_refinement=choice)
    return out, {"refinement": report, "lens_coverage": coverage}
