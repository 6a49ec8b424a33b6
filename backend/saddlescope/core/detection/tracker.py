"""Following labelled markers from one frame to the next (thesis 4.5.4-4.5.5, Fig. 4.13).

A window follows the markers' constant-velocity prediction (4.5.4); in it, blobs pass the threshold and
area filters, and the best assignment of blobs to markers is chosen: near the prediction, similar area,
vectors between markers that match the last frame within a tolerance (4.5.5, eq. 4.6-4.11, vectors
rather than distances) and the same cross-product signs as the first frame (Fig. 4.13). Flashes are
skipped; a marker that is not found is a gap, never a guess.
"""

from __future__ import annotations

import itertools
import math
import statistics

import cv2
import numpy as np

from saddlescope.core.detection.blobs import _label
from saddlescope.core.detection.pattern import _THRESHOLD_FRACTION, MarkerPattern, _above_surrounds
from saddlescope.core.detection.refine import _refine

__all__: list[str] = []


def _cross_signs(xy: np.ndarray, min_sine: float = 0.1) -> dict[tuple[int, int, int], float]:
    """Sign of (r_ij x r_jk)_3 for every marker triple that is clearly not collinear (Fig. 4.13)."""
    out = {}
    for i, j, k in itertools.combinations(range(xy.shape[0]), 3):
        a, b = xy[j] - xy[i], xy[k] - xy[j]
        cross = a[0] * b[1] - a[1] * b[0]
        norm = math.hypot(*a) * math.hypot(*b)
        if norm > 0 and abs(cross) / norm > min_sine:
            out[(i, j, k)] = math.copysign(1.0, cross)
    return out


