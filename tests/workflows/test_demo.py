"""The demo (casep.workflows.demo) in reduced size: Table 1, figures, report."""

from __future__ import annotations

import numpy as np

from casep.cli import main
from casep.workflows.demo import DEMO_METHODS, run_demo


def test_demo_reduced(tmp_path, capsys, monkeypatch):
    # with a spare core the command starts the figure worker before it imports the demo, and hands it over (the
    # figures drawn in this process: tests/reporting/test_demo_figures.py)
    import casep.reporting.demo_figures as figures

    made = []
    init = figures.FigureJobs.__init__

    def record(self, parallel):
        made.append(parallel)
        init(self, parallel)

    monkeypatch.setattr(figures, "spare_core", lambda: True)
    monkeypatch.setattr(figures.FigureJobs, "__init__", record)
    assert main(["demo", "--out", str(tmp_path), "--rate", "10"]) == 0
    assert made == [True]  # one worker, the command's
    text = capsys.readouterr().out
    header = next(line for line in text.splitlines() if line.startswith("coefficient"))
    for label, _, _ in DEMO_METHODS:
        assert label in header
    assert "CRLB std" in header and "Ka2zy" in text
    for name in ("fig3_residuals_ls.png", "fig4_residuals_wavelet_rels.png", "coefficient_errors.png",
                 "rels_convergence.png", "singular_values.png"):
        assert (tmp_path / name).read_bytes()[:4] == b"\x89PNG"
    report = (tmp_path / "report.md").read_text()
    assert "## Table 1" in report and "![fig3_residuals_ls](fig3_residuals_ls.png)" in report
    assert "## Impact miss" in report and "LS   predicts downrange" in report
    assert (tmp_path / "miss_budget.png").read_bytes()[:4] == b"\x89PNG" and "instrument-error miss at impact" in text


def test_demo_results_are_consistent():
    res = run_demo(None, rate=10.0, seed=2)
    assert res.files == ()
    r = res.results
    # wavelet+RELS residuals are small only because they are w.r.t. the de-noised dv.
    assert max(r["wavelet+RELS"].residual_rms.values()) < 0.5 * min(r["LS"].residual_rms.values())
    assert r["wavelet+RELS"].denoise is not None and 0.08 < r["wavelet+RELS"].sigma < 0.12
    # bounded stays inside its documented box; MAP is pulled towards its prior.
    from casep.simulation.paper import demo_bounds

    box = demo_bounds(res.sim.model.names)
    est = r["bounded"].estimate
    for j, n in enumerate(res.sim.model.names):
        assert box[n][0] - 1e-9 <= est[j] <= box[n][1] + 1e-9
    assert np.all(np.isfinite(res.diagnostics.crlb_std))


def test_demo_impact_miss_is_known_although_the_coefficients_are_not():
    """The demo's LS and MAP predictions of the instrument-error miss: within 4 std of the true miss,
    std a few tens of metres on a ~3.5 km miss, and the demo's shortcut for the burnout sensitivities
    (trapezoid of the kept S_V) equals casep.impact_analysis integrating them itself."""
    import casep

    res = run_demo(None, rate=10.0, seed=3)
    true = res.true_miss
    assert 3000 < true[0] < 4000 and -2000 < true[1] < -1000  # the paper truth's miss
    for label in ("LS", "MAP"):
        ia = res.impact[label]
        sd = np.sqrt(np.diag(ia.cov))
        assert np.all(sd < 50) and np.all(np.abs(ia.miss - true) < 4 * sd)
    ref = casep.impact_analysis(res.sim.flight, res.results["LS"], res.sim.model)
    np.testing.assert_allclose(res.impact["LS"].miss, ref.miss, rtol=1e-9)
    np.testing.assert_allclose(res.impact["LS"].cov, ref.cov, rtol=1e-9)


