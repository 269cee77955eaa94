"""The Problem object: built once, reduced block by block, the same answers as the arrays."""

from unittest import mock

import numpy as np
import pytest

import casep
from casep.checks.time_offset import time_offset_test
from casep.estimators.registry import METHODS, run_method
from casep.model.sv import SVBuilder, build_sv
from casep.regression.linalg import reduce_qr, reduce_qr_blocks
from casep.regression.problem import Problem
from casep.simulation.simulate import simulate_flight


@pytest.fixture(scope="module")
def sim():
    return simulate_flight("paper", seed=3, rate=20.0)


@pytest.fixture(scope="module")
def streamed(sim):
    return Problem.from_flight(sim.flight, sim.model, keep_sv=False, block_rows=1000)  # 4 blocks, never whole


def _invariants(red):
    """What every QR of [S | y] shares: R^T R, R^T q, ||y||^2 (scaled coordinates)."""
    return red.R.T @ red.R, red.R.T @ red.qty, red.qty @ red.qty + red.rho2


def test_block_reduction_equals_one_shot(rng):
    S = rng.standard_normal((5000, 3, 8)) * np.logspace(-2, 3, 8)
    S[:, :, 3] = 0.0  # a zero column
    y = rng.standard_normal((5000, 3))
    a = reduce_qr(S, y)
    b = reduce_qr_blocks(((S[i:i + 700], y[i:i + 700]) for i in range(0, 5000, 700)), 8)
    assert b.m == a.m
    np.testing.assert_allclose(b.scale, a.scale, rtol=1e-13)
    for u, v in zip(_invariants(a), _invariants(b)):
        np.testing.assert_allclose(v, u, rtol=1e-12, atol=1e-12 * np.max(np.abs(u)))


def test_blocks_of_sv_equal_build_sv(sim, streamed):
    S = build_sv(sim.model, sim.flight.t, sim.flight.f)
    got = np.concatenate([S_b.copy() for _, S_b, _ in streamed.blocks(700)])
    np.testing.assert_array_equal(got, S)  # same recursion, same chunks: bit for bit
    np.testing.assert_array_equal(streamed.sv(), S)


def test_streamed_problem_equals_arrays_for_every_method(sim, streamed):
    S = build_sv(sim.model, sim.flight.t, sim.flight.f)
    labels = {"names": sim.model.names, "units": sim.model.units, "si_factors": sim.model.si_factors}
    opts = {"bounded": {"bounds": {"Kg0x": [-50.0, 50.0]}}, "map": {"prior": {"Kg0x": {"mean": 0.0, "std": 10.0}}},
            "gls": {"tau": 1.0}, "rels": {"noise_order": 1}}
    for method in METHODS:
        fresh = Problem.from_flight(sim.flight, sim.model, keep_sv=False, block_rows=1000)  # Huber/GLS: S whole
        with np.errstate(all="ignore"):
            a = run_method(method, S, sim.flight.dv, sim.flight.t, opts.get(method, {}), **labels)
            b = run_method(method, fresh, None, fresh.t, opts.get(method, {}))
        ok = np.isfinite(a.estimate)
        np.testing.assert_array_equal(ok, np.isfinite(b.estimate))
        # Different (equally valid) QR factorisations: agreement to a small fraction of the std.
        np.testing.assert_allclose(b.estimate[ok], a.estimate[ok], rtol=0, atol=1e-6 * np.nanmax(a.std), err_msg=method)
        np.testing.assert_allclose(b.std[ok], a.std[ok], rtol=1e-6, err_msg=method)
        assert b.model == sim.model.name and b.n_samples == sim.flight.n_samples


def test_residuals_by_blocks_equal_dense(sim, streamed, rng):
    x = rng.standard_normal(streamed.n)
    S = build_sv(sim.model, sim.flight.t, sim.flight.f)
    np.testing.assert_allclose(streamed.residuals(x), sim.flight.dv - S @ x, rtol=0, atol=1e-9)


def test_noise_free_recovery_through_from_flight(sim):
    truth = np.asarray(sim.truth)
    S = build_sv(sim.model, sim.flight.t, sim.flight.f)
    flight = casep.FlightData(t=sim.flight.t, f=sim.flight.f, dv=S @ truth, source="noise-free")
    pb = Problem.from_flight(flight, sim.model, keep_sv=False, block_rows=2048)
    with np.errstate(all="ignore"):
        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = casep.solve_ols(pb, sigma=1e-6)
    ok = np.isfinite(res.estimate)
    assert ok.sum() == pb.n
    np.testing.assert_allclose(res.estimate, truth, rtol=1e-6, atol=1e-8 * np.max(np.abs(truth)))


