"""Every result type follows the result protocol of casep.results: ``text()``, ``to_dict()``, ``success``,
``status``, ``message``; the names of an earlier casep warn; casep's own code calls none of them."""

from __future__ import annotations

import ast
import dataclasses
import importlib
import json
import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from casep.results import DEPRECATED_NAMES, PROTOCOL, Completed, Result, deprecated_alias

RESULT_TYPES = [
    ("casep.estimators.result", "EstimateResult"),
    ("casep.impact.result", "ImpactAnalysis"),
    ("casep.montecarlo.result", "MonteCarloResult"),
    ("casep.design.result", "DesignResult"),
    ("casep.calibration.result", "Calibration"),
    ("casep.calibration.consistency", "Consistency"),
    ("casep.workflows.demo", "DemoResult"),
    ("casep.noise.denoise", "DenoiseResult"),
    ("casep.checks.diagnostics", "Diagnostics"),
    ("casep.noise.model", "NoiseModel"),
    ("casep.noise.whiteness", "WhitenessTest"),
    ("casep.noise.identification", "NoiseIdentification"),
    ("casep.regression.outliers", "OutlierFlags"),
    ("casep.workflows.radar", "RadarResult"),
    ("casep.calibration.handturned", "MultipositionCalibration"),
    ("casep.calibration.segment", "Segmentation"),
    ("casep.navigation.result", "NavigationResult"),
]


def _members(cls) -> set[str]:
    """Names a class provides: attributes and methods, and dataclass fields (set per instance)."""
    fields = {f.name for f in dataclasses.fields(cls)} if dataclasses.is_dataclass(cls) else set()
    return {m for m in PROTOCOL if m in fields or hasattr(cls, m)}


@pytest.mark.parametrize("module, name", RESULT_TYPES)
def test_every_result_type_has_the_five_members(module, name):
    cls = getattr(importlib.import_module(module), name)
    assert _members(cls) == set(PROTOCOL), f"{name} lacks {set(PROTOCOL) - _members(cls)}"
    for method in ("to_dict", "text"):
        assert callable(getattr(cls, method)), f"{name}.{method} is not a method"


def _finite_or_null(obj, where="") -> list[str]:
    """Paths in plain data whose number is not finite, or whose value is not plain data."""
    if obj is None or isinstance(obj, (str, bool)):
        return []
    if isinstance(obj, int):
        return []
    if isinstance(obj, float):
        return [] if math.isfinite(obj) else [f"{where}: {obj}"]
    if isinstance(obj, dict):
        return [p for k, v in obj.items() for p in _finite_or_null(v, f"{where}.{k}")]
    if isinstance(obj, (list, tuple)):
        return [p for i, v in enumerate(obj) for p in _finite_or_null(v, f"{where}[{i}]")]
    return [f"{where}: {type(obj).__name__} is not plain data"]


def check_protocol(res) -> dict:
    """The five members on an instance: types, plain finite data, text; returns the data."""
    assert isinstance(res, Result), type(res).__name__
    assert isinstance(res.success, bool) and isinstance(res.status, int) and not isinstance(res.status, bool)
    assert isinstance(res.message, str) and res.message.strip(), type(res).__name__
    text = res.text()
    assert isinstance(text, str) and text.strip()
    data = res.to_dict()
    assert isinstance(data, dict)
    bad = _finite_or_null(data)
    assert not bad, f"{type(res).__name__}.to_dict(): {bad[:5]}"
    json.dumps(data, allow_nan=False)  # what a JSON writer does with it
    return data


def check_old_names_warn(res) -> int:
    """Every old name the type still has warns and gives what its new name gives; the count checked."""
    n = 0
    for old in DEPRECATED_NAMES:
        alias = getattr(type(res), old, None)
        if not callable(alias):
            continue  # not a method of this type (a field of that name is data, not an alias)
        with pytest.warns(DeprecationWarning, match=rf"{type(res).__name__}\.{old}\(\) is deprecated"):
            got = getattr(res, old)()
        assert got is not None
        n += 1
    return n


# ------------------------------------------------------------------ instances of each type
@pytest.fixture(scope="module")
def regression():
    rng = np.random.default_rng(7)
    N = 400
    t = np.arange(N) * 0.05
    S = rng.standard_normal((N, 3, 4))
    y = S @ np.array([1.0, -2.0, 0.5, 3.0]) + 0.1 * rng.standard_normal((N, 3))
    y[123, 1] += 5.0  # one outlier, 50 noise sigma
    return S, y, t


