"""Curve fits of the registered marker coordinates and their analytic derivatives (thesis 5.5).

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

Goodness of fit as MATLAB's Curve Fitting Toolbox: SSE, R², adjusted R² (with the residual
degrees of freedom n − p, ω counted as a parameter), RMSE = sqrt(SSE / (n − p)), and 95 %
confidence intervals of the coefficients from the Jacobian at the solution.

Correlated noise. MATLAB's intervals and the textbook AICc assume residuals independent from
sample to sample. Tracked markers are not: camera noise is correlated over two or three frames
and skin sliding over many. Then a harmonic's coefficients scatter with the noise's spectral
density at that harmonic, not with its average variance: for noise whose lag-1 autocorrelation
is 0.5 a low harmonic scatters up to sqrt(3) times wider than the textbook says (its 95 %
intervals cover about 75 % of the time), and a harmonic made of noise passes AICc two to three
times as often as with white noise. So the fits also take the noise as first-order
autoregressive, its correlation estimated from their residuals (the sandwich covariance of least
squares under AR(1) noise; a non-parametric Newey-West estimate covered 95 % intervals only
76-87 % of the time on two strides). Each standard error is the larger of the AR(1) and the
textbook one, and AICc and BIC compare orders with the added harmonics' Wald statistic, the
smaller of the two, in place of the fall of n log SSE (the same for white noise): neither is
ever more liberal than MATLAB's, and both stop trusting noise that is correlated at the
harmonics' frequencies.
``criterion="aicc_white"`` keeps the textbook AICc.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import least_squares
from scipy.signal import lfilter
from scipy.stats import t as student_t

from saddlescope.core.errors import InputError, KinematicsError

__all__ = [
    "CRITERIA",
    "GoodnessOfFit",
    "LinearFit",
    "fit_linear",
    "FourierFit",
    "count_extrema",
    "fit_fourier",
    "MarkerKinematics",
    "fit_marker_kinematics",
]

CRITERIA = ("aicc", "aicc_white", "bic", "adj_r2")


@dataclass(frozen=True)
class GoodnessOfFit:
    """Goodness-of-fit numbers of one least-squares fit (n samples, p parameters)."""

    sse: float
    r2: float
    adj_r2: float
    rmse: float
    n: int
    n_params: int
    aicc: float
    bic: float
    # lag-1 autocorrelation of the residuals, and of the noise as the standard errors take it
    # (bias-corrected, clipped to [0, 0.98]; see the module's note on correlated noise)
    residual_lag1: float = 0.0
    noise_lag1: float = 0.0

    @property
    def dfe(self) -> int:
        """Residual degrees of freedom n - p."""
        return self.n - self.n_params

    def as_dict(self) -> dict:
        return {"sse": self.sse, "r2": self.r2, "adj_r2": self.adj_r2, "rmse": self.rmse, "n": self.n,
                "n_params": self.n_params, "dfe": self.dfe, "aicc": self.aicc, "bic": self.bic,
                "residual_lag1": self.residual_lag1, "noise_lag1": self.noise_lag1}


def _goodness(y: np.ndarray, residuals: np.ndarray, n_params: int) -> GoodnessOfFit:
    n = y.shape[0]
    sse = float(np.sum(residuals**2))
    sst = float(np.sum((y - y.mean()) ** 2))
    dfe = n - n_params
    r2 = 1.0 - sse / sst if sst > 0 else 1.0
    adj = 1.0 - (1.0 - r2) * (n - 1) / dfe if dfe > 0 else float("nan")
    rmse = float(np.sqrt(sse / dfe)) if dfe > 0 else float("nan")
    # A floor keeps the criteria finite for exact (noise-free) fits; ties then favour fewer parameters.
    sse_eff = max(sse, n * (1e-12 * max(np.sqrt(sst / max(n, 1)), 1e-300)) ** 2)
    loglik_term = n * np.log(sse_eff / n)
    aicc = float(loglik_term + 2 * n_params + (2 * n_params * (n_params + 1) / (n - n_params - 1)
                                               if n - n_params - 1 > 0 else np.inf))
    bic = float(loglik_term + n_params * np.log(n))
    return GoodnessOfFit(sse=sse, r2=float(r2), adj_r2=float(adj), rmse=rmse, n=n, n_params=n_params,
                         aicc=aicc, bic=bic)


def _lag1(residuals: np.ndarray) -> float:
    """Lag-1 autocorrelation of a residual series (0 for a constant one)."""
    r = residuals - residuals.mean()
    den = float(np.dot(r, r))
    return float(np.dot(r[1:], r[:-1]) / den) if den > 0 and r.size > 2 else 0.0


def _noise_correlation(residual_lag1: float, jac: np.ndarray, bread: np.ndarray) -> float:
    """The noise's lag-1 autocorrelation from a fit's residuals' (:func:`_lag1`), corrected for the bias
    fitting puts into it (white noise's residuals have E[sum e_t e_t-1] = -s^2 tr(H L), H the hat matrix, L the
    lag-1 shift: about -p / n for slow regressors), and clipped to [0, 0.98]: negative or no
    correlation keeps the textbook intervals, so they are never narrower than MATLAB's."""
    n, p = jac.shape
    if n - p < 3:
        return 0.0
    tr_hl = float(np.trace(bread @ (jac[1:].T @ jac[:-1])))
    return float(np.clip(residual_lag1 + tr_hl / (n - p), 0.0, 0.98))


