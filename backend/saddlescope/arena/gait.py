"""Gait model of the synthetic arena: the saddle body's exact motion as Fourier series.

The saddle body (saddle plus the horse's back under it, with markers 1-3 on the skin and the saddle
point S) moves as a rigid body: its origin O(t) translates with a constant forward speed plus
periodic surge, vertical and lateral oscillation, and it rotates by R(t) built from periodic roll,
pitch and yaw angles. Every channel is a Fourier series of the stride frequency f0,
``c(t) = sum_k A_k cos(2 pi k f0 t + phi_k)`` (k = 1..K), so positions, velocities and
accelerations of any body point, and the angular velocity and acceleration of the body, are exact
closed forms (no numerical differentiation).

Frame of this module ("arena frame", metres): the thesis's motion reference frame axes, x = direction
of travel, y = gravity (down), z = x cross y; its origin is on the track line at the height of the
body origin at rest, abreast of the middle camera. Body axes coincide with arena axes when all angles
are zero. The markers sit on the camera-facing side of the horse (``camera_side`` = -1 or +1 along z).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from saddlescope.core.errors import InputError
from saddlescope.core.types import GAITS

__all__ = [
    "CHANNELS",
    "GAIT_RANGES",
    "MARKER_LAYOUTS",
    "MARKER_NAMES",
    "N_HARMONICS",
    "SADDLE_NAME",
    "SKIN_MODELS",
    "SKIN_NOISE_BAND_HZ",
    "SKIN_NOISE_COMPONENTS",
    "SKIN_NOISE_RMS_M",
    "GaitModel",
    "acceleration_harmonics",
    "fourier_series",
    "saddle_vertical_peak_to_peak",
    "sample_gait",
    "with_high_harmonic",
    "with_t_cross",
]

CHANNELS: tuple[str, ...] = ("x", "y", "z", "roll", "pitch", "yaw")
N_HARMONICS = 4
MARKER_NAMES: tuple[str, ...] = ("marker1", "marker2", "marker3")
SADDLE_NAME = "saddle"
# "stride_locked": sliding at the stride's first two harmonics plus a wobble near the third, a few
# millimetres, as a real flank slides with the limbs; no fit can tell its stride-locked part from the
# body's motion, so it sets a floor under any three-marker method. "noise": only small random
# sliding, not locked to the stride (what rigid registration and the fits are there to reject).
# "none": markers fixed to the saddle body (checks of the stages alone).
SKIN_MODELS: tuple[str, ...] = ("stride_locked", "noise", "none")  # the first is the default
# Markers 1-3 on the flank: "thesis", a shallow V (the middle marker 3-5 cm below the line of the
# others, as in the thesis's photographs), or "triangle", the middle one about 10 cm below (what the
# README recommends: the roll about the row is then fixed 4-12 times better)
MARKER_LAYOUTS: tuple[str, ...] = ("thesis", "triangle")  # the first is the default
_TRIANGLE_DROP_M = 0.06  # extra drop of marker 2 in the triangle layout (before the horse's scale)
SKIN_NOISE_RMS_M = (0.0004, 0.0010)  # per marker and in-plane axis, drawn in this range
SKIN_NOISE_BAND_HZ = (0.3, 6.0)
SKIN_NOISE_COMPONENTS = 48

# Literature ranges (SCIENCE.md, "Reference numbers"); the speed bands are narrowed inside the
# literature range so that two strides fit in the thesis rig's 6.5 m field of view.
GAIT_RANGES: dict[str, dict] = {
    "walk": {"stride_hz": (0.86, 0.94), "speed_m_s": (1.25, 1.75), "pp_y_m": (0.02, 0.04)},
    "sitting_trot": {"stride_hz": (1.32, 1.48), "speed_m_s": (2.65, 3.2), "pp_y_m": (0.08, 0.13)},
    "rising_trot": {"stride_hz": (1.32, 1.48), "speed_m_s": (2.9, 3.5), "pp_y_m": (0.08, 0.14)},
    "canter": {"stride_hz": (1.61, 1.69), "speed_m_s": (3.6, 4.4), "pp_y_m": (0.17, 0.27)},
}

# Relative harmonic amplitudes (k = 1..4) of each channel per gait: walk and trot have their
# vertical oscillation at 2x stride frequency, canter at 1x (SCIENCE.md). Translations in metres,
# angles in degrees; the vertical channel is rescaled afterwards to the sampled peak-to-peak.
_SHAPES: dict[str, dict[str, list[float]]] = {
    "walk": {
        "x": [0.004, 0.012, 0.002, 0.0],
        "y": [0.12, 1.0, 0.08, 0.04],
        "z": [0.014, 0.003, 0.002, 0.0],
        "roll": [1.0, 0.3, 0.1, 0.0],
        "pitch": [0.5, 1.0, 0.2, 0.0],
        "yaw": [1.5, 0.3, 0.0, 0.0],
    },
    "sitting_trot": {
        "x": [0.002, 0.018, 0.003, 0.0],
        "y": [0.05, 1.0, 0.04, 0.05],
        "z": [0.008, 0.004, 0.001, 0.0],
        "roll": [1.0, 1.0, 0.2, 0.0],
        "pitch": [0.3, 1.5, 0.3, 0.0],
        "yaw": [1.0, 0.4, 0.0, 0.0],
    },
    "rising_trot": {
        "x": [0.004, 0.02, 0.003, 0.0],
        "y": [0.12, 1.0, 0.04, 0.05],
        "z": [0.008, 0.004, 0.001, 0.0],
        "roll": [1.2, 1.0, 0.2, 0.0],
        "pitch": [0.4, 1.5, 0.3, 0.0],
        "yaw": [1.0, 0.4, 0.0, 0.0],
    },
    "canter": {
        "x": [0.035, 0.01, 0.003, 0.0],
        "y": [1.0, 0.08, 0.025, 0.008],
        "z": [0.02, 0.006, 0.002, 0.0],
        "roll": [2.0, 0.6, 0.2, 0.0],
        "pitch": [4.0, 1.0, 0.3, 0.0],
        "yaw": [1.5, 0.4, 0.1, 0.0],
    },
}


def fourier_series(
    t_s: np.ndarray, f0_hz: float, amplitudes: np.ndarray, phases_rad: np.ndarray, *, derivative: int = 0
) -> np.ndarray:
    """Evaluate sum_k A_k cos(2 pi k f0 t + phi_k) (k = 1..K) or its 1st/2nd time derivative.

    t_s : ndarray of shape (T,); amplitudes, phases_rad : ndarray of shape (K,). Returns (T,).
    """
    t = np.asarray(t_s, dtype=np.float64)
    k = np.arange(1, len(amplitudes) + 1, dtype=np.float64)
    w = 2.0 * np.pi * f0_hz * k  # rad/s per harmonic
    arg = np.multiply.outer(t, w) + np.asarray(phases_rad, dtype=np.float64)
    amps = np.asarray(amplitudes, dtype=np.float64)
    if derivative == 0:
        return np.cos(arg) @ amps
    if derivative == 1:
        return -np.sin(arg) @ (amps * w)
    if derivative == 2:
        return -np.cos(arg) @ (amps * w**2)
    raise InputError(f"fourier_series derivative must be 0, 1 or 2, got {derivative}")


def _skew(v: np.ndarray) -> np.ndarray:
    """Cross-product matrices of shape (3, 3) of a vector (3,)."""
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _axis_rotation(axis: int, angle: np.ndarray) -> np.ndarray:
    """Rotations about a coordinate axis by angle (T,) -> (T, 3, 3)."""
    c, s = np.cos(angle), np.sin(angle)
    out = np.zeros(angle.shape + (3, 3))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    out[..., axis, axis] = 1.0
    out[..., i, i] = c
    out[..., j, j] = c
    out[..., i, j] = -s
    out[..., j, i] = s
    return out


def _vee(m: np.ndarray) -> np.ndarray:
    """Vector of the skew-symmetric part of (T, 3, 3) matrices -> (T, 3)."""
    a = 0.5 * (m - np.swapaxes(m, -1, -2))
    return np.stack([a[..., 2, 1], a[..., 0, 2], a[..., 1, 0]], axis=-1)


@dataclass(frozen=True)
class GaitModel:
    """Exact periodic motion of the saddle body in the arena frame (metres, seconds).

    ``harmonics[name]`` = (amplitudes (K,), phases (K,)) for channels x (surge, m), y (vertical, m),
    z (lateral, m), roll / pitch / yaw (rad, about the x / z / y axes; R = R_y(yaw) R_z(pitch)
    R_x(roll)). The forward position is ``speed (t - t_cross) + surge(t)``; the body origin is at
    rest height y = 0 on the track line z = 0 on average. ``body_points_m`` holds marker1..3 and
    saddle in body coordinates, shape (3,) each. ``skin`` holds the markers' skin motion relative to
    the body: per marker amplitudes (3, J) m, frequencies (J,) Hz and phases (3, J) rad.
    """

    gait: str
    stride_hz: float
    speed_m_s: float
    t_cross_s: float
    harmonics: dict[str, tuple[np.ndarray, np.ndarray]]
    body_points_m: dict[str, np.ndarray]
    camera_side: float
    skin: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)
    horse_height_m: float = 1.65
    # a ride of several passes in front of the cameras (issue 38): per pass (t_cross_s, speed_m_s), in
    # time order; the forward position is that of the pass whose crossing is nearest in time (the horse
    # changes pass out of view, going round the arena), the stride's phase runs on. Empty: one pass at
    # ``speed_m_s`` crossing at ``t_cross_s``.
    passes: tuple[tuple[float, float], ...] = ()
    # with passes: the travel stops this far (m) either side of the crossing, out of every view (0: never),
    # so that a horse far along the track never projects near a converging camera's image plane
    pass_reach_m: float = 0.0

    @property
    def period_s(self) -> float:
        """One stride (s)."""
        return 1.0 / self.stride_hz

    # --- translation and rotation -------------------------------------------------------------
    def origin(self, t_s: np.ndarray, *, derivative: int = 0) -> np.ndarray:
        """Body origin O(t) or its derivative in the arena frame: (T,) -> (T, 3) m, m/s or m/s^2."""
        t = np.atleast_1d(np.asarray(t_s, dtype=np.float64))
        out = np.empty(t.shape + (3,))
        for axis, name in enumerate(("x", "y", "z")):
            amps, phases = self.harmonics[name]
            out[:, axis] = fourier_series(t, self.stride_hz, amps, phases, derivative=derivative)
        t_cross, speed = self._travel(t)
        travel = speed * (t - t_cross)
        reach = self.pass_reach_m if self.passes and self.pass_reach_m > 0 else np.inf
        if derivative == 0:
            out[:, 0] += np.clip(travel, -reach, reach)
        elif derivative == 1:
            out[:, 0] += np.where(np.abs(travel) < reach, speed, 0.0)
        return out

    def _travel(self, t: np.ndarray) -> tuple[np.ndarray | float, np.ndarray | float]:
        """The crossing instant (s) and forward speed (m/s) in force at each of ``t`` (T,)."""
        if not self.passes:
            return self.t_cross_s, self.speed_m_s
        crossings = np.array([p[0] for p in self.passes])
        speeds = np.array([p[1] for p in self.passes])
        # the pass in force changes halfway between two crossings (out of every camera's view)
        idx = np.searchsorted(0.5 * (crossings[1:] + crossings[:-1]), t)
        return crossings[idx], speeds[idx]

    def angles(self, t_s: np.ndarray, *, derivative: int = 0) -> np.ndarray:
        """Roll, pitch, yaw (rad) or their derivatives: (T,) -> (T, 3)."""
        t = np.atleast_1d(np.asarray(t_s, dtype=np.float64))
        cols = []
        for name in ("roll", "pitch", "yaw"):
            amps, phases = self.harmonics[name]
            cols.append(fourier_series(t, self.stride_hz, amps, phases, derivative=derivative))
        return np.stack(cols, axis=-1)

    def rotation(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """R(t), dR/dt, d2R/dt2 of body -> arena at ``t_s`` (T,) s, each (T, 3, 3), exact by the product rule."""
        ang = [self.angles(t_s, derivative=d) for d in range(3)]
        mats = []
        # R = A B C with A = R_y(yaw), B = R_z(pitch), C = R_x(roll)
        for axis, col in ((1, 2), (2, 1), (0, 0)):
            e = np.zeros(3)
            e[axis] = 1.0
            k = _skew(e)
            th, dth, ddth = ang[0][:, col], ang[1][:, col], ang[2][:, col]
            m = _axis_rotation(axis, th)
            dm = (m @ k) * dth[:, None, None]  # dE/dt = E K theta'
            ddm = m @ (k[None] * ddth[:, None, None] + (k @ k)[None] * (dth**2)[:, None, None])
            mats.append((m, dm, ddm))
        (a, da, dda), (b, db, ddb), (c, dc, ddc) = mats
        r = a @ b @ c
        dr = da @ b @ c + a @ db @ c + a @ b @ dc
        ddr = dda @ b @ c + a @ ddb @ c + a @ b @ ddc + 2.0 * (da @ db @ c + da @ b @ dc + a @ db @ dc)
        return r, dr, ddr

    def angular(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Angular velocity omega (rad/s) and acceleration alpha (rad/s^2) in the arena frame, (T, 3) each.

        At instants ``t_s`` (T,) s.
        """
        r, dr, ddr = self.rotation(t_s)
        rt = np.swapaxes(r, -1, -2)
        omega = _vee(dr @ rt)  # skew(omega) = dR R^T
        alpha = _vee(ddr @ rt)  # skew(alpha) = skew part of d2R R^T (dR dR^T is symmetric)
        return omega, alpha

    def point(self, r_body_m: np.ndarray, t_s: np.ndarray, *, derivative: int = 0) -> np.ndarray:
        """A body point ``r_body_m`` (3,) m in the arena frame at ``t_s`` (T,) s.

        Returns its position (T, 3) m, velocity m/s or acceleration m/s^2 (``derivative`` 0, 1, 2).
        """
        r = np.asarray(r_body_m, dtype=np.float64)
        rot = self.rotation(t_s)[derivative]
        return self.origin(t_s, derivative=derivative) + rot @ r

    def skin_offset(self, name: str, t_s: np.ndarray, *, derivative: int = 0) -> np.ndarray:
        """Skin motion of marker ``name`` in body coordinates at instants ``t_s`` (T,) s.

        Returns the offset (T, 3) m or its ``derivative``-th time derivative; zero where none is
        modelled.
        """
        t = np.atleast_1d(np.asarray(t_s, dtype=np.float64))
        sk = self.skin.get(name)
        if sk is None:
            return np.zeros(t.shape + (3,))
        w = 2.0 * np.pi * sk["freq_hz"]
        # d^n/dt^n A sin(w t + phi) = A w^n sin(w t + phi + n pi/2)
        arg = np.multiply.outer(t, w)[:, None, :] + sk["phase_rad"][None] + derivative * np.pi / 2
        return np.sum((sk["amp_m"] * w**derivative)[None] * np.sin(arg), axis=-1)

    def skin_common_mode(self, t_s: np.ndarray, *, derivative: int = 0) -> np.ndarray:
        """The mean of markers 1-3's skin sliding in the arena frame (T, 3) m, or its derivative (up to 2).

        At instants ``t_s`` (T,) s. This is the part of the sliding that moves all three markers
        alike, which a rigid body fitted to them cannot tell from the body's own motion and which so
        goes straight into the saddle point.
        """
        t = np.atleast_1d(np.asarray(t_s, dtype=np.float64))
        s = [np.mean([self.skin_offset(n, t, derivative=d) for n in MARKER_NAMES], axis=0) for d in range(3)]
        rot = self.rotation(t)
        # (R s)'' = R'' s + 2 R' s' + R s''
        terms = {0: ((0, 0, 1.0),), 1: ((1, 0, 1.0), (0, 1, 1.0)), 2: ((2, 0, 1.0), (1, 1, 2.0), (0, 2, 1.0))}
        return sum(c * np.einsum("tij,tj->ti", rot[r], s[k]) for r, k, c in terms[derivative])

    def marker_positions(self, t_s: np.ndarray, *, skin: bool = True) -> np.ndarray:
        """Markers 1-3 and the saddle point in the arena frame, (T, 4, 3) m at ``t_s`` (T,) s; skin motion on 1-3."""
        t = np.atleast_1d(np.asarray(t_s, dtype=np.float64))
        rot = self.rotation(t)[0]
        org = self.origin(t)
        out = np.empty(t.shape + (4, 3))
        for i, name in enumerate(MARKER_NAMES + (SADDLE_NAME,)):
            r = self.body_points_m[name][None, :]
            if skin and name in self.skin:
                r = r + self.skin_offset(name, t)
            out[:, i] = org + np.einsum("tij,tj->ti", rot, np.broadcast_to(r, (len(t), 3)))
        return out

    # --- serialisation -------------------------------------------------------------------------
    def to_dict(self) -> dict:
        """Everything needed to evaluate the motion (JSON-ready lists)."""
        return {
            "gait": self.gait,
            "stride_hz": self.stride_hz,
            "f0_hz": self.stride_hz,
            "speed_m_s": self.speed_m_s,
            "t_cross_s": self.t_cross_s,
            "camera_side": self.camera_side,
            "horse_height_m": self.horse_height_m,
            "rotation_order": "R = R_y(yaw) @ R_z(pitch) @ R_x(roll), body -> arena",
            "series": "c(t) = sum_k A_k cos(2 pi k f0 t + phi_k), k = 1..K; x adds speed (t - t_cross)",
            "harmonics": {
                k: {"amplitudes": a.tolist(), "phases_rad": p.tolist()}
                for k, (a, p) in self.harmonics.items()
            },
            "body_points_m": {k: v.tolist() for k, v in self.body_points_m.items()},
            "skin": {k: {kk: vv.tolist() for kk, vv in v.items()} for k, v in self.skin.items()},
            **({"passes": [{"t_cross_s": t, "speed_m_s": v} for t, v in self.passes],
                "pass_reach_m": self.pass_reach_m} if self.passes else {}),
        }

    @classmethod
    def from_dict(cls, d: dict) -> GaitModel:
        """The model written by :meth:`to_dict` (truth.json ``truth.model``); InputError if incomplete."""
        try:
            harm = {
                k: (np.asarray(v["amplitudes"], float), np.asarray(v["phases_rad"], float))
                for k, v in d["harmonics"].items()
            }
            missing = [c for c in CHANNELS if c not in harm]
            if missing:
                raise InputError(f"gait model lacks the harmonics of channel(s) {missing}")
            return cls(
                gait=d["gait"],
                stride_hz=float(d["stride_hz"]),
                speed_m_s=float(d["speed_m_s"]),
                t_cross_s=float(d["t_cross_s"]),
                harmonics=harm,
                body_points_m={k: np.asarray(v, float) for k, v in d["body_points_m"].items()},
                camera_side=float(d["camera_side"]),
                skin={
                    k: {kk: np.asarray(vv, float) for kk, vv in v.items()}
                    for k, v in d.get("skin", {}).items()
                },
                horse_height_m=float(d.get("horse_height_m", 1.65)),
                passes=tuple((float(p["t_cross_s"]), float(p["speed_m_s"])) for p in d.get("passes", ())),
                pass_reach_m=float(d.get("pass_reach_m", 0.0)),
            )
        except (KeyError, TypeError) as exc:
            raise InputError(f"truth gait model is incomplete: missing or malformed {exc}") from None


