"""One fit request (FitSpec), checked once; noise-free flights through the default path.

The request is built at the edge (keywords, command line) and checked by one validator; a
keyword equal to its default is still "given"; a FitSpec passed directly fits the same as the
keywords that build it. Noise-free flights (one rule, :meth:`casep.regression.problem.Problem.is_noise_free`)
go through ``casep separate --json`` with exit 0, nothing rejected as a glitch, the truth recovered to
1e-2 of its Cramer-Rao std at 0.1 m/s, and every JSON number finite.
"""

from __future__ import annotations

import dataclasses
import json
import pickle

import numpy as np
import pytest

import casep
from casep.cli import main
from casep.estimators.registry import METHODS, NOISE_OPTIONS, OPTIONS, Choices, CoefficientTable, Interval
from casep.estimators.spec import NOT_GIVEN, FitSpec, NoiseSpec
from casep.exceptions import NoiseFreeWarning


@pytest.fixture(scope="module")
def clean_problem(platform36):
    """A noise-free 20 Hz, 120 s synthetic flight's Problem and its truth."""
    from casep.simulation.paper import TABLE1_TRUTH
    from casep.simulation.synthetic import excitation_force, inject_errors

    t = np.arange(0.0, 120.0, 0.05)
    f = excitation_force(t, duration=120.0)
    truth = np.array([TABLE1_TRUTH[n] for n in platform36.names])
    flight = casep.FlightData(t, f, inject_errors(platform36, t, f, truth))
    return casep.regression.problem.Problem.from_flight(flight, platform36), flight, truth


# --------------------------------------------------------------------------- the request


def test_a_value_equal_to_the_default_given_twice_is_given_both(clean_problem):
    pb, _, _ = clean_problem
    p0 = OPTIONS["p0"].default
    with pytest.raises(ValueError, match=r"option --p0 \(`p0`\) given both as a keyword and in `options`"):
        casep.separate(pb, method="rls", p0=p0, options={"p0": p0})
    # was: silently 1.0, the keyword equal to its default
    with pytest.raises(ValueError, match=r"option --p0 \(`p0`\) given both"):
        casep.separate(pb, method="rls", p0=1e6, options={"p0": 1.0})


def test_a_keyword_equal_to_its_default_is_given(clean_problem):
    """An option given to a method that does not take it is refused even at its default value."""
    pb, _, _ = clean_problem
    with pytest.raises(ValueError, match=r"option --p0 \(`p0`\) is not taken by method `ols`"):
        casep.separate(pb, method="ols", p0=OPTIONS["p0"].default)


def test_spec_fits_as_its_keywords(clean_problem, platform36):
    pb, _, _ = clean_problem
    spec = FitSpec.build("ridge", lam=0.5, noise="white", robust=None)
    assert spec == FitSpec("ridge", {"lam": 0.5}, noise=NoiseSpec("white", robust="none"))
    with pytest.warns(NoiseFreeWarning):
        a = casep.separate(pb, platform36, "ridge", lam=0.5, noise="white", robust=None)
    with pytest.warns(NoiseFreeWarning):
        b = casep.separate(pb, platform36, spec=spec)
    np.testing.assert_array_equal(a.estimate, b.estimate)  # the same request, the same fit, bit for bit
    with pytest.raises(ValueError, match="`spec` given with `lam`"):
        casep.separate(pb, spec=spec, lam=0.1)


