"""The estimator registry (casep.estimators.registry): one table read by separate(), the CLI and Monte Carlo."""

from __future__ import annotations

import json
import sys

import numpy as np
import pytest

import casep
from casep.cli import main
from casep.estimators.registry import METHODS, NOISE_OPTIONS, OPTIONS, check_method_options
from casep.simulation.synthetic import excitation_force, inject_errors

# A value for every option, other than its default (files: a mapping), for the "not taken" checks.
_VALUES = {"p0": 1e4, "weight": 2.0, "forgetting": 0.999, "noise_order": 2, "lam": 1e-3, "bounds": {"Kg0x": 0.5},
           "prior": {"Kg0x": {"mean": 0.5, "std": 0.1}}, "n_components": 20, "tau": 1.0}
for _name, _option in OPTIONS.items():  # an option of a method added to the registry: a value its rules accept
    if _name not in _VALUES:
        _VALUES[_name] = next(v for v in (2, 0.5, 2.0, 0.99, "a") if any(r.accepts(v) for r in _option.rules))


@pytest.fixture(scope="module")
def clean_flight(platform36, truth36):
    t = np.arange(0.0, 120.0, 0.1)
    f = excitation_force(t, duration=120.0)
    return casep.FlightData(t, f, inject_errors(platform36, t, f, truth36))


def test_registry_is_what_separate_and_montecarlo_use():
    from casep.montecarlo import BATCHED
    from casep.workflows.separate import METHODS as SEPARATE_METHODS

    assert tuple(METHODS) == SEPARATE_METHODS
    assert set(BATCHED) == {k for k, m in METHODS.items() if m.batched}
    assert set(_VALUES) == set(OPTIONS)
    for m in METHODS.values():  # its public solver in its module; the built-in ones also as casep.<solver>
        assert callable(getattr(sys.modules[m.core.__module__], m.solver))
        assert set(m.required) <= set(m.options) <= set(OPTIONS)
    for name in ("ols", "rls", "rels", "ridge", "bounded", "pcr", "map", "gls", "huber"):
        assert callable(getattr(casep, METHODS[name].solver))


@pytest.mark.parametrize("method", list(METHODS))
def test_option_of_another_method_is_an_error_naming_both(method, clean_flight, platform36):
    for name in OPTIONS:
        if name in METHODS[method].options:
            continue
        with pytest.raises(ValueError) as e:
            check_method_options(method, {name: _VALUES[name]})
        assert OPTIONS[name].flag in str(e.value) and f"method `{method}`" in str(e.value)
        if name in NOISE_OPTIONS:  # the noise model's: every method takes it through separate()
            continue
        with pytest.raises(ValueError, match=f"is not taken by method `{method}`"):
            casep.separate(clean_flight, platform36, method, **{name: _VALUES[name]},
                           **{r: _VALUES[r] for r in METHODS[method].required})


@pytest.mark.parametrize("method", [m for m in METHODS if METHODS[m].required])
def test_required_options(method):
    with pytest.raises(ValueError, match=f"is required for method `{method}`"):
        check_method_options(method, {})


def test_cli_refuses_option_of_another_method(tmp_path, clean_flight, capsys):
    p = tmp_path / "f.csv"
    casep.write_flight(clean_flight, p)
    out = tmp_path / "r.json"
    assert main(["separate", str(p), "--method", "ols", "--lambda", "5", "--json", str(out)]) == 2
    err = capsys.readouterr().err
    assert "--lambda" in err and "method `ols`" in err and "ridge" in err and not out.exists()