def test_time_offset_test_is_the_same_from_residuals_or_dv(sim, streamed):
    """Frisch-Waugh-Lovell: the test reads only the part off span S (casep.checks.plausibility caches it)."""
    S = build_sv(sim.model, sim.flight.t, sim.flight.f)
    res = casep.solve_ols(S, sim.flight.dv)
    r = sim.flight.dv - S @ res.estimate
    a = time_offset_test(S, r, sim.flight.t, sim.flight.f)
    b = time_offset_test(streamed, sim.flight.dv, sim.flight.t, sim.flight.f)
    np.testing.assert_allclose([b.offset, b.offset_std, b.jerk], [a.offset, a.offset_std, a.jerk], rtol=1e-6)


def test_separate_and_demo_build_sv_and_qr_once(sim, tmp_path):
    """S_V integrated once per flight, the one QR reused by every method of the demo."""
    real_build = SVBuilder._integrate
    with mock.patch.object(SVBuilder, "_integrate", autospec=True, side_effect=real_build) as integ, \
            mock.patch("casep.regression.problem.reduce_qr_blocks", wraps=reduce_qr_blocks) as red_b, \
            mock.patch("casep.regression.problem.reduce_qr", wraps=reduce_qr) as red:
        casep.separate(sim.flight, sim.model, "ols")
        assert red.call_count + red_b.call_count == 1
        # S_V: once to reduce, once more for the residual checks (regenerated, never held whole)
        assert integ.call_count == 1  # a flight of this size keeps S_V (SV_KEEP_BYTES)
    from casep.workflows import demo

    with mock.patch.object(SVBuilder, "_integrate", autospec=True, side_effect=real_build) as integ, \
            mock.patch("casep.regression.problem.reduce_qr", wraps=reduce_qr) as red:
        demo.run_demo(None, seed=1, rate=20.0)
        assert integ.call_count == 1 + 1  # the simulator's truth, the demo's one Problem
        assert red.call_count == 1


def test_reduction_only_problem_refuses_rows():
    red = reduce_qr(np.eye(4, 2) + 1.0, np.ones(4))
    pb = Problem.from_reduction(red, names=("a", "b"), units=("", ""), si_factors=(1.0, 1.0))
    assert not pb.has_rows
    with pytest.raises(ValueError, match="only a reduction"):
        pb.residuals(np.zeros(2))
    with pytest.raises(ValueError, match="`y` must be omitted"):
        casep.solve_ols(Problem.from_arrays(np.eye(4, 2) + 1.0, np.ones(4)), np.ones(4))


def test_problem_from_arrays_equals_arrays_to_1e12_for_every_method(sim):
    """Same S, same one-shot QR: a Problem and the arrays give the same numbers (1e-12 relative)."""
    S = build_sv(sim.model, sim.flight.t, sim.flight.f)
    labels = {"names": sim.model.names, "units": sim.model.units, "si_factors": sim.model.si_factors}
    opts = {"bounded": {"bounds": {"Kg0x": [-50.0, 50.0]}}, "map": {"prior": {"Kg0x": {"mean": 0.0, "std": 10.0}}},
            "gls": {"tau": 1.0}, "rels": {"noise_order": 1}}
    for method in METHODS:
        pb = Problem.from_arrays(S, sim.flight.dv, sim.flight.t, model=sim.model.name, **labels)
        with np.errstate(all="ignore"):
            a = run_method(method, S, sim.flight.dv, sim.flight.t, opts.get(method, {}), **labels)
            b = run_method(method, pb, None, pb.t, opts.get(method, {}))
        ok = np.isfinite(a.estimate)
        np.testing.assert_array_equal(ok, np.isfinite(b.estimate), err_msg=method)
        scale = np.max(np.abs(a.estimate[ok]))
        np.testing.assert_allclose(b.estimate[ok], a.estimate[ok], rtol=1e-12, atol=1e-12 * scale, err_msg=method)
        np.testing.assert_allclose(b.std[ok], a.std[ok], rtol=1e-12, err_msg=method)
        np.testing.assert_allclose(b.residuals, a.residuals, rtol=0, atol=1e-12 * np.max(np.abs(a.residuals)),
                                   err_msg=method)