def test_spec_is_frozen_and_decides_who_owns_tau():
    gls = FitSpec.build("gls", tau=2.0)
    assert gls.options["tau"] == 2.0 and gls.noise.tau is None  # gls: its own one tau
    ols = FitSpec.build("ols", tau=2.0)
    assert "tau" not in ols.options and ols.noise.tau == 2.0 and ols.noise.kind == "gm"  # the noise model's
    cli_form = FitSpec.build("ols", options={"tau": 2.0})  # the command line's --tau: the same owner
    assert cli_form == ols
    with pytest.raises(ValueError, match=r"option --tau \(`tau`\) given with option --noise \(`noise`\) 'white'"):
        FitSpec.build("ols", tau=2.0, noise="white")
    with pytest.raises(dataclasses.FrozenInstanceError):
        ols.method = "gls"  # type: ignore[misc]
    with pytest.raises(TypeError):
        ols.options["lam"] = 1.0  # type: ignore[index]
    assert repr(NOT_GIVEN) == "NOT_GIVEN" and not NOT_GIVEN
    spec = FitSpec.build("ridge", lam=0.5, noise="gm", tau=1.0, wavelet_options=None)
    again = pickle.loads(pickle.dumps(spec))  # a spec travels to worker processes
    assert again == spec and hash(again) == hash(spec) and pickle.loads(pickle.dumps(NOT_GIVEN)) is NOT_GIVEN


def test_noise_kinds_flow_from_the_noise_module():
    """The noise kind is checked against casep.noise.model.NOISE_KINDS: every kind it knows is accepted."""
    from casep.noise.model import NOISE_KINDS

    for kind in NOISE_KINDS:
        assert FitSpec.build("ols", noise=kind).noise.kind == kind
    with pytest.raises(ValueError, match=r"option --noise \(`noise`\) must be auto \| gm \| gmw \| white, got 'pink'"):
        FitSpec.build("ols", noise="pink")


def _bad_values(option) -> list:
    """A value out of each rule's range or choices (what the rules themselves refuse)."""
    out: list = []
    for r in option.rules:
        if isinstance(r, Interval):
            out.append(r.high * 2 + 1 if r.high is not None else (r.kind(r.low) - 1 if r.low is not None else None))
        elif isinstance(r, Choices):
            out.append("no-such-choice")
        elif isinstance(r, CoefficientTable):
            out.append(5)
    return [v for v in out if v is not None and not any(r.accepts(v) for r in option.rules)]


_CASES = [(m, o.name, v) for m, meth in METHODS.items() for o in meth.option_specs for v in _bad_values(o)]


@pytest.mark.parametrize("method, option, value", _CASES)
def test_one_validator_names_the_option_api_and_cli(good_flight_csv, capsys, method, option, value):
    """A bad value of every registered method's option: the API (FitSpec, what casep.separate builds) and the
    command line refuse it with the option's name and the registry's rule."""
    spec_opt = OPTIONS[option]
    with pytest.raises((ValueError, TypeError)) as e:
        FitSpec.build(method, options={option: value})
    api = str(e.value)
    assert api == f"option {spec_opt.flag} (`{option}`) of method `{method}` must be {spec_opt.rule}, got {value!r}"
    if not any(isinstance(r, CoefficientTable) for r in spec_opt.rules):  # a table is a file on the command line
        with pytest.raises(SystemExit) as ex:
            main(["separate", str(good_flight_csv), "--method", method, spec_opt.flag, str(value)])
        err = capsys.readouterr().err
        # the same form (the command line does not know the method yet when it parses the value)
        assert ex.value.code == 2
        assert f"error: option {spec_opt.flag} (`{option}`) must be {spec_opt.rule}, got '{value}'" in err


@pytest.fixture(scope="module")
def good_flight_csv(tmp_path_factory, clean_problem):
    _, flight, _ = clean_problem
    p = tmp_path_factory.mktemp("fitspec") / "clean.csv"
    casep.write_flight(flight, p)
    return p


# --------------------------------------------------------------------------- noise-free flights


def _finite_json(path) -> dict:
    from conftest import finite_json

    return finite_json(path)


def _crlb_std(flight, model) -> np.ndarray:
    """The Cramer-Rao std of the flight's coefficients at 0.1 m/s of white noise."""
    from casep.checks.diagnostics import crlb_covariance
    from casep.workflows.separate import regression_rows

    S, _, _ = regression_rows(flight, model)
    return np.sqrt(np.diag(crlb_covariance(S, 0.1)))  # what 0.1 m/s of noise would allow