def _covariance(jac: np.ndarray, residuals: np.ndarray, residual_lag1: float, floor_var: float = 0.0
                ) -> tuple[np.ndarray, np.ndarray, float]:
    """Covariances (p, p) of least-squares parameters with Jacobian ``jac`` (n, p): the textbook
    s^2 (J'J)^-1, s^2 = SSE / (n - p), and, from the ``residuals`` (n,) in sample order, the one for
    AR(1) noise of lag-1 autocorrelation rho: the sandwich (J'J)^-1 J' Sigma J (J'J)^-1 with
    Sigma_ij = s^2 rho^|i-j|. For a harmonic this is the noise's spectral density at its frequency,
    which is what its coefficients scatter with. Sigma J is two exponential filters, forward and
    back, so no n x n matrix is formed (a gap between samples counts as one sample step). ``floor_var``
    (J'J)^-1 is added to both (keeps an exact fit's tests finite). Returns (AR(1), textbook, rho)."""
    n, p = jac.shape
    # QR of the Jacobian avoids squaring its condition number in J^T J.
    _, r = np.linalg.qr(jac)
    try:
        r_inv = np.linalg.inv(r)
    except np.linalg.LinAlgError:
        r_inv = np.linalg.pinv(r)
    bread = r_inv @ r_inv.T
    s2 = float(residuals @ residuals) / max(n - p, 1)
    white = (s2 + floor_var) * bread
    rho = _noise_correlation(residual_lag1, jac, bread)
    if rho <= 0:
        return white, white, 0.0
    fwd = lfilter([1.0], [1.0, -rho], jac, axis=0)
    back = lfilter([1.0], [1.0, -rho], jac[::-1], axis=0)[::-1]
    return bread @ (s2 * (jac.T @ (fwd + back - jac))) @ bread + floor_var * bread, white, rho


