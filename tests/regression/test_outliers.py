"""Studentized residuals and outlier flags (casep.regression.outliers)."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

import casep
from casep.regression.outliers import flag_outliers, studentized_residuals
from casep.regression.problem import Problem
from casep.simulation.simulate import simulate_flight


def test_studentized_residuals_equal_leave_one_out_refits(rng):
    """Independent construction: leverages from the explicit hat matrix A A^+, t_i from refitting
    without row i (sigma of the others), for every row of a small regression."""
    S = rng.standard_normal((30, 3, 4))
    y = S @ np.array([1.0, -2.0, 0.5, 3.0]) + 0.1 * rng.standard_normal((30, 3))
    t, r, h, dof = studentized_residuals(Problem.from_arrays(S, y))
    A, b = S.reshape(-1, 4), y.reshape(-1)
    H = A @ np.linalg.pinv(A)
    np.testing.assert_allclose(h.reshape(-1), np.diag(H), atol=1e-14)
    x = np.linalg.lstsq(A, b, rcond=None)[0]
    ref = []
    for i in range(b.size):
        keep = np.arange(b.size) != i
        xi = np.linalg.lstsq(A[keep], b[keep], rcond=None)[0]
        s2 = np.sum((b[keep] - A[keep] @ xi) ** 2) / (b.size - 1 - 4)
        ref.append((b[i] - A[i] @ x) / np.sqrt(s2 * (1 - H[i, i])))
    np.testing.assert_allclose(t.reshape(-1), ref, rtol=1e-10)
    np.testing.assert_allclose(r.reshape(-1), b - A @ x, atol=1e-12)
    assert dof == b.size - 4 - 1


@pytest.fixture(scope="module")
def paper10():
    sim = simulate_flight("paper", seed=1, rate=10.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return sim, Problem.from_flight(sim.flight, sim.model)


def test_every_injected_outlier_is_flagged_and_named(paper10, rng):
    """10 rows 8 sigma off (random samples and axes) in a 10 Hz paper flight: all flagged at the
    default family-wise 1 %, no other row; the rows come back with sample, time and axis."""
    sim, p = paper10
    k = rng.choice(p.y.shape[0], 10, replace=False)
    ax = rng.integers(0, 3, 10)
    y = p.y.copy()
    y[k, ax] += 8 * 0.1 * rng.choice([-1.0, 1.0], 10)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fl = flag_outliers(p.with_y(y))
    assert {(r["sample"], r["axis"]) for r in fl.rows} == {(int(a), "xyz"[b]) for a, b in zip(k, ax)}
    r0 = fl.rows[0]
    assert r0["t"] == pytest.approx(sim.flight.t[r0["sample"]]) and abs(r0["t_value"]) > fl.threshold
    assert "estimate with --method huber" in fl.text()


def test_false_alarm_rate_is_the_nominal_rate(paper10, rng):
    """Clean white noise, per-row rate 0.01: 8 seeded draws x 5853 rows flag 1 % of rows (+-0.15 %,
    about 4 binomial std); the default family-wise threshold is the Bonferroni quantile."""
    from scipy import stats

    sim, p = paper10
    S = p.sv()
    clean = S @ np.asarray(sim.truth)
    flagged = tested = 0
    for _ in range(8):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            fl = flag_outliers(p.with_y(clean + 0.1 * rng.standard_normal(clean.shape)), rate=0.01)
        flagged += fl.count
        tested += fl.rows_tested
    assert abs(flagged / tested - 0.01) < 0.0015, flagged / tested
    d = flag_outliers(p)
    assert d.threshold == pytest.approx(stats.t.isf(0.01 / (2 * d.rows_tested), d.rows_tested - p.rank().rank - 1))


def test_cli_outliers_option(paper10, tmp_path, capsys):
    from casep.cli import main

    sim, _ = paper10
    dv = sim.flight.dv.copy()
    dv[100, 1] += 1.0
    import dataclasses

    casep.write_flight(dataclasses.replace(sim.flight, dv=dv), tmp_path / "f.csv")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["separate", str(tmp_path / "f.csv"), "--outliers", "--json", str(tmp_path / "r.json")]) == 0
    out = capsys.readouterr().out
    d = json.loads((tmp_path / "r.json").read_text())["diagnostics"]["outliers_studentized"]
    assert d["count"] == 1 and d["rows"][0]["sample"] == 100
    line = d["rows"][0]["line"]  # one numbering: the file's line and the time, in the output and the JSON
    assert float((tmp_path / "f.csv").read_text().splitlines()[line - 1].split(",")[0]) == pytest.approx(10.0)
    assert "outliers: 1 row(s)" in out and f"line {line} of f.csv (t = 10 s) dv_y" in out
    with pytest.raises(ValueError, match="`alpha` must be in"):
        flag_outliers(Problem.from_flight(sim.flight, sim.model), alpha=2.0)
