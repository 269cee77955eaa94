"""The demo (casep.demo) in reduced size: Table 1, figures, report."""

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
