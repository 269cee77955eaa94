"""An estimate's facts each have one home: ``settings`` the inputs, ``extras`` what the method found.

For every registered method: ``settings`` hold the options as asked (given, or by their defaults: "auto",
"gcv", None), and solving again with the found value given as the input gives the same settings keys,
the input in ``settings``, the same found value in ``extras`` and the same estimate. Result files of
an earlier casep (found values in ``settings``, facts in both ``diagnostics`` and ``extras``; written by
``data/old_results/make_old_results.py``) still read, in today's form.
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pytest

from casep.estimators.reading import read_result
from casep.estimators.registry import METHODS
from casep.estimators.result import EstimateResult
from casep.regression.problem import Problem
from casep.simulation.simulate import simulate_flight

OLD = Path(__file__).parent / "data" / "old_results"

#: The options a method cannot run without.
REQUIRED = {"bounded": {"bounds": {"Kg0x": [-0.01, 0.01], "Ka0y": 0.0}},
            "map": {"prior": {"Kg0x": {"mean": 0.0, "std": 2.0}}}}

#: Per method: (the option a rule or default resolves, its settings key, the value found in the extras,
#: the found value as the settings line prints it).
FOUND = {
    "ols": ("rcond", "rcond", lambda e: e.rcond, lambda v: f"rcond {v:.3g}"),
    "gls": ("tau", "tau", lambda e: e.tau, lambda v: f"tau {v:.4g} s"),
    "ridge": ("lam", "lambda", lambda e: e.lam, lambda v: f"lambda {v:.4g} on unit-norm columns"),
    "pcr": ("n_components", "n_components", lambda e: e.n_components, lambda v: f"{v} of 36 components kept"),
    "rls": ("history_stride", "history_stride", lambda e: e.history_stride, None),
    "rels": ("history_stride", "history_stride", lambda e: e.history_stride, None),
}
#: Methods that use every option as given (what they find is not an option: outliers, active bounds).
AS_GIVEN = {"huber", "map", "bounded"}
#: Settings that hold the value used rather than the input (none: every found value is in the extras).
STILL_IN_SETTINGS: set[str] = set()
#: Settings keys that are no option: ``sigma`` (given, or how it is estimated) and the solver bounded always uses.
NOT_OPTIONS = {"sigma"}
ALWAYS = {"bounded": {"solver": "active set"}}
#: Option name -> its settings key where they differ.
KEY = {"lam": "lambda"}


@pytest.fixture(scope="module")
def problem(platform36):
    """The paper flight at 5 Hz in Gauss-Markov noise (tau 1 s), seeded."""
    return Problem.from_flight(simulate_flight("paper-ar1", seed=7, rate=5.0).flight, platform36)


def _solve(problem, method, **options):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the paper's regression is ill-conditioned: said by the result
        return METHODS[method].solve(problem, **{**REQUIRED.get(method, {}), **options})


def test_every_method_is_classified():
    """A method added to the registry says here whether a rule or default of it resolves an input."""
    assert set(METHODS) == set(FOUND) | AS_GIVEN and not set(FOUND) & AS_GIVEN


@pytest.mark.parametrize("method", list(METHODS))
def test_settings_hold_the_inputs(method, problem):
    meth = METHODS[method]
    res = _solve(problem, method)
    asked = {o.name: o.default for o in meth.option_specs + meth.keywords}
    asked.update({**meth.fixed, **REQUIRED.get(method, {})})
    expected = {KEY.get(k, k): v for k, v in asked.items()}
    if method == "bounded":  # the box as [low, high], a fixed value as [v, v]
        expected["bounds"] = {"Kg0x": [-0.01, 0.01], "Ka0y": [0.0, 0.0]}
    if method == "ols":
        expected["rcond"] = None  # not given: the default threshold, which OLSExtras records
    expected.update(ALWAYS.get(method, {}))
    got = {k: v for k, v in res.settings.items() if k not in NOT_OPTIONS | STILL_IN_SETTINGS}
    assert got == {k: v for k, v in expected.items() if k not in STILL_IN_SETTINGS}
    assert res.settings["sigma"] == ("robust (MAD) scale" if method == "huber" else "estimated")
    given = _solve(problem, method, sigma=0.25)
    assert given.settings["sigma"] == 0.25 and "sigma given 0.25 m/s" in given.text()


@pytest.mark.parametrize("method", list(FOUND))
def test_found_value_given_back_as_input(method, problem):
    option, key, found_in, printed = FOUND[method]
    first = _solve(problem, method)
    found = found_in(first.extras)
    assert found is not None
    if key not in STILL_IN_SETTINGS:
        assert first.settings[key] != found  # the rule or default asked ("auto", "gcv", None), not the value
    again = _solve(problem, method, **{option: found})
    assert again.settings.keys() == first.settings.keys()
    assert again.settings[key] == found  # given: an input now
    assert found_in(again.extras) == pytest.approx(found, rel=1e-12)
    np.testing.assert_allclose(again.estimate, first.estimate, rtol=1e-9, atol=0)
    if printed is not None:  # the settings line shows the value found, as it shows the value given
        assert printed(found) in first.settings_line() and printed(found) in again.settings_line()
    back = EstimateResult.from_json(json.loads(json.dumps(first.to_dict())))
    assert back.settings == first.settings and back.extras == first.extras  # today's form reads back unchanged


def test_facts_found_are_not_in_the_diagnostics(problem):
    """Outliers, the RELS noise model, the effective dof, the active bounds, the dropped directions: each
    only in its method's extras."""
    moved = {"outliers", "noise_model", "effective_dof", "active_bounds", "dropped_directions"}
    for method in METHODS:
        res = _solve(problem, method, **({"noise_order": 1} if method == "rels" else {}))
        assert not moved & set(res.diagnostics), method
        assert not moved & set(res.to_dict()["diagnostics"]), method
    assert _solve(problem, "rels", noise_order=1).extras.ma_coefficients
    assert "Kg0x" in _solve(problem, "bounded").extras.active_bounds


