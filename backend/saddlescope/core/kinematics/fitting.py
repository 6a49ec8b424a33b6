"""Curve fits of every registered marker coordinate and their analytic derivatives (thesis 5.5).

x (travel): a straight line (or a line plus a Fourier series), y (gravity) and z: Fourier series
of the stride (:mod:`saddlescope.core.kinematics.curve_fits`). A rigid body has one fundamental, so
the fits' fundamentals are pooled, and the markers share the order their centroid needs.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import cast

import numpy as np
from scipy.stats import t as student_t

from saddlescope.core.errors import InputError, KinematicsError
from saddlescope.core.findings import Finding
from saddlescope.core.kinematics.curve_fits import FourierFit, LinearFit, fit_fourier, fit_linear

__all__ = [
    "MarkerKinematics",
    "fit_marker_kinematics",
]


@dataclass(frozen=True)
class MarkerKinematics:
    """Fits and analytic derivatives of every marker's motion-frame coordinates.

    fits_x : tuple (M,) of LinearFit (thesis) or FourierFit (``x_model="fourier"``);
    fits_y, fits_z : tuple of FourierFit (M,);
    t_s : ndarray of shape (F,); velocity_m_s, acceleration_m_s2 : ndarray of shape (F, M, 3);
    omega_rad_s : float, the common fundamental (pooled) or NaN when each fit kept its own;
    omega_per_fit : ndarray of shape (M, 3), the free fundamental of each axis's Fourier fit
    (NaN for a linear x);
    flags : tuple of Finding.
    """

    t_s: np.ndarray
    fits_x: tuple
    fits_y: tuple
    fits_z: tuple
    velocity_m_s: np.ndarray
    acceleration_m_s2: np.ndarray
    omega_rad_s: float
    omega_per_fit: np.ndarray
    flags: tuple[Finding, ...] = ()

    @property
    def average_speed_m_s(self) -> float:
        """Mean travel speed of the markers (the slope of the x fits, thesis 5.5.3)."""
        return float(np.mean([f.slope if isinstance(f, LinearFit) else f.trend[0] for f in self.fits_x]))

    def position_m(self, t_s) -> np.ndarray:
        """Every marker's fitted position from its x, y and z fits.

        Parameters
        ----------
        t_s : ndarray of shape (F,)
            Times (s).

        Returns
        -------
        ndarray of shape (F, M, 3)
            Positions (m), motion frame.
        """
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
                          max_order: int | None = None, up_to_frame_rate: bool = False) -> MarkerKinematics:
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
        Which series' w are pooled: the vertical (y) ones (default: the best measured on any rig;
        a thesis-rig canter's x series read w 2.8 % off, the vertical acceleration 8.5 % off) or all.
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
    up_to_frame_rate : bool, optional
        Higher orders of the vertical (y) series up to what the frame rate resolves, while the criterion
        asks (:func:`fit_fourier`); only y: z and x would take a narrow rig's noise for harmonics.

    Returns
    -------
    MarkerKinematics
    """
    t_s, xyz = _check_window(t_s, xyz_m, omega_from=omega_from, x_model=x_model)
    n_mark = xyz.shape[1]
    label = tuple(names[m] if names is not None and m < len(names) else f"marker {m + 1}" for m in range(n_mark))
    how = _SeriesOptions(period_s=period_s, criterion=criterion, extra_orders=extra_orders,
                         max_order=max_order, x_model=x_model, trend_degree=trend_degree, labels=label,
                         up_to_frame_rate=up_to_frame_rate)
    fits, xyz, rejected = _fit_markers(t_s, xyz, how, reject_sigma, reject_min_m)
    whole = np.all(np.isfinite(xyz), axis=(1, 2))
    if shared_order and n_mark > 1 and whole.sum() >= 8:
        _share_centroid_order(fits, t_s, xyz, whole, how)
    omega_per_fit = _free_omegas(fits, n_mark)
    flags = rejected + [flag for f in fits.values() if isinstance(f, FourierFit) for flag in f.flags]
    pooled = float("nan")
    if common_omega:
        pooled, pooling_flags = _pool_omega(fits, t_s, xyz, how, omega_from,
                                            _base_vertical_fits(fits, t_s, xyz, how, whole, shared_order))
        flags += pooling_flags
    vel, acc = _derivatives(fits, t_s, xyz.shape)
    return MarkerKinematics(t_s=t_s, fits_x=tuple(fits[m, 0] for m in range(n_mark)),
                            fits_y=tuple(fits[m, 1] for m in range(n_mark)),
                            fits_z=tuple(fits[m, 2] for m in range(n_mark)), velocity_m_s=vel,
                            acceleration_m_s2=acc, omega_rad_s=pooled, omega_per_fit=omega_per_fit,
                            flags=tuple(flags))


