"""The demo (casep.workflows.demo) in reduced size: Table 1, figures, report."""

from __future__ import annotations

import numpy as np

from casep.cli import main
from casep.workflows.demo import DEMO_METHODS, run_demo


def test_demo_reduced(tmp_path, capsys):
    assert main(["demo", "--out", str(tmp_path), "--rate", "10"]) == 0
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