@pytest.mark.parametrize("method", list(METHODS))
def test_every_method_runs_through_separate_with_its_defaults(method, clean_flight, platform36, truth36):
    """Conformance (reduced): each registered method, defaults only (required files: the truth
    as prior / fixed box), returns the result contract; OLS and GLS recover the noise-free truth."""
    extra = {"bounds": {n: [v - abs(v) - 1, v + abs(v) + 1] for n, v in zip(platform36.names, truth36)},
             "prior": {n: {"mean": v, "std": abs(v) + 1} for n, v in zip(platform36.names, truth36)}}
    res = casep.separate(clean_flight, platform36, method, **{r: extra[r] for r in METHODS[method].required})
    assert res.method == method and res.model == "platform36"
    # bounded with no active bound is least squares: its std are then plain sampling std
    assert res.std_kind == ("sampling" if method == "bounded" else METHODS[method].std_kind)
    data = json.loads(json.dumps(res.to_dict(), allow_nan=False))
    assert data["names"] == list(platform36.names) and len(data["estimates"]) == 36
    if method in ("ols", "gls"):
        np.testing.assert_allclose(res.estimate, truth36, rtol=1e-5)


def test_methods_command_lists_the_registry(capsys):
    assert main(["methods", "--json"]) == 0
    table = json.loads(capsys.readouterr().out)
    assert [m["name"] for m in table] == list(METHODS)
    ridge = next(m for m in table if m["name"] == "ridge")
    assert ridge["options"][0]["flag"] == "--lambda" and ridge["std_kind"] == "sampling"
    assert ridge["extras"] == {"type": "RidgeExtras", "fields": ["lam", "rule", "effective_dof"]}
    assert "posterior" in next(m for m in table if m["name"] == "map")["std_kind_meaning"]
    assert main(["methods"]) == 0
    assert "--noise-order" in capsys.readouterr().out


def test_std_kind_is_a_declared_field_and_extras_a_declared_type():
    """Method.std_kind is a declared, validated field; each method declares its extras dataclass."""
    import dataclasses

    import pytest as _pytest

    from casep.estimators.registry import METHODS, Method
    from casep.estimators.result import STD_KIND_MEANINGS
    assert "std_kind" in {f.name for f in dataclasses.fields(Method)}
    declared = {"ols": "sampling", "gls": "sampling", "ridge": "sampling", "pcr": "sampling", "huber": "sampling",
                "map": "posterior", "rls": "posterior", "rels": "posterior", "bounded": "conditional"}
    for name, m in METHODS.items():
        assert m.std_kind in STD_KIND_MEANINGS and m.std_kind == declared.get(name, m.std_kind), name
        assert dataclasses.is_dataclass(m.extras_type) and m.extras_type.__dataclass_params__.frozen, name
    with _pytest.raises(ValueError, match="std_kind"):
        dataclasses.replace(METHODS["ols"], name="fake", std_kind="exact")


def test_workflows_ask_the_method_not_its_name():
    """separate, solve_problem, the several-flight path and radar read a method's declaration, never its
    name: no `method == "gls"`-style test in them (what a method does is in its own module)."""
    import re
    from pathlib import Path

    import casep.workflows

    names = "|".join(METHODS)
    pattern = re.compile(rf"""(==|!=|\bin\b|\bnot in\b)\s*\(?\s*["']({names})["']|["']({names})["']\s*(==|!=|\bin\b)""")
    root = Path(casep.workflows.__file__).parent
    for module in ("separate.py", "../estimators/solve.py", "flights.py", "radar.py", "fusion.py"):
        hits = [line for line in (root / module).read_text().splitlines()
                if pattern.search(line) and not line.lstrip().startswith("#")]
        assert hits == [], (module, hits)


def test_a_solver_keyword_given_to_a_method_that_ignores_it_is_refused():
    """`max_condition_index` is PCR's keyword: separate() with another method refuses it, naming the taker."""
    from casep.regression.problem import Problem

    rng = np.random.default_rng(0)
    S = rng.standard_normal((50, 3, 3))
    problem = Problem.from_arrays(S, S @ np.ones(3) + 0.01 * rng.standard_normal((50, 3)), np.arange(50) * 0.1)
    with pytest.raises(ValueError, match=r"\(`max_condition_index`\) is not taken by method `ols`; it is a keyword"):
        casep.separate(problem, method="ols", max_condition_index=10, noise="white", robust="none")
    res = casep.separate(problem, method="pcr", max_condition_index=10, noise="white", robust="none")
    assert res.success
