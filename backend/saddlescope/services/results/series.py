"""The ride page's derived series: fitted curves over measured samples, residuals, weighted acceleration.

Everything here is computed from a stored result document with the science core's own functions, so
the page shows the analysis, not a second one:

- the saddle point S's measured positions (the registered data) with a Fourier/line fit per axis
  (``core.kinematics.fit_marker_kinematics``, the same fit the markers get), and its velocity and
  acceleration as measured (central differences of the measured positions) against the fitted ones
  (the result's own, the fits' derivatives), each with its residual (measured - fitted);
- the W_b- and W_k-weighted vertical acceleration over time and its harmonic spectrum, weighted
  exactly per harmonic with the complex response (``core.vibration.weighting_response``), from the
  result's vertical harmonics (``core.saddle.vertical_harmonics`` when an older result lacks them).

Fitting 10,000 samples takes seconds, so :func:`derived_series` computes all of them once, at full
resolution, when a result is stored (``services.results.documents.commit_result``); the ride page decimates them.

:data:`DERIVED` declares each series (its name with its unit, what it is): the ride page's view serves
exactly these, and the API's ``ResultSeries`` is made from the same declarations, so a new series is
its computation and its line there (and its chart in the ride page's list, ``views/ride.js``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from saddlescope.core.kinematics import fit_marker_kinematics
from saddlescope.core.saddle import vertical_harmonics
from saddlescope.core.vibration import weighting_response

__all__ = [
    "DERIVED", "DERIVED_FORMAT", "DERIVED_SERIES", "WEIGHTINGS", "DerivedSeries", "derived_series",
    "fitted_saddle_series", "strides_analysed", "vertical_harmonics_of", "weighted_series",
]

WEIGHTINGS = (("wb", "Wb"), ("wk", "Wk"))  # (key suffix, ISO/BS weighting name): W_b = BS 6841, W_k = ISO 2631-1
# The stored derived series' and ride pages' format (services/results/documents.py): a stored file of another format
# is computed again and replaced. Bump it when a series is added or computed differently (a new chart).
DERIVED_FORMAT = 1


@dataclass(frozen=True)
class DerivedSeries:
    """One series :func:`derived_series` computes: its name (unit suffix) and what it is, for the API's schema."""

    name: str
    description: str


# Every derived series, in the ride page's view whether or not a result can give it (None then).
DERIVED = (
    DerivedSeries("position_fitted_m", "S's position from a Fourier (or straight-line) fit per axis"),
    DerivedSeries("position_residual_m", "measured minus fitted position"),
    DerivedSeries("velocity_measured_m_s", "central differences of the measured positions"),
    DerivedSeries("velocity_residual_m_s", "measured minus fitted velocity (the result's velocity_m_s)"),
    DerivedSeries("acceleration_measured_m_s2", "second differences of the measured positions"),
    DerivedSeries("acceleration_residual_m_s2", "measured minus fitted acceleration (the result's acceleration_m_s2)"),
    DerivedSeries("acc_y_wb_m_s2", "vertical acceleration weighted with W_b (BS 6841), exact per harmonic"),
    DerivedSeries("acc_y_wk_m_s2", "vertical acceleration weighted with W_k (ISO 2631-1), exact per harmonic"),
)
DERIVED_SERIES = tuple(series.name for series in DERIVED)


def _array(values: Any, columns: int | None = None) -> np.ndarray | None:
    try:
        arr = np.asarray(values if values is not None else [], dtype=np.float64)
    except (TypeError, ValueError):
        return None
    if arr.size == 0 or (columns is not None and (arr.ndim != 2 or arr.shape[1] != columns)):
        return None
    return arr


def _rows(arr: np.ndarray | None) -> list | None:
    """JSON-safe values (NaN as None), rounded: 7 decimals are far below what a chart shows."""
    if arr is None:
        return None
    rounded = np.round(np.asarray(arr, dtype=np.float64), 7)
    # numpy's stubs take no None as a branch of `where`; numpy does (an object array)
    return np.where(np.isfinite(rounded), rounded, None).tolist()  # type: ignore[call-overload]


def strides_analysed(doc: dict[str, Any]) -> int | None:
    """Whole strides in the analysed window (the thesis analyses two)."""
    n = (doc.get("params") or {}).get("n_periods")
    if isinstance(n, int | float) and n > 0:
        return int(n)
    period, duration = doc.get("period_s"), (doc.get("window") or {}).get("duration_s")
    if isinstance(period, int | float) and isinstance(duration, int | float) and period > 0:
        return max(1, int(round(duration / period)))
    return None