class _Tracker:
    """The per-frame state of :func:`track_markers` (kept private: the public API is the function).

    Per frame: predict (constant velocity), label the window around the prediction, assign blobs to
    markers on the labeller's plain centroids (cheap), then compute sub-pixel centroids of the
    assigned blobs only. The state is a handful of numbers per marker, kept in plain Python lists:
    at 640x480 the whole step must cost well under a millisecond.
    """

    def __init__(self, pattern: MarkerPattern, *, threshold_fixed: bool, window_px, distance_tol: float,
                 pad_px: int, shape):
        self.M = pattern.xy_px.shape[0]
        self.est = pattern.xy_px.tolist()          # [[x, y], ...] estimated positions
        self.vel = [0.0, 0.0]  # px / frame, shared by the markers (one body)
        self.ref_area = pattern.area_px.astype(float).tolist()
        self.ref_contrast = np.maximum(pattern.peak - pattern.background, 2.0).tolist()
        self.background = float(np.median(pattern.background))
        self.ref_background = pattern.background.astype(float).tolist()  # per marker
        self.threshold = pattern.threshold
        self.threshold_fixed = threshold_fixed
        self.area_range = pattern.area_range_px
        # vec_ref[a][b] = x_b - x_a on the last frame where both markers were seen
        self.vec_ref = [[(q[0] - p[0], q[1] - p[1]) for q in self.est] for p in self.est]
        self.signs = _cross_signs(pattern.xy_px)
        self.tol = distance_tol
        self.pad = pad_px
        self.window_px = window_px
        self.H, self.W = shape
        self.base_margin = max(3.0 * pattern.diameter_px, 12.0)
        self.speed_cap = 3 * self.base_margin
        self.lost = 0
        self.steps = 0
        self.level: float | None = None  # running mean grey level of the window (flash guard)

    def window(self, pred) -> tuple[tuple[int, int, int, int], float]:
        grow = 1.5 ** min(self.lost, 12)
        if self.steps < 3:  # the speed is not known yet
            grow *= 2.0
        speed = math.hypot(*self.vel)
        margin = self.base_margin * grow + 0.5 * speed  # the prediction already moved by the speed
        xs = [p[0] for p in pred]
        ys = [p[1] for p in pred]
        if self.window_px is not None:
            w, h = self.window_px
            cx, cy = sum(xs) / len(xs), sum(ys) / len(ys)
            box = (cx - grow * w / 2, cy - grow * h / 2, cx + grow * w / 2, cy + grow * h / 2)
        else:
            box = (min(xs) - margin, min(ys) - margin, max(xs) + margin + 1, max(ys) + margin + 1)
        x0, y0 = max(math.floor(box[0]), 0), max(math.floor(box[1]), 0)
        x1, y1 = min(math.ceil(box[2]), self.W), min(math.ceil(box[3]), self.H)
        return (x0, y0, x1, y1), margin

    def assign(self, xy: list, area: list, pred: list, gate: float) -> list[int]:
        """Best candidate index per marker (-1 = missing): near the prediction, similar area, same pattern."""
        if not xy:
            return [-1] * self.M
        g2 = gate * gate
        options = []
        costs = []
        for i, (px, py) in enumerate(pred):
            lo, hi = 0.25 * self.ref_area[i], 4.0 * self.ref_area[i]
            row = [((x - px) ** 2 + (y - py) ** 2) / g2 for x, y in xy]
            cand = [k for k, c in enumerate(row) if c <= 1.0 and lo <= area[k] <= hi]
            if len(cand) > 4:
                cand = sorted(cand, key=row.__getitem__)[:4]
            options.append(cand + [-1])
            costs.append(row)
        def i_of(combo):
            return next(i for i, c in enumerate(combo) if c >= 0)

        # After a loss, one lone blob proves nothing: ask for two markers that keep their pattern.
        min_found = 2 if self.lost > 0 and self.M >= 2 else 0
        best_cost, best = math.inf, None
        for combo in itertools.product(*options):
            if min_found and sum(c >= 0 for c in combo) < min_found:
                continue
            if self.M >= 2 and sum(c >= 0 for c in combo) == 1 and costs[i_of(combo)][max(combo)] > 0.25:
                continue  # a lone marker has no pattern to vouch for it: it must sit close to its prediction
            total = 0.0
            seen = set()
            for i, c in enumerate(combo):
                if c < 0:
                    total += 2.0  # a gap costs more than any blob within the gate
                elif c in seen:
                    total = math.inf
                    break
                else:
                    seen.add(c)
                    total += costs[i][c]
            if total >= best_cost:
                continue
            total += self._pattern_cost(combo, xy)
            if total < best_cost:
                best_cost, best = total, combo
        return list(best) if best is not None else [-1] * self.M

    def _pattern_cost(self, combo, xy) -> float:
        """Distance filter (eq. 4.11) and cross-product filter; inf when the combination breaks either.

        The distance filter compares the vector between two markers with the last one seen, not just
        its length: a look-alike mirrored across a nearly straight row of markers keeps the distances
        (and, for a straight row, an unreliable cross-product sign) but not the direction.
        """
        found = [i for i, c in enumerate(combo) if c >= 0]
        if len(found) < 2:
            return 0.0
        cost = 0.0
        scale = 0.5 / (len(found) - 1)
        for a, b in itertools.combinations(found, 2):
            rx, ry = self.vec_ref[a][b]
            ref_len = math.hypot(rx, ry)
            if ref_len <= 0:
                continue
            pa, pb = xy[combo[a]], xy[combo[b]]
            rel = math.hypot(pb[0] - pa[0] - rx, pb[1] - pa[1] - ry) / ref_len
            if rel > self.tol:
                return math.inf
            cost += scale * (rel / self.tol) ** 2
        for (i, j, k), sign in self.signs.items():
            if combo[i] >= 0 and combo[j] >= 0 and combo[k] >= 0:
                pi, pj, pk = xy[combo[i]], xy[combo[j]], xy[combo[k]]
                cross = (pj[0] - pi[0]) * (pk[1] - pj[1]) - (pj[1] - pi[1]) * (pk[0] - pj[0])
                if math.copysign(1.0, cross) != sign:
                    return math.inf
        return cost

    def step(self, gray: np.ndarray) -> tuple[list, list]:
        """Markers on one frame: ([x, y] or None per marker, area or None per marker)."""
        self.steps += 1
        vx, vy = self.vel
        pred = [[p[0] + vx, p[1] + vy] for p in self.est]
        (x0, y0, x1, y1), margin = self.window(pred)
        M = self.M
        found: list = [None] * M
        areas: list = [None] * M
        if x1 - x0 < 1 or y1 - y0 < 1:
            self._update(pred, found, areas, [], [])
            return found, areas
        win = gray[y0:y1, x0:x1]  # a view: only the window is read
        level = cv2.mean(win)[0]
        if self.level is None:
            self.level = level
        n, labels, stats, cents = _label(win, self.threshold)
        lo, hi = self.area_range
        area_all = stats[1:n, cv2.CC_STAT_AREA]
        if abs(level - self.level) > 0.25 * min(self.ref_contrast) or area_all.sum() > 0.25 * win.size:
            # The window's brightness jumped (a flash, glare, the sun): whatever shines now is not
            # to be trusted. Skip the frame as if the markers were hidden.
            self._update(pred, found, areas, [], [])
            return found, areas
        self.level += 0.2 * (level - self.level)
        keep = np.flatnonzero((area_all >= lo) & (area_all <= hi)) + 1
        cand_xy = (cents[keep] + (x0, y0)).tolist()
        cand_area = stats[keep, cv2.CC_STAT_AREA].tolist()
        combo = self.assign(cand_xy, cand_area, pred, margin)
        marks = [m for m, c in enumerate(combo) if c >= 0]
        peaks: list = []
        bgs: list = []
        if marks:
            ids = keep[[combo[m] for m in marks]]
            out = _refine(gray, labels, ids, stats[ids, :4], self.pad, self.threshold, (x0, y0)).tolist()
            for m, c, (cx, cy, peak, bg) in zip(marks, ids.tolist(), out, strict=True):
                bx, by, bw, bh = (int(v) for v in stats[c, :4])
                if bx + x0 == 0 or by + y0 == 0 or bx + x0 + bw == self.W or by + y0 + bh == self.H:
                    # Cut by the image border: part of the marker is outside, its centroid is not the
                    # marker's centre. A gap, not a biased point (the prediction still follows it).
                    continue
                found[m] = [cx, cy]
                areas[m] = float(stats[c, cv2.CC_STAT_AREA])
                peaks.append(peak)
                bgs.append(bg)
        self._update(pred, found, areas, peaks, bgs)
        return found, areas

    def _update(self, pred, found, areas, peaks, bgs) -> None:
        seen = [m for m in range(self.M) if found[m] is not None]
        if not seen:
            self.lost += 1
            self.est = pred
            self.vel = [0.9 * self.vel[0], 0.9 * self.vel[1]]
            return
        self.lost = 0
        # The markers sit on one body and turn little between frames: they share one velocity (the
        # median of those seen), and a marker not seen is placed by the pattern, from those seen and
        # the vectors last measured between them. Per-marker velocities let a marker taken on a
        # wrong blob for a frame fling its prediction away: a pole passing a thesis-rig walk merged
        # two predictions onto one marker, and two markers were lost for the rest of the ride.
        new = []
        for m in range(self.M):
            if found[m] is not None:
                new.append(found[m])
                continue
            px = sum(found[s][0] + self.vec_ref[s][m][0] for s in seen) / len(seen)
            py = sum(found[s][1] + self.vec_ref[s][m][1] for s in seen) / len(seen)
            new.append([px, py])
        vx, vy = (statistics.median(found[m][k] - self.est[m][k] for m in seen) for k in (0, 1))
        speed = math.hypot(vx, vy)
        # a wrong match must not fling the window away
        cap = min(1.0, self.speed_cap / speed) if speed > 0 else 1.0
        self.vel = [cap * vx, cap * vy]
        self.est = new
        for a, b in itertools.combinations(seen, 2):
            pa, pb = found[a], found[b]
            self.vec_ref[a][b] = (pb[0] - pa[0], pb[1] - pa[1])
            self.vec_ref[b][a] = (pa[0] - pb[0], pa[1] - pb[1])
        for m, peak, bg in zip(seen, peaks, bgs, strict=True):
            self.ref_area[m] += 0.1 * (areas[m] - self.ref_area[m])
            self.ref_contrast[m] += 0.1 * (max(peak - bg, 2.0) - self.ref_contrast[m])
            self.ref_background[m] += 0.1 * (bg - self.ref_background[m])
        self.background += 0.1 * (sorted(bgs)[len(bgs) // 2] - self.background)
        if not self.threshold_fixed:
            # Follow slow lighting changes: a fixed fraction up the dimmest marker's contrast.
            self.threshold = _above_surrounds(
                self.background + _THRESHOLD_FRACTION * max(min(self.ref_contrast), 2.0),
                self.ref_background, self.ref_contrast)
