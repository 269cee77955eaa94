"""Conformance of every registered method: option rules, noise-free recovery, result contract, JSON.

Parametrised over :data:`casep.estimators.registry.METHODS`, so a method added to the registry is
tested here without a line of its own. The bad values are generated from each option's declared
rules (an out-of-range number, a wrong type, a bad choice), not written per method.
"""

import dataclasses
import json
import warnings

import numpy as np
import pytest

import casep
from casep.estimators import registry
from casep.estimators.registry import (
    METHODS,
    NOISE_OPTIONS,
    OPTIONS,
    Choices,
    CoefficientTable,
    Interval,
    check_method_options,
)
from casep.estimators.result import SIGMA_SOURCES, EstimateResult
from casep.io.result_files import write_json_atomic
from casep.model.sv import build_sv
from casep.regression.problem import Problem
from casep.simulation.simulate import simulate_flight


def _bad_values(option):
    """Values no rule of the option accepts, derived from the rules."""
    out = [object()]  # wrong type for every rule
    for r in option.rules:
        if isinstance(r, Interval):
            out += [np.nan, "x" if not any(isinstance(q, Choices) for q in option.rules) else 1j]
            if r.low is not None:
                out.append((r.low - 1) if r.kind is int
                           else (r.low - abs(r.low) - 1.0 if r.closed in ("both", "left") else r.low))
            if r.high is not None:
                out.append(r.high * 2 + 1)
            if r.kind is int:
                out.append(1.5)
        if isinstance(r, Choices):
            out.append("no-such-choice")
        if isinstance(r, CoefficientTable):
            out.append(5)
    return [v for v in out if not any(r.accepts(v) for r in option.rules)]


CASES = [(m, o, v) for m, meth in METHODS.items() for o in meth.options for v in _bad_values(OPTIONS[o])]


def _case_id(m, o, v) -> str:  # stable across processes (pytest-xdist): no object address in it
    return f"{m}-{o}-{'object()' if type(v) is object else repr(v)}"[:60]


@pytest.mark.parametrize("method,option,value", CASES, ids=[_case_id(m, o, v) for m, o, v in CASES])
def test_bad_option_value_is_an_error_naming_it(method, option, value, clean_flight):
    with pytest.raises((ValueError, TypeError), match=f"`{option}`"):
        check_method_options(method, {option: value})
    given = {option: value}
    for req in METHODS[method].required:  # the required ones, valid, so that the bad one is what fails
        given.setdefault(req, {"Kg0x": [-1.0, 1.0]} if req == "bounds" else {"Kg0x": {"mean": 0.0, "std": 1.0}})
    with pytest.raises((ValueError, TypeError), match=f"`{option}`"):
        casep.separate(clean_flight[0], "platform36", method, **given)


@pytest.mark.parametrize("method", list(METHODS))
def test_option_of_another_method_is_an_error(method):
    other = next(o for o in OPTIONS if o not in METHODS[method].options)
    with pytest.raises(ValueError, match=f"`{other}`.*`{method}`"):
        check_method_options(method, {other: OPTIONS[other].default if OPTIONS[other].default is not None else 1})


@pytest.mark.parametrize("method", list(METHODS))
def test_option_of_another_method_through_separate(method, clean_flight):
    """Through ``separate`` too, for every option the method does not take (a valid, non-default value);
    the noise model's options (``tau``) are every method's there."""
    given = {r: _good_value(OPTIONS[r]) for r in METHODS[method].required}
    for other in (o for o in OPTIONS if o not in METHODS[method].options and o not in NOISE_OPTIONS):
        with pytest.raises(ValueError, match=f"`{other}`.*`{method}`"):
            casep.separate(clean_flight[0], "platform36", method, **given, **{other: _good_value(OPTIONS[other])})


def _good_value(option):
    """A value the option's rules accept that is not its default."""
    candidates = (2, 0.5, 0.99, 3.0, {"Kg0x": [-1.0, 1.0]}, {"Kg0x": {"mean": 0.0, "std": 1.0}})
    return next(v for v in candidates if any(r.accepts(v) for r in option.rules) and v != option.default)


@pytest.fixture(scope="module")
def clean_flight():
    sim = simulate_flight("paper", seed=2, rate=10.0)
    S = build_sv(sim.model, sim.flight.t, sim.flight.f)
    truth = np.asarray(sim.truth)
    flight = casep.FlightData(t=sim.flight.t, f=sim.flight.f, dv=S @ truth, source="noise-free paper, 10 Hz")
    return flight, sim.model, truth


#: Settings that make each method's bias vanish on noise-free data (why, per method):
UNBIASED = {
    "rls": {"p0": 1e20},  # a flat prior: RLS = least squares (bias ~ 1 / p0)
    "rels": {"p0": 1e20},  # the same; the MA model fits zero residuals
    "ridge": {"lam": 1e-14},  # lambda -> 0: least squares
    "bounded": {"bounds": {"Kg0x": [-1e6, 1e6]}},  # no bound active
    "pcr": {"n_components": 36},  # every component kept: least squares
    "map": {"prior": {"Kg0x": {"mean": 0.0, "std": 1e8}}},  # a flat prior
    "gls": {"tau": 1.0},  # whitening an exact fit leaves it exact
}


@pytest.fixture(scope="module")
def results(clean_flight):
    flight, model, _ = clean_flight
    pb = Problem.from_flight(flight, model)
    out = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # noise-free data: NoiseFreeWarning, ill-conditioning
        for m in METHODS:
            out[m] = casep.separate(pb, model, m, sigma=1e-3, **UNBIASED.get(m, {}))
    return out


