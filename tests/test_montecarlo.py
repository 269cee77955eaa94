"""Monte Carlo (casep.montecarlo): statistics, batched = per-run, CLI in reduced size."""

from __future__ import annotations

import json

import numpy as np
import pytest

from casep.cli import main
from casep.montecarlo import run_montecarlo


@pytest.mark.montecarlo
def test_ols_efficiency_and_coverage_on_seeded_run():
    res = run_montecarlo("paper", runs=300, methods=["ols"], seed=3, rate=20.0)
    st = res.stats("ols")
    assert 0.93 < np.median(st["efficiency"]) < 1.07
    assert 0.93 < np.median(st["coverage95"]) < 0.97
    assert np.all((st["coverage95"] > 0.88) & (st["coverage95"] < 0.995))
    assert np.all(np.abs(st["bias"]) < 4 * res.crlb_std / np.sqrt(300))


def test_batched_equals_per_run():
    methods = ["ols", "rls", "ridge:1e-5", "pcr", "map"]
    fast = run_montecarlo("paper", runs=4, methods=methods, seed=5, rate=10.0)
    slow = run_montecarlo("paper", runs=4, methods=methods, seed=5, rate=10.0, batched=False, workers=1)
    for m in methods:
        sd = slow.stds[m]
        ok = np.isfinite(sd)
        assert np.max(np.abs(fast.estimates[m] - slow.estimates[m])[ok] / sd[ok]) < 1e-8, m
        np.testing.assert_allclose(fast.stds[m][ok], sd[ok], rtol=1e-8)


def test_per_run_methods_in_processes_match_serial():
    a = run_montecarlo("paper-pitch", runs=3, methods=["rels", "wavelet+ols"], seed=2, rate=10.0, workers=2)
    b = run_montecarlo("paper-pitch", runs=3, methods=["rels", "wavelet+ols"], seed=2, rate=10.0, workers=1)
    for m in ("rels", "wavelet+ols"):
        np.testing.assert_array_equal(a.estimates[m], b.estimates[m])
    assert np.isnan(a.estimates["rels"][:, a.names.index("Kg1xz")]).all()  # zero column on a pitch flight


def test_cli_json_csv_figure(tmp_path, capsys):
    out, csv, fig = tmp_path / "mc.json", tmp_path / "mc.csv", tmp_path / "mc.png"
    assert main(["montecarlo", "--scenario", "paper", "--runs", "5", "--rate", "10", "--methods", "ols,rls,bounded",
                 "--seed", "1", "--workers", "1", "--json", str(out), "--csv", str(csv), "--figure", str(fig)]) == 0
    data = json.loads(out.read_text())
    assert data["scenario"] == "paper" and data["runs"] == 5 and data["seed"] == 1
    rows = data["methods"]["ols"]["coefficients"]
    assert len(rows) == 36 and set(rows[0]) >= {"name", "unit", "true", "bias", "rms", "crlb_std", "efficiency",
                                                   "coverage95"}
    assert rows[0]["efficiency"] == pytest.approx(rows[0]["crlb_std"] / rows[0]["rms"])
    assert csv.read_text().splitlines()[0] == "method,name,unit,true,bias,rms,crlb_std,efficiency,coverage95"
    assert len(csv.read_text().splitlines()) == 1 + 3 * 36
    assert fig.read_bytes()[:4] == b"\x89PNG"
    assert "median efficiency" in capsys.readouterr().out


def test_bad_arguments(capsys):
    with pytest.raises(ValueError, match="unknown method `foo`"):
        run_montecarlo(runs=2, methods=["foo"])
    with pytest.raises(ValueError, match="`runs` must be an int >= 1"):
        run_montecarlo(runs=0)
    assert main(["montecarlo", "--runs", "2", "--methods", "ols,ridge:abc"]) == 2
    assert "ridge:<lambda> needs a number" in capsys.readouterr().err
