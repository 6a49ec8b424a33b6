"""The saddle-point localizer: where a lost checkerboard may be, and grids grown over its corners."""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import cv2
import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

__all__: list[str] = []  # helpers of the package's other modules only


@dataclass(frozen=True)
class _Cluster:
    box: np.ndarray  # (x0, y0, x1, y1) px round the points, with room for the board's outer squares
    spacing: float  # px, typical distance between neighbouring points
    points: np.ndarray  # (M, 2) px, the saddle points
    theta: np.ndarray  # (M,) rad, direction of each point's positive curvature (it turns 90 degrees from
    # a board's corner to the next along the grid, as the dark squares swap diagonals)


def _saddle_clusters(gray: np.ndarray, n_corners: int) -> list[_Cluster]:
    """Dense clusters of strong saddle points that may hold a board of ``n_corners`` corners.

    Saddle strength is minus the Hessian determinant (high at checkerboard corners); the largest cluster
    comes first.
    """
    g = cv2.GaussianBlur(gray.astype(np.float32), (0, 0), 1.0)
    xx = cv2.Sobel(g, cv2.CV_32F, 2, 0, ksize=3)
    yy = cv2.Sobel(g, cv2.CV_32F, 0, 2, ksize=3)
    xy = cv2.Sobel(g, cv2.CV_32F, 1, 1, ksize=3)
    s = np.maximum(xy * xy - xx * yy, 0.0)
    k = max(n_corners // 2, 2)
    # the board's corners are the strongest saddles of the frame: keep those within 5x of its middle one
    s[[0, -1], :] = 0
    s[:, [0, -1]] = 0
    peaks = (s >= cv2.dilate(s, np.ones((3, 3), np.uint8))) & (s > 0)
    values = s[peaks]
    if len(values) < k:
        return []
    ys, xs = np.nonzero(peaks & (s > 0.2 * np.partition(values, -k)[-k]))
    if len(xs) < k:
        return []
    # sub-pixel peaks (a parabola through three samples each way)
    c, l, r, u, d = s[ys, xs], s[ys, xs - 1], s[ys, xs + 1], s[ys - 1, xs], s[ys + 1, xs]
    dx = 0.5 * (l - r) / np.minimum(l + r - 2 * c, -1e-12)
    dy = 0.5 * (u - d) / np.minimum(u + d - 2 * c, -1e-12)
    pts = np.column_stack([xs + np.clip(dx, -0.5, 0.5), ys + np.clip(dy, -0.5, 0.5)]).astype(np.float64)
    theta = 0.5 * np.arctan2(2 * xy[ys, xs], xx[ys, xs] - yy[ys, xs]).astype(np.float64)
    tree = cKDTree(pts)
    nearest = tree.query(pts, k=2)[0][:, 1]
    pairs = tree.query_pairs(2.0 * float(np.median(nearest)), output_type="ndarray")
    graph = csr_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(pts), len(pts)))
    _, label = connected_components(graph, directed=False)
    clusters = []
    for lab, count in zip(*np.unique(label, return_counts=True), strict=True):
        if count >= k:
            member = label == lab
            p = pts[member]
            spacing = float(np.median(nearest[member]))
            pad = 2.5 * spacing  # the outer squares and a margin round the inner corners
            clusters.append(_Cluster(np.concatenate([p.min(axis=0) - pad, p.max(axis=0) + pad]), spacing, p,
                                     theta[member]))
    return sorted(clusters, key=lambda cl: -len(cl.points))


def _grids_from_saddles(cluster: _Cluster, inner_corners: tuple[int, int]) -> list[np.ndarray]:
    """Candidate board corners (rows * cols, 2), row-major, from a lattice grown over a cluster's points.

    The lattice grows from the saddle point nearest the cluster's middle; every full cols x rows window
    of it is a candidate (the lattice also takes in the corners of the board's outer squares, and
    perhaps points beyond). The caller checks them.

    Neighbours along the grid are about a step away, where the step (which perspective changes slowly)
    predicts them, and of the other polarity.
    """
    cols, rows = inner_corners
    pts, theta = cluster.points, cluster.theta
    if len(pts) < cols * rows:
        return []
    # a lattice point's four neighbours along the grid are among its eight nearest points
    _, nearest = cKDTree(pts).query(pts, k=min(9, len(pts)))
    xy, th, near8 = pts.tolist(), theta.tolist(), nearest[:, 1:].tolist()

    def across(i: int, j: int) -> bool:  # neighbours along the grid: positive curvature turned 90 degrees
        return math.cos(2 * (th[i] - th[j])) < 0

    seed = int(np.argmin(np.sum((pts - pts.mean(axis=0)) ** 2, axis=1)))
    near = [j for j in near8[seed] if across(seed, j)
            and math.dist(xy[seed], xy[j]) < 1.8 * cluster.spacing]
    if len(near) < 2:
        return []
    u = pts[near[0]] - pts[seed]
    v = max((pts[j] - pts[seed] for j in near[1:]),
            key=lambda w: abs(u[0] * w[1] - u[1] * w[0]) / np.linalg.norm(w))
    if abs(u[0] * v[1] - u[1] * v[0]) < 0.5 * np.linalg.norm(u) * np.linalg.norm(v):
        return []  # no second direction
    node = {(0, 0): seed}
    steps = {(0, 0): (tuple(u), tuple(v))}
    taken = {seed}
    todo = [(0, 0)]
    while todo:
        i, j = todo.pop()
        (ux, uy), (vx, vy) = steps[(i, j)]
        here = node[(i, j)]
        hx, hy = xy[here]
        for di, dj, sx, sy in ((1, 0, ux, uy), (-1, 0, -ux, -uy), (0, 1, vx, vy), (0, -1, -vx, -vy)):
            key = (i + di, j + dj)
            if key in node:
                continue
            px, py = hx + sx, hy + sy
            k = min(near8[here], key=lambda m: (xy[m][0] - px) ** 2 + (xy[m][1] - py) ** 2)
            if math.dist(xy[k], (px, py)) > 0.3 * math.hypot(sx, sy) or not across(here, k):
                continue
            if k in taken:
                return []  # one point on two grid places: not a lattice
            node[key] = k
            taken.add(k)
            fx, fy = xy[k][0] - hx, xy[k][1] - hy
            steps[key] = ((di * fx, di * fy), (vx, vy)) if di else ((ux, uy), (dj * fx, dj * fy))
            todo.append(key)
        if len(node) > (cols + 4) * (rows + 4):
            return []
    ij = np.array(list(node))
    lo = ij.min(axis=0)
    ni, nj = ij.max(axis=0) - lo + 1
    have = np.zeros((ni, nj), bool)
    where = np.zeros((ni, nj, 2))
    have[ij[:, 0] - lo[0], ij[:, 1] - lo[1]] = True
    where[ij[:, 0] - lo[0], ij[:, 1] - lo[1]] = pts[list(node.values())]
    grids = []
    for a, b in {(cols, rows), (rows, cols)}:  # the board's columns along the lattice's first axis or second
        for oi, oj in itertools.product(range(ni - a + 1), range(nj - b + 1)):
            if have[oi:oi + a, oj:oj + b].all():
                win = where[oi:oi + a, oj:oj + b]
                grids.append((win.transpose(1, 0, 2) if a == cols else win).reshape(-1, 2))
    return grids