def saddle_vertical_peak_to_peak(model: GaitModel, *, samples: int = 4096) -> float:
    """Peak-to-peak vertical displacement (m) of the saddle point S over one stride period."""
    t = np.arange(samples) * (model.period_s / samples)
    y = model.point(model.body_points_m[SADDLE_NAME], t)[:, 1]
    # refine the two extrema on the exact function (parabola through the neighbours)
    pp = []
    for sign in (1.0, -1.0):
        i = int(np.argmax(sign * y))
        ts = t[i] + np.array([-1.0, 0.0, 1.0]) * (model.period_s / samples)
        ys = model.point(model.body_points_m[SADDLE_NAME], ts)[:, 1]
        denom = ys[0] - 2 * ys[1] + ys[2]
        pp.append(ys[1] - 0.125 * (ys[2] - ys[0]) ** 2 / denom if denom != 0 else ys[1])
    return float(pp[0] - pp[1])


def sample_gait(
    gait: str,
    rng: np.random.Generator,
    *,
    camera_side: float,
    t_cross_s: float = 0.0,
    speed_range_m_s: tuple[float, float] | None = None,
    skin_model: str = "stride_locked",
    marker_layout: str = "thesis",
) -> GaitModel:
    """Draw one horse's gait: stride frequency, speed, Fourier coefficients, marker layout, skin motion.

    ``camera_side`` (+1 or -1) is the arena z side of the horse that faces the cameras (markers and
    saddle point go there). ``speed_range_m_s`` narrows the speed band (e.g. to fit a field of view).
    ``skin_model`` is one of :data:`SKIN_MODELS` (see :func:`_skin_motion`); ``marker_layout`` one of
    :data:`MARKER_LAYOUTS`. Neither changes the random draws: a seed gives the same horse under each.
    """
    if skin_model not in SKIN_MODELS:
        raise InputError(f"unknown skin model {skin_model!r}; expected one of {', '.join(SKIN_MODELS)}")
    if marker_layout not in MARKER_LAYOUTS:
        raise InputError(f"unknown marker layout {marker_layout!r}; expected one of {', '.join(MARKER_LAYOUTS)}")
    if gait not in GAIT_RANGES:
        raise InputError(f"unknown gait {gait!r}; expected one of {', '.join(GAITS)}")
    rng_ = GAIT_RANGES[gait]
    stride_hz = float(rng.uniform(*rng_["stride_hz"]))
    lo, hi = speed_range_m_s or rng_["speed_m_s"]
    speed = float(rng.uniform(lo, hi))
    pp_target = float(rng.uniform(*rng_["pp_y_m"]))
    horse_height = float(rng.uniform(1.55, 1.75))
    harmonics = _draw_harmonics(gait, rng)
    s = float(np.sign(camera_side)) or 1.0
    body = _draw_body_points(rng, s, horse_height / 1.65, marker_layout)
    skin = _skin_motion(skin_model, rng, stride_hz)

    model = GaitModel(
        gait=gait,
        stride_hz=stride_hz,
        speed_m_s=speed,
        t_cross_s=t_cross_s,
        harmonics=harmonics,
        body_points_m=body,
        camera_side=s,
        skin=skin,
        horse_height_m=horse_height,
    )
    return _with_vertical_peak_to_peak(model, pp_target)


