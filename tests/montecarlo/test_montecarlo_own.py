"""Monte Carlo on one's own trajectory and truth; dispersion draws kept per run; resumed tasks counted."""

from __future__ import annotations

import json

import numpy as np
import pytest

from casep.cli import main


@pytest.fixture(scope="module")
def own(tmp_path_factory):
    """A flight file (paper, 5 Hz) and its truth sidecar, as casep simulate writes them."""
    from casep.simulation.simulate import simulate_flight, write_simulation

    folder = tmp_path_factory.mktemp("own")
    flight, side = write_simulation(simulate_flight("paper", seed=4, rate=5.0), folder / "mine.csv")
    return flight, side


def test_montecarlo_on_own_trajectory_matches_its_crlb(own):
    """The CRLB of the runs is that of the file's own S_V with the truth file's noise (by hand), and OLS is
    efficient on it (RMS error / CRLB std near 1 over 40 runs: mean over 36 coefficients within 15 %)."""
    import casep
    from casep.checks.diagnostics import crlb_covariance
    from casep.montecarlo import run_montecarlo

    flight, side = own
    truth = json.loads(side.read_text())
    res = run_montecarlo("paper", runs=40, methods=["ols"], workers=1, progress=False, flight=flight, truth=truth,
                         noise="white")
    fl = casep.read_flight(flight)
    model = casep.load_model(truth["model"])
    S = casep.build_sv(model, fl.t, fl.f)
    crlb = np.sqrt(np.diag(crlb_covariance(S, truth["noise"]["sigma"])))
    np.testing.assert_allclose(res.crlb_std, crlb, rtol=1e-9)
    np.testing.assert_allclose(res.truth, [truth["coefficients"][n] for n in model.names])
    assert res.scenario == "flight mine.csv"
    ratio = 1.0 / res.stats("ols")["efficiency"]  # RMS / CRLB; chi-square(40)/40 per coefficient
    assert 0.85 < float(np.mean(ratio)) < 1.15, ratio


def test_cli_montecarlo_own_trajectory_resumes_and_says_so(own, tmp_path, capsys):
    flight, side = own
    out = tmp_path / "mc"
    argv = ["montecarlo", "--noise", "white", "--flight", str(flight), "--truth", str(side), "--runs", "8",
            "--methods", "ols",
            "--workers", "1", "--no-progress", "--out", str(out)]
    assert main(argv) == 0
    first = capsys.readouterr().out
    assert "scenario flight mine.csv" in first and "none resumed" in first
    assert main(argv) == 0
    m = __import__("re").search(r"resumed (\d+) of (\d+) tasks", capsys.readouterr().out)
    assert m and m.group(1) == m.group(2)
    assert main(["montecarlo", "--noise", "white", "--flight", str(flight), "--runs", "2"]) == 2
    assert "--flight and --truth go together" in capsys.readouterr().err


def test_dispersion_draws_kept_per_run(tmp_path):
    """runs.parquet holds each run's dispersion draws (main: only the estimates); read back on resume."""
    import pyarrow.parquet as pq

    from casep.montecarlo import run_montecarlo

    disp = {"thrust_scale": {"dist": "normal", "mean": 1.0, "std": 0.01},
            "launch_azimuth_deg": {"dist": "uniform", "low": -1.0, "high": 1.0}}
    kw = dict(runs=3, methods=["ols"], rate=2.0, workers=1, progress=False, dispersions=disp, out=tmp_path / "mc")
    res = run_montecarlo("paper", **kw, noise="white")
    tab = pq.read_table(tmp_path / "mc" / "runs.parquet").to_pandas()
    per_run = tab.groupby("run")[["draw_thrust_scale", "draw_launch_azimuth_deg"]].nunique()
    assert (per_run == 1).all().all()  # one draw per run, on each of its rows
    first = tab.groupby("run")["draw_thrust_scale"].first().to_numpy()
    np.testing.assert_array_equal(first, res.draws["thrust_scale"])
    assert len(set(first)) == 3 and np.all(np.abs(first - 1.0) < 0.06)
    again = run_montecarlo("paper", **kw, noise="white")
    assert again.resumed == again.tasks > 0
    np.testing.assert_array_equal(again.draws["launch_azimuth_deg"], res.draws["launch_azimuth_deg"])


def test_montecarlo_on_own_strapdown_flight_reads_its_signal_columns(tmp_path):
    """A strapdown flight file (q_*, fb_*, w_*, no f_*) runs: S_V is built from its own signal columns (the CRLB
    of the runs is that of casep.build_sv on the file's columns, as casep diagnose and separate report it), and
    the summary names the terms the flight cannot determine (an axial-thrust boost: 12 of strapdown33's, exactly
    dependent on partners it excites; 12 more exactly dependent ones are determined in practice, reported as
    separate reports them) and pools RMS z and coverage over the rest."""
    import casep
    from casep.montecarlo import run_montecarlo
    from casep.simulation.simulate import simulate_flight, write_simulation

    flight, side = write_simulation(simulate_flight("strapdown-boost", seed=2, rate=2.0), tmp_path / "sd.csv")
    truth = json.loads(side.read_text())
    truth.pop("noise")  # the flight's own least-squares residual std: white
    res = run_montecarlo("paper", runs=3, methods=["ols"], workers=1, progress=False, flight=flight, truth=truth,
                         noise="white")
    fl = casep.read_flight(flight)
    model = casep.load_model(truth["model"])
    S = casep.build_sv(model, fl.t, fl.f, signals=fl.signals)
    strict = np.isfinite(np.diag(casep.checks.crlb_covariance(S, 1.0)))
    sd = casep.checks.diagnose(S, sigma=1.0, names=model.names, units=model.units, scales=model.scales).crlb_std
    assert strict.sum() == 9 and np.array_equal(res.determined, np.isfinite(sd)) and int(res.determined.sum()) == 21
    ok = res.determined
    np.testing.assert_allclose(res.crlb_std[ok] / sd[ok], res.crlb_std[ok][0] / sd[ok][0], rtol=1e-6)  # one sigma
    # every run's OLS estimate exists exactly where the bound is finite (separate's rule, one function)
    assert np.array_equal(np.isfinite(res.estimates["ols"]).all(axis=0), ok)
    text, d = res.text(), res.to_dict()
    assert "determined 21 of 33 coefficients" in text and "unidentifiable 12" in text and "RMS z" in text
    assert len(d["unidentifiable"]) == 12 and d["methods"]["ols"]["determined"]["count"] == 63


def test_montecarlo_says_which_determined_coefficients_separate_calls_not_determined(tmp_path):
    """The summary's 'determined' is a finite CRLB std; the coefficients whose bound is at or above their declared
    magnitudes (casep separate's 'not determined', the same function) are named as such, in the text and JSON."""
    from casep.estimators.registry import not_determined
    from casep.montecarlo import run_montecarlo

    res = run_montecarlo("paper", runs=2, methods=["ols"], workers=1, progress=False, noise="white")
    nd = not_determined(res.names, res.crlb_std, res.magnitudes)
    assert res.magnitudes and 0 < len(nd) < int(res.determined.sum())
    d = res.to_dict()
    assert d["not_determined"] == [res.names[j] for j in nd]
    assert f"of these, {len(nd)} have a CRLB std at or above their declared magnitudes" in res.text()
