"""The board walk's views and a wand pass adjusted together (issue 35): a middle-band board refined by a wand.

A first version held each lens's focal length at the board's and fitted the poses and k1, k2 to the wand's
ends alone. On rendered band rides that left the board's own views
0.26 % off in scale (arena ``wide_partial`` seed 2041): a board seen only in the middle of the image fixes
the focal lengths to a few tenths of a percent (the right camera's -0.72 %), which the board's rig makes up
for with its poses; poses fitted to the wand with that focal length no longer fit the board.

Here every board corner (every third of each view: a view's pose needs few, and the solve costs a third)
and every wand end are residuals of one adjustment: the non-reference cameras' poses, each lens's k1 and k2,
every board pose and every frame's wand (centre and direction, its length held). The focal lengths and
principal points stay the board's, and the poses stay consistent with them through the board's views; the
wand extends k1, k2 to the image edges. On seed 2041 the board's squares came out 0.08 % off (0.03 % with the
board alone, 0.26 % refined by the wand alone), the wand's held-out length 3.9 mm r.m.s. (84 mm with the
board alone). Freeing a focal-length factor per camera too gave 0.05 % and 1.6 mm but moved every focal
length by -1.0 to -1.6 % together (an object at one depth cannot tell focal length from distance), and cost
four times the CPU: not done. The wand's ends are taken in outward from the board's reach in stages
(:data:`~saddlescope.core.calibration.wand._REFINE_STAGES`).
"""

from __future__ import annotations

from collections.abc import Mapping

import cv2
import numpy as np
from scipy.optimize import least_squares
from scipy.sparse import coo_matrix

from saddlescope.core.calibration.boards import object_points_mm
from saddlescope.core.calibration.bundle_adjustment import _initial_board_poses
from saddlescope.core.calibration.projection import _distort_project, _intr_vector, _rotation_matrices
from saddlescope.core.calibration.views import BoardView
from saddlescope.core.calibration.wand import (
    _REFINE_STAGES,
    WandView,
    _direction,
    _to_reference,
    _wand_frames,
    _within,
    wand_length_errors,
)
from saddlescope.core.errors import InputError
from saddlescope.core.types import Board, Camera, Rig

__all__ = ["refine_board_and_wand"]

_N_LENS = 2  # per camera: k1, k2
BOARD_CORNER_STEP = 3  # every third corner of each board view


class _Observations:
    """One kind of observation: camera index, what is seen (instant or frame), which point, and its pixels."""

    def __init__(self, cam: np.ndarray, item: np.ndarray, point: np.ndarray, xy: np.ndarray):
        self.cam, self.item, self.point, self.xy = cam, item, point, xy


def _board_observations(names: list[str], views: Mapping[str, list[BoardView]], instants: Mapping[int, int],
                        corner_step: int) -> _Observations:
    """Every ``corner_step``-th corner of each view seen at an initialised instant (a view's pose needs few)."""
    parts = [(c, instants[v.frame], np.asarray(v.ids, int)[::corner_step],
              np.asarray(v.corners_px, np.float64)[::corner_step])
             for c, n in enumerate(names) for v in views.get(n, []) if v.frame in instants]
    if not parts:
        return _Observations(*(np.empty(0, int),) * 3, np.empty((0, 2)))
    return _Observations(np.concatenate([np.full(len(ids), c) for c, _, ids, _ in parts]),
                         np.concatenate([np.full(len(ids), i) for _, i, ids, _ in parts]),
                         np.concatenate([ids for _, _, ids, _ in parts]), np.concatenate([xy for *_, xy in parts]))


def _wand_observations(names: list[str], views: Mapping[str, list[WandView]], frames: Mapping[int, int]
                       ) -> _Observations:
    rows = [(c, frames[v.frame], v.ends_px) for c, n in enumerate(names) for v in views.get(n, []) if v.frame in frames]
    return _Observations(np.repeat([r[0] for r in rows], 2).astype(int), np.repeat([r[1] for r in rows], 2).astype(int),
                         np.tile([0, 1], len(rows)), np.concatenate([r[2] for r in rows]))


