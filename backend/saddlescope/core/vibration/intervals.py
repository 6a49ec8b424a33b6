"""95 % intervals on a ride's indicators, and whether a ride is too uncertain for a decision (issue 27).

What the result already knows is turned into a noise model of the saddle point's vertical
harmonics, the stride frequency and the speed (:func:`interval_sources`), and carried through the
indicators by a seeded parametric bootstrap (:func:`bootstrap_indicators`): the nonlinear ones
(VDV, crest factor, peaks, daily times and distances) get their interval from the draws'
percentiles, not from a linearisation.

The noise model, per draw (standard deviations; all relative unless said):

- one gain common to every harmonic and to the displacement, from the calibration's scale
  (``board_square_error_pct``), the spread of the saddle point's acceleration over the thesis's ω
  versions, the roll a rig that fixes depth poorly cannot see (SCIENCE.md, the weak axis), lens
  distortion extrapolated beyond the board's region, and the skin-motion floor (the markers'
  sliding, which no rigid body fitted to them removes; ``bench.analysis.kinematics_floor``), and the
  share of the saddle point's vertical acceleration that is not its harmonic series (a broken
  reconstruction: the indicators describe a periodic motion that is not there);
- per harmonic, complex: the markers' Fourier fits' coefficient covariance under correlated noise
  (their 95 % confidence intervals, ``kinematics.fitting``) carried to the acceleration by (kω)²,
  plus a shape floor (skin motion bends each harmonic on its own);
- the weighted peaks (and so the crest factors) and the peak-to-peak displacement each get a floor of
  their own per gait (``SKIN_FLOORS``): they are tail statistics, moved by skin motion more than
  moving each harmonic a little can account for (exact markers, seeds 1001-1040);
- the fundamental from the fits' ω interval; the speed from the travel fit's slope interval, the
  calibration's scale and, where the lens is extrapolated, the lens's.

The floors (``FLOORS``) were set on arena rides of seeds 1001-1099 and checked on seeds 2001-2099
(``saddlescope bench``, key ``coverage``; ``docs/accuracy.md``).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping

import numpy as np

from saddlescope.core.errors import TriangulationError, VibrationError
from saddlescope.core.vibration.exposure import A8_ACTION_M_S2, A8_LIMIT_M_S2, VDV_ACTION_M_S175, VDV_LIMIT_M_S175
from saddlescope.core.vibration.weighting import weighting_response

__all__ = ["COMFORT_BAND_EDGES_M_S2", "FLOORS", "INTERVAL_KEYS", "MAX_HALF_WIDTH_FRACTION", "SKIN_FLOORS",
           "bootstrap_indicators",
           "decision_uncertainty", "interval_sources", "ride_intervals"]

INTERVAL_KEYS: tuple[str, ...] = (
    "acc_y_wb_rms", "acc_y_wk_rms", "vdv_y_wb", "vdv_y_wk", "acc_y_max", "crest_factor_y", "crest_factor_y_wk",
    "acc_y_wb_peak", "acc_y_wk_peak", "acc_y_rms",
    *(f"{kind}_{basis}_{level}_{w}_{unit}" for kind, unit in (("t", "h"), ("d", "km")) for basis in ("a8", "vdv")
      for level in ("action", "limit") for w in ("wb", "wk")),
    "vel_x_avg_kmh", "amplitude_y_m", "stride_frequency_hz", "vdv_ratio_y_wb")

# One-sigma floors (fractions), set on the build rides (see the module note)
FLOORS: dict[str, float] = {
    "depth_roll": 0.01,       # roll lost where the rig fixes depth this badly (params.depth_anisotropy)
    # times the squared share of detections where the lens is extrapolated: a few % just outside the
    # board's region cost little, a third of the crossing a lot. Fitted (maximum likelihood) on the
    # wide_partial canters of build seeds 1013-1016 and 0-11 (bands 0.6-1.0, shares 0.58-0.73) once
    # samples whose depth rests on the extrapolated lens are left out of the analysis
    # (core.saddle._run_off_guessed_lens): W_b r.m.s. errors r.m.s. 4.0 % (worst 9.8 %), 3.6 % of it
    # the lens's. (Before that fix one canter in four broke, +200-400 %, and this was 0.5.)
    "outside_board": 0.08,
    "omega_spread": 0.2,      # per (median spread of S's acceleration over the ω versions / its r.m.s.)
    "fit_inflation": 1.0,     # the markers' fit noise carried to S (lever arm, rotation)
    "f0": 0.0005,             # the stride period's own floor (the window's edges)
    # the same where the fits saw fewer strides than the indicators span (a partial view analysed on one
    # stride): the wide_partial build canters' stride frequency r.m.s. 0.48 % off (worst 1.2 %), where
    # the fits' own ω interval said 0.1-0.2 %
    "f0_short": 0.005,
    "speed": 0.002,           # the travel direction's tilt and the window's edges
    # the speed's, times the squared share of detections where the lens is extrapolated: the scale
    # there is the lens's, not the board's. The wide_partial build canters (shares 0.6-0.7) were 0.3-0.9 %
    # slow while guessed-depth samples were analysed (this was 0.01 then); left out, r.m.s. 0.06 %
    "speed_outside_board": 0.001,
    # times the r.m.s. residual of S's vertical acceleration about its harmonic series, relative to the
    # series' r.m.s.: the part of the motion that is not the periodic motion the indicators describe.
    # One for one, in the gain and the weighted peaks: on the build rides it is below 0.002 but on
    # one wide_partial canter of four (seed 1014), 0.36, whose W_b r.m.s. came out 3.0 times the
    # truth and crest factor 37 % high (a reconstruction broken by the extrapolated lens)
    "not_periodic": 1.0,
    # times the share of the stride's phase no fitted frame measured (a marker hidden at the same moment
    # of every stride, issue 38; quality.stride_phase_unmeasured_share): the fits bend freely there. Only
    # for results analysed before the phase-deletion test (quality.stride_phase_deletion), and for shares
    # below a tenth of the stride where the test could not be done. A fifth gives ±20 %
    "unmeasured_phase": 0.5,
    # times the phase-deletion test's median change of the indicators (core.kinematics.hidden_phase: as
    # much of the stride left out again at 6 other moments and the ride refitted): what the hidden part
    # costs THIS ride. Set on exact-marker arena rides with the rear marker hidden for a fifth of every
    # stride at a random phase (docs/accuracy.md): the hidden part's worst cost over W_b, W_k, VDV and
    # the displacement was 0.1-7 % at the trots and canters (the walk's up to 52 %, marked), 0.8 times the
    # test's median change in the median and 4.1 times at most; with the skin floors every cost of a ride
    # not marked fell inside its interval, and 3 of the 45 trots and canters were marked (1.5: 10)
    "unmeasured_phase_deletion": 1.0,
    # the same for the test as it is now (quality.stride_phase_deletion.method "one_gap"): the hidden part is
    # filled with the analysis's own fit and each refit leaves one window out elsewhere, as the analysis had one
    # gap (two gaps made a thesis rig's fits drop their orders: the test measured the second gap). Set on the
    # same 60 exact-marker rides (docs/accuracy.md): cost over median change 1.2 in the median, 3.8 at the 90th
    # percentile; with the skin floors 59 of 60 costs inside the interval at 1.0 and 1.5 alike, 2 of the 45
    # trots and canters marked (2.0: 4; the two-gap test at 1.0: 59 of 60, 5 marked)
    "unmeasured_phase_deletion_one_gap": 1.5,
    # where the test could not be done (too few strides fitted) and a tenth of the stride or more was
    # unmeasured: ±20 %, which marks the ride too uncertain (a one-stride canter with a boot over its
    # rear marker came out +88 % with ±8 % before the partly covered samples were left out)
    "unmeasured_phase_untested": 0.1,
}

# The skin-motion floor per gait: (gain, harmonic shape, weighted peak, displacement). The gain and the
# shape together are what the markers' sliding on the skin alone costs the W_b r.m.s.: the exact marker
# positions (no cameras) of build seeds 1001-1040 on the thesis rig and 1001-1020 on the wide one, 60
# rides a gait (`bench.analysis.exact_marker_floor`), put it off by r.m.s. 5.4 / 5.3 % at the walk,
# 2.1 % at the trots and 2.5 % at the canter (its VDV 2.6-2.8 %). The shape (each harmonic on its own,
# complex) moves the r.m.s. by 2.1 % at the walk, 1.0-1.1 % at the trots and 1.7 % at the canter; the
# gain is the rest, sqrt(observed² - shape's²). (It was half the worst of seeds 1001-1006 only: walk
# 3.1 %, canter 1.3 %, which left the walk's and the canter's intervals too narrow.) The walk's floor
# alone makes its 95 % interval ±10.5 %: wider than a decision needs (MAX_HALF_WIDTH_FRACTION), for
# any walk filmed with skin markers. Sliding the three markers share moves the body they define
# (arena seed 2005: 11.8 % of the vertical acceleration), which no rigid body fitted to them can tell.
# The weighted peaks' and displacement's terms from the same exact markers: their weighted crest factor
# is off by r.m.s. 3.4 % at the walk, 1.2-1.3 % at the trots and 3.7 % at the canter, three times what
# the shape floor gives it (0.9, 0.4 and 1.4 %): a peak is a tail statistic, where the few harmonics
# skin motion bends add up in phase, and moving each harmonic a little does not make a tail. The rest,
# sqrt(observed² - shape's²), multiplies the weighted peaks of every draw (and so the crest factors).
# Likewise the peak-to-peak displacement (the walk's: r.m.s. 7.3 %, 4 % high on average, against 3.9 %
# from gain and shape; the trots' 2.3-2.5 % against 2.1 %; the canter's less).
SKIN_FLOORS: dict[str, tuple[float, float, float, float]] = {
    "walk": (0.050, 0.04, 0.033, 0.062), "sitting_trot": (0.017, 0.02, 0.012, 0.013),
    "rising_trot": (0.016, 0.02, 0.012, 0.009), "canter": (0.020, 0.04, 0.034, 0.0)}

# A ride is too uncertain for a decision when its W_b r.m.s. interval's half-width exceeds this share
# of the value. Such an interval spans a ratio of at most 1.1 / 0.9 = 1.22, less than between any two
# adjacent edges of ISO 2631-1's comfort bands (Annex C.2.3; their lower edges below, m/s²: not
# uncomfortable < 0.315 < a little < 0.5 < fairly < 0.8 < uncomfortable < 1.25 < very < 2.0 <
# extremely uncomfortable): an interval narrow enough never straddles more than one band edge.
MAX_HALF_WIDTH_FRACTION = 0.10
COMFORT_BAND_EDGES_M_S2: tuple[float, ...] = (0.315, 0.5, 0.8, 1.25, 2.0)

_Z95 = 1.959963984540054
_DEPTH_ANISOTROPY = 5.0  # PipelineParams.depth_anisotropy's default
_OUTSIDE_FLAG = re.compile(r"outside the region the calibration board covered in (\d+(?:\.\d+)?) %")


def _half_width_sigma(ci) -> float:
    """One sigma from a [low, high] 95 % interval (NaN when absent)."""
    try:
        lo, hi = float(ci[0]), float(ci[1])
    except (TypeError, ValueError, IndexError):
        return math.nan
    return (hi - lo) / (2 * _Z95) if math.isfinite(lo) and math.isfinite(hi) else math.nan


def _fit_harmonic_sigma(fits_y: list, n_harmonics: int, omega: float) -> np.ndarray:
    """Per harmonic k, the std (m/s²) of the cosine and sine coefficients of a marker's vertical acceleration.

    From each marker's vertical fit: its coefficients' 95 % intervals (correlated noise accounted
    for) times (kω)²; root mean square over the markers; zero beyond the fits' order.
    """
    per_marker = []
    for fit in fits_y:
        ci = fit.get("ci95") or {}
        sig = [np.nanmean([_half_width_sigma(a), _half_width_sigma(b)])
               for a, b in zip(ci.get("a", []), ci.get("b", []), strict=False)]
        per_marker.append(sig)
    pos = np.full(n_harmonics, np.nan)
    if per_marker:
        order = max(len(s) for s in per_marker)
        padded = np.full((len(per_marker), order), np.nan)
        for i, s in enumerate(per_marker):
            padded[i, :len(s)] = s
        with np.errstate(invalid="ignore"):
            rms = np.sqrt(np.nanmean(padded ** 2, axis=0)) if order else np.array([])
        pos[:min(order, n_harmonics)] = rms[:n_harmonics]
    # beyond the fits' order S's harmonics come from products of the fitted ones (the rotation terms),
    # whose noise is counted there
    pos = np.where(np.isfinite(pos), pos, 0.0)
    k = np.arange(1, n_harmonics + 1)
    return pos * (k * omega) ** 2


def _relative_sigma(fits: list, key: str, value_of) -> float:
    """Median relative one-sigma of a fitted quantity over the markers' fits (NaN when none)."""
    out = []
    for fit in fits:
        ci = (fit.get("ci95") or {}).get(key)
        value = value_of(fit)
        if ci is None or value is None or not value:
            continue
        ci = ci[0] if isinstance(ci[0], list) else ci
        out.append(abs(_half_width_sigma(ci) / value))
    return float(np.nanmedian(out)) if out else math.nan


