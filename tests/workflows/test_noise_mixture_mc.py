"""Seeded Monte Carlo in Gauss-Markov plus white range noise: every registered method honest through
the default workflow (noise 'auto'), and noise 'white' or 'gm' on such data warned with the factor.

The rows: the paper-range-gm flight (20 Hz, tracking from 8 s, two dropouts: late tracking and
gaps) from 60 to 150 s (both dropouts; a shorter window leaves too few correlation times for
the noise model to be fitted well), its tracking time tags off by a drawn offset (``dt_trk``,
N(0, 1) ms like every coefficient, fitted as ``--time-offset auto`` does after the alignment),
noise Gauss-Markov tau 1 s std 0.09 m/s plus white 0.045 m/s on every axis.
``benchmarks/mc_noise_mixture.py`` runs the whole flight with more draws.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from conftest import dishonest_methods

import casep
from casep.estimators.solve import prepare_rows, solve_problem
from casep.exceptions import IllConditionedWarning, NoiseNotWhiteWarning
from casep.regression.problem import Problem
from casep.simulation.noise import NoiseModel as SimNoise

#: The mixture of the issue: Gauss-Markov 1 s, 0.09 m/s, plus white 0.045 m/s.
MIXTURE = SimNoise("ar1", 0.09, tau=1.0, white_sigma=0.045)


def mixture_rows(window: tuple[float, float] = (60.0, 150.0)):
    """(S_V with the time-offset column, times, names) of the paper-range-gm rows in `window`."""
    from casep.model.loader import with_time_offset
    from casep.simulation.simulate import simulate_flight

    sim = simulate_flight("paper-range-gm", seed=0)
    model = casep.load_model(with_time_offset(casep.load_model("platform36")))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the flight checks' gap warning
        pb = Problem.from_flight(sim.flight, model)
    keep = (pb.t >= window[0]) & (pb.t <= window[1])
    return pb.sv()[keep], pb.t[keep], model.names


def draw(S, t, names, seq, truth=None):
    """One draw: truth (N(0, 1) natural units: the time offset in ms) plus mixture noise."""
    rng = np.random.default_rng(seq)
    tr = rng.standard_normal(S.shape[-1]) if truth is None else np.asarray(truth, dtype=float)
    e = MIXTURE.sample(t, rng)
    return Problem.from_arrays(S, S @ tr + e, t, names=names), tr


def study(S, t, names, runs: int, seed: int) -> dict[str, np.ndarray]:
    """z = (estimate - reference) / std of every method over `runs` draws (the reference as in
    ``tests/noise/test_noise_model.py``: the truth; the method's noise-free answer on the same
    rows for ridge and pcr; truths drawn from MAP's and RLS's prior, so their std are checked by
    Bayesian coverage)."""
    from casep.estimators.registry import METHODS

    prior = {nm_: {"mean": 0.0, "std": 1.0} for nm_ in names}
    opts = {"map": {"prior": prior}, "rls": {"p0": 100.0}, "rels": {"p0": 100.0},
            "bounded": {"bounds": {"Ka0x": [-1e3, 1e3], "Ka0y": [-1e3, 1e3]}}}
    out: dict[str, list] = {m: [] for m in METHODS}
    for k in range(runs):
        pb, tr = draw(S, t, names, np.random.SeedSequence(seed, spawn_key=(k,)))
        rows = prepare_rows(pb, "auto")
        for method in out:
            if method == "gls":
                res = solve_problem(pb, "gls").result
            else:
                res = solve_problem(pb, method, opts.get(method), rows=rows).result
            ref = tr
            if method in ("ridge", "pcr"):
                clean = rows.solved.with_y(rows.solved.sv() @ tr)
                ref = (casep.solve_ridge(clean, lam=float(res.extras.lam)) if method == "ridge" else
                       casep.solve_pcr(clean, n_components=int(res.extras.n_components))).estimate
            z = (res.estimate - ref) / res.std
            out[method].append(z[np.isfinite(z)])
    return {m: np.concatenate(v) for m, v in out.items()}


@pytest.fixture(scope="module")
def rows90():
    return mixture_rows()


@pytest.mark.montecarlo
def test_every_method_is_honest_in_gauss_markov_plus_white_noise(rows90):
    """RMS z in [0.85, 1.15], 95 % coverage in [0.92, 0.98] for every registered method (8 draws of
    37 coefficients: the coverage's sampling std is about 0.013, the RMS z's about 0.04, more where
    the coefficients of a draw are correlated)."""
    S, t, names = rows90
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IllConditionedWarning)
        warnings.simplefilter("ignore", NoiseNotWhiteWarning)  # a chance rejection in one draw is not the test
        stats = study(S, t, names, 8, seed=41)
    bad = dishonest_methods(stats)
    assert not bad, bad


@pytest.mark.parametrize("noise", ["white", "gm"])
def test_white_and_gm_on_the_mixture_warn_with_the_factor(rows90, noise):
    """noise 'white' or 'gm' on Gauss-Markov plus white data: the whitened residuals are still
    correlated, and the warning says by how much the std are too small (GM with tau ~0.2 s:
    about 2x; white: more)."""
    S, t, names = rows90
    pb, _ = draw(S, t, names, np.random.SeedSequence(5))
    with pytest.warns(NoiseNotWhiteWarning, match=r"(not white|still correlated) \(.*x Q .* too small") as rec, \
            warnings.catch_warnings():
        warnings.simplefilter("ignore", IllConditionedWarning)
        res = solve_problem(pb, "ols", noise=noise, robust="none").result
    wd = res.diagnostics["whiteness"]
    assert wd["noise"] == noise and wd["rejected"]
    assert wd["std_factor_median"] > 1.4, wd
    assert any(f"{wd['std_factor_median']:.2g}x too small" in str(w.message) for w in rec)
    with warnings.catch_warnings():
        warnings.simplefilter("error", NoiseNotWhiteWarning)  # auto: the mixture, whitened residuals white
        warnings.simplefilter("ignore", IllConditionedWarning)
        res = solve_problem(pb, "ols", noise="auto", robust="none").result
    assert res.diagnostics["whiteness"]["noise"] == "auto" and not res.diagnostics["whiteness"]["rejected"]
    assert "gauss-markov+white" in {a["model"] for a in res.diagnostics["noise"]["axes"].values()}
