"""Monte Carlo as separate runs it: the same noise defaults, any method option, no robust fit in front of Huber."""

from __future__ import annotations

import inspect

import numpy as np
import pytest

import casep
from casep.cli import build_parser, main
from casep.montecarlo import run_montecarlo
from casep.montecarlo.methods import parse_method


def test_montecarlo_has_the_noise_defaults_of_separate():
    """Before: montecarlo --noise white, separate --noise auto (a campaign's coverage was not separate's)."""
    default = casep.NoiseSpec()  # the fit request's defaults: separate's when not given
    mc = inspect.signature(run_montecarlo).parameters
    assert (mc["noise"].default, mc["robust"].default) == (default.kind, default.robust) == ("auto", "auto")
    a, b = build_parser().parse_args(["montecarlo"]), build_parser().parse_args(["separate", "f.csv"])
    assert (a.noise, a.robust) == (b.noise, b.robust)


@pytest.mark.parametrize("spec, options, linear", [
    ("ridge:lam=0.1", {"lam": 0.1}, True), ("ridge:lambda=gcv", {"lam": "gcv"}, False),
    ("rls:p0=1e6:forgetting=0.999", {"p0": 1e6, "forgetting": 0.999}, False), ("rls:1e3", {"p0": 1e3}, True),
    ("rels:noise-order=2", {"noise_order": 2}, False), ("pcr:components=5", {"n_components": 5}, True)])
def test_a_spec_sets_any_option_of_its_method(spec, options, linear):
    s = parse_method(spec)
    assert dict(s.options) == options and s.linear is linear


@pytest.mark.parametrize("spec, words", [
    ("ridge:lam=-1",
     "method `ridge:lam=-1`: option `lam` (--lambda) of method `ridge` must be gcv | lcurve | float > 0"),
    ("rls:forgetting=2", "option `forgetting` (--forgetting) of method `rls` must be float in [0.5, 1], got '2'"),
    ("rls:fog=1", "`fog=1` is not an option of `rls`"), ("rls:p0=1:p0=2", "an option is given twice"),
    ("map:prior=p.json", "option `prior` is a file: give it with --prior FILE")])
def test_a_bad_option_in_a_spec_is_refused_naming_it(spec, words, capsys):
    assert main(["montecarlo", "--runs", "2", "--rate", "10", "--workers", "1", "--methods", spec]) == 2
    assert words in capsys.readouterr().err


def test_spec_options_reach_the_solver():
    """``rls:p0=1e3:forgetting=1`` (per run, the recursive solver) equals ``rls:1e3`` (batched, the
    linear map), to 1e-8 of the std; forgetting 0.99 is another estimator."""
    kw = dict(runs=3, seed=2, rate=10.0, workers=1, noise="white", progress=False)
    res = run_montecarlo("paper", methods=["rls:1e3", "rls:p0=1e3:forgetting=1", "rls:p0=1e3:forgetting=0.99"], **kw)
    a, b, c = (res.estimates[m] for m in res.estimates)
    sd = res.stds["rls:1e3"]
    assert np.max(np.abs(a - b) / sd) < 1e-8
    assert np.max(np.abs(a - c) / sd) > 1e-3


@pytest.mark.parametrize("argv", [["separate", "FLIGHT", "--method", "huber", "--robust", "huber"],
                                  ["montecarlo", "--runs", "2", "--rate", "10", "--methods", "ols,huber",
                                   "--robust", "bisquare"]])
def test_huber_with_a_robust_filter_is_refused(argv, capsys, tmp_path):
    """Before: accepted, exit 0, the glitches weighed twice."""
    flight = tmp_path / "f.csv"
    assert main(["simulate", "--rate", "5", "-o", str(flight)]) == 0
    capsys.readouterr()
    assert main([str(flight) if a == "FLIGHT" else a for a in argv]) == 2
    err = capsys.readouterr().err
    assert "with method `huber`: Huber's M-estimator is robust already" in err and "Use: robust 'none'" in err