def test_demo_result_protocol(tmp_path):
    """DemoResult follows casep.results.Result: to_dict is JSON, text is what `casep demo` prints."""
    import json

    from casep.results import Result
    from casep.workflows.demo import summary_lines

    res = run_demo(tmp_path, rate=10.0, seed=4, parallel=True)  # the figures by a worker process
    assert isinstance(res, Result)
    assert all(p.read_bytes()[:4] == b"\x89PNG" for p in res.files if p.suffix == ".png") and len(res.files) == 8
    d = json.loads(json.dumps(res.to_dict(), allow_nan=False))
    assert d["seed"] == 4 and d["n_samples"] == res.sim.flight.n_samples
    assert set(d["results"]) == {label for label, _, _ in DEMO_METHODS}
    np.testing.assert_allclose(d["results"]["LS"]["estimates"], res.results["LS"].estimate)
    assert d["truth"]["Ka0x"] == res.sim.truth[res.sim.model.names.index("Ka0x")]
    assert sorted(d["impact"]) == ["LS", "MAP"] and len(d["true_miss"]) == 2
    text = res.text()
    assert res.table in text and f"report and figures in {tmp_path}/" in text
    for line in summary_lines(res.sim, res.results, res.diagnostics.crlb_std):
        assert line in text
    assert "LS   predicts downrange" in text


def test_demo_shares_rows_and_matches_separate():
    """The demo fits the noise model once for its methods; each result is the one separate() gives."""
    from casep.regression.problem import Problem
    from casep.simulation.paper import demo_bounds, demo_prior
    from casep.workflows.separate import separate

    res = run_demo(None, rate=10.0, seed=5)
    model = res.sim.model
    problem = Problem.from_flight(res.sim.flight, model, keep_sv=True)
    extra = {"bounded": {"bounds": demo_bounds(model.names)}, "map": {"prior": demo_prior(model.names)}}
    import warnings

    from casep.exceptions import IllConditionedWarning

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IllConditionedWarning)
        for label, method, opts in DEMO_METHODS:
            ref = separate(problem, model, method, **opts, **extra.get(method, {}))
            got = res.results[label]
            np.testing.assert_array_equal(got.estimate, ref.estimate)
            np.testing.assert_array_equal(got.std, ref.std)
            np.testing.assert_array_equal(got.residuals, ref.residuals)
            assert got.settings == ref.settings and got.status == ref.status


def test_demo_judges_biased_methods_by_what_the_data_know():
    """On the full-rate paper flight ridge moves Ka2y, which the flight cannot see, by more than 5 of its own
    std (its std omit the shrinkage bias): judge_setup judges a regularised method with its Cramer-Rao std
(the least-squares std of the same rows) where its own are smaller, and does not warn.
    Its error against the truth is within 2 least-squares std. A result beyond 100 x a declared magnitude
    by those std still warns."""
    import dataclasses
    import warnings

    import pytest

    from casep.exceptions import MagnitudeWarning
    from casep.workflows.separate import judge_setup

    with warnings.catch_warnings():
        warnings.simplefilter("error", MagnitudeWarning)
        res = run_demo(None, seed=1)
    model = res.sim.model
    j = model.names.index("Ka2y")
    ridge, ls = res.results["ridge"], res.results["LS"]
    err = abs(ridge.estimate[j] - res.sim.truth[j])
    assert abs(ridge.estimate[j]) - 5 * ridge.std[j] >= 100 * model.scales["Ka2y"]  # what the plain check flags
    assert err > 5 * ridge.std[j] and err < 2 * ls.std[j]
    assert "magnitudes" not in ridge.diagnostics
    # A real set-up mistake: Ka0x (well determined) at 1e4 x its declared magnitude, std as determined.
    k = model.names.index("Ka0x")
    wrong = dataclasses.replace(ridge, estimate=np.where(np.arange(len(model.names)) == k,
                                                         1e4 * model.scales["Ka0x"], ridge.estimate))
    with pytest.warns(MagnitudeWarning, match="Ka0x"):
        judged = judge_setup(wrong, None, model, noise_free=False)
    np.testing.assert_array_equal(judged.std, ridge.std)  # the result keeps its own std
    assert judged.diagnostics["magnitudes"][0]["name"] == "Ka0x"