@dataclass(frozen=True)
class _SeriesOptions:
    """What every marker's series are fitted with (options of :func:`fit_marker_kinematics`).

    ``trend_degree`` is the y and z series' trend; ``labels`` names the markers for messages.
    """

    period_s: float
    criterion: str
    extra_orders: int
    max_order: int | None
    x_model: str
    trend_degree: int
    labels: tuple[str, ...]
    up_to_frame_rate: bool = False

    @property
    def axes(self) -> dict[int, int]:
        """The Fourier-fitted axes (0 x, 1 y, 2 z) and their trend degree."""
        axes = {1: self.trend_degree, 2: self.trend_degree}
        return {0: 1, **axes} if self.x_model == "fourier" else axes


_Fits = dict[tuple[int, int], LinearFit | FourierFit]


def _check_window(t_s, xyz_m, *, omega_from: str, x_model: str) -> tuple[np.ndarray, np.ndarray]:
    """The window's times (F,) and positions (F, M, 3) as float arrays; InputError for bad input."""
    t_s = np.asarray(t_s, dtype=np.float64)
    xyz = np.asarray(xyz_m, dtype=np.float64)
    if xyz.ndim != 3 or xyz.shape[2] != 3 or t_s.shape != (xyz.shape[0],):
        raise InputError(f"xyz_m must have shape (F, M, 3) with F = len(t_s); got {xyz.shape} and "
                         f"{t_s.shape}")
    if omega_from not in ("vertical", "all"):
        raise InputError(f"omega_from must be 'vertical' or 'all', got {omega_from!r}")
    if x_model not in ("linear", "fourier"):
        raise InputError(f"x_model must be 'linear' or 'fourier', got {x_model!r}")
    return t_s, xyz


def _fit_marker(fits: _Fits, m: int, t_s: np.ndarray, xyz: np.ndarray, how: _SeriesOptions) -> None:
    """Fit marker ``m``'s three coordinates into ``fits[m, axis]``."""
    if how.x_model == "linear":
        fits[m, 0] = fit_linear(t_s, xyz[:, m, 0], name=f"{how.labels[m]} x")
    for c, degree in how.axes.items():
        fits[m, c] = fit_fourier(t_s, xyz[:, m, c], period_s=how.period_s, criterion=how.criterion,
                                 extra_orders=how.extra_orders, trend_degree=degree,
                                 name=f"{how.labels[m]} {'xyz'[c]}", max_order=how.max_order,
                                 up_to_frame_rate=how.up_to_frame_rate and c == 1)


def _wild_samples(t_s: np.ndarray, xyz_marker: np.ndarray, marker_fits: list, reject_sigma: float,
                  reject_min_m: float) -> np.ndarray:
    """Samples (F,) of one marker (F, 3) further from any of its three fits than the rejection bound."""
    wild = np.zeros(xyz_marker.shape[0], dtype=bool)
    for c in range(3):
        r = xyz_marker[:, c] - marker_fits[c].evaluate(t_s)
        fin = np.isfinite(r)
        if fin.sum() < 5:
            continue
        scale = 1.4826 * float(np.median(np.abs(r[fin] - np.median(r[fin]))))
        wild |= fin & (np.abs(r) > max(reject_sigma * scale, reject_min_m))
    return wild