def test_inputs_are_not_repeated_in_the_extras(problem):
    """MAP's prior and bounded's box are inputs: in settings only (the settings line still shows them)."""
    import dataclasses

    bounded, map_ = _solve(problem, "bounded"), _solve(problem, "map")
    assert set(dataclasses.asdict(bounded.extras)) == {"active_bounds"} and dataclasses.asdict(map_.extras) == {}
    assert "bounds on 2 of 36 coefficients" in bounded.settings_line()
    assert "Gaussian prior on 1 of 36 coefficients" in map_.settings_line() and "Kg0x 0 +- 2" in map_.settings_line()


def test_robust_sigma_is_found_not_given(platform36):
    """A robust fit's sigma (the M-estimator's) is the result's sigma; settings say none was given."""
    import casep

    fl = simulate_flight("paper", seed=8, rate=5.0).flight
    dv = fl.dv.copy()
    dv[100:110, 0] += 5.0  # glitches 50 sigma off
    fl = casep.FlightData(fl.t, fl.f, dv)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = casep.separate(fl, platform36, "ols", noise="white", robust="huber")
    assert res.sigma_source == "robust" and res.settings["sigma"] == "estimated"
    assert f"sigma {res.sigma:.4g} m/s (robust estimate)" in res.settings_line()


def _old(name: str) -> dict:
    return json.loads((OLD / f"{name}.json").read_text())


#: Per old file: what its settings become and where its found values went (from the old file's own fields).
OLD_CASES = {
    "ols": lambda old, r: (r.settings["rcond"] == old["settings"]["rcond"]  # given or not: the file cannot tell
                           and r.extras.rcond == old["settings"]["rcond"]),
    "gls": lambda old, r: (r.settings["tau"] == "auto" and r.extras.tau == old["settings"]["tau"]
                           and r.extras.tau_rule == "reml"),
    "gls_flights": lambda old, r: (r.settings["tau"] == "auto" and r.extras.flight_taus == old["settings"]["tau"]
                                   and r.extras.tau == pytest.approx(np.mean(list(old["settings"]["tau"].values())))),
    "ridge": lambda old, r: (r.settings["lambda"] == "gcv" and r.extras.lam == old["settings"]["lambda"]
                             and r.extras.rule == "gcv"
                             and r.extras.effective_dof == old["diagnostics"]["effective_dof"]),
    "huber": lambda old, r: (r.settings["flag"] == old["settings"]["flag_sigma"]
                             and r.extras.iterations == old["settings"]["iterations"]
                             and r.extras.scale == old["settings"]["scale"]
                             and r.extras.outliers == old["diagnostics"]["outliers"]),
    "pcr": lambda old, r: (r.settings["n_components"] is None and r.settings["max_condition_index"] == 1000.0
                           and r.extras.n_components == old["settings"]["n_components"]
                           and r.extras.dropped_directions == old["diagnostics"]["dropped_directions"]),
    "rels": lambda old, r: (list(r.extras.ma_coefficients) == old["diagnostics"]["noise_model"]["ma_coefficients"]
                            and r.extras.innovation_rms == old["diagnostics"]["noise_model"]["innovation_rms"]),
    "bounded": lambda old, r: r.extras.active_bounds == old["diagnostics"]["active_bounds"],
}
#: Keys of an old file that today's form does not have (found values in settings, facts twice).
OLD_KEYS = {"settings": {"tau_rule", "lambda_rule", "rule", "iterations", "scale", "flag_sigma", "outliers_flagged"},
            "diagnostics": {"outliers", "noise_model", "effective_dof", "active_bounds", "dropped_directions"}}


@pytest.mark.parametrize("name", list(OLD_CASES))
@pytest.mark.parametrize("with_extras", [True, False], ids=["file", "file-without-extras"])
def test_an_old_result_file_reads_in_todays_form(name, with_extras, tmp_path):
    old = _old(name)
    if not with_extras:  # a file of a casep before extras: the found values only in settings and diagnostics
        old = {**old, "extras": None}
    path = tmp_path / f"{name}.json"
    path.write_text(json.dumps(old))
    res, model = read_result(path)  # the file's model found by name, its coefficients checked against it
    assert model.name == "platform36" and res.method == old["method"]
    assert not OLD_KEYS["settings"] & set(res.settings) and not OLD_KEYS["diagnostics"] & set(res.diagnostics)
    assert type(res.extras) is METHODS[res.method].extras_type
    assert OLD_CASES[name](old, res)
    np.testing.assert_array_equal(res.estimate, [c["estimate"] for c in old["coefficients"]])
    assert res.settings_line().startswith("settings: ")
    again = EstimateResult.from_json(json.loads(json.dumps(res.to_dict())))  # written in today's form
    assert again.settings == res.settings and again.extras == res.extras and again.diagnostics == res.diagnostics