@pytest.fixture(scope="module")
def paper():
    """The paper flight at 5 Hz and its OLS estimate."""
    import casep
    from casep.simulation.simulate import simulate_flight

    sim = simulate_flight("paper", seed=1, rate=5.0)
    return sim, casep.solve_ols(casep.Problem.from_flight(sim.flight, sim.model))


def _estimate(regression):
    from casep import solve_ols

    S, y, _ = regression
    return solve_ols(S, y, names=["a", "b", "c", "d"])


def _analyses(regression):
    from casep.checks.diagnostics import diagnose
    from casep.noise.denoise import denoise
    from casep.noise.identification import identify_noise
    from casep.noise.model import NoiseModel
    from casep.noise.whiteness import whiteness_test
    from casep.regression.outliers import flag_outliers
    from casep.regression.problem import Problem

    S, y, t = regression
    r = y - S @ np.linalg.lstsq(S.reshape(-1, 4), y.reshape(-1), rcond=None)[0]
    return [diagnose(S, y), NoiseModel.gauss_markov(1.5), NoiseModel.white(), whiteness_test(r, t),
            identify_noise(0.1 * np.random.default_rng(1).standard_normal(4096), 0.05),
            flag_outliers(Problem.from_arrays(S, y, t)), denoise(y)]


def test_estimate_and_analyses_follow_the_protocol(regression):
    results = [_estimate(regression), *_analyses(regression)]
    warned = 0
    for res in results:
        check_protocol(res)
        warned += check_old_names_warn(res)
    assert warned >= 4  # table, report (x2), summary
    diag, noise, _, white, ident, flags, _ = results[1:]
    assert "condition number" in diag.text() and "Allan deviation" in ident.text()
    assert noise.text() == noise.line() and "GM tau 1.5 s" in noise.text()
    assert "whiteness" in white.message and white.text().strip()
    assert flags.count >= 1 and flags.rows[0]["sample"] == 123 and flags.rows[0]["axis"] == "y"  # the outlier
    assert "sample 124" in flags.text() and len(flags.text(top=1)) <= len(flags.text())


def test_an_estimate_is_a_result_plain_data_and_text_agree():
    """to_dict() is plain JSON data holding the numbers text() prints."""
    from casep import solve_ols

    rng = np.random.default_rng(3)
    S = rng.standard_normal((200, 3, 4))
    D = np.array([1.0, -2.0, 0.5, 3.0])
    y = S @ D + 0.01 * rng.standard_normal((200, 3))
    res = solve_ols(S, y, names=["a", "b", "c", "d"])
    data = json.loads(json.dumps(check_protocol(res), allow_nan=False))
    est = [c["estimate"] for c in data["coefficients"]]
    ref = np.linalg.lstsq(S.reshape(-1, 4), y.reshape(-1), rcond=None)[0]  # independent least squares
    np.testing.assert_allclose(est, ref, rtol=1e-10, atol=1e-12)
    for name in ("a", "b", "c", "d"):
        assert name in res.text()


def test_a_result_that_cannot_fail_says_what_it_is(regression):
    for res in _analyses(regression):
        assert isinstance(res, Completed)
        assert res.success is True and res.status == 0
        assert res.message == type(res).what and type(res).what != Completed.what


def test_paper_flight_estimate_impact_and_consistency(paper):
    import casep
    from casep.calibration.consistency import consistency

    sim, res = paper
    data = check_protocol(res)
    assert data["success"] is res.success and data["status"] == res.status and data["message"] == res.message
    impact = casep.impact_analysis(sim.flight, res)
    check_protocol(impact)
    assert check_old_names_warn(impact) == 2  # to_json, table
    cons = consistency(res, res, labels=("first", "second"))
    check_protocol(cons)
    assert cons.success and cons.status == 0 and "consistent" in cons.message
    assert check_old_names_warn(cons) == 2  # summary, report