def _confidence(jac: np.ndarray, gof: GoodnessOfFit, residuals: np.ndarray,
                level: float = 0.95, scale: float = 0.0) -> tuple[np.ndarray, np.ndarray, tuple, GoodnessOfFit]:
    """Standard errors, half-widths of the confidence intervals and the two covariances of
    :func:`_covariance` for the parameters of Jacobian (n, p), and ``gof`` with the residuals' and
    the noise's lag-1 autocorrelation filled in (see the module's note on correlated noise). Each
    standard error is the larger of the two: the AR(1) model can put less noise at a high harmonic
    than there is (smooth noise that is not AR(1)), and no interval here is narrower than MATLAB's.
    ``scale`` is the data's r.m.s. about its mean: a variance of (1e-12 scale)^2 is the floor, as in
    the criteria."""
    if gof.dfe <= 0:
        nan = np.full(jac.shape[1], np.nan)
        cov_nan = np.full((jac.shape[1],) * 2, np.nan)
        return nan, nan, (cov_nan, cov_nan), gof
    lag1 = _lag1(residuals)
    cov_ar1, cov_white, rho = _covariance(jac, residuals, lag1, (1e-12 * scale) ** 2)
    se = np.sqrt(np.clip(np.maximum(np.diag(cov_ar1), np.diag(cov_white)), 0.0, None))
    return (se, student_t.ppf(0.5 + level / 2, gof.dfe) * se, (cov_ar1, cov_white),
            replace(gof, residual_lag1=lag1, noise_lag1=rho))


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
        """Value (0), velocity (1) or acceleration (2) at times ``t`` of any shape."""
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
    name : str
        What is fitted, for error messages.
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
        several fits, see :func:`fit_marker_kinematics`).
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
    flags: tuple[str, ...] = field(default_factory=tuple)
    trend: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def order(self) -> int:
        return int(self.a.shape[0])

    @property
    def f0_hz(self) -> float:
        return self.omega_rad_s / (2 * np.pi)

    def evaluate(self, t, derivative: int = 0) -> np.ndarray:
        """Value (0), velocity (1) or acceleration (2) at times ``t`` of any shape (analytic)."""
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
    period_s : float
    prominence : float, optional
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
               ) -> tuple[np.ndarray, float, np.ndarray, np.ndarray, tuple[str, ...]]:
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
    flags: tuple[str, ...] = ()
    omega = float(res.x[-1])
    if not (0.8 * omega0 <= omega <= 1.25 * omega0) or not res.success:
        flags = (f"{name}: the fitted fundamental ({omega / (2 * np.pi):.3f} Hz) left the neighbourhood of "
                 f"the stride frequency ({omega0 / (2 * np.pi):.3f} Hz); kept the stride frequency",)
        return coef, omega0, y - design @ coef, design, flags
    return res.x[:-1], omega, residual(res.x), jacobian(res.x), flags


def _penalty(n: int, p: int, criterion: str) -> float:
    """The parameter penalty of AICc (2p + 2p(p+1)/(n-p-1)) or BIC (p log n)."""
    if criterion == "bic":
        return p * float(np.log(n))
    return 2 * p + (2 * p * (p + 1) / (n - p - 1) if n - p - 1 > 0 else np.inf)


def _choose(fits: list, criterion: str, n_poly: int) -> int:
    """Index of the chosen candidate. ``fits`` rows are (order, coef, omega, resid, gof, se, half,
    flags, omega_free, (cov_ar1, cov_white)), orders ascending. "aicc" and "bic" score the orders
    as the criterion does, with the Wald statistic of the harmonics each step up adds in place of
    that step's fall of n log SSE: the smaller of the statistics under the AR(1) and the textbook
    covariance, so correlated noise does not pass for a harmonic, and white noise is judged as the
    textbook criterion judges it."""
    if len(fits) == 1:
        return 0
    if criterion in ("aicc_white", "adj_r2"):
        def key(g: GoodnessOfFit) -> float:
            return g.aicc if criterion == "aicc_white" else -g.adj_r2
        return min(range(len(fits)), key=lambda i: (key(fits[i][4]), fits[i][0]))
    # Each step up the orders is scored by the Wald statistic of the harmonics it adds, taken in the
    # bigger fit; the steps add up as the falls of n log SSE do in the textbook criterion.
    scores = [_penalty(fits[0][4].n, fits[0][4].n_params, criterion)]
    total_wald = 0.0
    for (low, *_), (o, coef, _, _, gof, _, _, _, _, cov) in zip(fits[:-1], fits[1:], strict=True):
        # the coefficients of harmonics low+1 .. o: a_k at n_poly + k - 1, b_k at n_poly + o + k - 1
        idx = np.array([n_poly + k - 1 for k in range(low + 1, o + 1)]
                       + [n_poly + o + k - 1 for k in range(low + 1, o + 1)], dtype=int)
        walds = []
        for one in cov:  # the AR(1) and the textbook covariance: the smaller statistic counts
            c = one[np.ix_(idx, idx)]
            if np.all(np.isfinite(c)):
                walds.append(float(coef[idx] @ np.linalg.lstsq(c, coef[idx], rcond=None)[0]))
            else:
                walds.append(np.inf if np.any(coef[idx] != 0) else 0.0)
        wald = min(walds)
        total_wald += wald * gof.n / max(gof.dfe, 1)  # with the likelihood's variance SSE / n, as AICc
        scores.append(_penalty(gof.n, gof.n_params, criterion) - total_wald)
    return min(range(len(fits)), key=lambda i: (scores[i], fits[i][0]))