def _recovery_in_crlb_std(estimates: np.ndarray, truth: np.ndarray, flight, model) -> float:
    return float(np.max(np.abs(estimates - truth) / _crlb_std(flight, model)))


def _check_clean(data: dict, truth: np.ndarray, flight, model) -> None:
    diag = data["diagnostics"]
    assert diag.get("robust", {}).get("rejected_count", 0) == 0  # nothing rejected as a glitch
    assert diag["noise"]["rule"].startswith("noise-free")  # the noise model saw the flight as the checks did
    est = np.array([c["estimate"] for c in data["coefficients"]])
    assert _recovery_in_crlb_std(est, truth, flight, model) <= 0.01


def _clean_scenario(name: str):
    from casep.simulation.scenarios import get_scenario

    return get_scenario(name).without_noise()  # what casep simulate --noise-free flies


def test_noise_free_simulated_flight_from_the_command_line(tmp_path, capsys, platform36):
    """As an analyst checks a set-up: casep simulate --noise-free, then casep separate --json (exit 0, nothing
    rejected as a glitch, the truth recovered to 1e-2 of its Cramer-Rao std at 0.1 m/s, every number finite)."""
    path, out = tmp_path / "clean.csv", tmp_path / "r.json"
    assert main(["simulate", "--noise-free", "--rate", "10", "-o", str(path)]) == 0
    side = json.loads((tmp_path / "clean.truth.json").read_text())
    assert side["noise"]["sigma"] == 0.0 == side["noise"]["outlier_rate"]
    code = main(["separate", str(path), "--json", str(out)])
    printed = capsys.readouterr()
    assert code == 0, printed.err
    assert "glitch" not in printed.out + printed.err and "at the rounding level" in printed.err  # a warning
    truth = np.array([side["coefficients"].get(n, 0.0) for n in platform36.names])
    _check_clean(_finite_json(out), truth, casep.read_flight(path), platform36)


@pytest.mark.parametrize("model, lever", [("platform36", None), ("models/platform36_leverarm.py", (0.5, 0.2, -0.1))])
def test_noise_free_flight_default_path_json(tmp_path, capsys, model, lever):
    """platform36 and a signal model (lever arm: attitude and rate signals), noise-free: exit 0, no glitch."""
    from casep.simulation.simulate import simulate_flight

    kw = {} if model == "platform36" else {"model": model, "lever_arm": np.array(lever)}
    sim = simulate_flight(_clean_scenario("paper"), seed=0, rate=20.0, **kw)
    assert np.all(sim.noise == 0.0)
    path, out = tmp_path / "clean.csv", tmp_path / "r.json"
    casep.write_flight(sim.flight, path)
    code = main(["separate", str(path), "--model", model, "--json", str(out)])
    printed = capsys.readouterr()
    assert code == 0, printed.err
    assert "glitch" not in printed.out + printed.err and "at the rounding level" in printed.err  # a warning
    truth = np.array(sim.truth, dtype=float)
    if lever is not None:  # the tracked point's offset, injected by the trajectory: the model's lx, ly, lz
        truth[[sim.model.names.index(n) for n in ("lx", "ly", "lz")]] = lever
    _check_clean(_finite_json(out), truth, sim.flight, sim.model)


def test_noise_free_range_pair_default_path_json(tmp_path, capsys):
    """A telemetry + tracking pair (two rates, tracking from 10 s), noise-free, through --tracking."""
    from casep.simulation.simulate import simulate_two_rate

    d = simulate_two_rate(_clean_scenario("paper"), telemetry_rate=50.0, tracking_rate=10.0, tracking_start=10.0)
    tel, trk, out = tmp_path / "tel.csv", tmp_path / "trk.csv", tmp_path / "r.json"
    d.write(tel, trk)
    code = main(["separate", str(tel), "--tracking", str(trk), "--json", str(out)])
    printed = capsys.readouterr()
    assert code == 0, printed.err
    said = printed.out + printed.err  # residuals at the interpolation floor of the pair (two rates)
    assert "glitch" not in said and "at the interpolation floor" in said
    data = _finite_json(out)
    flight = casep.read_flight_pair(tel, trk)
    _check_clean(data, d.truth, flight, d.model)


