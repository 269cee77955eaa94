"""Self-contained HTML report and the CLI's --figures / --report / exit status."""

from __future__ import annotations

import base64
import json
import re
from pathlib import Path

import numpy as np
import pytest

import casep
from casep.cli import main
from casep.reporting.report import write_report

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "data" / "example_flight.csv"


@pytest.fixture(scope="module")
def paper_csv(tmp_path_factory):
    from casep.simulation.simulate import simulate_flight

    sim = simulate_flight("paper", seed=1, rate=20.0)
    p = tmp_path_factory.mktemp("report") / "paper20.csv"
    casep.write_flight(sim.flight, p)
    return p


@pytest.fixture(scope="module")
def paper_ols(paper_csv):
    """The flight of `paper_csv` as read back, platform36 and its OLS result: separated once for the tests
    that report on it."""
    flight = casep.read_flight(paper_csv)
    model = casep.load_model("platform36")
    return flight, model, casep.separate(flight, model, "ols")


def _external_references(text: str) -> list[str]:
    """Anything a browser would fetch: src/href not a data: URI, url(...), @import."""
    refs = re.findall(r'(?:src|href)\s*=\s*"(?!data:)([^"]*)"', text)
    return refs + re.findall(r"url\(|@import|<link|<script", text)


def test_report_is_self_contained_with_table_and_images(tmp_path):
    flight = casep.read_flight(EXAMPLE)
    res = casep.separate(flight, "platform36", "rls")
    path = write_report(res, tmp_path / "r.html", flight=flight, warnings=["a <suspicious> thing"], source="x.csv")
    text = path.read_text(encoding="utf-8")
    assert text.startswith("<!DOCTYPE html>") and text.rstrip().endswith("</html>")
    assert '<table id="coefficients">' in text
    assert all(f"<td>{n}</td>" in text for n in res.names)
    assert f"{res.estimate[0]:.6g}" in text
    images = re.findall(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"', text)
    assert len(images) == 3  # residuals, estimates, history
    assert all(base64.b64decode(b)[:8] == b"\x89PNG\r\n\x1a\n" for b in images)
    assert _external_references(text) == []
    assert "a &lt;suspicious&gt; thing" in text  # escaped
    assert "<th>p0</th>" in text and "<th>forgetting</th>" in text  # settings table
    assert f"status {res.status}: {res.message}" in text
    assert list(tmp_path.iterdir()) == [path]  # temporary figures removed


def test_cli_figures_and_report(tmp_path, capsys):
    figs, rep, out = tmp_path / "new" / "figs", tmp_path / "r.html", tmp_path / "r.json"
    assert main(["separate", str(EXAMPLE), "--method", "rels", "--figures", str(figs), "--report", str(rep),
                 "--json", str(out)]) == 0
    assert sorted(p.name for p in figs.iterdir()) == ["estimates.png", "history.png", "residuals.png"]
    assert all(p.stat().st_size > 1000 for p in figs.iterdir())
    text = rep.read_text(encoding="utf-8")
    assert text.count("data:image/png;base64,") == 3 and _external_references(text) == []
    o = capsys.readouterr().out
    assert f"report written to {rep}" in o and "figures:" in o


def test_cli_report_folder_missing_exit_2_nothing_computed(tmp_path, capsys):
    out = tmp_path / "r.json"
    assert main(["separate", str(EXAMPLE), "--json", str(out), "--report", str(tmp_path / "no" / "r.html")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("casep: error: --report") and err.count("\n") == 1
    assert not out.exists()


def test_cli_wound_up_rls_exit_1_json_says_failed(paper_csv, tmp_path, capsys):
    # Before: estimates 1e16, residual RMS 1e11 m/s, "success": true and exit 0.
    out = tmp_path / "r.json"
    assert main(["separate", str(paper_csv), "--method", "rls", "--forgetting", "0.9", "--json", str(out)]) == 1
    data = json.loads(out.read_text())
    assert data["success"] is False and data["status"] == -3
    assert all(np.isfinite(c["estimate"]) for c in data["coefficients"])
    cap = capsys.readouterr()
    assert "does not fit the data" in cap.out
    assert cap.err.startswith("casep: result not successful: failed: rls residual RMS")
    assert main(["separate", str(paper_csv), "--method", "rls", "--json", str(out)]) == 0  # lambda = 1 unchanged
    assert json.loads(out.read_text())["success"] is True


def test_report_has_the_impact_miss_when_the_flight_has_its_state(paper_ols, tmp_path):
    """A simulated flight (r_*, v_* columns): the report shows the predicted miss and its std as
    casep.impact_analysis computes them, and the two impact figures; a flight without them says why."""
    flight, _, res = paper_ols
    text = write_report(res, tmp_path / "r.html", flight=flight).read_text(encoding="utf-8")
    ia = casep.impact_analysis(flight, res)
    assert "<h2>Impact miss</h2>" in text
    assert f"<td>predicted (linear)</td><td>{ia.miss[0]:.1f}</td><td>{ia.std[0]:.1f}</td>" in text
    assert text.count("data:image/png;base64,") == 4  # residuals, estimates, miss budget, ellipse
    bare = casep.read_flight(EXAMPLE)
    text = write_report(casep.separate(bare, "platform36", "ols"), tmp_path / "b.html", flight=bare).read_text()
    assert "No impact miss: the flight has no r_x" in text


def test_report_shows_the_impact_it_is_given_and_computes_nothing_again(paper_ols, tmp_path, monkeypatch):
    """The caller computes the impact (and has the model) once: the report neither integrates S_V again nor
    reloads the model; impact=None leaves the section out; a wrong type is refused."""
    import casep.impact.miss
    import casep.model.loader
    from casep.reporting.report import impact_or_reason

    flight, model, res = paper_ols
    ia = impact_or_reason(res, flight, model)
    assert isinstance(ia, casep.ImpactAnalysis)

    def refuse(*args, **kwargs):
        raise AssertionError("computed again")

    monkeypatch.setattr(casep.impact.miss, "impact_analysis", refuse)
    monkeypatch.setattr(casep.model.loader, "load_model", refuse)
    text = write_report(res, tmp_path / "r.html", flight=flight, impact=ia, model=model).read_text(encoding="utf-8")
    assert f"<td>predicted (linear)</td><td>{ia.miss[0]:.1f}</td><td>{ia.std[0]:.1f}</td>" in text
    assert 'id="headline"' in text  # the declared magnitudes of the model given
    assert text.count("data:image/png;base64,") == 4
    text = write_report(res, tmp_path / "n.html", flight=flight, impact=None, model=model).read_text(encoding="utf-8")
    assert "<h2>Impact miss</h2>" not in text and text.count("data:image/png;base64,") == 2
    text = write_report(res, tmp_path / "s.html", impact="No impact miss: why.", model=model).read_text()
    assert "<p>No impact miss: why.</p>" in text
    with pytest.raises(TypeError, match="`impact` must be an ImpactAnalysis"):
        write_report(res, tmp_path / "x.html", impact=1.0, model=model)
    assert not (tmp_path / "x.html").exists()
    assert impact_or_reason(res, None) is None