def _outside_board_share(result) -> float:
    """The largest share of a camera's detections outside the board's region (lens extrapolated)."""
    shares = result.quality.get("markers_outside_board_fraction")
    if isinstance(shares, Mapping) and shares:
        return float(max(shares.values()))
    found = []
    for f in result.findings:
        if f.code != "calibration.coverage":
            continue
        if "outside_share_pct" in f.values:
            found.append(f.values["outside_share_pct"] / 100)
        # results written before the share was a number hold it in the sentence only (read back by
        # saddlescope.io.legacy_flags, without values)
        elif m := _OUTSIDE_FLAG.search(f.detail):
            found.append(float(m.group(1)) / 100)
    return max(found, default=0.0)


def _speed_sigma(fits_x: list) -> float:
    """Relative one-sigma of the average speed from the travel fits (slope, or a Fourier fit's trend)."""
    def slope(fit):
        if "trend" in fit and fit["trend"]:
            return fit["trend"][0]
        return fit.get("slope")
    sig_trend = _relative_sigma(fits_x, "trend", slope)
    return sig_trend if math.isfinite(sig_trend) else _relative_sigma(fits_x, "slope", slope)


def _fewer_strides_fitted(result) -> bool:
    """Whether the analysed window held fewer strides than the indicators span (:func:`_indicator_strides`)."""
    period_s = float(result.period_s or 0.0)
    return period_s > 0 and round(float(result.window.duration_s) / period_s) < _indicator_strides(result)


