"""benchmarks/car_drive_road.py's pooled fit of one left-out term over the windows, and car_drive.py's differenced RTK
positions that skip a change of the satellite count or of the fix."""

from __future__ import annotations

import types

import numpy as np
import pytest


@pytest.fixture(scope="module")
def road():
    from conftest import benchmark_module

    with benchmark_module("car_drive_road", prefix="car_drive") as mod:
        yield mod


def _window(estimate, covariance, gain):
    res = types.SimpleNamespace(names=tuple(SIX), estimate=np.asarray(estimate, float),
                                covariance=np.asarray(covariance, float), success=True)
    return types.SimpleNamespace(result=res, consider_gain=np.asarray(gain, float), consider_names=("t0", "t1"))


SIX = ("ba_x", "ba_y", "ba_z", "bg_x", "bg_y", "bg_z")


def test_one_term_against_a_dense_gls(road):
    """Windows holding ``m + A_k[:, 1] c`` plus noise of their covariance and the instability at rest: the pooled fit
    equals a GLS written out over the stacked windows with the block-diagonal covariance (numpy's solve, no
    whitening), its chi-square the weighted residual sum, and without noise it returns c exactly."""
    rng = np.random.default_rng(5)
    K, m, c = 9, rng.normal(size=6), 2.5
    inst = np.diag([road.INSTABILITY.get(n, 0.0) ** 2 for n in SIX])
    ws, X, Y, V = [], [], [], []
    for _ in range(K):
        L = rng.normal(size=(6, 6)) * 0.3
        C = L @ L.T + 0.1 * np.eye(6)
        G = rng.normal(size=(6, 2))
        x = m + G[:, 1] * c + rng.multivariate_normal(np.zeros(6), C + inst)
        ws.append(_window(x, C, G))
        X.append(np.hstack([np.eye(6), G[:, [1]]]))
        Y.append(x)
        V.append(np.linalg.inv(C + inst))
    X, Y = np.vstack(X), np.concatenate(Y)
    W = np.zeros((6 * K, 6 * K))
    for k, v in enumerate(V):
        W[6 * k:6 * k + 6, 6 * k:6 * k + 6] = v
    p = np.linalg.solve(X.T @ W @ X, X.T @ W @ Y)
    chi2 = float((Y - X @ p) @ W @ (Y - X @ p))
    got = road.one_term(ws, 1)
    assert got[0] == pytest.approx(chi2, rel=1e-9)
    assert got[1] == pytest.approx(p[-1], rel=1e-9)
    assert got[2] == pytest.approx(np.sqrt(np.linalg.inv(X.T @ W @ X)[-1, -1]), rel=1e-9)
    exact = [_window(m + w.consider_gain[:, 1] * c, w.result.covariance, w.consider_gain) for w in ws]
    assert road.one_term(exact, 1)[1] == pytest.approx(c, abs=1e-9)
    assert road.one_term(exact, None)[0] > 1.0  # the term is needed: constant biases alone leave a misfit


def test_same_satellites_skips_changes():
    """Five epochs on a straight line at 0.25 s: the differenced velocity is the line's everywhere; with
    same_satellites the difference across a change of ns (epochs 1-2) and the one touching a float epoch (3-4)
    are left out, the others kept with the same values."""
    from conftest import benchmark_module

    with benchmark_module("car_drive") as cd:
        t = 1.0e9 + 0.25 * np.arange(5)
        pos = {"t": t, "lat": 40.0 + 1e-6 * np.arange(5), "lon": np.full(5, -105.0), "h": 1600.0 + 0.1 * np.arange(5),
               "q": np.array([1, 1, 1, 1, 2.0]), "ns": np.array([22, 22, 21, 21, 21.0])}
        every = cd.velocity_from_positions(pos)
        same = cd.velocity_from_positions(pos, same_satellites=True)
    assert every["t"].size == 4
    np.testing.assert_allclose(same["t"], every["t"][[0, 2]])
    np.testing.assert_allclose(same["vu"], every["vu"][[0, 2]])
    np.testing.assert_allclose(every["vu"], 0.4, atol=2e-3)  # 0.1 m per 0.25 s, to the Earth's curvature