def test_demo_result_is_no_plain_success_when_a_method_fails(paper):
    import casep
    from casep.checks.diagnostics import diagnose
    from casep.workflows.demo import DemoResult

    sim, res = paper
    diag = diagnose(casep.Problem.from_flight(sim.flight, sim.model))
    demo = DemoResult(sim=sim, results={"LS": res}, diagnostics=diag, table="Table 1")
    check_protocol(demo)
    assert demo.success is res.success and "1 methods" in demo.message
    failed = dataclasses.replace(res, success=False, status=-1, message="no coefficient determined")
    bad = DemoResult(sim=sim, results={"LS": res, "bad": failed}, diagnostics=demo.diagnostics, table="Table 1")
    assert not bad.success and bad.status == -1 and "bad: no coefficient determined" in bad.message


def test_monte_carlo_result_follows_the_protocol():
    from casep.montecarlo.result import MonteCarloResult

    truth = np.array([1.0, -2.0])
    err = np.array([[0.1, 1.0], [-0.3, -1.0], [0.2, 1.0], [0.0, -1.0]])
    mc = MonteCarloResult(scenario="hand", runs=4, seed=9, names=("a", "b"), units=("mg", "ppm"), truth=truth,
                          crlb_std=np.array([0.2, np.nan]), estimates={"ols": truth + err},
                          stds={"ols": None}, seconds={"ols": 0.5})
    data = check_protocol(mc)
    assert data["methods"]["ols"]["coefficients"][1]["crlb_std"] is None  # NaN written as null
    assert check_old_names_warn(mc) == 1 and mc.text().endswith(mc.method_table())


def test_calibration_follows_the_protocol():
    from casep import calibrate
    from casep.calibration import load_calibration_model
    from casep.calibration.simulate import ferraris_design, simulate_session

    model = load_calibration_model("ferraris")
    truth = dict(zip(model.names, np.random.default_rng(1).normal(size=model.n_coefficients)))
    for i, a in enumerate("xyz"):
        truth[f"Ma_{a}{a}"], truth[f"Mg_{a}{a}"] = 200.0 + 10 * i, 16.0 + i
    ses, segs = simulate_session(model, truth, ferraris_design(20, 30), rate=50.0)
    cal = calibrate(ses, segs, model)
    check_protocol(cal)
    assert cal.success and "accelerometer:" in cal.message and "gyro:" in cal.message
    assert check_old_names_warn(cal) == 1


def test_deprecated_alias_passes_arguments_and_names_both():
    class Thing:
        def text(self, top: int = 5) -> str:
            return f"top {top}"

        table = deprecated_alias("text", "table")

    with pytest.warns(DeprecationWarning, match=r"Thing\.table\(\) is deprecated.*use text\(\)"):
        assert Thing().table(3) == "top 3"
    assert Thing.table.__name__ == "table" and "text" in Thing.table.__doc__


# ------------------------------------------------------------------ casep's own code calls no old name
#: Calls of these names that are not results' old names: pyarrow's ``pa.table`` and the simulated
#: trajectory's ``summary()`` (a dict of its key figures).
_NOT_ALIASES = {("pa", "table"), ("trajectory", "summary")}


def _old_name_calls(path: Path, rel: str) -> list[str]:
    found = []
    for node in ast.walk(ast.parse(path.read_text(), filename=rel)):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr in DEPRECATED_NAMES:
            recv = node.func.value
            name = recv.id if isinstance(recv, ast.Name) else recv.attr if isinstance(recv, ast.Attribute) else ""
            if (name, node.func.attr) in _NOT_ALIASES:
                continue
            found.append(f"{rel}:{node.lineno}: .{node.func.attr}()")
    return found


def test_casep_calls_no_old_name():
    import casep

    root = Path(casep.__file__).resolve().parent
    found = [hit for p in sorted(root.rglob("*.py"))
             for hit in _old_name_calls(p, str(p.relative_to(root.parent)))]
    assert not found, "casep calls the old names of text()/to_dict(): " + "; ".join(found)


def test_the_scan_finds_an_old_name_call(tmp_path):
    """The negative control: a file that prints ``res.table()`` and ``cons.report()`` is caught."""
    p = tmp_path / "cli.py"
    p.write_text("print(res.table())\nprint(cons.report())\nx = pa.table({})\nprint(res.text())\n")
    assert [h.split(": ")[1] for h in _old_name_calls(p, "cli.py")] == [".table()", ".report()"]


def test_importing_a_result_module_warns_nothing():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for module, _ in RESULT_TYPES:
            importlib.import_module(module)