def _indicator_strides(result) -> int:
    """How many strides the indicators span: ``params.n_periods``, else their duration's, else 2."""
    ind, vh = result.indicators, result.vertical_harmonics
    return int((result.params or {}).get("n_periods") or round(ind.get("duration_s", 0) * vh.f0_hz) or 2)


def _unmeasured_phase_part(quality: Mapping) -> float:
    """The common gain's part (relative sigma) for the stride phase no fitted frame measured.

    The phase-deletion test's r.m.s. change (``quality["stride_phase_deletion"]``) where it was done;
    where it could not be done, the share's fixed cost but at least ±20 % (the ride is too uncertain);
    results analysed before the test (and small shares it could not test) keep the share's fixed cost.
    """
    share = float(quality.get("stride_phase_unmeasured_share") or 0.0)
    test = quality.get("stride_phase_deletion")
    if not share or not test:
        return FLOORS["unmeasured_phase"] * share
    if not test.get("tested"):
        return max(FLOORS["unmeasured_phase"] * share, FLOORS["unmeasured_phase_untested"])
    factor = FLOORS["unmeasured_phase_deletion_one_gap" if test.get("method") == "one_gap" else
                    "unmeasured_phase_deletion"]
    return factor * float(test["median_change"])


def interval_sources(result, *, depth_anisotropy: float | None = None) -> dict:
    """The noise model's standard deviations for one ride, from what its result knows.

    Parameters
    ----------
    result : RideResult
    depth_anisotropy : float, optional
        How many times worse the rig fixes depth than image position at the markers; computed from
        the rig at the motion frame's origin when not given.

    Returns
    -------
    dict
        ``gain`` (relative, common to the harmonics and the displacement) with its parts in
        ``gain_parts``, ``harmonic_m_s2`` (K,) the per-harmonic coefficient std, ``shape`` (relative, per
        harmonic), ``f0`` and ``speed`` (relative).
    """
    from saddlescope.core.triangulation.uncertainty import position_uncertainty

    q, vh = result.quality, result.vertical_harmonics
    fits = result.markers.fits or {}
    amps = np.asarray(vh.amplitudes_m_s2, dtype=float)
    omega = 2 * np.pi * float(vh.f0_hz)
    checks = result.rig.checks or {}
    scale = float(checks.get("board_square_error_pct", 0.0) or 0.0) / 100
    acc_rms = float(np.sqrt(np.sum(amps ** 2) / 2))
    spread = float(q.get("saddle_acceleration_spread_m_s2_median") or 0.0) / max(acc_rms, 1e-9)
    if depth_anisotropy is None and not result.rig.cameras:
        depth_anisotropy = 1.0  # motion capture: positions measured directly, no camera geometry
    elif depth_anisotropy is None:
        try:
            depth_anisotropy = float(position_uncertainty(result.rig, result.motion_frame.origin_mm)["anisotropy"])
        except TriangulationError:  # cameras that cannot fix the point: depth-poor
            depth_anisotropy = math.inf
    outside = _outside_board_share(result)
    parts = {"calibration_scale": scale, "omega_versions": FLOORS["omega_spread"] * spread,
             "depth_roll": FLOORS["depth_roll"] if depth_anisotropy >= _DEPTH_ANISOTROPY else 0.0,
             "lens_extrapolated": FLOORS["outside_board"] * outside ** 2,
             "unmeasured_phase": _unmeasured_phase_part(q)}
    # an unknown gait takes the widest floors
    widest = tuple(max(parts) for parts in zip(*SKIN_FLOORS.values(), strict=True))
    skin_gain, shape, skin_peak, skin_disp = SKIN_FLOORS.get(result.gait or "", widest)
    parts["skin_motion"] = skin_gain
    residual = float(q.get("vertical_harmonic_fit_rms_m_s2") or 0.0) / max(acc_rms, 1e-9)
    parts["not_periodic"] = FLOORS["not_periodic"] * residual
    f0_sig = _relative_sigma(fits.get("y", []), "omega_rad_s", lambda f: f.get("omega_rad_s"))
    speed_fit = _speed_sigma(fits.get("x", []))
    return {
        "gain": float(np.sqrt(sum(v ** 2 for v in parts.values()))), "gain_parts": parts,
        "harmonic_m_s2": FLOORS["fit_inflation"] * _fit_harmonic_sigma(fits.get("y", []), amps.size, omega),
        "shape": shape, "peak": float(np.hypot(skin_peak, parts["not_periodic"])), "displacement": skin_disp,
        "f0": float(np.hypot(f0_sig if math.isfinite(f0_sig) else 0.0,
                             FLOORS["f0_short"] if _fewer_strides_fitted(result) else FLOORS["f0"])),
        "speed": float(np.sqrt((speed_fit if math.isfinite(speed_fit) else 0.0) ** 2 + scale ** 2
                               + FLOORS["speed"] ** 2 + (FLOORS["speed_outside_board"] * outside ** 2) ** 2)),
        "depth_anisotropy": depth_anisotropy, "outside_board_share": outside,
    }