def test_noise_free_several_flights_default_path_json(tmp_path, capsys):
    from casep.simulation.simulate import simulate_flight

    paths = []
    for seed, name in ((0, "paper"), (1, "paper-pitch")):
        sim = simulate_flight(_clean_scenario(name), seed=seed, rate=10.0)
        paths.append(tmp_path / f"{name}.csv")
        casep.write_flight(sim.flight, paths[-1])
    out = tmp_path / "r.json"
    code = main(["separate", *map(str, paths), "--json", str(out)])
    printed = capsys.readouterr()
    assert code == 0, printed.err
    assert "glitch" not in printed.out + printed.err and "disagree" not in printed.out
    data = _finite_json(out)
    assert data["consistency"]["overall"] is None  # no noise to test the flights' consistency against
    for fl in data["flights"]:
        assert max(fl["residual_rms"].values()) < 1e-9
    # the coefficients recovered to 1e-2 of their joint Cramer-Rao std at 0.1 m/s (both flights' rows stacked)
    from casep.checks.diagnostics import crlb_covariance
    from casep.workflows.separate import regression_rows

    S = np.concatenate([regression_rows(casep.read_flight(p), sim.model)[0] for p in paths])
    crlb = dict(zip(sim.model.names, np.sqrt(np.diag(crlb_covariance(S, 0.1)))))
    est = dict(zip(data["names"], np.array(data["estimates"], dtype=float)))
    truth = dict(zip(sim.model.names, np.array(sim.truth, dtype=float)))
    assert set(est) == set(truth)  # platform36: every coefficient shared by the flights
    worst = max(abs(est[n] - truth[n]) / crlb[n] for n in est)
    assert worst <= 0.01, worst


@pytest.mark.parametrize("method, option", [(m, o) for m in METHODS for o in sorted(OPTIONS)
                                            if o not in METHODS[m].options
                                            and o not in ("bounds", "prior", *NOISE_OPTIONS)][:12])
def test_an_option_of_another_method_same_message_api_and_cli(good_flight_csv, capsys, method, option):
    """An option the method does not take: the same message from casep.separate, FitSpec and casep separate.
    (``tau`` is every method's: the noise model's, or GLS's own.)"""
    opt = OPTIONS[option]
    value = opt.default if opt.default is not None else 1
    with pytest.raises(ValueError) as e:
        FitSpec.build(method, **{option: value})
    api = str(e.value)
    assert api.startswith(f"option {opt.flag} (`{option}`) is not taken by method `{method}`")
    assert main(["separate", str(good_flight_csv), "--method", method, opt.flag, str(value)]) == 2
    assert f"casep: error: {api}" in capsys.readouterr().err


@pytest.mark.parametrize("name, flag, value", [("outliers", "--outliers", 2.0), ("exclude_outliers",
                                                                                  "--exclude-outliers", 1.5),
                                               ("outliers", "--outliers", 0.0), ("exclude_outliers",
                                                                                  "--exclude-outliers", -0.01)])
def test_outlier_chances_are_checked_with_the_request(good_flight_csv, capsys, name, flag, value):
    """A false-alarm chance outside (0, 1) is refused where the request is made, naming the option (was:
    accepted, then refused mid-fit as `alpha`)."""
    with pytest.raises(ValueError, match=rf"^option {flag} \(`{name}`\) must be a false-alarm chance in \(0, 1\)"):
        FitSpec.build("ols", **{name: value})
    assert main(["separate", str(good_flight_csv), flag, str(value)]) == 2
    assert f"casep: error: option {flag} (`{name}`) must be a false-alarm chance in (0, 1)" in capsys.readouterr().err
