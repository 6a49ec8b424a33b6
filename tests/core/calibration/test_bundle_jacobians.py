"""The bundle adjustment's analytic Jacobians and per-view normal equations against plain references."""

import numpy as np
import pytest

from saddlescope.core.calibration.bundle_adjustment import _NCAM, _Bundle


def _random_bundle(rng, n_cams=2, n_inst=4, n_obs=90, in_order=False):
    obj = np.c_[rng.uniform(0, 300, (24, 2)), np.zeros(24)]
    if in_order:  # whole views one after another, all of one size (the adjustment reshapes them)
        per_view = n_obs // (n_cams * n_inst)
        cam = np.repeat(np.arange(n_cams), n_inst * per_view)
        inst = np.tile(np.repeat(np.arange(n_inst), per_view), n_cams)
        n_obs = len(cam)
    else:  # observations in shuffled order: views are not contiguous, and of different sizes
        cam, inst = rng.integers(0, n_cams, n_obs), rng.integers(0, n_inst, n_obs)
    bundle = _Bundle(obj, cam, inst, rng.integers(0, 24, n_obs), rng.normal(0, 1, (n_obs, 2)), n_cams, n_inst)
    cams = np.zeros((n_cams, _NCAM))
    cams[:, :4] = [1400, 1410, 960, 540]
    cams[:, 4:9] = [-0.1, 0.05, 0.001, -0.002, -0.02]
    cams[1:, 9:12] = rng.normal(0, 0.2, (n_cams - 1, 3))
    cams[1:, 12:] = [-500, 10, 80]
    boards = np.c_[rng.normal(0, 0.3, (n_inst, 3)), rng.uniform(-200, 200, (n_inst, 2)),
                   rng.uniform(1500, 3000, n_inst)]
    return bundle, cams, boards


def _central_difference(f, x, k, h):
    up, down = x.copy(), x.copy()
    up[:, k] += h
    down[:, k] -= h
    return (f(up) - f(down)) / (2 * h)


def test_analytic_jacobians_match_central_differences():
    bundle, cams, boards = _random_bundle(np.random.default_rng(0))
    A, B = bundle.jacobians(cams, boards)
    for k in range(_NCAM):
        h = 1e-6 * max(1.0, np.abs(cams[:, k]).max())
        fd = _central_difference(lambda c: bundle.residuals(c, boards), cams, k, h)
        assert np.allclose(A[:, :, k], fd, rtol=1e-5, atol=1e-6 * np.abs(fd).max() + 1e-9), k
    for k in range(6):
        h = 1e-6 * max(1.0, np.abs(boards[:, k]).max())
        fd = _central_difference(lambda b: bundle.residuals(cams, b), boards, k, h)
        assert np.allclose(B[:, :, k], fd, rtol=1e-5, atol=1e-6 * np.abs(fd).max() + 1e-9), k


@pytest.mark.parametrize("in_order", [False, True])
def test_per_view_normal_equations_equal_the_dense_products(in_order):
    rng = np.random.default_rng(1)
    bundle, cams, boards = _random_bundle(rng, n_cams=3, n_inst=5, n_obs=150, in_order=in_order)
    assert bundle._in_order == in_order
    A, B = bundle.jacobians(cams, boards)
    r = bundle.residuals(cams, boards)
    w = rng.uniform(0.2, 1.0, len(r))
    U, V, W, gc, gb = bundle.normal_equations(A, B, r, w)
    # the dense Jacobian, (2 M, C * 15 + I * 6)
    C, I, M = bundle.C, bundle.I, len(r)
    J = np.zeros((M, 2, C * _NCAM + I * 6))
    for m in range(M):
        J[m, :, bundle.cam[m] * _NCAM:(bundle.cam[m] + 1) * _NCAM] = A[m]
        J[m, :, C * _NCAM + 6 * bundle.inst[m]:C * _NCAM + 6 * (bundle.inst[m] + 1)] = B[m]
    J = J.reshape(2 * M, -1)
    ww = np.repeat(w, 2)
    H, g = J.T @ (ww[:, None] * J), J.T @ (ww * r.ravel())
    n = C * _NCAM
    for c in range(C):
        assert np.allclose(U[c], H[c * _NCAM:(c + 1) * _NCAM, c * _NCAM:(c + 1) * _NCAM])
        for i in range(I):
            assert np.allclose(W[c, i], H[c * _NCAM:(c + 1) * _NCAM, n + 6 * i:n + 6 * (i + 1)])
    for i in range(I):
        assert np.allclose(V[i], H[n + 6 * i:n + 6 * (i + 1), n + 6 * i:n + 6 * (i + 1)])
    assert np.allclose(gc.ravel(), g[:n]) and np.allclose(gb.ravel(), g[n:])