@pytest.mark.parametrize("method", list(METHODS))
def test_noise_free_exact_recovery(method, results, clean_flight):
    _, _, truth = clean_flight
    res = results[method]
    ok = np.isfinite(res.estimate)
    assert ok.all(), res.reasons
    # against each coefficient's CRLB at sigma = 1 mm/s (OLS's std here; Huber's own std collapses with
    # its residuals on noise-free data): the error is below 1 % of it for every coefficient
    crlb = results["ols"].std
    assert np.max(np.abs(res.estimate - truth) / crlb) < 1e-2


@pytest.mark.parametrize("method", list(METHODS))
def test_result_contract(method, results):
    _check_contract(results[method])


def _check_contract(res):
    n = len(res.names)
    assert len(res.units) == n and res.estimate.shape == (n,) and res.si_factors.shape == (n,)
    assert res.std_kind in ("sampling", "posterior", "conditional")
    assert res.std_kind == METHODS[res.method].std_kind or res.method == "bounded"  # bounded: conditional if active
    assert np.isfinite(res.sigma) and res.sigma > 0 and res.sigma_source in SIGMA_SOURCES
    assert res.model == "platform36"
    C = res.covariance
    ok = np.isfinite(res.estimate)
    assert C.shape == (n, n)
    np.testing.assert_array_equal(np.isnan(C).all(axis=1), ~ok)
    Cs = C[np.ix_(ok, ok)]
    np.testing.assert_allclose(Cs, Cs.T, rtol=1e-10, atol=1e-300)
    assert np.min(np.linalg.eigvalsh((Cs + Cs.T) / 2) / np.max(np.diag(Cs))) > -1e-9  # PSD
    np.testing.assert_allclose(np.sqrt(np.diag(Cs)), res.std[ok], rtol=1e-9)
    assert isinstance(res.extras, METHODS[res.method].extras_type)
    assert dataclasses.is_dataclass(res.extras) and type(res.extras).__dataclass_params__.frozen
    if METHODS[res.method].recursive:
        assert res.history is not None and len(res.history_names) == res.history.shape[1]
        assert res.history_names[:n] == res.names
        noise_terms = res.history_names[n:]
        assert len(noise_terms) == res.extras.noise_order == len(res.extras.ma_coefficients)
        if noise_terms:  # RELS: the last history row ends with the final MA coefficients
            np.testing.assert_allclose(res.history[-1, n:], res.extras.ma_coefficients, rtol=1e-12)
    else:
        assert res.history is None and res.history_names is None
    data = json.loads(json.dumps(res.to_dict(), allow_nan=False))
    assert data["std_kind"] == res.std_kind and data["sigma_source"] == res.sigma_source
    assert data["extras"] == json.loads(json.dumps(dataclasses.asdict(res.extras)))
    assert data["history_names"] == (list(res.history_names) if res.history_names is not None else None)


@pytest.mark.parametrize("method", list(METHODS))
def test_json_round_trip(method, results, tmp_path):
    res = results[method]
    path = tmp_path / "r.json"
    write_json_atomic(res.to_dict(), path)
    back = EstimateResult.from_json(path)
    for field in ("method", "names", "units", "model", "status", "success", "message", "sigma_source", "std_kind",
                  "rank", "n_samples"):
        assert getattr(back, field) == getattr(res, field), field
    np.testing.assert_allclose(back.estimate, res.estimate, rtol=1e-15)
    np.testing.assert_allclose(back.std, res.std, rtol=1e-15)
    np.testing.assert_allclose(back.covariance, res.covariance, rtol=1e-15)
    np.testing.assert_allclose(back.si_factors, res.si_factors, rtol=1e-15)
    assert type(back.extras) is type(res.extras)
    assert back.to_dict()["extras"] == res.to_dict()["extras"]
    if not any(isinstance(v, (dict, list)) and not isinstance(v, tuple)
               for v in dataclasses.asdict(res.extras).values()):
        assert back.extras == res.extras  # scalars and tuples: equal as objects
    assert back.to_dict()["residual_rms"] == res.to_dict()["residual_rms"]


def test_the_contract_check_catches_a_violation(monkeypatch, results):
    """The contract check can fail: a fake method registered with another std_kind, or with another
    extras type, or a recursive method whose history lacks its names, is caught."""
    bad = dataclasses.replace(results["ols"], method="fake")
    _check_contract_fake = _check_contract
    fake = dataclasses.replace(METHODS["ols"], name="fake", summary="a fake")
    monkeypatch.setitem(registry.METHODS, "fake", dataclasses.replace(fake, std_kind="posterior"))
    with pytest.raises(AssertionError):  # std_kind "sampling" where "posterior" is declared
        _check_contract_fake(bad)
    monkeypatch.setitem(registry.METHODS, "fake", fake)
    _check_contract_fake(bad)  # now conforming: the check passes
    monkeypatch.setitem(registry.METHODS, "fake", dataclasses.replace(fake, extras_type=METHODS["ridge"].extras_type))
    with pytest.raises(AssertionError):  # OLSExtras where RidgeExtras is declared
        _check_contract_fake(bad)
    monkeypatch.setitem(registry.METHODS, "fake", dataclasses.replace(fake, recursive=True))
    with pytest.raises(AssertionError):  # declared recursive, no history
        _check_contract_fake(bad)


def test_result_rejects_an_unknown_std_kind_sigma_source_or_extras_type(results):
    res = results["ridge"]
    with pytest.raises(ValueError, match="std_kind"):
        dataclasses.replace(res, std_kind="exact")
    with pytest.raises(ValueError, match="sigma_source"):
        dataclasses.replace(res, sigma_source="guessed")
    with pytest.raises(ValueError, match="RidgeExtras"):
        dataclasses.replace(res, extras=results["ols"].extras)