def _series_metrics(f0: np.ndarray, coef: np.ndarray, weighting: str | None, n_periods: int) -> dict:
    """r.m.s., peak and VDV of periodic series, one per row.

    f0 : (D,) Hz; coef : (D, K) complex, a(t) = Re Σ_k coef_k e^{i2πkf0t}; VDV over ``n_periods``.
    """
    k = np.arange(1, coef.shape[1] + 1)
    if weighting is not None:
        coef = coef * weighting_response(weighting, f0[:, None] * k[None, :])
    rms = np.sqrt(np.sum(np.abs(coef) ** 2, axis=1) / 2)  # Parseval
    n_grid = max(64 * coef.shape[1], 256)
    theta = 2 * np.pi * np.arange(n_grid) / n_grid
    a = _real_series(coef, k, theta)
    a2 = a * a
    return {"rms": rms, "peak": _grid_peak(np.abs(a)), "vdv": (n_periods * np.mean(a2 * a2, axis=1) / f0) ** 0.25}


def _real_series(coef: np.ndarray, k: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Re Σ_k coef_k e^{ikθ} per row, (D, N): real products (a complex matmul is ten times slower)."""
    arg = np.outer(k, theta)
    return coef.real @ np.cos(arg) - coef.imag @ np.sin(arg)


def _grid_peak(y: np.ndarray) -> np.ndarray:
    """Each row's maximum of a periodic grid, refined by the parabola through it and its neighbours."""
    i = np.argmax(y, axis=1)
    rows = np.arange(y.shape[0])
    n = y.shape[1]
    y0, ym, yp = y[rows, i], y[rows, (i - 1) % n], y[rows, (i + 1) % n]
    curv = ym - 2 * y0 + yp
    with np.errstate(divide="ignore", invalid="ignore"):
        peak = y0 - (ym - yp) ** 2 / (8 * curv)
    return np.where(curv < 0, np.maximum(peak, y0), y0)


def _check_bootstrap(f0_hz: float, amps: np.ndarray, phases: np.ndarray, n_periods: int, draws: int,
                     sources: Mapping) -> None:
    """Refuse inputs the bootstrap cannot use, each with what was expected."""
    if amps.ndim != 1 or amps.size == 0 or phases.shape != amps.shape:
        raise VibrationError(f"amplitudes and phases must be 1-D of one length, got shapes {amps.shape} and "
                             f"{phases.shape}")
    if not (np.all(np.isfinite(amps)) and np.all(np.isfinite(phases))):
        raise VibrationError("amplitudes and phases must be finite")
    if not (isinstance(f0_hz, int | float | np.floating) and math.isfinite(f0_hz) and f0_hz > 0):
        raise VibrationError(f"f0_hz must be a positive number of Hz, got {f0_hz!r}")
    if int(n_periods) < 1 or int(draws) < 10:
        raise VibrationError(f"n_periods must be >= 1 and draws >= 10, got {n_periods} and {draws}")
    missing = {"f0", "gain", "speed", "shape", "harmonic_m_s2"} - set(sources)
    if missing:
        raise VibrationError(f"sources lack {', '.join(sorted(missing))} (see interval_sources)")
    if np.shape(sources["harmonic_m_s2"]) != amps.shape:
        raise VibrationError(f"sources['harmonic_m_s2'] has shape {np.shape(sources['harmonic_m_s2'])}, the "
                             f"harmonics {amps.shape}")


def bootstrap_indicators(*, f0_hz: float, amplitudes_m_s2, phases_rad, n_periods: int, speed_kmh: float,
                         amplitude_y_m: float, sources: Mapping, draws: int = 400,
                         rng: np.random.Generator) -> dict[str, np.ndarray]:
    """Every key of :data:`INTERVAL_KEYS` for ``draws`` draws of the noise model (row 0: the estimate).

    Parameters
    ----------
    f0_hz : float
        The vertical series' fundamental (the stride frequency).
    amplitudes_m_s2, phases_rad : array_like of shape (K,)
        S's vertical acceleration a(t) = Σ A_k cos(2πk f0 t + φ_k).
    n_periods : int
        Periods in the analysed window (VDV).
    speed_kmh, amplitude_y_m : float
        The estimates of the average speed and the peak-to-peak displacement.
    sources : mapping
        :func:`interval_sources`.
    draws : int
    rng : numpy.random.Generator

    Returns
    -------
    dict of str -> ndarray of shape (draws + 1,)
    """
    amps = np.atleast_1d(np.asarray(amplitudes_m_s2, dtype=float))
    phases = np.atleast_1d(np.asarray(phases_rad, dtype=float))
    _check_bootstrap(f0_hz, amps, phases, n_periods, draws, sources)
    coef0 = amps * np.exp(1j * phases)
    n_k = coef0.size
    z = rng.standard_normal((draws, 4 + 4 * n_k))
    zero = np.zeros((1, z.shape[1]))
    z = np.vstack([zero, z])
    f0 = f0_hz * (1 + sources["f0"] * z[:, 0])
    gain = 1 + sources["gain"] * z[:, 1]
    speed = speed_kmh * (1 + sources["speed"] * z[:, 2])
    shape = sources["shape"] * (z[:, 4:4 + n_k] + 1j * z[:, 4 + n_k:4 + 2 * n_k]) / np.sqrt(2)
    sig_k = np.asarray(sources["harmonic_m_s2"], dtype=float)[None, :]
    noise = sig_k * (z[:, 4 + 2 * n_k:4 + 3 * n_k] + 1j * z[:, 4 + 3 * n_k:4 + 4 * n_k])
    # a cos + b sin with a, b of std σ: the complex coefficient a - ib
    coef = coef0[None, :] * (gain[:, None] + shape) + noise
    m = {w: _series_metrics(f0, coef, w, n_periods) for w in ("Wb", "Wk", None)}
    # the weighted peaks' own floor (SKIN_FLOORS), common to W_b and W_k: the weightings lift the
    # harmonics where skin motion bends the shape most, and a peak is where they align
    peak_factor = 1 + float(sources.get("peak", 0.0)) * z[:, 3]
    for w in ("Wb", "Wk"):
        m[w]["peak"] = m[w]["peak"] * peak_factor
    out = {"acc_y_wb_rms": m["Wb"]["rms"], "acc_y_wk_rms": m["Wk"]["rms"], "vdv_y_wb": m["Wb"]["vdv"],
           "vdv_y_wk": m["Wk"]["vdv"], "acc_y_max": m[None]["peak"], "acc_y_rms": m[None]["rms"],
           "crest_factor_y": m["Wb"]["peak"] / m["Wb"]["rms"], "crest_factor_y_wk": m["Wk"]["peak"] / m["Wk"]["rms"],
           "acc_y_wb_peak": m["Wb"]["peak"], "acc_y_wk_peak": m["Wk"]["peak"]}
    duration_s = n_periods / f0
    out["vdv_ratio_y_wb"] = m["Wb"]["vdv"] / (1.4 * m["Wb"]["rms"] * duration_s ** 0.25)  # ISO 2631-1 6.3.3
    thresholds = {"a8": {"action": A8_ACTION_M_S2, "limit": A8_LIMIT_M_S2},
                  "vdv": {"action": VDV_ACTION_M_S175, "limit": VDV_LIMIT_M_S175}}
    for w in ("wb", "wk"):
        met = m["Wb" if w == "wb" else "Wk"]
        for level in ("action", "limit"):
            t_a8 = 8.0 * (thresholds["a8"][level] / met["rms"]) ** 2  # eq. 7.10-7.13
            t_vdv = duration_s * (thresholds["vdv"][level] / met["vdv"]) ** 4 / 3600  # corrected eq. 7.14-7.17
            out[f"t_a8_{level}_{w}_h"], out[f"t_vdv_{level}_{w}_h"] = t_a8, t_vdv
            out[f"d_a8_{level}_{w}_km"], out[f"d_vdv_{level}_{w}_km"] = speed * t_a8, speed * t_vdv  # eq. 7.18-7.25
    out["vel_x_avg_kmh"] = speed
    out["stride_frequency_hz"] = f0
    # the displacement: the drawn acceleration integrated twice, relative to the estimate's own
    k = np.arange(1, n_k + 1)
    pos = _real_series(-coef / (k * 2 * np.pi * f0[:, None]) ** 2, k, np.linspace(0, 2 * np.pi, 512, endpoint=False))
    p2p = pos.max(axis=1) - pos.min(axis=1)
    out["amplitude_y_m"] = amplitude_y_m * p2p / p2p[0] if p2p[0] > 0 else np.full_like(p2p, amplitude_y_m)
    # the displacement's own floor (SKIN_FLOORS), drawn after the others so that they stay as they were
    z_disp = np.concatenate([[0.0], rng.standard_normal(draws)])
    out["amplitude_y_m"] = out["amplitude_y_m"] * (1 + float(sources.get("displacement", 0.0)) * z_disp)
    return out


def ride_intervals(result, *, draws: int = 400, seed: int = 0, sources: Mapping | None = None
                   ) -> dict[str, tuple[float, float]]:
    """The 95 % interval (2.5th and 97.5th percentiles of the bootstrap) of every indicator of a ride.

    Parameters
    ----------
    result : RideResult
    draws : int
        Bootstrap draws (400: the percentiles' own scatter is ~3 % of the width).
    seed : int
        The draws are seeded: the same result gives the same intervals.
    sources : mapping, optional
        :func:`interval_sources` (computed when not given).

    Returns
    -------
    dict of str -> (low, high)
        For the keys of :data:`INTERVAL_KEYS` the result's indicators hold.
    """
    vh, ind = result.vertical_harmonics, result.indicators
    n_periods = _indicator_strides(result)
    sources = sources if sources is not None else interval_sources(result)
    samples = bootstrap_indicators(f0_hz=float(vh.f0_hz), amplitudes_m_s2=vh.amplitudes_m_s2,
                                   phases_rad=vh.phases_rad, n_periods=n_periods,
                                   speed_kmh=float(ind["vel_x_avg_kmh"]), amplitude_y_m=float(ind["amplitude_y_m"]),
                                   sources=sources, draws=draws, rng=np.random.default_rng(seed))
    out = {}
    for key in INTERVAL_KEYS:
        if key not in ind or not math.isfinite(float(ind[key])):
            continue
        draws_k = samples[key][1:]
        draws_k = draws_k[np.isfinite(draws_k)]
        if draws_k.size:
            lo, hi = np.percentile(draws_k, [2.5, 97.5])
            # the estimate itself stays inside (percentiles of a skewed few hundred draws can miss it)
            out[key] = (float(min(lo, ind[key])), float(max(hi, ind[key])))
    return out


def _largest_part(sources: Mapping | None) -> str:
    """", mostly from ..." naming the largest part of the common gain, or "" without sources."""
    parts = (sources or {}).get("gain_parts") or {}
    known = {k: float(v) for k, v in parts.items() if k in _GAIN_PART_WORDS and v}
    if not known:
        return ""
    return f", mostly from {_GAIN_PART_WORDS[max(known, key=lambda part: known[part])]}"


def _band(value: float) -> int:
    return int(np.searchsorted(COMFORT_BAND_EDGES_M_S2, value, side="right"))


# what each part of the common gain is, in a club's words (the largest one is named in the verdict)
_GAIN_PART_WORDS = {
    "skin_motion": "the markers sliding on the skin, which no camera can remove (at the walk this alone is "
                   "about ±10 %, against the walk's small motion)",
    "lens_extrapolated": "the markers being seen where the calibration board never went (carry the board to "
                         "the edges of every camera's view)",
    "omega_versions": "the saddle's rotation being poorly fixed by the three markers (spread them further apart)",
    "calibration_scale": "the calibration board's measured size (check the square size entered)",
    "depth_roll": "the cameras fixing depth poorly (place them further apart)",
    "not_periodic": "a saddle motion that does not repeat stride by stride (a reconstruction that broke, or an "
                    "uneven ride)",
    "unmeasured_phase": "a marker hidden at the same moment of every stride (place the markers where the rider's "
                        "leg, the tail or a lunge line does not pass)",
}


def decision_uncertainty(indicators: Mapping[str, float], intervals: Mapping[str, tuple[float, float]],
                         sources: Mapping | None = None) -> str | None:
    """Why a ride is too uncertain for a decision (a sentence), or None when it is not.

    The rule (``docs/accuracy.md``): the W_b r.m.s.'s 95 % interval's half-width exceeds
    :data:`MAX_HALF_WIDTH_FRACTION` of the value (narrower intervals never span more than one ISO 2631-1
    comfort band edge, :data:`COMFORT_BAND_EDGES_M_S2`; checked again here for a changed threshold).
    With ``sources`` (:func:`interval_sources`) the sentence names the largest part of the common gain.
    """
    if "acc_y_wb_rms" not in intervals or "acc_y_wb_rms" not in indicators:
        return "the W_b r.m.s. has no interval, so its uncertainty is unknown"
    value = float(indicators["acc_y_wb_rms"])
    lo, hi = intervals["acc_y_wb_rms"]
    half = 0.5 * (hi - lo) / value if value > 0 else math.inf
    if half > MAX_HALF_WIDTH_FRACTION:
        return (f"the W_b r.m.s. is known only to ±{100 * half:.0f} % (95 % interval {lo:.2f}-{hi:.2f} m/s²; "
                f"a decision needs ±{100 * MAX_HALF_WIDTH_FRACTION:.0f} %)" + _largest_part(sources))
    if _band(hi) - _band(lo) > 1:
        return (f"the W_b r.m.s.'s 95 % interval {lo:.2f}-{hi:.2f} m/s² spans more than one ISO 2631-1 comfort "
                "band")
    return None
