"""Shared fixtures: seeded rng, set-up models, the paper's truth and a synthetic flight."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import casep
from casep.simulation.paper import TABLE1_TRUTH
from casep.simulation.synthetic import excitation_force


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20261121)


@pytest.fixture(scope="session")
def platform36() -> casep.ErrorModel:
    return casep.load_model("platform36")


@pytest.fixture(scope="session")
def platform39() -> casep.ErrorModel:
    return casep.load_model("platform39_misalignment")


@pytest.fixture(scope="session")
def truth36(platform36) -> np.ndarray:
    return np.array([TABLE1_TRUTH[n] for n in platform36.names])


@pytest.fixture(scope="session")
def flight_tf() -> tuple[np.ndarray, np.ndarray]:
    """180 s at 20 Hz of the analytic excitation (all three axes)."""
    t = np.arange(0.0, 180.0, 0.05)
    return t, excitation_force(t)


@pytest.fixture(scope="session")
def paper_problem(platform36):
    """S_V, dv and truth of the paper scenario at 20 Hz (seed 1)."""
    from casep.simulation.simulate import simulate_flight

    sim = simulate_flight("paper", seed=1, rate=20.0)
    S = casep.build_sv(platform36, sim.flight.t, sim.flight.f)
    return S, np.array(sim.flight.dv), sim.truth


def augmented_lstsq(S2: np.ndarray, y: np.ndarray, prior_precision_sqrt: np.ndarray,
                    prior_mean: np.ndarray) -> np.ndarray:
    """Independent reference: argmin ||y - S x||^2 + ||diag(p) (x - mu)||^2 on unit-norm columns."""
    c = np.linalg.norm(S2, axis=0)
    A = np.vstack([S2 / c, np.diag(prior_precision_sqrt / c)])
    b = np.concatenate([y, prior_precision_sqrt * prior_mean])
    return np.linalg.lstsq(A, b, rcond=None)[0] / c


def dishonest_methods(stats: dict, rms=(0.85, 1.15), coverage=(0.92, 0.98)) -> dict:
    """``{method: (RMS z, 95 % coverage)}`` of the methods whose z (Monte Carlo, method -> z values)
    fall outside the honest ranges."""
    bad = {}
    for m, z in stats.items():
        r, cov = float(np.sqrt(np.mean(z**2))), float(np.mean(np.abs(z) <= 1.96))
        if not (rms[0] <= r <= rms[1] and coverage[0] <= cov <= coverage[1]):
            bad[m] = (round(r, 3), round(cov, 3))
    return bad


def noise_free_errors(flight, model, truth, sigma: float = 0.1):
    """Separate a noise-free flight with platform36 OLS (its ill-conditioning warning expected) and
    return ``(result, |estimate - truth| / CRLB std at noise sigma)``: how exactly the pipeline recovers
    the truth, in units of what noise would allow."""
    from casep.checks.diagnostics import crlb_covariance
    from casep.exceptions import IllConditionedWarning
    from casep.workflows.separate import regression_rows

    with pytest.warns(IllConditionedWarning):
        res = casep.separate(flight, "platform36")
    S, _, _ = regression_rows(flight, model)
    crlb = np.sqrt(np.diag(crlb_covariance(S, sigma)))
    est = np.asarray(res.estimate)[[res.names.index(n) for n in model.names]]  # an Earth-fixed flight adds dt_trk
    return res, np.abs(est - np.asarray(truth)) / crlb


@pytest.fixture(scope="session", autouse=True)
def _one_blas_thread_per_xdist_worker():
    """With pytest-xdist (`-n 2`), each worker process uses one BLAS thread: two workers on two
    cores, not four threads fighting for them (oversubscription made a Monte Carlo 30x slower)."""
    import os

    if not os.environ.get("PYTEST_XDIST_WORKER"):
        yield
        return
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        yield


def finite_json(path) -> dict:
    """The JSON file, refusing any non-finite number (Infinity/NaN) anywhere in it."""

    def refuse(token):
        raise AssertionError(f"non-finite number {token} in {path}")

    data = json.loads(path.read_text(), parse_constant=refuse)

    def walk(x, where="$"):
        if isinstance(x, dict):
            for k, v in x.items():
                walk(v, f"{where}.{k}")
        elif isinstance(x, list):
            for i, v in enumerate(x):
                walk(v, f"{where}[{i}]")
        elif isinstance(x, float):
            assert math.isfinite(x), where

    walk(data)
    return data