def fit_fourier(t, y, *, period_s: float, order: int | None = None, criterion: str = "aicc",
                fit_omega: bool = True, prominence: float = 0.1, extra_orders: int = 1,
                trend_degree: int = 0, name: str = "y", max_order: int | None = None) -> FourierFit:
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
        samples accounted for (see the module's note); the textbook AICc; or largest adjusted R².
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

    Returns
    -------
    FourierFit
    """
    t, y = _check_series(t, y, name)
    if extra_orders < 0:
        raise InputError(f"extra_orders must be >= 0, got {extra_orders}")
    if trend_degree not in (0, 1, 2):
        raise InputError(f"trend_degree must be 0, 1 or 2, got {trend_degree}")
    if criterion not in CRITERIA:
        raise InputError(f"criterion must be one of {CRITERIA}, got {criterion!r}")
    if not np.isfinite(period_s) or period_s <= 0:
        raise InputError(f"period_s must be positive, got {period_s}")
    omega0 = 2 * np.pi / period_s
    n_poly = trend_degree + 1
    extrema = None
    if order is None:
        extrema = count_extrema(t, y, period_s=period_s, prominence=prominence, trend_degree=trend_degree)
        orders = [max(1, extrema // 2) + extra for extra in range(extra_orders + 1)]
        if max_order is not None:
            if max_order < 1:
                raise InputError(f"max_order must be at least 1, got {max_order}")
            orders = sorted({min(o, int(max_order)) for o in orders})
        used_criterion = criterion
    else:
        if order < 1:
            raise InputError(f"order must be at least 1, got {order}")
        orders = [int(order)]
        used_criterion = "given"

    def n_params(o):
        return n_poly + 2 * o + int(fit_omega)

    if t.size < n_params(orders[0]) + 1:
        raise KinematicsError(f"{name}: {t.size} samples are too few for a Fourier fit of order {orders[0]}")
    orders = [o for o in orders if t.size >= n_params(o) + 1]
    t0 = float(t.mean())
    tau = t - t0
    fits = []
    for o in orders:
        coef, omega, resid, jac, flags = _fit_order(tau, y, omega0, o, fit_omega, name, trend_degree)
        omega_free = fit_omega and not flags
        n_lin = n_poly + 2 * o
        se, half, cov, gof = _confidence(jac if omega_free else jac[:, :n_lin],
                                         _goodness(y, resid, n_lin + int(omega_free)), resid, scale=float(np.std(y)))
        fits.append((o, coef, omega, resid, gof, se, half, flags, omega_free, cov))
    best = fits[_choose(fits, criterion, n_poly)]
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
                      omega_source="fitted" if omega_free else "fixed", criterion=used_criterion,
                      extrema_per_period=extrema, candidates=candidates, flags=flags,
                      trend=np.array(values["trend"]))


@dataclass(frozen=True)
class MarkerKinematics:
    """Fits and analytic derivatives of every marker's motion-frame coordinates.

    fits_x : tuple (M,) of LinearFit (thesis) or FourierFit (``x_model="fourier"``);
    fits_y, fits_z : tuple of FourierFit (M,);
    t_s : ndarray of shape (F,); velocity_m_s, acceleration_m_s2 : ndarray of shape (F, M, 3);
    omega_rad_s : float, the common fundamental (pooled) or NaN when each fit kept its own;
    omega_per_fit : ndarray of shape (M, 3), the free fundamental of each axis's Fourier fit
    (NaN for a linear x);
    flags : tuple of str.
    """

    t_s: np.ndarray
    fits_x: tuple
    fits_y: tuple
    fits_z: tuple
    velocity_m_s: np.ndarray
    acceleration_m_s2: np.ndarray
    omega_rad_s: float
    omega_per_fit: np.ndarray
    flags: tuple[str, ...] = ()

    @property
    def average_speed_m_s(self) -> float:
        """Mean travel speed of the markers (the slope of the x fits, thesis 5.5.3)."""
        return float(np.mean([f.slope if isinstance(f, LinearFit) else f.trend[0] for f in self.fits_x]))

    def position_m(self, t_s) -> np.ndarray:
        """Every marker's fitted position (F, M, 3) at times t_s (s), from its x, y and z fits."""
        t = np.asarray(t_s, dtype=np.float64)
        out = np.empty((t.size, len(self.fits_y), 3))
        for c, per_marker in enumerate((self.fits_x, self.fits_y, self.fits_z)):
            for m, fit in enumerate(per_marker):
                out[:, m, c] = fit.evaluate(t)
        return out


def fit_marker_kinematics(t_s, xyz_m, *, period_s: float, common_omega: bool = True,
                          criterion: str = "aicc", extra_orders: int = 1, x_model: str = "linear",
                          trend_degree: int = 0, names: tuple[str, ...] | None = None,
                          reject_sigma: float | None = 5.0, reject_min_m: float = 0.003,
                          shared_order: bool = True, omega_from: str = "vertical",
                          max_order: int | None = None) -> MarkerKinematics:
    """Fit x linearly and y, z with Fourier series for every marker; differentiate analytically.

    Parameters
    ----------
    t_s : ndarray of shape (F,)
        Times of the analysis window (s).
    xyz_m : ndarray of shape (F, M, 3)
        Registered marker positions in the motion frame (m), NaN in gaps.
    period_s : float
        Stride period (start value of the fundamental).
    common_omega : bool, optional
        A rigid body has one fundamental: when True (default) each Fourier series is first fitted
        with its own w, the inverse-variance weighted mean of those w is taken, and every series
        is refitted (linearly, same order) with it. This keeps the markers' velocities
        consistent, which the angular velocity (differences of marker velocities) needs. When
        False, each fit keeps its own w as in the thesis.
    omega_from : {"vertical", "all"}
        Which series' w are pooled: the vertical (y) ones (default) or every Fourier series. The
        saddle's vertical oscillation is the gait's strongest periodic motion and the best measured
        on any rig; a narrow rig's poorly fixed depth leaks slow, non-periodic errors into x and z
        that a free w absorbs with too small a standard error (a thesis-rig canter's x series read
        w 2.8 % off, pulling the pooled stride 0.44 % off and the vertical acceleration from 3.5 % to
        8.5 % error).
    criterion : str
        Order selection criterion, see :func:`fit_fourier`.
    extra_orders : int, optional
        See :func:`fit_fourier`.
    x_model : {"linear", "fourier"}
        ``"linear"``: the thesis's straight line (constant speed, zero x acceleration);
        ``"fourier"``: a line plus a Fourier series, which keeps the surge (the speed's variation
        within the stride).
    trend_degree : int, optional
        Polynomial trend added to the y and z series (see :func:`fit_fourier`).
    names : tuple of str, optional
        Marker names for messages.
    reject_sigma, reject_min_m : optional
        A sample whose residual in any coordinate exceeds ``reject_sigma`` robust standard
        deviations (1.4826 median absolute residuals) of that fit and ``reject_min_m`` is a wild
        detection: the marker's sample is left out and its series refitted (None: keep all).
    shared_order : bool, optional
        The body's translation is in every marker, with the camera noise averaged down over the
        markers in their centroid: when the centroid's series needs a higher order than a marker's
        own (same criterion), that marker's series takes the centroid's order. A canter's fourth
        harmonic (under a millimetre, yet 13 % of the vertical acceleration's r.m.s.) drowned in
        each marker's noise on the thesis rig and was dropped.
    max_order : int, optional
        Cap on every Fourier series' order (see :func:`fit_fourier`).

    Returns
    -------
    MarkerKinematics
    """
    t_s = np.asarray(t_s, dtype=np.float64)
    xyz = np.asarray(xyz_m, dtype=np.float64)
    if xyz.ndim != 3 or xyz.shape[2] != 3 or t_s.shape != (xyz.shape[0],):
        raise InputError(f"xyz_m must have shape (F, M, 3) with F = len(t_s); got {xyz.shape} and "
                         f"{t_s.shape}")
    if omega_from not in ("vertical", "all"):
        raise InputError(f"omega_from must be 'vertical' or 'all', got {omega_from!r}")
    if x_model not in ("linear", "fourier"):
        raise InputError(f"x_model must be 'linear' or 'fourier', got {x_model!r}")
    n_mark = xyz.shape[1]
    label = [names[m] if names is not None and m < len(names) else f"marker {m + 1}" for m in range(n_mark)]
    # Fourier-fitted axes and their trend degree.
    axes = {1: trend_degree, 2: trend_degree}
    if x_model == "fourier":
        axes = {0: 1, **axes}
    fits: dict[tuple[int, int], LinearFit | FourierFit] = {}

    def fit_marker(m: int) -> None:
        if x_model == "linear":
            fits[m, 0] = fit_linear(t_s, xyz[:, m, 0], name=f"{label[m]} x")
        for c, degree in axes.items():
            fits[m, c] = fit_fourier(t_s, xyz[:, m, c], period_s=period_s, criterion=criterion,
                                     extra_orders=extra_orders, trend_degree=degree,
                                     name=f"{label[m]} {'xyz'[c]}", max_order=max_order)

    rejected: list[str] = []
    for m in range(n_mark):
        fit_marker(m)
        if reject_sigma is None:
            continue
        # Outliers judged against the fit itself: unlike a local smoother it keeps the harmonics.
        wild = np.zeros(xyz.shape[0], dtype=bool)
        for c in range(3):
            r = xyz[:, m, c] - fits[m, c].evaluate(t_s)
            fin = np.isfinite(r)
            if fin.sum() < 5:
                continue
            scale = 1.4826 * float(np.median(np.abs(r[fin] - np.median(r[fin]))))
            wild |= fin & (np.abs(r) > max(reject_sigma * scale, reject_min_m))
        if wild.any() and np.isfinite(xyz[~wild, m, 1]).sum() >= 0.8 * np.isfinite(xyz[:, m, 1]).sum():
            xyz = xyz.copy() if not rejected else xyz
            xyz[wild, m] = np.nan
            rejected.append(f"{label[m]}: {int(wild.sum())} wild samples left out of its fits "
                            f"(beyond {reject_sigma:g} robust standard deviations)")
            fit_marker(m)
    whole = np.all(np.isfinite(xyz), axis=(1, 2))
    if shared_order and n_mark > 1 and whole.sum() >= 8:
        for c, degree in axes.items():
            try:
                order_c = fit_fourier(t_s[whole], xyz[whole, :, c].mean(axis=1), period_s=period_s,
                                      criterion=criterion, extra_orders=extra_orders, trend_degree=degree,
                                      name=f"markers' centroid {'xyz'[c]}", max_order=max_order).order
            except KinematicsError:
                continue
            for m in range(n_mark):
                own = fits[m, c]
                if own.order < order_c:
                    g = fit_fourier(t_s, xyz[:, m, c], period_s=period_s, order=order_c, trend_degree=degree,
                                    name=f"{label[m]} {'xyz'[c]}")
                    fits[m, c] = replace(g, criterion=f"{criterion} of the centroid", candidates=own.candidates,
                                         extrema_per_period=own.extrema_per_period)
    omega_per_fit = np.full((n_mark, 3), np.nan)
    for (m, c), f in fits.items():
        if isinstance(f, FourierFit):
            omega_per_fit[m, c] = f.omega_rad_s
    flags = rejected + [flag for f in fits.values() if isinstance(f, FourierFit) for flag in f.flags]
    pooled = float("nan")
    if common_omega:
        keys = [k for k, f in fits.items() if isinstance(f, FourierFit)]
        se = np.array([fits[k].se["omega_rad_s"] for k in keys])
        omegas = np.array([fits[k].omega_rad_s for k in keys])
        ok = np.isfinite(se) & (se > 0)
        if omega_from == "vertical":
            vertical = ok & np.array([c == 1 for _, c in keys])
            ok = vertical if vertical.any() else ok
        if ok.any():
            w = 1.0 / se[ok] ** 2
            pooled = float(np.sum(w * omegas[ok]) / np.sum(w))
            pooled_se = float(1.0 / np.sqrt(np.sum(w)))
        else:
            pooled = 2 * np.pi / period_s
            pooled_se = float("nan")
            flags.append("no fit determined the fundamental; used the stride period's")
        for m, c in keys:
            free = fits[m, c]
            g = fit_fourier(t_s, xyz[:, m, c], period_s=2 * np.pi / pooled, order=free.order, fit_omega=False,
                            trend_degree=axes[c], name=f"{label[m]} {'xyz'[c]}")
            half = student_t.ppf(0.975, max(g.gof.dfe, 1)) * pooled_se
            fits[m, c] = _with_pooled_omega(g, free, pooled_se, half)
    vel = np.empty(xyz.shape)
    acc = np.empty(xyz.shape)
    for (m, c), fit in fits.items():
        vel[:, m, c] = fit.evaluate(t_s, 1)
        acc[:, m, c] = fit.evaluate(t_s, 2)
    return MarkerKinematics(t_s=t_s, fits_x=tuple(fits[m, 0] for m in range(n_mark)),
                            fits_y=tuple(fits[m, 1] for m in range(n_mark)),
                            fits_z=tuple(fits[m, 2] for m in range(n_mark)), velocity_m_s=vel,
                            acceleration_m_s2=acc, omega_rad_s=pooled, omega_per_fit=omega_per_fit,
                            flags=tuple(flags))


def _with_pooled_omega(fixed: FourierFit, free: FourierFit, pooled_se: float, half: float) -> FourierFit:
    """The fixed-w refit, labelled with the pooled w's uncertainty and the free fit's order choice."""
    se = dict(fixed.se, omega_rad_s=pooled_se)
    ci = dict(fixed.ci, omega_rad_s=np.array([fixed.omega_rad_s - half, fixed.omega_rad_s + half]))
    return FourierFit(a0=fixed.a0, a=fixed.a, b=fixed.b, omega_rad_s=fixed.omega_rad_s, t0=fixed.t0,
                      gof=fixed.gof, ci=ci, se=se, residuals=fixed.residuals, omega_source="pooled",
                      criterion=free.criterion, extrema_per_period=free.extrema_per_period,
                      candidates=free.candidates, flags=free.flags, trend=fixed.trend)
