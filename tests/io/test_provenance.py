"""Provenance in the JSON, the .mat and the report; the report as an analyst reads it.

On main the report, JSON and .mat did not say which tracking file, frame, site, time alignment,
exclusions or command produced them; the report title named only the telemetry file, printed raw
numbers, stayed green with warnings; the .mat had residuals without their times and no groups.
"""

from __future__ import annotations

import hashlib
import json
import re

import numpy as np
import pytest

from casep.cli import main


@pytest.fixture(scope="module")
def late_pair(tmp_path_factory):
    """Telemetry 20 Hz and tracking 5 Hz, 0.1 m/s noise."""
    from casep.simulation.simulate import simulate_two_rate

    d = simulate_two_rate("paper", seed=3, telemetry_rate=20.0, tracking_rate=5.0)
    folder = tmp_path_factory.mktemp("prov")
    tel, trk = folder / "tel.csv", folder / "trk.csv"
    d.write(tel, trk)
    return tel, trk


def _sha(p) -> str:
    return hashlib.sha256(p.read_bytes()).hexdigest()


def test_provenance_everywhere(late_pair, tmp_path, capsys):
    from scipy.io import loadmat

    tel, trk = late_pair
    js, mat, rep = tmp_path / "r.json", tmp_path / "r.mat", tmp_path / "r.html"
    argv = ["separate", str(tel), "--tracking", str(trk), "--model", "platform36_timeoffset", "--sigma", "0.5",
            "--json", str(js), "--mat", str(mat), "--report", str(rep)]
    assert main(argv) == 0
    assert "given noise sigma 0.5 m/s disagrees" in capsys.readouterr().err  # a warning: the status is not green
    prov = json.loads(js.read_text())["provenance"]
    files = {f["role"]: f for f in prov["inputs"]}
    assert files["telemetry"]["file"] == str(tel) and files["telemetry"]["sha256"] == _sha(tel)
    assert files["tracking"]["file"] == str(trk) and files["tracking"]["sha256"] == _sha(trk)
    assert prov["command_line"].startswith("casep separate ") and str(trk) in prov["command_line"]
    fl = prov["flights"][0]
    assert fl["tracking_frame"] == {"frame": "launch"} and fl["grid"] == "tracking"
    assert abs(fl["time_alignment"]["tau_s"]) < 0.01 and fl["time_alignment"]["applied_s"] == 0.0
    assert "unobserved" in fl["exclusions"]
    assert prov["options"]["model"] == "platform36_timeoffset" and prov["options"]["sigma"] == 0.5
    # .mat: the residuals with their times, the groups, the provenance
    m = loadmat(mat, simplify_cells=True)
    assert m["t_residuals"].shape[0] == m["residuals"].shape[0] > 0
    assert np.all(np.diff(m["t_residuals"]) > 0)
    assert len(m["groups"]) >= 1 and all(isinstance(n, str) for n in np.atleast_1d(m["groups"][0]))
    assert json.loads(m["provenance_json"])["inputs"][1]["sha256"] == _sha(trk)
    assert list(m["input_sha256"]) == [_sha(tel), _sha(trk)]
    # report: both files in the title, the headline, formatted numbers, the status not green, provenance
    text = rep.read_text()
    title = re.search(r"<h1>(.*?)</h1>", text).group(1)
    assert str(tel) in title and str(trk) in title
    assert re.search(r'<p class="warn" id="status">status 1: .*\(\d+ warning\(s\) below\)', text)
    assert re.search(r'id="headline"><b>This flight determines \d+ of 37 coefficients</b>', text)
    assert "<h2>Provenance</h2>" in text and _sha(trk) in text
    settings = re.search(r'<table id="settings">(.*?)</table>', text, re.S).group(1)
    assert not re.search(r"\d\.\d{8,}", settings)  # no raw 16-digit floats
    diag = re.search(r'<table id="diagnostics">(.*?)</table>', text, re.S).group(1)
    assert "[[" not in diag and "['" not in diag  # groups not printed as a Python list


def test_headline_combinations_closed_form():
    """Two coefficients known only through their sum: neither is determined, the sum is (std of the
    combination from the covariance by hand)."""
    from casep.estimators.result import EstimateResult
    from casep.reporting.report import determined

    C = np.array([[1.0, -0.999], [-0.999, 1.0]]) * 4.0  # std 2 each, the sum's variance 4 (2 - 1.998) = 0.008
    res = EstimateResult(method="ols", names=("a", "b"), units=("u", "u"), estimate=np.zeros(2),
                         std=np.sqrt(np.diag(C)), covariance=C, reasons={}, residuals=np.zeros((0, 3)), sigma=1.0,
                         rank=2, status=1, message="", success=True, si_factors=np.ones(2))
    d = determined(res, {"a": 1.0, "b": 1.0})
    assert d["determined"] == [] and d["rest"] == ["a", "b"]
    (c,) = d["combinations"]
    assert c["terms"] == pytest.approx({"a": 1.0, "b": 1.0}) or c["terms"] == pytest.approx({"a": -1.0, "b": -1.0})
    assert c["std"] == pytest.approx(np.sqrt(0.008 / 2), rel=1e-9)  # unit-norm eigenvector (a + b) / sqrt 2


def test_estimates_figure_one_panel_per_instrument(tmp_path):
    """The estimates figure plotted t-statistics labelled "value / scale" on one axis (dt_trk at 104 flattened
    the other 36); now one panel per instrument, in units of the declared magnitude."""
    import casep
    from casep.reporting.plots import instrument_groups

    names = casep.load_model("platform36_timeoffset").names
    g = instrument_groups(names)
    assert list(g) == ["gyro x", "gyro y", "gyro z", "accelerometer x", "accelerometer y", "accelerometer z",
                       "other"]
    assert [names[j] for j in g["other"]] == ["dt_trk"]
    assert [names[j] for j in g["gyro x"]] == ["Kg0x", "Kg1x", "Kg1xy", "Kg1xz", "Kg2x"]
    assert sum(len(v) for v in g.values()) == len(names)