def _draw_harmonics(gait: str, rng: np.random.Generator) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Amplitudes (K,) and phases (K,) rad of every channel: the gait's shape scaled by 0.7-1.3 each.

    Translations in metres, angles in radians (the shapes hold degrees).
    """
    harmonics: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for name in CHANNELS:
        shape = np.asarray(_SHAPES[gait][name], dtype=np.float64)
        amps = shape * rng.uniform(0.7, 1.3, N_HARMONICS)
        if name in ("roll", "pitch", "yaw"):
            amps = np.deg2rad(amps)
        phases = rng.uniform(-np.pi, np.pi, N_HARMONICS)
        harmonics[name] = (amps, phases)
    return harmonics


def _draw_body_points(rng: np.random.Generator, s: float, scale: float, marker_layout: str) -> dict[str, np.ndarray]:
    """Markers 1-3 and the saddle point S in body coordinates (3,) m each, with small per-horse changes.

    ``s`` (+1 or -1) is the camera-facing side along body z; ``scale`` the horse's height over 1.65 m.
    """
    jit = lambda sd: rng.normal(0.0, sd)  # noqa: E731  small per-horse layout changes
    spacing = float(rng.uniform(0.17, 0.23))
    x1 = -0.15 + jit(0.015)
    drop = _TRIANGLE_DROP_M if marker_layout == "triangle" else 0.0
    return {
        # a shallow V along the flank behind the rider's leg, numbered front (withers) to back
        "marker1": np.array([x1, 0.26 * scale + jit(0.01), s * (0.27 + jit(0.01))]),
        "marker2": np.array([x1 - spacing, (0.30 + drop) * scale + jit(0.01), s * (0.28 + jit(0.01))]),
        "marker3": np.array(
            [x1 - spacing - float(rng.uniform(0.17, 0.23)), 0.25 * scale + jit(0.01), s * (0.27 + jit(0.01))]
        ),
        # S on the saddle's side, above the marker row (hidden by the rider during the ride)
        SADDLE_NAME: np.array([-0.25 + jit(0.02), -0.03 + jit(0.01), s * (0.2 + jit(0.01))]),
    }


def _with_vertical_peak_to_peak(model: GaitModel, pp_target_m: float) -> GaitModel:
    """The model with its vertical channel scaled so that S's peak-to-peak equals the target (m).

    Six fixed-point steps: the body's rotation adds a little to S's vertical travel.
    """
    for _ in range(6):
        pp = saddle_vertical_peak_to_peak(model)
        amps, phases = model.harmonics["y"]
        harmonics = dict(model.harmonics)
        harmonics["y"] = (amps * (pp_target_m / pp), phases)
        model = GaitModel(
            gait=model.gait,
            stride_hz=model.stride_hz,
            speed_m_s=model.speed_m_s,
            t_cross_s=model.t_cross_s,
            harmonics=harmonics,
            body_points_m=model.body_points_m,
            camera_side=model.camera_side,
            skin=model.skin,
            horse_height_m=model.horse_height_m,
        )
    return model


def with_high_harmonic(model: GaitModel, order: int, share: float, rng: np.random.Generator) -> GaitModel:
    """The model with a vertical harmonic of the stride at ``order`` (beyond the gait's four) added.

    Its acceleration's r.m.s. is ``share`` of the vertical acceleration's r.m.s. before it; its phase
    is drawn from ``rng``. (A trot whose saddle rings at its 6th harmonic, 8-9 Hz, issue 38.)
    """
    amps, phases = (np.asarray(v, dtype=np.float64) for v in model.harmonics["y"])
    w = 2 * np.pi * model.stride_hz * np.arange(1, len(amps) + 1)
    acc_rms = float(np.sqrt(np.sum((amps * w**2) ** 2) / 2))
    k = int(order)
    new_amps = np.concatenate([amps, np.zeros(max(k - len(amps), 0))])
    new_phases = np.concatenate([phases, np.zeros(max(k - len(phases), 0))])
    new_amps[k - 1] = share * acc_rms * np.sqrt(2.0) / (2 * np.pi * model.stride_hz * k) ** 2
    new_phases[k - 1] = float(rng.uniform(-np.pi, np.pi))
    harmonics = dict(model.harmonics)
    harmonics["y"] = (new_amps, new_phases)
    return replace(model, harmonics=harmonics)


def _skin_motion(skin_model: str, rng: np.random.Generator, stride_hz: float) -> dict:
    """Per marker, the skin's sliding over the body as a sum of sines.

    Amplitudes (3, J) m along body x, y, z, frequencies (J,) Hz, phases (3, J) rad. Both sliding
    models are drawn from the same stream whichever is asked for, so a seed gives the same horse and
    cameras under each.
    """
    locked, noise = {}, {}
    for name in MARKER_NAMES:
        # two stride harmonics plus one incommensurate wobble, a few millimetres
        freq = np.array([stride_hz, 2.0 * stride_hz, stride_hz * float(rng.uniform(2.6, 3.4))])
        amp = rng.uniform(0.0005, 0.0025, (3, 3)) * np.array([1.0, 1.0, 0.4])[None, :]
        locked[name] = {"amp_m": amp, "freq_hz": freq, "phase_rad": rng.uniform(-np.pi, np.pi, (3, 3))}
    for name in MARKER_NAMES:
        # band-limited random sliding: many sines at random frequencies, displacement falling as
        # 1/f (soft tissue), each axis scaled to its drawn r.m.s., the flank's normal (z) to 0.4 of it
        freq = rng.uniform(*SKIN_NOISE_BAND_HZ, SKIN_NOISE_COMPONENTS)
        amp = (1.0 / freq)[None, :] * rng.rayleigh(1.0, (3, SKIN_NOISE_COMPONENTS))
        rms = rng.uniform(*SKIN_NOISE_RMS_M, 3) * np.array([1.0, 1.0, 0.4])
        amp *= (rms / np.sqrt(0.5 * np.sum(amp**2, axis=1)))[:, None]
        noise[name] = {"amp_m": amp, "freq_hz": freq,
                       "phase_rad": rng.uniform(-np.pi, np.pi, (3, SKIN_NOISE_COMPONENTS))}
    return {"stride_locked": locked, "noise": noise, "none": {}}[skin_model]


def with_t_cross(model: GaitModel, t_cross_s: float) -> GaitModel:
    """The same horse crossing the arena origin at another time."""
    return GaitModel(
        gait=model.gait,
        stride_hz=model.stride_hz,
        speed_m_s=model.speed_m_s,
        t_cross_s=float(t_cross_s),
        harmonics=model.harmonics,
        body_points_m=model.body_points_m,
        camera_side=model.camera_side,
        skin=model.skin,
        horse_height_m=model.horse_height_m,
    )


def acceleration_harmonics(
    model: GaitModel, r_body_m: np.ndarray, *, axis: int = 1, n_harmonics: int = 40, samples: int = 512
) -> tuple[np.ndarray, np.ndarray]:
    """Cosine series of a body point's acceleration along ``axis``: (A_k, phi_k), k = 1..n.

    ``r_body_m`` (3,) is the point in body coordinates; returns amplitudes (n,) m/s^2 and phases
    (n,) rad of a(t) = sum_k A_k cos(2 pi k f0 t + phi_k) with t the model's (left-clip) time. The exact
    acceleration is periodic (the forward speed is constant), so the FFT of ``samples`` points over
    one period gives the coefficients to machine precision while samples > 2 n.
    """
    if samples <= 2 * n_harmonics:
        raise InputError(f"need more than {2 * n_harmonics} samples per period for {n_harmonics} harmonics")
    t = np.arange(samples) * (model.period_s / samples)
    a = model.point(r_body_m, t, derivative=2)[:, axis]
    spec = np.fft.rfft(a) / samples
    c = spec[1 : n_harmonics + 1]
    return 2.0 * np.abs(c), np.angle(c)
