"""The result's terminal table, JSON shape and exports (casep.estimators.result, `separate --mat/--csv`)."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

import casep
from casep.cli import main
from casep.estimators.result import write_csv, write_mat
from casep.simulation.synthetic import excitation_force, inject_errors

SIGMA = 0.01  # m/s, white noise of the test flight


@pytest.fixture(scope="module")
def noisy_flight(platform36, truth36):
    """120 s at 10 Hz of the analytic excitation, paper truth, 0.01 m/s white noise (seeded)."""
    rng = np.random.default_rng(20261122)
    t = np.arange(0.0, 120.0, 0.1)
    f = excitation_force(t, duration=120.0)
    dv = inject_errors(platform36, t, f, truth36) + SIGMA * rng.standard_normal((t.size, 3))
    return casep.FlightData(t, f, dv)


@pytest.fixture(scope="module")
def flight_csv(tmp_path_factory, noisy_flight):
    p = tmp_path_factory.mktemp("result") / "flight.csv"
    casep.write_flight(noisy_flight, p)
    return p


def _separate(flight, method, **kw):
    import warnings

    from casep.exceptions import IllConditionedWarning

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IllConditionedWarning)  # the paper's regression is ill-conditioned
        return casep.separate(flight, "platform36", method, **kw)


def _settings_line(res) -> str:
    lines = [ln for ln in res.text().splitlines() if ln.startswith("settings: ")]
    assert len(lines) == 1, res.text()
    return lines[0]


# Per method: keyword arguments and what its settings line must show (computed from the result).
CASES = {
    "ols": ({}, lambda r: [f"rcond {r.extras.rcond:.3g}", "std sampling"]),
    "gls": ({}, lambda r: [f"tau {r.extras.tau:.4g} s (REML estimate)", "std sampling"]),
    "ridge": ({}, lambda r: [f"lambda {r.extras.lam:.4g} on unit-norm columns (GCV)",
                             f"effective dof {r.extras.effective_dof:.3g} of 36"]),
    "rls": ({"p0": 1e4, "forgetting": 0.99999},
            lambda r: ["p0 1e+04", "forgetting 0.99999",
                       f"effective prior std {r.diagnostics['effective_prior_std']:.4g}", "std posterior"]),
    "rels": ({"noise_order": 2}, lambda r: [
        "MA(2) noise model",
        f"c1 {r.extras.ma_coefficients[0]:.4g} "
        f"+- {r.extras.ma_std[0]:.2g}",
        f"c2 {r.extras.ma_coefficients[1]:.4g}"]),
    "pcr": ({"n_components": 30}, lambda r: ["30 of 36 components kept", "6 dropped (condition index"]),
    "map": ({"prior": {"Kg0x": {"mean": 0.0, "std": 2.0}, "Ka0y": {"mean": 1.0, "std": 0.5}}},
            lambda r: ["Gaussian prior on 2 of 36 coefficients", "Kg0x 0 +- 2", "Ka0y 1 +- 0.5", "std posterior"]),
    "bounded": ({"bounds": {"Kg0x": [-0.01, 0.01], "Ka0y": 0.0}},
                lambda r: ["bounds on 2 of 36 coefficients", "1 fixed",
                           "std conditional on the active set (understated)"]),
}


@pytest.mark.parametrize("method", list(CASES))
def test_table_prints_settings_line_per_method(noisy_flight, method):
    kw, expected = CASES[method]
    res = _separate(noisy_flight, method, **kw)
    line = _settings_line(res)
    for text in expected(res):
        assert text in line, (text, line)
    assert "sigma estimated from the residuals" in line


def test_settings_line_given_sigma_and_tau(noisy_flight):
    from casep.exceptions import NoiseNotWhiteWarning

    with pytest.warns(NoiseNotWhiteWarning, match="gls"):  # a tau of 0.5 s given for white noise: said
        res = _separate(noisy_flight, "gls", tau=0.5, sigma=0.02)
    line = _settings_line(res)
    assert "tau 0.5 s (given)" in line and "sigma given 0.02 m/s" in line


def test_json_parallel_arrays_full_rank(noisy_flight, truth36):
    """Octave-style decode: flat numeric arrays with no null on a full-rank flight."""
    res = _separate(noisy_flight, "ols")
    data = json.loads(json.dumps(res.to_dict(), allow_nan=False))
    names = list(casep.load_model("platform36").names)
    assert data["names"] == names == [c["name"] for c in data["coefficients"]]
    assert data["units"] == [c["unit"] for c in data["coefficients"]]
    for key in ("estimates", "std"):
        assert len(data[key]) == 36 and all(isinstance(v, float) for v in data[key]), key
    assert data["estimates"] == [c["estimate"] for c in data["coefficients"]]
    assert data["std"] == [c["std"] for c in data["coefficients"]]
    assert data["std_kind"] == "sampling"
    # 0.01 m/s noise: the estimate is within 5 std of the truth for every coefficient
    z = (np.array(data["estimates"]) - truth36) / np.array(data["std"])
    assert np.max(np.abs(z)) < 5.0


def test_json_parallel_arrays_null_only_where_missing(tmp_path, platform36, truth36):
    t = np.arange(0.0, 60.0, 0.1)
    f = excitation_force(t, duration=60.0, cross_range=False)  # pitch plane: some columns zero
    p = tmp_path / "pitch.csv"
    casep.write_flight(casep.FlightData(t, f, inject_errors(platform36, t, f, truth36)), p)
    out = tmp_path / "r.json"
    assert main(["separate", str(p), "--json", str(out)]) == 0
    data = json.loads(out.read_text())
    missing = [c["name"] for c in data["coefficients"] if c["estimate"] is None]
    assert 0 < len(missing) < 36 and "Kg1xz" in missing
    assert [n for n, v in zip(data["names"], data["estimates"]) if v is None] == missing
    assert [n for n, v in zip(data["names"], data["std"]) if v is None] == missing


def test_mat_round_trip(noisy_flight, tmp_path):
    from scipy.io import loadmat

    res = _separate(noisy_flight, "bounded", bounds={"Kg0x": [-0.01, 0.01], "Ka0y": 0.0})
    out = tmp_path / "r.mat"
    write_mat(res, out)
    m = loadmat(out, simplify_cells=True)
    assert list(m["names"]) == list(res.names) and list(m["units"]) == list(res.units)
    np.testing.assert_array_equal(m["estimates"], res.estimate)  # exact: doubles
    np.testing.assert_array_equal(m["std"], res.std)  # NaN at the bound / fixed, equal_nan by default
    assert np.isnan(m["std"][res.names.index("Ka0y")])
    np.testing.assert_array_equal(m["covariance"], res.covariance)
    np.testing.assert_array_equal(m["residuals"], res.residuals)
    assert m["method"] == "bounded" and m["std_kind"] == "conditional" and m["message"] == res.message
    assert m["sigma"] == res.sigma and bool(m["success"]) is True
    assert m["settings"]["bounds"]["Kg0x"][0] == -0.01
    assert m["extras"]["active_bounds"]["Ka0y"] == "fixed"
    assert m["reasons"][res.names.index("Ka0y")] == "fixed to its given value"


def test_mat_has_history_for_recursive(noisy_flight, tmp_path):
    from scipy.io import loadmat

    res = _separate(noisy_flight, "rels")
    write_mat(res, tmp_path / "r.mat")
    m = loadmat(tmp_path / "r.mat", simplify_cells=True)
    np.testing.assert_array_equal(m["history"], res.history)
    assert m["extras"]["ma_coefficients"] == res.extras.ma_coefficients[0]


def test_csv_round_trip(noisy_flight, tmp_path):
    res = _separate(noisy_flight, "bounded", bounds={"Kg0x": [-0.01, 0.01], "Ka0y": 0.0})
    write_csv(res, tmp_path / "r.csv")
    with open(tmp_path / "r.csv", newline="", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["name"] for r in rows] == list(res.names)
    est = np.array([float(r["estimate"]) if r["estimate"] else np.nan for r in rows])
    std = np.array([float(r["std"]) if r["std"] else np.nan for r in rows])
    np.testing.assert_array_equal(est, res.estimate)  # 17 significant digits: exact
    np.testing.assert_array_equal(std, res.std)
    r = rows[res.names.index("Ka0y")]
    assert r["std"] == "" and r["reason"] == "fixed to its given value" and float(r["estimate"]) == 0.0


def test_cli_mat_and_csv(flight_csv, tmp_path, capsys):
    from scipy.io import loadmat

    js, mat, cs = tmp_path / "r.json", tmp_path / "r.mat", tmp_path / "r.csv"
    assert main(["separate", str(flight_csv), "--json", str(js), "--mat", str(mat), "--csv", str(cs)]) == 0
    out = capsys.readouterr().out
    assert f"MAT file written to {mat}" in out and f"CSV written to {cs}" in out
    data = json.loads(js.read_text())
    np.testing.assert_array_equal(loadmat(mat, simplify_cells=True)["estimates"], data["estimates"])
    with open(cs, newline="", encoding="utf-8") as fh:
        assert [float(r["estimate"]) for r in csv.DictReader(fh)] == data["estimates"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.csv", "r.json", "r.mat"]  # no temporary left


def test_diagnose_figures_creates_folder(flight_csv, tmp_path, capsys):
    figs = tmp_path / "new" / "figs"
    assert main(["diagnose", str(flight_csv), "--figures", str(figs)]) == 0
    assert (figs / "singular_values.png").stat().st_size > 0
    assert (figs / "variance_decomposition.png").stat().st_size > 0


def test_json_covariance_natural_units_with_null_rows(tmp_path, platform36, truth36):
    """docs/reference/file-formats.md "Result JSON": n x n, model order, natural units; null rows and
    columns for coefficients without an estimate; its diagonal is std^2."""
    import json

    from casep.simulation.synthetic import excitation_force, inject_errors

    t = np.arange(0.0, 60.0, 0.1)
    f = excitation_force(t, duration=60.0, cross_range=False)  # pitch plane: zero columns
    rng = np.random.default_rng(3)
    dv = inject_errors(platform36, t, f, truth36) + 0.1 * rng.standard_normal((t.size, 3))
    S = casep.build_sv(platform36, t, f)
    with pytest.warns(casep.IllConditionedWarning):
        res = casep.solve_ols(S, dv, names=platform36.names, units=platform36.units)
    data = json.loads(json.dumps(res.to_dict(), allow_nan=False))
    C = data["covariance"]
    n = len(platform36.names)
    assert len(C) == n and all(len(r) == n for r in C)
    missing = [j for j, r in enumerate(data["coefficients"]) if r["estimate"] is None]
    assert missing and all(C[j][k] is None and C[k][j] is None for j in missing for k in range(n))
    ok = [j for j in range(n) if j not in missing]
    diag = np.array([C[j][j] for j in ok])
    np.testing.assert_allclose(np.sqrt(diag), [data["std"][j] for j in ok], rtol=1e-12)
    M = np.array([[C[j][k] for k in ok] for j in ok])
    np.testing.assert_allclose(M, M.T, rtol=1e-12, atol=0)


def test_crlb_vif_groups_computed_on_first_use(monkeypatch, rng):
    """A solve does not compute the CRLB, VIF and groups; the first read does, once, and they are right:
    CRLB std = sigma sqrt(diag((S^T S)^-1)), uncentred VIF = diag((Z^T Z)^-1) on unit-norm columns."""
    from casep.estimators import _base

    calls = []
    real = _base.collinearity
    monkeypatch.setattr(_base, "collinearity", lambda *a: calls.append(1) or real(*a))
    S = rng.normal(size=(300, 3, 4))
    y = S @ np.array([1.0, 2.0, 3.0, 4.0]) + 0.1 * rng.normal(size=(300, 3))
    res = casep.solve_ols(S, y)
    assert calls == []  # well conditioned: nothing read them
    A = S.reshape(-1, 4)
    crlb = res.sigma * np.sqrt(np.diag(np.linalg.inv(A.T @ A)))
    np.testing.assert_allclose(list(res.diagnostics["crlb_std"].values()), crlb, rtol=1e-10)
    Z = A / np.linalg.norm(A, axis=0)
    np.testing.assert_allclose(list(res.diagnostics["vif"].values()), np.diag(np.linalg.inv(Z.T @ Z)), rtol=1e-10)
    assert res.diagnostics["groups"] == [] and calls == [1]  # computed once, then kept
    data = json.loads(json.dumps(res.to_dict()))
    assert set(data["diagnostics"]) >= {"crlb_std", "vif", "groups", "condition_number"}
    assert calls == [1]
