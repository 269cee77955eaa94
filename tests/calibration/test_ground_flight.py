"""Ground versus flight: the consistency test, the ground result as a flight prior (API and CLI)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy import stats

import casep
from casep import calibrate
from casep.calibration import load_calibration_model
from casep.calibration.consistency import consistency, ground_prior
from casep.calibration.simulate import ferraris_design, simulate_session, tilted_design
from casep.cli import main
from casep.estimators.result import EstimateResult
from casep.simulation.synthetic import excitation_force, inject_errors


def _gaussian_result(names, units, mean, cov, method="ols"):
    n = len(names)
    return EstimateResult(method=method, names=tuple(names), units=tuple(units), estimate=np.asarray(mean, float),
                          std=np.sqrt(np.diag(cov)), covariance=np.asarray(cov, float), reasons={},
                          residuals=np.zeros((0, 3)), sigma=1.0, rank=n, status=1, message="", success=True,
                          si_factors=np.ones(n), model="m")


@pytest.mark.montecarlo
def test_consistency_chi2_and_z_are_calibrated():
    """Two independent Gaussian estimates of the same truth, correlated covariances: chi2 ~ chi2_4, z ~ N(0, 1);
    a shift of 5 std in one coefficient is flagged."""
    rng = np.random.default_rng(11)
    names, units = ["a", "b", "c", "d"], ["mg"] * 4
    A = rng.normal(size=(4, 4))
    Cg = A @ A.T + 0.5 * np.eye(4)
    B = rng.normal(size=(4, 4))
    Cf = B @ B.T + 0.2 * np.eye(4)
    truth = rng.normal(size=4)
    chi, zs = [], []
    for _ in range(400):
        g = rng.multivariate_normal(truth, Cg)
        f = rng.multivariate_normal(truth, Cf)
        c = consistency(_gaussian_result(names, units, g, Cg), _gaussian_result(names, units, f, Cf))
        chi.append(c.chi2)
        zs.append(c.z)
    assert c.dof == 4
    assert abs(np.mean(chi) - 4.0) < 4 * np.sqrt(8.0 / 400)  # chi2_4: mean 4, var 8
    assert stats.kstest(chi, "chi2", args=(4,)).pvalue > 1e-3
    assert abs(np.std(np.ravel(zs)) - 1.0) < 0.06
    # closed form of one case: z = d / sqrt(Cg + Cf)_jj, chi2 = d^T (Cg + Cf)^-1 d
    d = f - g
    np.testing.assert_allclose(c.z, d / np.sqrt(np.diag(Cg + Cf)), rtol=1e-12)
    assert c.chi2 == pytest.approx(d @ np.linalg.solve(Cg + Cf, d), rel=1e-10)
    f_bad = g + np.array([0, 0, 5 * np.sqrt(Cg[2, 2] + Cf[2, 2]), 0])
    bad = consistency(_gaussian_result(names, units, g, Cg), _gaussian_result(names, units, f_bad, Cf))
    assert bad.disagree == ["c"] and abs(bad.z[2] - 5.0) < 1e-12


def test_consistency_refuses_units_and_map_and_leaves_out_what_one_misses():
    g = _gaussian_result(["a", "b"], ["mg", "mg"], [1, 2], np.eye(2))
    with pytest.raises(ValueError, match="`a` is in mg in the ground estimate but in ug"):
        consistency(g, _gaussian_result(["a", "b"], ["ug", "mg"], [1, 2], np.eye(2)))
    with pytest.raises(ValueError, match="MAP estimate"):
        consistency(g, _gaussian_result(["a", "b"], ["mg", "mg"], [1, 2], np.eye(2), method="map"))
    f = _gaussian_result(["a", "b", "c"], ["mg"] * 3, [1.5, np.nan, 0], np.diag([1.0, np.nan, 1.0]))
    c = consistency(g, f)
    assert c.names == ("a",) and c.left_out == ("b",) and c.dof == 1


def _ground_truth(flight):
    from casep.simulation.paper import TABLE1_TRUTH

    truth = {n: TABLE1_TRUTH[n] for n in flight.names}
    truth.update({f"Sg_{i}{j}": (300.0 if i == j else 20.0) for i in "xyz" for j in "xyz"})
    return truth


@pytest.fixture(scope="module")
def ground_cal():
    model = load_calibration_model("platform36_ground")
    flight = casep.load_model("platform36")
    truth = _ground_truth(flight)
    # noise: 1e-4 m/s^2 (10 ug) and 1e-6 rad/s (0.2 deg/h) per sample; positions tilted 20 arcsec rms
    ses, segs = simulate_session(model, truth, ferraris_design(200, 200) + tilted_design(200), rate=100.0,
                                 noise=(1e-4, 1e-6), position_error_deg=20 / 3600, seed=5)
    return calibrate(ses, segs, model), truth


def test_ground_result_as_flight_prior_carries_names_units_covariance_exactly(ground_cal):
    cal, _ = ground_cal
    flight = casep.load_model("platform36")
    prior = ground_prior(cal, flight)
    names = prior["correlation"]["names"]
    assert names == list(flight.names)  # all 36, flight order; the gyro scale (Sg_*) left out
    idx = [cal.names.index(n) for n in names]
    C = cal.result.covariance[np.ix_(idx, idx)]
    sd = np.array([prior[n]["std"] for n in names])
    np.testing.assert_array_equal([prior[n]["mean"] for n in names], cal.result.estimate[idx])
    np.testing.assert_allclose(np.asarray(prior["correlation"]["matrix"]) * np.outer(sd, sd), C, rtol=1e-14,
                               atol=1e-300)
    for n in names:
        assert cal.result.units[cal.names.index(n)] == flight.units[flight.index(n)]
    # the prior as MAP reads it: the same Gaussian (information rows reproduce C^-1)
    from casep.estimators.map import prior_information

    W, _, mu, _ = prior_information(prior, flight.names)
    np.testing.assert_allclose(np.linalg.inv(W.T @ W), C, rtol=1e-8, atol=1e-12 * np.max(np.abs(C)))


def test_separate_with_ground_prior_reports_consistency_and_fuse_too(ground_cal, tmp_path, capsys):
    cal, truth = ground_cal
    flight_model = casep.load_model("platform36")
    t = np.arange(0.0, 120.0, 0.1)
    f = excitation_force(t, duration=120.0)
    D = np.array([truth[n] for n in flight_model.names])
    dv = inject_errors(flight_model, t, f, D) + np.random.default_rng(3).normal(0, 0.01, (t.size, 3))
    flight_csv = tmp_path / "flight.csv"
    casep.write_flight(casep.FlightData(t, f, dv), flight_csv)
    gpath = tmp_path / "ground.json"
    gpath.write_text(json.dumps(cal.to_dict()))
    out, html = tmp_path / "map.json", tmp_path / "map.html"
    assert main(["separate", str(flight_csv), "--method", "map", "--prior", str(gpath), "--json", str(out),
                 "--report", str(html)]) == 0
    text = capsys.readouterr().out
    assert "prior versus flight alone" in text and "overall: chi2" in text
    assert "prior_consistency" in html.read_text()  # in the report's diagnostics table
    pc = json.loads(out.read_text())["diagnostics"]["prior_consistency"]
    assert pc["overall"]["consistent"] and pc["overall"]["dof"] > 10  # same truth: consistent
    # a flight whose Ka0x differs by 20 mg from the ground: flagged
    D_bad = D.copy()
    D_bad[flight_model.index("Ka0x")] += 20.0
    dv_bad = inject_errors(flight_model, t, f, D_bad) + np.random.default_rng(4).normal(0, 0.01, (t.size, 3))
    bad_csv = tmp_path / "bad.csv"
    casep.write_flight(casep.FlightData(t, f, dv_bad), bad_csv)
    # the prior the flight contradicts drives second-order terms to 1e5 x their declared magnitudes: a failed
    # result (exit 1), its JSON still written with the consistency test that explains it
    assert main(["separate", str(bad_csv), "--method", "map", "--prior", str(gpath), "--json", str(out)]) == 1
    assert json.loads(out.read_text())["success"] is False
    pc = json.loads(out.read_text())["diagnostics"]["prior_consistency"]
    assert not pc["overall"]["consistent"] and "Ka0x" in pc["disagree"]
    # the prior conflict said in the failed result's message, naming the coefficient and what to do
    message = json.loads(out.read_text())["message"]
    assert "prior conflict: the flight alone DISAGREES with the prior" in message and "Ka0x" in message
    assert "drop the prior" in message
    # fuse: the ground result with a flight-only result, consistency printed first
    ols = tmp_path / "ols.json"
    assert main(["separate", str(flight_csv), "--json", str(ols)]) == 0
    capsys.readouterr()
    fused = tmp_path / "fused.json"
    assert main(["fuse", str(gpath), str(ols), "--json", str(fused)]) == 0
    text = capsys.readouterr().out
    assert f"ground {gpath} versus flight {ols}" in text and "overall: chi2" in text
    d = json.loads(fused.read_text())
    assert d["model"] == "platform36" and d["names"] == list(flight_model.names)