def fitted_saddle_series(doc: dict[str, Any]) -> dict[str, list | None]:
    """S's fitted position and, per quantity, measured samples and residuals (each shape (N, 3)).

    Empty when the result has no saddle track or too few samples to fit.
    """
    saddle = doc.get("saddle") or {}
    t = _array(saddle.get("t_s"))
    position = _array(saddle.get("position_m"), 3)
    period = doc.get("period_s")
    if t is None or position is None or len(t) != len(position) or len(t) < 8 or period is None or not period > 0:
        return {}
    x_model = (doc.get("params") or {}).get("x_model") or "linear"
    try:
        fit = fit_marker_kinematics(t, position[:, None, :], period_s=float(period), x_model=x_model,
                                    trend_degree=1 if x_model == "fourier" else 0)
        fitted = np.stack([f.evaluate(t) for f in (fit.fits_x[0], fit.fits_y[0], fit.fits_z[0])], axis=1)
    except (ValueError, ArithmeticError, np.linalg.LinAlgError, RuntimeError):
        return {}  # e.g. a window too short for its order: the page then shows the measured data only
    out = {"position_fitted_m": _rows(fitted), "position_residual_m": _rows(position - fitted)}
    # measured velocity and acceleration: central differences of the measured positions
    velocity = np.gradient(position, t, axis=0)
    acceleration = np.gradient(velocity, t, axis=0)
    # one-sided differences at the window's ends are no measurement of the curve: left out
    velocity[[0, -1]] = np.nan
    acceleration[[0, 1, -2, -1]] = np.nan
    for quantity, unit, measured in (("velocity", "m_s", velocity), ("acceleration", "m_s2", acceleration)):
        out[f"{quantity}_measured_{unit}"] = _rows(measured)
        stored = _array(saddle.get(f"{quantity}_{unit}"), 3)  # the fits' derivatives, as the result has them
        if stored is not None and len(stored) == len(t):
            out[f"{quantity}_residual_{unit}"] = _rows(measured - stored)
    return out


def vertical_harmonics_of(doc: dict[str, Any]) -> dict[str, Any] | None:
    """``{f0_hz, amplitudes_m_s2, phases_rad}`` of S's vertical acceleration (None without a track)."""
    stored = doc.get("vertical_harmonics") or {}
    if stored.get("f0_hz") and stored.get("amplitudes_m_s2"):
        return {"f0_hz": float(stored["f0_hz"]), "amplitudes_m_s2": list(stored["amplitudes_m_s2"]),
                "phases_rad": list(stored.get("phases_rad") or [0.0] * len(stored["amplitudes_m_s2"]))}
    saddle = doc.get("saddle") or {}
    t = _array(saddle.get("t_s"))
    acc = _array(saddle.get("acceleration_m_s2"), 3)
    pos = _array(saddle.get("position_m"), 3)
    period = doc.get("period_s")
    if t is None or acc is None or pos is None or len(t) < 8 or period is None or not period > 0:
        return None
    if len(acc) != len(t) or len(pos) != len(t) or not np.isfinite(acc[:, 1]).all():
        return None
    harm = vertical_harmonics(t, acc[:, 1], pos[:, 1], float(period), fit_order=2)
    return {"f0_hz": float(harm["f0_hz"]), "amplitudes_m_s2": [float(a) for a in harm["amplitudes_m_s2"]],
            "phases_rad": [float(p) for p in harm["phases_rad"]]}


def weighted_series(doc: dict[str, Any], t_s: list[float]) -> tuple[dict[str, list | None], dict[str, Any] | None]:
    """The W_b- and W_k-weighted vertical acceleration at times `t_s`, and the harmonic spectrum.

    Returns ``({"acc_y_wb_m_s2": [...], "acc_y_wk_m_s2": [...]}, spectrum)`` where ``spectrum`` is
    ``{"f0_hz", "frequency_hz", "amplitude_m_s2", "amplitude_wb_m_s2", "amplitude_wk_m_s2"}``
    (bars at k·f0), or ``({}, None)`` without a vertical track.
    """
    harm = vertical_harmonics_of(doc)
    if harm is None:
        return {}, None
    f0 = harm["f0_hz"]
    amps = np.asarray(harm["amplitudes_m_s2"], dtype=np.float64)
    phases = np.asarray(harm["phases_rad"], dtype=np.float64)
    freqs = f0 * np.arange(1, len(amps) + 1)
    t = np.asarray(t_s, dtype=np.float64)
    series: dict[str, list | None] = {}
    spectrum: dict[str, Any] = {"f0_hz": f0, "frequency_hz": _rows(freqs), "amplitude_m_s2": _rows(amps)}
    for suffix, name in WEIGHTINGS:
        response = weighting_response(name, freqs)  # eq. 7.x: each harmonic times H(j 2 pi k f0)
        gain, lag = np.abs(response), np.angle(response)
        weighted = (amps * gain)[:, None] * np.cos(2 * np.pi * freqs[:, None] * t[None, :] + (phases + lag)[:, None])
        series[f"acc_y_{suffix}_m_s2"] = _rows(weighted.sum(axis=0)) if t.size else []
        spectrum[f"amplitude_{suffix}_m_s2"] = _rows(amps * gain)
    return series, spectrum


def derived_series(doc: dict[str, Any]) -> dict[str, Any]:
    """Every derived series of result `doc` at full resolution, as stored beside the result.

    Returns ``{"format", "samples", "series", "spectrum"}``: ``series`` maps the names of
    :func:`fitted_saddle_series` and :func:`weighted_series` to one row per sample of S's track (the
    weighted acceleration at every sample time: decimating it gives exactly the values at the drawn
    times), ``spectrum`` is the harmonic spectrum (None without a vertical track).
    """
    t_s = (doc.get("saddle") or {}).get("t_s") or []
    n = len(t_s)
    series: dict[str, list | None] = {name: values for name, values in fitted_saddle_series(doc).items()
                                      if isinstance(values, list) and len(values) == n}
    weighted, spectrum = weighted_series(doc, t_s)
    series.update(weighted)
    return {"format": DERIVED_FORMAT, "samples": n, "series": series, "spectrum": spectrum}
