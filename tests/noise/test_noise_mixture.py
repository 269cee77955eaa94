"""The Gauss-Markov plus white noise model: the whitening kernel against dense generalised least
squares, its digits when dt << tau, the compiled filter against its numpy reference, REML recovery
of tau and both std, and the nested choice of ``auto``."""

from __future__ import annotations

import numpy as np
import pytest

from casep import _compiled
from casep._kernels import ar1_terms, gmw_filter_numpy
from casep.noise.fit import Reml, estimable_basis, fit_noise
from casep.noise.model import NOISE_KINDS, NoiseModel, whiten, whiten_series
from casep.regression.problem import Problem


def _times(rng, n: int, dt: float = 0.05) -> np.ndarray:
    """Jittered spacing (+-40 %) with two gaps (30 and 4 steps)."""
    steps = dt * (1.0 + 0.4 * rng.uniform(-1, 1, n - 1))
    steps[n // 3] = 30 * dt
    steps[2 * n // 3] = 4 * dt
    return np.concatenate([[0.0], np.cumsum(steps)])


def _dense_axis(t: np.ndarray, tau: float | None, share: float, r: float) -> np.ndarray:
    """The exact covariance of one axis: r^2 [(1 - w) exp(-|t_i - t_j| / tau) + w I]."""
    if tau is None:
        return r**2 * np.eye(t.size)
    return r**2 * ((1.0 - share) * np.exp(-np.abs(t[:, None] - t[None, :]) / tau) + share * np.eye(t.size))


MODELS = {"white": NoiseModel(scale=(1.0, 1.5, 0.7)),
          "gm": NoiseModel(kind="gm", tau=(0.5, 2.0, 0.2), scale=(1.0, 1.5, 0.7)),
          "gmw": NoiseModel(kind="gmw", tau=(0.5, 2.0, 0.2), scale=(1.0, 1.5, 0.7), share=(0.2, 0.6, 0.05)),
          "mixed": NoiseModel(kind="auto", tau=(1.0, None, 0.3), scale=(1.0, 1.2, 0.8), share=(0.3, 0.0, 0.0))}


@pytest.mark.parametrize("name", list(MODELS))
def test_whitening_equals_dense_cholesky_gls(name, rng):
    """GLS on the whitened rows (uneven times, two gaps, N = 200) equals the dense Cholesky GLS to
    1e-10; sum ln F_k + 2 N ln r equals ln det of the dense covariance."""
    N, n = 200, 4
    t = _times(rng, N)
    nm = MODELS[name]
    S = rng.normal(size=(N, 3, n))
    y = rng.normal(size=(N, 3))
    Sw, yw = whiten(S, y, t, nm)
    x = np.linalg.lstsq(Sw.reshape(-1, n), yw.reshape(-1), rcond=None)[0]
    A_ours = Sw.reshape(-1, n).T @ Sw.reshape(-1, n)
    A, b = np.zeros((n, n)), np.zeros(n)
    for a in range(3):
        C = _dense_axis(t, nm.tau[a], nm.share[a], nm.scale[a])
        L = np.linalg.cholesky(C)
        As, ys = np.linalg.solve(L, S[:, a, :]), np.linalg.solve(L, y[:, a])
        A += As.T @ As
        b += As.T @ ys
        _, ld, _ = whiten_series(np.ones((N, 1)), t, nm.tau[a], nm.share[a])
        assert ld + 2 * N * np.log(nm.scale[a]) == pytest.approx(np.linalg.slogdet(C)[1], rel=1e-10, abs=1e-9)
    np.testing.assert_allclose(x, np.linalg.solve(A, b), rtol=1e-10)
    np.testing.assert_allclose(A_ours, A, rtol=1e-10)


def test_block_by_block_carries_the_filter_state(rng):
    """Whitening in blocks (the state carried) equals whitening the whole series."""
    t = _times(rng, 300)
    X = rng.normal(size=(300, 3))
    for share in (0.0, 0.3):
        whole, ld, _ = whiten_series(X, t, 0.7, share)
        parts, lds, st = [], 0.0, None
        for sl in (slice(0, 1), slice(1, 117), slice(117, 300)):
            W, ldb, st = whiten_series(X[sl], t[sl], 0.7, share, st)
            parts.append(W)
            lds += ldb
        np.testing.assert_allclose(np.vstack(parts), whole, rtol=1e-13, atol=1e-14)
        assert lds == pytest.approx(ld, rel=1e-13)


@pytest.mark.parametrize("share", [0.0, 0.01, 0.5, 0.999])
def test_compiled_filter_equals_numpy_reference(share, rng):
    t = _times(rng, 500)
    X = rng.normal(size=(500, 5))
    dt = np.concatenate([[np.inf], np.diff(t)])
    outs = []
    for kernel in (_compiled.gmw_filter, gmw_filter_numpy):
        m, P, out = np.zeros(5), np.zeros(1), np.empty((500, 5))
        ld = kernel(X, dt, 0.8, share, m, P, out)
        outs.append((out, ld, m, P))
    np.testing.assert_allclose(outs[0][0], outs[1][0], rtol=1e-13, atol=1e-14)
    assert outs[0][1] == pytest.approx(outs[1][1], rel=1e-13)
    np.testing.assert_allclose(outs[0][2], outs[1][2], rtol=1e-13, atol=1e-14)


def test_short_steps_keep_their_digits():
    """dt = 1e-4 s, tau = 10 s: 1 - a^2 = 2e-5 to full precision (the series of 1 - exp(-2x) is the
    reference; ``1 - a**2`` would lose five digits), and the whitened AR(1) rows with it."""
    x = 1e-5  # dt / tau
    series = 2 * x - 2 * x**2 + (4 / 3) * x**3 - (2 / 3) * x**4 + (4 / 15) * x**5  # 1 - e^(-2x), error ~ x^6
    a, b = ar1_terms(1e-4, 10.0)
    assert float(b) == pytest.approx(series, rel=4e-16)
    assert abs(1.0 - float(a) ** 2 - series) / series > 1e-13  # the naive form: digits lost
    rng = np.random.default_rng(2)
    t = 1e-4 * np.arange(200)
    X = rng.normal(size=(200, 1))
    W = whiten_series(X, t, 10.0)[0]
    a_exact = 1.0 - x + x**2 / 2 - x**3 / 6 + x**4 / 24  # exp(-x)
    ref = (X[1:, 0] - a_exact * X[:-1, 0]) / np.sqrt(series)
    np.testing.assert_allclose(W[1:, 0], ref, rtol=1e-13)


def test_short_steps_mixture_against_dense():
    """dt = 1e-4 s, tau = 10 s, white share 0.3: the filter against the dense Cholesky (well
    conditioned: the white part bounds its eigenvalues below by 0.3)."""
    rng = np.random.default_rng(4)
    t = 1e-4 * np.arange(200) + 1e-6 * rng.uniform(size=200)
    X = rng.normal(size=(200, 2))
    W, ld, _ = whiten_series(X, t, 10.0, 0.3)
    C = _dense_axis(t, 10.0, 0.3, 1.0)
    np.testing.assert_allclose(W.T @ W, X.T @ np.linalg.solve(C, X), rtol=1e-10)
    assert ld == pytest.approx(np.linalg.slogdet(C)[1], rel=1e-10)


def test_reml_equals_the_dense_restricted_likelihood_with_white_parts(rng):
    """Differences of -2 l_R between parameter sets (white parts, GM, white) equal the dense
    computation's; the lag-product Gram of AR(1) equals the whitened one."""
    N, n = 150, 3
    t = _times(rng, N)
    S = rng.normal(size=(N, 3, n))
    y = rng.normal(size=(N, 3))
    pb = Problem.from_arrays(S, y, t)
    reml = Reml(pb, estimable_basis(pb))
    sets = [((0.8, 0.3, 1.5), (1.0, 1.5, 0.7), (0.2, 0.0, 0.5)), ((0.4, None, 3.0), (1.0, 1.0, 1.0), (0.0,) * 3),
            ((None, None, None), (1.0, 2.0, 0.5), (0.0,) * 3), ((2.0, 2.0, 2.0), (1.0, 1.0, 1.0), (0.9, 0.1, 0.01))]

    def dense(taus, sc, ww):
        Ls = [np.linalg.cholesky(_dense_axis(t, taus[a], ww[a], sc[a])) for a in range(3)]
        A = np.vstack([np.linalg.solve(Ls[a], S[:, a, :]) for a in range(3)])
        b = np.concatenate([np.linalg.solve(Ls[a], y[:, a]) for a in range(3)])
        rss = float(np.sum((b - A @ np.linalg.lstsq(A, b, rcond=None)[0]) ** 2))
        return (3 * N - n) * np.log(rss) + sum(2 * np.sum(np.log(np.diag(L))) for L in Ls) \
            + np.linalg.slogdet(A.T @ A)[1]

    ours = [reml.evaluate(*s)[0] for s in sets]
    np.testing.assert_allclose(np.diff(ours), np.diff([dense(*s) for s in sets]), rtol=1e-8, atol=1e-7)
    assert reml._lags[0] is None  # jittered times: the rows are whitened (no grouping)
    reg = Problem.from_arrays(S, y, 0.05 * np.r_[0:N // 2, N // 2 + 40:N + 40])  # a grid with a gap
    r2 = Reml(reg, estimable_basis(reg))
    assert r2._lags[0] is not None and r2._lags[0].d.size <= 10
    for tau in (0.01, 1.0, 300.0):
        M, ld = r2._lags[1].gram(tau)
        W, ld2, _ = whiten_series(r2.Z[1], reg.t, tau)
        np.testing.assert_allclose(M, W.T @ W, rtol=1e-9, atol=1e-9 * np.abs(M).max())
        assert ld == pytest.approx(ld2, rel=1e-12)


def test_reml_recovers_tau_and_both_std():
    """20 Hz, 1000 s (20000 samples per axis), GM tau 1 s std 0.09 m/s plus white 0.045 m/s, three
    regressors. For T / tau = 1000 the sampling std of ln tau is about sqrt(2 tau / T) ~ 0.045 for
    pure Gauss-Markov and about twice that with the white part: tau within 30 % (3 sd); the white std
    (20000 samples, well separated from the GM part at high frequency) within 6 %; the GM std
    (its variance estimate as uncertain as tau) within 15 %."""
    from casep.simulation.noise import ar1_noise

    rng = np.random.default_rng(11)
    t = 0.05 * np.arange(20000)
    S = rng.normal(size=(t.size, 3, 3))
    e = ar1_noise(t, 0.09, 1.0, rng) + 0.045 * rng.standard_normal((t.size, 3))
    nm = fit_noise(Problem.from_arrays(S, S @ np.array([1.0, -2.0, 0.5]) + e, t), "gmw")
    d = nm.to_dict()["axes"]
    for a in "xyz":
        assert d[a]["model"] == "gauss-markov+white"
        assert d[a]["tau_s"] == pytest.approx(1.0, rel=0.3)
        assert d[a]["std_white_m_s"] == pytest.approx(0.045, rel=0.06)
        assert d[a]["std_gm_m_s"] == pytest.approx(0.09, rel=0.15)
    back = NoiseModel.from_dict(nm.to_dict())
    assert back.share == nm.share and back.tau == nm.tau and back.scale == nm.scale


def test_auto_nests_white_gm_and_gmw():
    """auto takes the simplest kind its tests do not reject, per axis: white, GM and GM plus white
    axes in one problem (seeded; the likelihood ratios are far from the threshold here)."""
    from casep.simulation.noise import ar1_noise

    rng = np.random.default_rng(12)
    t = 0.05 * np.arange(6000)
    S = rng.normal(size=(t.size, 3, 2))
    e = np.column_stack([0.1 * rng.standard_normal(t.size), ar1_noise(t, 0.1, 1.0, rng, axes=1)[:, 0],
                         ar1_noise(t, 0.09, 1.0, rng, axes=1)[:, 0] + 0.045 * rng.standard_normal(t.size)])
    nm = fit_noise(Problem.from_arrays(S, S @ np.array([1.0, 2.0]) + e, t), "auto")
    assert nm.axis_kinds() == ("white", "gm", "gmw")
    assert nm.lr_white[0] is None and (nm.lr_white[1] is None or nm.lr_white[1] < 5.412) and nm.lr_white[2] > 5.412


def test_noise_kinds_declared_once():
    """The command line offers exactly the API's kinds."""
    from casep.cli.app import build_parser

    parser = build_parser()
    sub = next(a for a in parser._subparsers._group_actions[0].choices["separate"]._actions
               if "--noise" in a.option_strings)
    assert tuple(sub.choices) == NOISE_KINDS and "gmw" in NOISE_KINDS


def test_noise_line_of_every_kind_reads_back():
    """The console line of a model with white, Gauss-Markov and Gauss-Markov plus white axes, from
    the model and from its JSON (a result file), and of a result written before the white share."""
    from casep.reporting.noise_text import noise_line

    nm = NoiseModel(kind="auto", tau=(None, 1.2, 0.8), scale=(1.0, 1.1, 0.9), rule="reml", lr=(1.0, 50.0, 80.0),
                    sigma=0.1, share=(0.0, 0.0, 0.25), lr_white=(None, 2.0, 30.0))
    line = nm.line()
    assert "x white" in line and "y GM tau 1.2 s std 0.11 m/s" in line and "z GM tau 0.8 s + white" in line
    assert noise_line(nm.to_dict()) == line
    old = {"kind": "gm", "rule": "reml", "axes": {a: {"model": "gauss-markov", "tau_s": 1.0, "scale": 1.0}
                                                  for a in "xyz"}}
    assert NoiseModel.from_dict(old).share == (0.0, 0.0, 0.0)


def test_an_infinite_likelihood_ratio_is_written_as_null_and_read_back():
    """An axis whose white fit has no finite likelihood (residuals at the rounding level there, the rest
    not: a noise-free flight with a 1 us tracking offset) gives LR inf: the result JSON holds it as null
    (JSON has no inf; the writer refused the whole file before) and reads it back as inf."""
    import json
    import math

    nm = NoiseModel(kind="auto", tau=(1.0, 1.0, 96.4), scale=(1.0, 0.7, 0.01), rule="reml",
                    lr=(6.98e4, 6.98e4, math.inf), lr_scale=math.inf, sigma=4e-6,
                    extra={"neg2_reml": -math.inf})
    d = nm.to_dict()
    text = json.dumps(d, allow_nan=False)  # raises on a non-finite number
    assert d["axes"]["z"]["lr"] is None and d["lr_scale"] is None and d["neg2_reml"] is None
    back = NoiseModel.from_dict(json.loads(text))
    assert back.lr == (6.98e4, 6.98e4, math.inf)
    assert "LR inf" in back.line()
