"""The numpy inner loops against the compiled ones they stand in for: the same numbers, bit for bit."""

from __future__ import annotations

import math
import sys

import numpy as np
import pytest

from casep import _compiled
from casep._kernels import (
    NUMPY_SAMPLES,
    PYTHON_FILTER_STEPS,
    all_pole_filter_python,
    robust_filter_keep,
    sv_integrate_chunk,
    sv_integrate_chunk_numpy,
)


@pytest.mark.parametrize("gcols, acols", [(np.arange(15), np.arange(15, 36)),  # platform36: two ranges
                                          (np.r_[0:15, 36:39], np.arange(15, 36)),  # columns after a gap
                                          (np.array([3, 1, 3]), np.array([1, 0]))])  # repeated, shared columns
def test_sv_chunk_numpy_is_the_compiled_loop(gcols, acols):
    rng = np.random.default_rng(3)
    n = int(max(gcols.max(), acols.max())) + 1
    carries = [rng.normal(size=(3, gcols.size)), rng.normal(size=(3, gcols.size)), rng.normal(size=(3, n)),
               rng.normal(size=(3, n))]
    mine = [c.copy() for c in carries]
    for K in (1, 2, 500):  # successive chunks carry phi, G_prev, I_prev, S_prev
        G, A, f = rng.normal(size=(K, 3, gcols.size)), rng.normal(size=(K, 3, acols.size)), rng.normal(size=(K, 3))
        half_dt = rng.uniform(0.001, 0.01, K)
        out0, out1 = np.empty((K, 3, n)), np.empty((K, 3, n))
        _compiled.sv_integrate_chunk(G, A, f, half_dt, gcols, acols, *carries, out0)
        sv_integrate_chunk_numpy(G, A, f, half_dt, gcols, acols, *mine, out1)
        assert np.array_equal(out0, out1)
        for a, b in zip(carries, mine):
            assert np.array_equal(a, b)


def test_sv_kernel_by_flight_length(monkeypatch):
    """numpy for a flight of up to NUMPY_SAMPLES samples while numba is not loaded, compiled beyond it
    or once numba is loaded (the two give the same numbers: the test above)."""
    assert sv_integrate_chunk(NUMPY_SAMPLES + 1) is _compiled.sv_integrate_chunk
    assert sv_integrate_chunk(10) is _compiled.sv_integrate_chunk  # loaded already: compiled
    monkeypatch.delitem(sys.modules, "casep._compiled")
    assert sv_integrate_chunk(NUMPY_SAMPLES) is sv_integrate_chunk_numpy


def _reference_keep(e, t, inv_tau, scale, thr, max_run, pred=None):
    """The sequential filter as a plain loop (the compiled kernel it replaced, line for line); with `pred`, the
    fit's prediction variance ``|G_k - a G_last|^2`` added to the innovation's (``|G_k|^2`` with no ``last``)."""
    N = e.shape[0]
    keep = np.ones(N, dtype=bool)
    last, run = -1, 0
    for k in range(N):
        big = False
        for j in range(3):
            if inv_tau[j] == 0.0 or last < 0:
                q = 0.0 if pred is None else sum(g * g for g in pred[k, j])
                nu = e[k, j] / (scale[j] if pred is None else math.sqrt(scale[j] ** 2 + q))
            else:
                x = (t[k] - t[last]) * inv_tau[j]
                a = math.exp(-x)
                if pred is None:
                    nu = (e[k, j] - a * e[last, j]) / (scale[j] * math.sqrt(-math.expm1(-2.0 * x)))
                else:
                    q = sum((g - a * h) ** 2 for g, h in zip(pred[k, j], pred[last, j]))
                    nu = (e[k, j] - a * e[last, j]) / math.sqrt(scale[j] ** 2 * -math.expm1(-2.0 * x) + q)
            if abs(nu) > thr:
                big = True
                break
        if big and run < max_run:
            keep[k] = False
            run += 1
        else:
            last, run = k, 0
    return keep


@pytest.mark.parametrize("inv_tau", [(0.0, 0.0, 0.0), (2.0, 0.0, 0.5), (50.0, 50.0, 50.0)])
@pytest.mark.parametrize("max_run", [0, 1, 5])
def test_robust_filter_is_the_compiled_loop(inv_tau, max_run):
    rng = np.random.default_rng(7)
    N = 4000
    t = np.cumsum(rng.uniform(0.005, 0.015, N))
    e = rng.normal(size=(N, 3))
    for i in rng.choice(N, 40, replace=False):  # glitches, some in runs, one at the start
        e[i: i + rng.integers(1, 8)] += rng.choice([-1, 1]) * rng.uniform(3, 30)
    e[0] += 20.0
    e[100, 1] = np.nan
    args = (np.array(inv_tau), np.array([1.0, 1.3, 0.8]), 4.0, max_run)
    k0, k1 = _reference_keep(e, t, *args), np.zeros(N, dtype=bool)
    robust_filter_keep(e, t, *args, k1)
    assert (~k0).sum() > (40 if max_run else -1)  # the test has rejections to agree on
    assert np.array_equal(k0, k1)


