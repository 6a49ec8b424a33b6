"""Goodness of fit of the curve fits, and their uncertainty under correlated noise (thesis 5.5).

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

from dataclasses import dataclass, replace

import numpy as np
from scipy.signal import lfilter
from scipy.stats import t as student_t

__all__ = [
    "CRITERIA",
    "GoodnessOfFit",
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
        """The numbers as a JSON-able dict (with ``dfe``).

        Returns
        -------
        dict of str -> float or int
        """
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
    """The noise's lag-1 autocorrelation from a fit's residuals' (:func:`_lag1`).

    Corrected for the bias fitting puts into it (white noise's residuals have E[sum e_t e_t-1] =
    -s^2 tr(H L), H the hat matrix, L the lag-1 shift: about -p / n for slow regressors), and
    clipped to [0, 0.98]: negative or no correlation keeps the textbook intervals, so they are never
    narrower than MATLAB's. ``jac`` is the Jacobian (n, p), ``bread`` its (J'J)^-1 (p, p).
    """
    n, p = jac.shape
    if n - p < 3:
        return 0.0
    tr_hl = float(np.trace(bread @ (jac[1:].T @ jac[:-1])))
    return float(np.clip(residual_lag1 + tr_hl / (n - p), 0.0, 0.98))


def _covariance(jac: np.ndarray, residuals: np.ndarray, residual_lag1: float, floor_var: float = 0.0
                ) -> tuple[np.ndarray, np.ndarray, float]:
    """Covariances (p, p) of least-squares parameters with Jacobian ``jac`` (n, p).

    The textbook s^2 (J'J)^-1, s^2 = SSE / (n - p), and, from the ``residuals`` (n,) in sample
    order, the one for AR(1) noise of lag-1 autocorrelation rho: the sandwich
    (J'J)^-1 J' Sigma J (J'J)^-1 with Sigma_ij = s^2 rho^|i-j|. For a harmonic this is the noise's
    spectral density at its frequency, which is what its coefficients scatter with. Sigma J is two
    exponential filters, forward and back, so no n x n matrix is formed (a gap between samples
    counts as one sample step). ``floor_var`` (J'J)^-1 is added to both (keeps an exact fit's tests
    finite). Returns (AR(1), textbook, rho).
    """
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
    """Standard errors and confidence intervals of the parameters of Jacobian (n, p).

    Returns the standard errors (p,), the half-widths (p,) of the intervals, the two covariances
    (p, p) of :func:`_covariance`, and ``gof`` with the residuals' and the noise's lag-1
    autocorrelation filled in (see the module's note on correlated noise). Each standard error is
    the larger of the two: the AR(1) model can put less noise at a high harmonic than there is
    (smooth noise that is not AR(1)), and no interval here is narrower than MATLAB's. ``scale`` is
    the data's r.m.s. about its mean: a variance of (1e-12 scale)^2 is the floor, as in the criteria.
    """
    if gof.dfe <= 0:
        nan = np.full(jac.shape[1], np.nan)
        cov_nan = np.full((jac.shape[1],) * 2, np.nan)
        return nan, nan, (cov_nan, cov_nan), gof
    lag1 = _lag1(residuals)
    cov_ar1, cov_white, rho = _covariance(jac, residuals, lag1, (1e-12 * scale) ** 2)
    se = np.sqrt(np.clip(np.maximum(np.diag(cov_ar1), np.diag(cov_white)), 0.0, None))
    return (se, student_t.ppf(0.5 + level / 2, gof.dfe) * se, (cov_ar1, cov_white),
            replace(gof, residual_lag1=lag1, noise_lag1=rho))



def _penalty(n: int, p: int, criterion: str) -> float:
    """The parameter penalty of AICc (2p + 2p(p+1)/(n-p-1)) or BIC (p log n)."""
    if criterion == "bic":
        return p * float(np.log(n))
    return 2 * p + (2 * p * (p + 1) / (n - p - 1) if n - p - 1 > 0 else np.inf)


def _choose(fits: list, criterion: str, n_poly: int) -> int:
    """Index of the chosen candidate order.

    ``fits`` rows are (order, coef, omega, resid, gof, se, half, flags, omega_free, (cov_ar1,
    cov_white)), orders ascending. "aicc" and "bic" score the orders as the criterion does, with the
    Wald statistic of the harmonics each step up adds in place of that step's fall of n log SSE: the
    smaller of the statistics under the AR(1) and the textbook covariance, so correlated noise does
    not pass for a harmonic, and white noise is judged as the textbook criterion judges it.
    """
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