def _fit_markers(t_s: np.ndarray, xyz: np.ndarray, how: _SeriesOptions, reject_sigma: float | None,
                 reject_min_m: float) -> tuple[_Fits, np.ndarray, list[Finding]]:
    """Every marker's fits, each refitted without its wild samples.

    Returns the fits by (marker, axis), the positions with the wild samples NaN (a copy once any
    is left out) and one message per marker that lost samples.
    """
    fits: _Fits = {}
    rejected: list[Finding] = []
    for m in range(xyz.shape[1]):
        _fit_marker(fits, m, t_s, xyz, how)
        if reject_sigma is None:
            continue
        # Outliers judged against the fit itself: unlike a local smoother it keeps the harmonics.
        wild = _wild_samples(t_s, xyz[:, m], [fits[m, c] for c in range(3)], reject_sigma, reject_min_m)
        if wild.any() and np.isfinite(xyz[~wild, m, 1]).sum() >= 0.8 * np.isfinite(xyz[:, m, 1]).sum():
            xyz = xyz.copy() if not rejected else xyz
            xyz[wild, m] = np.nan
            rejected.append(Finding("fit.wild_samples",
                                    f"{how.labels[m]}: {int(wild.sum())} wild samples left out of its fits "
                                    f"(beyond {reject_sigma:g} robust standard deviations)",
                                    {"samples": int(wild.sum()), "limit_sigma": reject_sigma}))
            _fit_marker(fits, m, t_s, xyz, how)
    return fits, xyz, rejected


def _share_centroid_order(fits: _Fits, t_s: np.ndarray, xyz: np.ndarray, whole: np.ndarray,
                          how: _SeriesOptions, axes: tuple[int, ...] | None = None) -> None:
    """Refit, at the order of the markers' centroid, every series whose own order is lower.

    ``whole`` (F,) marks the samples where every marker is present (the centroid's samples); ``axes``
    the axes to share (default: every Fourier-fitted one).
    """
    for c, degree in how.axes.items():
        if axes is not None and c not in axes:
            continue
        try:
            order_c = fit_fourier(t_s[whole], xyz[whole, :, c].mean(axis=1), period_s=how.period_s,
                                  criterion=how.criterion, extra_orders=how.extra_orders, trend_degree=degree,
                                  name=f"markers' centroid {'xyz'[c]}", max_order=how.max_order,
                                  up_to_frame_rate=how.up_to_frame_rate and c == 1).order
        except KinematicsError:
            continue
        for m in range(xyz.shape[1]):
            own = cast(FourierFit, fits[m, c])  # the keys of the Fourier series
            if own.order < order_c:
                g = fit_fourier(t_s, xyz[:, m, c], period_s=how.period_s, order=order_c, trend_degree=degree,
                                name=f"{how.labels[m]} {'xyz'[c]}")
                fits[m, c] = replace(g, criterion=f"{how.criterion} of the centroid", candidates=own.candidates,
                                     extrema_per_period=own.extrema_per_period)


def _pooled_fundamental(fits: _Fits, keys: list[tuple[int, int]], omega_from: str, period_s: float
                        ) -> tuple[float, float, list[Finding]]:
    """Inverse-variance weighted mean of the free fundamentals (rad/s), its standard error and a flag.

    The series of ``keys`` whose ω has a standard error count (only the vertical ones where any
    has, with ``omega_from="vertical"``); without any, the stride period's ω and a NaN error.
    """
    fourier = [cast(FourierFit, fits[k]) for k in keys]  # keys name Fourier series only
    se = np.array([f.se["omega_rad_s"] for f in fourier])
    omegas = np.array([f.omega_rad_s for f in fourier])
    ok = np.isfinite(se) & (se > 0)
    if omega_from == "vertical":
        vertical = ok & np.array([c == 1 for _, c in keys])
        ok = vertical if vertical.any() else ok
    if ok.any():
        w = 1.0 / se[ok] ** 2
        return float(np.sum(w * omegas[ok]) / np.sum(w)), float(1.0 / np.sqrt(np.sum(w))), []
    return 2 * np.pi / period_s, float("nan"), [
        Finding("fit.no_fundamental", "no fit determined the fundamental; used the stride period's")]