@pytest.mark.parametrize("inv_tau", [(0.0, 0.0, 0.0), (2.0, 0.0, 0.5), (50.0, 50.0, 50.0)])
def test_robust_filter_with_the_fits_prediction_is_a_plain_loop(inv_tau):
    """With the prediction factor G (N, 3, r): the vectorised kernel and its scalar recursion against a plain loop
    (the same rejections; prediction std up to twice the noise's, so some glitches are kept)."""
    rng = np.random.default_rng(8)
    N = 3000
    t = np.cumsum(rng.uniform(0.005, 0.015, N))
    e = rng.normal(size=(N, 3))
    pred = rng.normal(size=(N, 3, 4)) * rng.uniform(0.0, 1.0, (N, 1, 1))
    for i in rng.choice(N, 40, replace=False):
        e[i: i + rng.integers(1, 8)] += rng.choice([-1, 1]) * rng.uniform(3, 30)
    e[0] += 20.0
    args = (np.array(inv_tau), np.array([1.0, 1.3, 0.8]), 4.0, 5)
    k0, k1 = _reference_keep(e, t, *args, pred=pred), np.zeros(N, dtype=bool)
    robust_filter_keep(e, t, *args, k1, pred)
    assert 40 < (~k0).sum() < (~_reference_keep(e, t, *args)).sum()  # rejections, fewer than without G
    assert np.array_equal(k0, k1)


@pytest.mark.parametrize("a", [[1.0, -0.9], [1.0, 0.5, -0.2], [1.0, 0.3, 0.1, -0.05], [1.0]])
@pytest.mark.parametrize("python_steps", [PYTHON_FILTER_STEPS, 0])  # the loop over Python floats, the compiled one
def test_all_pole_filter_is_scipys_lfilter(a, python_steps, monkeypatch):
    from scipy.signal import lfilter as scipy_lfilter

    from casep import _kernels
    from casep._kernels import lfilter

    monkeypatch.setattr(_kernels, "PYTHON_FILTER_STEPS", python_steps)
    x = np.random.default_rng(5).normal(size=(3000, 3))
    x[7, 1] = 0.0
    x[9, 2] = -0.0
    assert np.array_equal(lfilter([1.0], a, x, axis=0), scipy_lfilter([1.0], a, x, axis=0))
    assert np.array_equal(lfilter([1.0, 0.5], a, x, axis=0), scipy_lfilter([1.0, 0.5], a, x, axis=0))  # scipy's


def test_all_pole_filter_python_is_the_compiled_loop():
    """The two all-pole filters on the same input, non-finite and signed-zero samples included: the same bits."""
    rng = np.random.default_rng(6)
    x = rng.normal(size=(500, 4))
    x[3, 0], x[10, 1], x[20, 2], x[30, 3] = np.inf, np.nan, -0.0, 0.0
    for a in ([1.0, -0.9], [1.0, 0.5, -0.2, 0.1], [1.0]):
        y0, y1 = np.empty_like(x), np.empty_like(x)
        _compiled.all_pole_filter(np.array(a), x, y0)
        all_pole_filter_python(np.array(a), x, y1)
        assert np.array_equal(y0, y1, equal_nan=True)
        assert np.array_equal(np.signbit(y0), np.signbit(y1))


def test_runs_against_a_plain_loop():
    """The run-length rule against a loop over the samples, on random masks with runs at both ends."""
    from casep._kernels import runs

    rng = np.random.default_rng(7)
    for n in (0, 1, 2, 17, 200):
        for p in (0.1, 0.5, 0.9):
            mask = rng.random(n) < p
            expected, start = [], None
            for k, m in enumerate(list(mask) + [False]):
                if m and start is None:
                    start = k
                elif not m and start is not None:
                    expected.append((start, k))
                    start = None
            assert runs(mask) == expected


def test_cumulative_trapezoid_against_the_closed_form_of_a_parabola():
    """On uneven steps the trapezoid of ``t^2`` from ``t_0`` is ``(t^3 - t_0^3) / 3 + sum h^3 / 6`` (each step's
    trapezoid overshoots the parabola's integral by ``h^3 / 6``), and that of a line is exact; zero at the first
    sample; every trailing axis integrated alike."""
    from casep._kernels import cumulative_trapezoid

    rng = np.random.default_rng(11)
    t = 1.5 + np.cumsum(rng.uniform(0.01, 0.2, 400))
    h = np.diff(t)
    parabola = (t**3 - t[0] ** 3) / 3 + np.concatenate([[0.0], np.cumsum(h**3 / 6)])
    line = 2.0 * (t - t[0]) - 0.75 * (t**2 - t[0] ** 2)  # int (2 - 1.5 t) dt
    y = np.stack([t**2, 2.0 - 1.5 * t], axis=1)[:, :, None] * np.array([1.0, -4.0])  # (N, 2, 2)
    got = cumulative_trapezoid(y, t)
    assert got.shape == y.shape and np.all(got[0] == 0.0)
    np.testing.assert_allclose(got[:, 0, 0], parabola, rtol=1e-13)
    np.testing.assert_allclose(got[:, 1, 0], line, rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(got[:, :, 1], -4.0 * got[:, :, 0])  # a power of two times: exact
    np.testing.assert_array_equal(cumulative_trapezoid(t**2, t), got[:, 0, 0])  # one dimension


def test_cumulative_trapezoid_is_the_sequential_sum():
    """The sum step by step in a plain loop, bit for bit (the numbers the callers had before it was shared)."""
    from casep._kernels import cumulative_trapezoid

    rng = np.random.default_rng(5)
    t, y = np.cumsum(rng.uniform(0.001, 0.02, 300)), rng.normal(size=(300, 3))
    expected = np.zeros_like(y)
    for k in range(1, t.size):
        expected[k] = expected[k - 1] + 0.5 * (y[k] + y[k - 1]) * (t[k] - t[k - 1])
    assert np.array_equal(cumulative_trapezoid(y, t), expected)
    assert cumulative_trapezoid(y[:1], t[:1]).tolist() == [[0.0, 0.0, 0.0]]