class _BoardWandBundle:
    """Residuals (px) of the board's corners and the wand's ends under one set of cameras."""

    def __init__(self, cams: list[Camera], board_obs: _Observations, n_instants: int, wand_obs: _Observations,
                 n_frames: int, obj_mm: np.ndarray, length_mm: float):
        self.cams, self.b, self.w, self.obj, self.L = cams, board_obs, wand_obs, obj_mm, length_mm
        self.C, self.I, self.F = len(cams), n_instants, n_frames
        self.intr0 = np.array([_intr_vector(c) for c in cams])
        self.n_pose, self.n_lens = 6 * (self.C - 1), _N_LENS * self.C

    def split(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Camera poses (C, 6), lenses' k1 k2 (C, 2), board poses (I, 6), wand poses (F, 5)."""
        a, b, c = self.n_pose, self.n_pose + self.n_lens, self.n_pose + self.n_lens + 6 * self.I
        poses = np.vstack([np.zeros(6), x[:a].reshape(-1, 6)])
        return poses, x[a:b].reshape(-1, _N_LENS), x[b:c].reshape(-1, 6), x[c:].reshape(-1, 5)

    def _project(self, X: np.ndarray, cam: np.ndarray, poses: np.ndarray, lens: np.ndarray) -> np.ndarray:
        intr = self.intr0[cam].copy()
        intr[:, 4:6] = lens[cam]
        xc = np.einsum("mij,mj->mi", _rotation_matrices(poses[:, :3])[cam], X) + poses[cam, 3:]
        return _distort_project(xc, intr)

    def residuals(self, x: np.ndarray) -> np.ndarray:
        poses, lens, boards, wand = self.split(x)
        Rb = _rotation_matrices(boards[:, :3])[self.b.item]
        Xb = np.einsum("mij,mj->mi", Rb, self.obj[self.b.point]) + boards[self.b.item, 3:]
        centre, d = wand[:, :3], _direction(wand[:, 3:])
        ends = np.stack([centre - d * self.L / 2, centre + d * self.L / 2], axis=1)
        Xw = ends[self.w.item, self.w.point]
        return np.concatenate([(self._project(Xb, self.b.cam, poses, lens) - self.b.xy).ravel(),
                               (self._project(Xw, self.w.cam, poses, lens) - self.w.xy).ravel()])

    def sparsity(self) -> coo_matrix:
        """Which parameters each residual depends on: its camera's pose and lens, its board's or wand's pose."""
        rows, cols = [], []
        offset_b = self.n_pose + self.n_lens
        offset_w = offset_b + 6 * self.I
        for obs, start, width, first_row in ((self.b, offset_b, 6, 0), (self.w, offset_w, 5, 2 * len(self.b.cam))):
            m = np.arange(len(obs.cam))
            every = np.ones(len(m), bool)
            blocks = [(obs.cam >= 1, 6 * (obs.cam - 1), 6), (every, self.n_pose + _N_LENS * obs.cam, _N_LENS),
                      (every, start + width * obs.item, width)]
            for use, first_col, n in blocks:
                for k in range(n):
                    for axis in (0, 1):
                        rows.append(first_row + 2 * m[use] + axis)
                        cols.append(first_col[use] + k)
        r, c = np.concatenate(rows), np.concatenate(cols)
        shape = (2 * (len(self.b.cam) + len(self.w.cam)), offset_w + 5 * self.F)
        return coo_matrix((np.ones(len(r), np.uint8), (r, c)), shape=shape)


def _stage(cams: list[Camera], board_views: Mapping[str, list[BoardView]], board: Board,
           wand_views: Mapping[str, list[WandView]], length_mm: float, loss: str) -> tuple[list[Camera], dict]:
    """One joint adjustment of the cameras, the board's poses and the wand's on these views."""
    names = [c.name for c in cams]
    obj = object_points_mm(board)
    inst_pose = _initial_board_poses({c.name: c for c in cams}, board_views, obj)
    instants = {f: i for i, f in enumerate(sorted(inst_pose))}
    frames, wand = _wand_frames(cams, wand_views)
    prob = _BoardWandBundle(cams, _board_observations(names, board_views, instants, BOARD_CORNER_STEP), len(instants),
                            _wand_observations(names, wand_views, {f: i for i, f in enumerate(frames)}),
                            len(frames), obj, length_mm)
    lens0 = np.array([_intr_vector(c)[4:6] for c in cams])
    x0 = np.concatenate([np.concatenate([c.rvec, c.t_mm]) for c in cams[1:]]
                        + [lens0.ravel(), np.array([inst_pose[f] for f in sorted(instants)]).ravel(), wand.ravel()])
    r0 = prob.residuals(x0)
    sol = least_squares(prob.residuals, x0, jac_sparsity=prob.sparsity(), loss=loss, f_scale=1.0, x_scale="jac",
                        method="trf", max_nfev=100)
    poses, lens, _, _ = prob.split(sol.x)
    poses[0] = np.concatenate([cams[0].rvec, cams[0].t_mm])
    out = []
    for c, p, k in zip(cams, poses, lens, strict=True):
        dist = np.pad(np.asarray(c.dist, np.float64).ravel(), (0, 5))[:5]
        dist[:2] = k
        out.append(Camera(c.name, c.K, dist, c.image_size, R=cv2.Rodrigues(p[:3])[0], t_mm=p[3:].copy(),
                          rms_px=c.rms_px, K_std=c.K_std))
    split = 2 * len(prob.b.cam)
    rms = {k: float(np.sqrt(np.mean(np.sum(v.reshape(-1, 2) ** 2, axis=1)))) if v.size else float("nan")
           for k, v in (("board_rms_px", sol.fun[:split]), ("wand_rms_px", sol.fun[split:]))}
    return out, {"n_frames": len(frames), "n_instants": len(instants), "n_evaluations": int(sol.nfev),
                 "initial_rms_px": float(np.sqrt(np.mean(np.sum(r0.reshape(-1, 2) ** 2, axis=1)))), **rms}


def refine_board_and_wand(rig: Rig, board_views: Mapping[str, list[BoardView]], board: Board,
                          wand_views: Mapping[str, list[WandView]], wand_length_mm: float, *,
                          reach_px: Mapping[str, float] | None = None, loss: str = "soft_l1") -> tuple[Rig, dict]:
    """A board-calibrated rig adjusted again with its board views and a wand pass together.

    ``wand_views``: the wand's ends on a clock of their own (the wand's frames), labelled alike in every camera
    (:func:`~saddlescope.core.calibration.wand.relabel_with_rig`); ``reach_px``: the board's lens reach per
    camera, from which the ends are taken in outward.

    Returns
    -------
    rig : Rig
        The adjusted cameras (first = reference), the board rig's checks plus the wand's length check.
    report : dict
        ``bundle`` (each stage's frames, instants, board and wand r.m.s. px, evaluations) and ``radial`` per
        camera: k1, k2 before and after.
    """
    names = [n for n in rig.names if wand_views.get(n)]
    if len(names) < 2:
        raise InputError("a wand refinement needs the wand seen by two or more cameras")
    ref = _to_reference(rig.cameras, rig.names[0])
    cams = [ref[n] for n in rig.names]
    before = {c.name: _intr_vector(c)[4:6].tolist() for c in cams}
    done = []
    for factor in _REFINE_STAGES if reach_px is not None else (np.inf,):
        within = _within([c for c in cams if c.name in names], wand_views, reach_px, factor)
        cams, stage = _stage(cams, board_views, board, within, wand_length_mm, loss)
        done.append({"reach_factor": None if not np.isfinite(factor) else factor, **stage})
    out = {c.name: c for c in cams}
    err = wand_length_errors(Rig(out), wand_views, wand_length_mm)
    checks = {**rig.checks, "wand_length_mm": float(wand_length_mm), "wand_frames": float(len(err)),
              "wand_length_rms_mm": float(np.sqrt(np.mean(err ** 2))) if len(err) else float("nan")}
    radial = {c.name: {"before": before[c.name], "after": _intr_vector(c)[4:6].tolist()} for c in cams}
    return Rig(out, checks=checks, flags=rig.flags, lens_models=rig.lens_models), {"bundle": done, "radial": radial}
