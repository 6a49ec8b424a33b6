"""Straight-line and Fourier-series fits of one coordinate, with analytic derivatives (thesis 5.5).

x (travel): a straight line, slope = average speed. y (gravity) and z: a Fourier series
``a0 + sum_k a_k cos(k w t) + b_k sin(k w t)`` (eq. 5.23) with the fundamental ``w`` fitted too
(nonlinear least squares from the period estimate). The fundamental is the *stride* frequency,
so a walk's or trot's vertical motion (twice per stride) is carried by the second harmonic.

Order. The thesis shows that a series of order N has at most 2N extrema per period of the
fundamental (eq. 5.24-5.33; its eq. 5.28 should read cos 2θ = cos²θ − sin²θ) and fits orders
E/2 and E/2 + 1, E being the number of extrema the user counted. Here E is counted per stride on
a smooth fixed-frequency fit of the data, ignoring wiggles smaller than ``prominence`` of the
peak-to-peak range, and the better of the two orders is chosen by the corrected Akaike
information criterion (AICc) unless another ``criterion`` is asked for.

How good each fit is, and how its order is chosen under correlated noise:
:mod:`saddlescope.core.kinematics.goodness_of_fit`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from saddlescope.core.errors import InputError, KinematicsError
from saddlescope.core.findings import Finding
from saddlescope.core.kinematics.goodness_of_fit import CRITERIA, GoodnessOfFit, _choose, _confidence, _goodness

__all__ = [
    "LinearFit",
    "fit_linear",
    "FourierFit",
    "count_extrema",
    "fit_fourier",
    "resolvable_order",
]


def _check_series(t, y, name: str) -> tuple[np.ndarray, np.ndarray]:
    t = np.asarray(t, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    if t.ndim != 1 or y.shape != t.shape:
        raise InputError(f"{name}: t and y must be 1-D arrays of equal length, got {t.shape} and {y.shape}")
    ok = np.isfinite(t) & np.isfinite(y)
    return t[ok], y[ok]


@dataclass(frozen=True)
class LinearFit:
    """Straight line ``y = intercept + slope * (t - t0)``; ``slope`` is the average speed.

    ci : ndarray of shape (2, 2)
        95 % intervals, rows (intercept, slope), columns (low, high).
    residuals : ndarray of shape (n,)
        Data minus fit at the samples used.
    """

    intercept: float
    slope: float
    t0: float
    gof: GoodnessOfFit
    ci: np.ndarray
    residuals: np.ndarray

    def evaluate(self, t, derivative: int = 0) -> np.ndarray:
        """Value (0), velocity (1) or acceleration (2) of the line.

        Parameters
        ----------
        t : ndarray of any shape
            Times (s).
        derivative : {0, 1, 2}
            Which derivative.

        Returns
        -------
        ndarray of the shape of ``t``
            Values in the fitted units (per s, per s² for the derivatives).
        """
        t = np.asarray(t, dtype=np.float64)
        if derivative == 0:
            return self.intercept + self.slope * (t - self.t0)
        if derivative == 1:
            return np.full_like(t, self.slope)
        if derivative == 2:
            return np.zeros_like(t)
        raise InputError(f"derivative must be 0, 1 or 2, got {derivative}")


def fit_linear(t, y, *, name: str = "x") -> LinearFit:
    """Least-squares straight line through (t, y), NaN samples ignored.

    Parameters
    ----------
    t, y : ndarray of shape (n,)
        Times (s) and values.
    name : str
        What is fitted, for error messages.

    Returns
    -------
    LinearFit
    """
    t, y = _check_series(t, y, name)
    if t.size < 3:
        raise KinematicsError(f"{name}: {t.size} samples are too few for a straight-line fit")
    t0 = float(t.mean())
    jac = np.column_stack([np.ones_like(t), t - t0])
    coef, *_ = np.linalg.lstsq(jac, y, rcond=None)
    residuals = y - jac @ coef
    _, half, _, gof = _confidence(jac, _goodness(y, residuals, 2), residuals, scale=float(np.std(y)))
    ci = np.column_stack([coef - half, coef + half])
    return LinearFit(intercept=float(coef[0]), slope=float(coef[1]), t0=t0, gof=gof, ci=ci,
                     residuals=residuals)


@dataclass(frozen=True)
class FourierFit:
    """Fourier series ``a0 + sum_k a_k cos(k w (t - t0)) + b_k sin(k w (t - t0))`` (eq. 5.23).

    a0 : float; a, b : ndarray of shape (N,); omega_rad_s : float (fundamental w); t0 : float
    (time origin, the mean sample time, which decorrelates w from the phases).
    ci : dict
        95 % intervals: ``"a0"`` (2,), ``"a"`` (N, 2), ``"b"`` (N, 2), ``"omega_rad_s"`` (2,)
        (the last is NaN-free only if ω was fitted or pooled).
    se : dict
        Standard errors with the same keys.
    omega_source : str
        ``"fitted"`` (nonlinear least squares), ``"fixed"`` (given) or ``"pooled"`` (common ω of
        several fits, see :func:`saddlescope.core.kinematics.fitting.fit_marker_kinematics`).
    criterion : str
        How the order was chosen (``"aicc"``, ``"aicc_white"``, ``"bic"``, ``"adj_r2"`` or
        ``"given"``).
    extrema_per_period : int or None
        The extrema counted per fundamental period (E of the order rule).
    candidates : tuple of dict
        The orders tried with their goodness of fit (for the dashboard).
    trend : ndarray of shape (D,)
        Coefficients of (t - t0)^1 .. (t - t0)^D of an optional polynomial trend added to the
        series (empty for the thesis's pure series). A linear trend absorbs drift (a slightly
        tilted travel axis, a lateral drift); a quadratic one also a constant acceleration
        (the centripetal acceleration on a curve). ``harmonics`` excludes the trend.
    """

    a0: float
    a: np.ndarray
    b: np.ndarray
    omega_rad_s: float
    t0: float
    gof: GoodnessOfFit
    ci: dict
    se: dict
    residuals: np.ndarray
    omega_source: str = "fitted"
    criterion: str = "given"
    extrema_per_period: int | None = None
    candidates: tuple = ()
    flags: tuple[Finding, ...] = field(default_factory=tuple)
    trend: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def order(self) -> int:
        """Number of harmonics N."""
        return int(self.a.shape[0])

    @property
    def f0_hz(self) -> float:
        """Fundamental frequency w / 2 pi (Hz)."""
        return self.omega_rad_s / (2 * np.pi)

    def evaluate(self, t, derivative: int = 0) -> np.ndarray:
        """Value (0), velocity (1) or acceleration (2) of the series, analytic.

        Parameters
        ----------
        t : ndarray of any shape
            Times (s).
        derivative : {0, 1, 2}
            Which derivative.

        Returns
        -------
        ndarray of the shape of ``t``
            Values in the fitted units (per s, per s² for the derivatives).
        """
        if derivative not in (0, 1, 2):
            raise InputError(f"derivative must be 0, 1 or 2, got {derivative}")
        t = np.asarray(t, dtype=np.float64)
        k = np.arange(1, self.order + 1)
        kw = k * self.omega_rad_s
        theta = (t[..., None] - self.t0) * kw
        # a cos θ + b sin θ = Re[(a - i b) e^{iθ}]; each derivative multiplies by i k w.
        c = (self.a - 1j * self.b) * (1j * kw) ** derivative
        out = np.real(np.sum(c * np.exp(1j * theta), axis=-1))
        poly = np.polynomial.polynomial.Polynomial(np.concatenate([[self.a0], self.trend]))
        return out + poly.deriv(derivative)(t - self.t0)

    def harmonics(self, derivative: int = 0) -> tuple[float, np.ndarray, np.ndarray]:
        """The series as ``sum_k A_k cos(2 pi k f0 t + phi_k)`` in the absolute time t.

        Parameters
        ----------
        derivative : {0, 1, 2}
            0: position harmonics; 1: velocity; 2: acceleration (what the vibration code takes).
            The constant ``a0`` is not included.

        Returns
        -------
        f0_hz : float
        amplitudes : ndarray of shape (N,)
        phases : ndarray of shape (N,), rad in (-pi, pi]
        """
        if derivative not in (0, 1, 2):
            raise InputError(f"derivative must be 0, 1 or 2, got {derivative}")
        k = np.arange(1, self.order + 1)
        kw = k * self.omega_rad_s
        amp = np.hypot(self.a, self.b) * kw**derivative
        # a cos θ + b sin θ = A cos(θ + φ) with φ = atan2(-b, a); then shift the origin to t = 0.
        phase = np.arctan2(-self.b, self.a) + derivative * np.pi / 2 - kw * self.t0
        phase = np.angle(np.exp(1j * phase))
        return self.f0_hz, amp, phase


def _design(tau: np.ndarray, omega: float, order: int, trend_degree: int = 0) -> np.ndarray:
    """Columns [1, tau .. tau^D, cos(k w tau) (k = 1..N), sin(k w tau) (k = 1..N)]."""
    k = np.arange(1, order + 1)
    theta = tau[:, None] * (k * omega)
    poly = tau[:, None] ** np.arange(trend_degree + 1)
    return np.column_stack([poly, np.cos(theta), np.sin(theta)])


def count_extrema(t, y, *, period_s: float, prominence: float = 0.1, max_order: int = 8,
                  trend_degree: int = 0) -> int:
    """Number E of extrema (maxima + minima) per period, robust to noise.

    A linear least-squares Fourier series with the fundamental ``2 pi / period_s`` (order up to
    ``max_order``, fewer for short records) smooths the data; its extrema over one period are
    counted cyclically with hysteresis: a turning point counts only if the curve then moves by at
    least ``prominence`` times its peak-to-peak range.

    Parameters
    ----------
    t, y : ndarray of shape (n,)
        Times (s) and values (NaN ignored).
    period_s : float
        The period whose extrema are counted (the stride).
    prominence : float, optional
        Smallest swing that counts, as a fraction of the peak-to-peak range.
    max_order : int, optional
        Highest harmonic of the smoothing series.
    trend_degree : int, optional
        Degree of a polynomial trend fitted alongside and left out of the count.

    Returns
    -------
    E : int
        An even number >= 2 (a periodic curve has as many minima as maxima).
    """
    t, y = _check_series(t, y, "count_extrema")
    if not np.isfinite(period_s) or period_s <= 0:
        raise InputError(f"period_s must be positive, got {period_s}")
    omega = 2 * np.pi / period_s
    order = int(max(1, min(max_order, (t.size - 2) // 4)))
    tau = t - t.mean()
    coef, *_ = np.linalg.lstsq(_design(tau, omega, order, trend_degree), y, rcond=None)
    grid = np.linspace(0.0, period_s, 720, endpoint=False)
    curve = _design(grid, omega, order) @ np.concatenate([[0.0], coef[trend_degree + 1:]])
    span = np.ptp(curve)
    if span <= 0:
        return 2
    h = prominence * span
    start = int(np.argmax(curve))
    seq = np.concatenate([curve[start:], curve[:start], curve[start:start + 1]])
    minima = 0
    looking_for_min = True
    run = seq[0]
    for value in seq[1:]:
        if looking_for_min:
            if value < run:
                run = value
            elif value >= run + h:
                minima += 1
                looking_for_min, run = False, value
        else:
            if value > run:
                run = value
            elif value <= run - h:
                looking_for_min, run = True, value
    return 2 * max(minima, 1)


def _fit_order(tau: np.ndarray, y: np.ndarray, omega0: float, order: int, fit_omega: bool,
               name: str, trend_degree: int
               ) -> tuple[np.ndarray, float, np.ndarray, np.ndarray, tuple[Finding, ...]]:
    """Coefficients [a0, trend_1..trend_D, a_1..a_N, b_1..b_N], omega, residuals, Jacobian, flags."""
    n_poly = trend_degree + 1
    design = _design(tau, omega0, order, trend_degree)
    coef, *_ = np.linalg.lstsq(design, y, rcond=None)
    if not fit_omega:
        return coef, omega0, y - design @ coef, design, ()
    k = np.arange(1, order + 1)

    def residual(p):
        return _design(tau, p[-1], order, trend_degree) @ p[:-1] - y

    def jacobian(p):
        w = p[-1]
        d = _design(tau, w, order, trend_degree)
        theta = tau[:, None] * (k * w)
        a, b = p[n_poly:n_poly + order], p[n_poly + order:-1]
        dw = np.sum(tau[:, None] * k * (-a * np.sin(theta) + b * np.cos(theta)), axis=1)
        return np.column_stack([d, dw])

    p0 = np.concatenate([coef, [omega0]])
    res = least_squares(residual, p0, jac=jacobian, method="lm", x_scale="jac", xtol=1e-15, ftol=1e-15,
                        gtol=1e-15, max_nfev=2000)
    flags: tuple[Finding, ...] = ()
    omega = float(res.x[-1])
    if not (0.8 * omega0 <= omega <= 1.25 * omega0) or not res.success:
        flags = (Finding("fit.fundamental_drift",
                         f"{name}: the fitted fundamental ({omega / (2 * np.pi):.3f} Hz) left the neighbourhood of "
                         f"the stride frequency ({omega0 / (2 * np.pi):.3f} Hz); kept the stride frequency",
                         {"fitted_hz": omega / (2 * np.pi), "stride_hz": omega0 / (2 * np.pi)}),)
        return coef, omega0, y - design @ coef, design, flags
    return res.x[:-1], omega, residual(res.x), jacobian(res.x), flags



def fit_fourier(t, y, *, period_s: float, order: int | None = None, criterion: str = "aicc",
                fit_omega: bool = True, prominence: float = 0.1, extra_orders: int = 1,
                trend_degree: int = 0, name: str = "y", max_order: int | None = None,
                up_to_frame_rate: bool = False) -> FourierFit:
    """Fit a Fourier series with its fundamental (eq. 5.23); order from the extrema rule.

    Parameters
    ----------
    t, y : ndarray of shape (n,)
        Times (s) and values (NaN ignored), over a whole number of periods.
    period_s : float
        The stride period: the start (or, with ``fit_omega=False``, the value) of 2 pi / w.
    order : int, optional
        Number of harmonics N; default: the best of E/2 .. E/2 + ``extra_orders`` by ``criterion``.
    criterion : {"aicc", "aicc_white", "bic", "adj_r2"}
        Order selection: smallest AICc (default) or BIC, both with the noise's correlation over
        samples accounted for (see :mod:`saddlescope.core.kinematics.goodness_of_fit`); the
        textbook AICc; or largest adjusted R².
    fit_omega : bool, optional
        Fit w too (nonlinear least squares) or keep 2 pi / period_s.
    prominence : float, optional
        See :func:`count_extrema`.
    extra_orders : int, optional
        Orders tried above E/2: 1 gives the thesis's pair E/2, E/2 + 1. More lets the criterion
        pick up small higher harmonics that hardly show as extrema but weigh in accelerations
        (the k-th harmonic's acceleration scales with k²).
    trend_degree : int, optional
        Degree of a polynomial trend fitted with the series (0: the thesis's series; see
        ``FourierFit.trend``).
    name : str
        What is fitted (e.g. ``"marker 1 y"``), for messages.
    max_order : int, optional
        Cap on the orders tried by the rule (a user's override: the criterion assumes white noise,
        and tracking noise correlated over frames can pass for a small high harmonic).
    up_to_frame_rate : bool, optional
        Keep trying higher orders, one at a time, while the criterion's best order is at or just below
        the highest tried, up to the harmonics the frame rate resolves (:func:`resolvable_order`) or
        ``max_order``: no harmonic the samples resolve is dropped because the extrema rule's range
        stopped short of it (a trot's saddle ringing at its 6th stride harmonic, 8-9 Hz, issue 38).

    Returns
    -------
    FourierFit
    """
    t, y = _check_series(t, y, name)
    _check_fourier_options(period_s, criterion, extra_orders, trend_degree)
    omega0 = 2 * np.pi / period_s
    n_poly = trend_degree + 1
    orders, used_criterion, extrema = _candidate_orders(
        t, y, period_s=period_s, order=order, criterion=criterion, prominence=prominence,
        extra_orders=extra_orders, trend_degree=trend_degree, max_order=max_order)

    def n_params(o):
        return n_poly + 2 * o + int(fit_omega)

    if t.size < n_params(orders[0]) + 1:
        raise KinematicsError(f"{name}: {t.size} samples are too few for a Fourier fit of order {orders[0]}")
    orders = [o for o in orders if t.size >= n_params(o) + 1]
    t0 = float(t.mean())
    tau = t - t0
    fits = [_fit_candidate(tau, y, omega0, o, fit_omega, name, trend_degree) for o in orders]
    chosen = _choose(fits, criterion, n_poly)
    if up_to_frame_rate and order is None:
        cap = resolvable_order(t, period_s)
        cap = cap if max_order is None else min(cap, int(max_order))
        # the best order at (or one below) the highest tried: the next harmonic may be resolved too
        while fits[chosen][0] >= fits[-1][0] - 1 and fits[-1][0] < cap and t.size >= n_params(fits[-1][0] + 1) + 1:
            fits.append(_fit_candidate(tau, y, omega0, fits[-1][0] + 1, fit_omega, name, trend_degree))
            chosen = _choose(fits, criterion, n_poly)
    return _fourier_fit(fits[chosen], fits, t0=t0, n_poly=n_poly, criterion=used_criterion, extrema=extrema)


# the highest stride harmonic fitted lies below this share of the samples' Nyquist frequency (above it
# the frame's exposure blurs it and the harmonics alias into each other)
NYQUIST_SHARE = 0.8
MAX_RESOLVED_ORDER = 16


def resolvable_order(t_s: np.ndarray, period_s: float) -> int:
    """The highest stride harmonic the samples ``t_s`` (s) resolve: below :data:`NYQUIST_SHARE` of their Nyquist.

    At least 1, at most :data:`MAX_RESOLVED_ORDER` (a thesis-rig 30 fps trot: 8; a 60 fps canter: 16).
    """
    t = np.sort(np.asarray(t_s, dtype=np.float64))
    steps = np.diff(t)
    steps = steps[steps > 0]
    if steps.size == 0 or not np.isfinite(period_s) or period_s <= 0:
        return 1
    nyquist_hz = 0.5 / float(np.median(steps))
    return int(min(MAX_RESOLVED_ORDER, max(1, np.floor(NYQUIST_SHARE * nyquist_hz * period_s))))


def _check_fourier_options(period_s: float, criterion: str, extra_orders: int, trend_degree: int) -> None:
    """Raise InputError for an option :func:`fit_fourier` cannot use."""
    if extra_orders < 0:
        raise InputError(f"extra_orders must be >= 0, got {extra_orders}")
    if trend_degree not in (0, 1, 2):
        raise InputError(f"trend_degree must be 0, 1 or 2, got {trend_degree}")
    if criterion not in CRITERIA:
        raise InputError(f"criterion must be one of {CRITERIA}, got {criterion!r}")
    if not np.isfinite(period_s) or period_s <= 0:
        raise InputError(f"period_s must be positive, got {period_s}")


def _candidate_orders(t: np.ndarray, y: np.ndarray, *, period_s: float, order: int | None, criterion: str,
                      prominence: float, extra_orders: int, trend_degree: int, max_order: int | None
                      ) -> tuple[list[int], str, int | None]:
    """The orders to try, the criterion that chooses among them, and the extrema E counted per period.

    A given ``order`` is the only candidate (criterion ``"given"``, E not counted); otherwise the
    extrema rule's E/2 .. E/2 + ``extra_orders`` (eq. 5.24-5.33), capped at ``max_order``.
    """
    if order is not None:
        if order < 1:
            raise InputError(f"order must be at least 1, got {order}")
        return [int(order)], "given", None
    extrema = count_extrema(t, y, period_s=period_s, prominence=prominence, trend_degree=trend_degree)
    orders = [max(1, extrema // 2) + extra for extra in range(extra_orders + 1)]
    if max_order is not None:
        if max_order < 1:
            raise InputError(f"max_order must be at least 1, got {max_order}")
        orders = sorted({min(o, int(max_order)) for o in orders})
    return orders, criterion, extrema


def _fit_candidate(tau: np.ndarray, y: np.ndarray, omega0: float, order: int, fit_omega: bool, name: str,
                   trend_degree: int) -> tuple:
    """One candidate order fitted, as the row :func:`_choose` ranks.

    Returns ``(order, coef, omega, residuals, gof, se, half, flags, omega_free, (cov_ar1, cov_white))``;
    ω counts as a parameter only where it was fitted (not where the fit fell back to the stride's).
    """
    n_poly = trend_degree + 1
    coef, omega, resid, jac, flags = _fit_order(tau, y, omega0, order, fit_omega, name, trend_degree)
    omega_free = fit_omega and not flags
    n_lin = n_poly + 2 * order
    se, half, cov, gof = _confidence(jac if omega_free else jac[:, :n_lin],
                                     _goodness(y, resid, n_lin + int(omega_free)), resid, scale=float(np.std(y)))
    return (order, coef, omega, resid, gof, se, half, flags, omega_free, cov)


def _fourier_fit(best: tuple, fits: list, *, t0: float, n_poly: int, criterion: str, extrema: int | None
                 ) -> FourierFit:
    """The chosen candidate row (see :func:`_fit_candidate`) as a FourierFit, the others as its candidates."""
    o, coef, omega, resid, gof, se, half, flags, omega_free, _ = best

    def pack(v):
        return {"a0": v[0], "trend": v[1:n_poly], "a": v[n_poly:n_poly + o],
                "b": v[n_poly + o:n_poly + 2 * o], "omega_rad_s": v[n_poly + 2 * o] if omega_free else np.nan}

    se_d = pack(se)
    half_d = pack(half)
    values = dict(pack(np.append(coef, omega)), omega_rad_s=omega)
    ci = {key: np.stack([values[key] - half_d[key], values[key] + half_d[key]], axis=-1) for key in values}
    candidates = tuple({"order": f[0], "omega_rad_s": f[2], **f[4].as_dict()} for f in fits)
    return FourierFit(a0=float(coef[0]), a=np.array(values["a"]), b=np.array(values["b"]),
                      omega_rad_s=float(omega), t0=t0, gof=gof, ci=ci, se=se_d, residuals=resid,
                      omega_source="fitted" if omega_free else "fixed", criterion=criterion,
                      extrema_per_period=extrema, candidates=candidates, flags=flags,
                      trend=np.array(values["trend"]))