def _pool_omega(fits: _Fits, t_s: np.ndarray, xyz: np.ndarray, how: _SeriesOptions, omega_from: str,
                base: _Fits | None = None) -> tuple[float, list[Finding]]:
    """Refit every Fourier series with the pooled fundamental; return it (rad/s) and any flag.

    ``base`` (:func:`_base_vertical_fits`) replaces the fits of its keys in the pooling only.
    """
    keys = [k for k, f in fits.items() if isinstance(f, FourierFit)]
    pooled, pooled_se, flags = _pooled_fundamental({**fits, **(base or {})}, keys, omega_from, how.period_s)
    for m, c in keys:
        free = cast(FourierFit, fits[m, c])  # keys name Fourier series only
        g = fit_fourier(t_s, xyz[:, m, c], period_s=2 * np.pi / pooled, order=free.order, fit_omega=False,
                        trend_degree=how.axes[c], name=f"{how.labels[m]} {'xyz'[c]}")
        half = student_t.ppf(0.975, max(g.gof.dfe, 1)) * pooled_se
        fits[m, c] = _with_pooled_omega(g, free, pooled_se, half)
    return pooled, flags

def _base_vertical_fits(fits: _Fits, t_s: np.ndarray, xyz: np.ndarray, how: _SeriesOptions, whole: np.ndarray,
                        shared_order: bool) -> _Fits:
    """The vertical series at the extrema rule's order (the centroid's where higher), for the pooled ω only.

    With orders up to the frame rate, the higher-order vertical fits' free ω pooled worse: the extrapolated
    partial-view canter's stride frequency went from 0.77 % to 1.38 % off (issue 38). The harmonics
    beyond the rule's order are small and noisy, and free to trade with ω over one stride; the fundamental
    is fixed by the strong low harmonics. Empty when the fits were not taken beyond the rule's order.
    """
    if not how.up_to_frame_rate:
        return {}
    rule = replace(how, up_to_frame_rate=False)
    base: _Fits = {}
    for m in range(xyz.shape[1]):
        try:
            base[m, 1] = fit_fourier(t_s, xyz[:, m, 1], period_s=how.period_s, criterion=how.criterion,
                                     extra_orders=how.extra_orders, trend_degree=how.axes[1],
                                     name=f"{how.labels[m]} y", max_order=how.max_order)
        except KinematicsError:
            return {}  # pool from the fits as they are
    if shared_order and xyz.shape[1] > 1 and whole.sum() >= 8:
        _share_centroid_order(base, t_s, xyz, whole, rule, axes=(1,))
    # a fit the rule already chose keeps its own pooled weight (same fit, same ω)
    return {k: f for k, f in base.items() if cast(FourierFit, fits[k]).order != cast(FourierFit, f).order}


def _free_omegas(fits: _Fits, n_mark: int) -> np.ndarray:
    """The fundamental (rad/s) of each marker's and axis's Fourier fit, (M, 3); NaN for a line."""
    omega_per_fit = np.full((n_mark, 3), np.nan)
    for (m, c), f in fits.items():
        if isinstance(f, FourierFit):
            omega_per_fit[m, c] = f.omega_rad_s
    return omega_per_fit


def _derivatives(fits: _Fits, t_s: np.ndarray, shape: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
    """Velocities and accelerations (F, M, 3) of every fit at the window's times t_s (F,), analytic."""
    vel = np.empty(shape)
    acc = np.empty(shape)
    for (m, c), fit in fits.items():
        vel[:, m, c] = fit.evaluate(t_s, 1)
        acc[:, m, c] = fit.evaluate(t_s, 2)
    return vel, acc


def _with_pooled_omega(fixed: FourierFit, free: FourierFit, pooled_se: float, half: float) -> FourierFit:
    """The fixed-w refit, labelled with the pooled w's uncertainty and the free fit's order choice."""
    se = dict(fixed.se, omega_rad_s=pooled_se)
    ci = dict(fixed.ci, omega_rad_s=np.array([fixed.omega_rad_s - half, fixed.omega_rad_s + half]))
    return FourierFit(a0=fixed.a0, a=fixed.a, b=fixed.b, omega_rad_s=fixed.omega_rad_s, t0=fixed.t0,
                      gof=fixed.gof, ci=ci, se=se, residuals=fixed.residuals, omega_source="pooled",
                      criterion=free.criterion, extrema_per_period=free.extrema_per_period,
                      candidates=free.candidates, flags=free.flags, trend=fixed.trend)
