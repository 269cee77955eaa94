"""Monte Carlo on Dask: workers, dispersions, truth from a prior, Parquet output, resume."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import casep
from casep.cli import main
from casep.montecarlo import run_montecarlo
from casep.simulation.paper import demo_prior

DISP = {"thrust_scale": {"dist": "normal", "mean": 1.0, "std": 0.01},
        "launch_azimuth_deg": {"dist": "uniform", "low": -2.0, "high": 2.0},
        "stage2_isp_scale": {"dist": "normal", "mean": 1.0, "std": 0.005}}


def _names():
    return casep.load_model("platform36").names


def _no_seconds(d: dict) -> dict:
    d = json.loads(json.dumps(d))
    for m in d["methods"].values():
        m.pop("seconds", None)
    return d


@pytest.fixture(scope="module")
def two_workers():
    """A running 2-worker Dask cluster (one thread each), reached by address like --scheduler."""
    import logging

    from distributed import LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0",
                      silence_logs=logging.CRITICAL) as cluster:
        yield cluster.scheduler_address


def test_same_seed_same_numbers_in_process_and_on_1_and_2_dask_workers(two_workers):
    """Dispersed trajectories, truths drawn from a prior, batched and per-run methods: the
    numbers depend on the seed only (not on the workers or the order tasks finish in)."""
    kw = dict(runs=3, methods=["ols", "map", "bounded"], seed=7, rate=1.0, dispersions=DISP,
              truth_prior=demo_prior(_names()), progress=False)
    here = run_montecarlo("paper", workers=1, dask=False, **kw, noise="white")
    one = run_montecarlo("paper", workers=1, dask=True, **kw, noise="white")  # its own LocalCluster of 1 worker
    two = run_montecarlo("paper", workers=2, dask=True, **kw, noise="white")  # its own LocalCluster of 2 workers
    remote = run_montecarlo("paper", scheduler=two_workers, **kw, noise="white")  # a running cluster, by address
    for r in (one, two, remote):
        for m in kw["methods"]:
            np.testing.assert_array_equal(r.estimates[m], here.estimates[m])
            np.testing.assert_array_equal(r.stds[m], here.stds[m])
        np.testing.assert_array_equal(r.truths, here.truths)
        assert _no_seconds(r.to_dict()) == _no_seconds(here.to_dict())
    assert here.to_dict()["truth_from_prior"] is True and here.to_dict()["dispersions"] == list(DISP)
    assert len({tuple(t) for t in here.truths}) == 3  # each run its own truth
    # each run its own trajectory: the CRLB differs from the nominal one
    nominal = run_montecarlo("paper", runs=2, methods=["ols"], seed=7, rate=1.0, workers=1, noise="white")
    assert not np.allclose(here.crlb_std, nominal.crlb_std, rtol=1e-6)


def test_nominal_per_run_methods_same_on_dask_and_in_process(two_workers):
    kw = dict(runs=5, methods=["ols", "rels", "gls"], seed=2, rate=2.0, progress=False)
    here = run_montecarlo("paper-ar1", workers=1, **kw, noise="white")
    two = run_montecarlo("paper-ar1", scheduler=two_workers, **kw, noise="white")
    for m in kw["methods"]:
        np.testing.assert_array_equal(two.estimates[m], here.estimates[m])


@pytest.mark.montecarlo
def test_map_bayesian_coverage_with_truth_drawn_from_its_prior():
    """Truth ~ prior, MAP with that prior and the known sigma: error / posterior std is N(0, 1)
    per coefficient, so RMS(error)/std ~ 1 and coverage ~ 0.95 (2000 seeded runs, batched MAP
    at 1 Hz: the 4-sigma band of a 2000-run coverage is +-0.02, of the RMS ratio +-0.06)."""
    prior = demo_prior(_names())
    runs = 2000
    res = run_montecarlo("paper", runs=runs, methods=["map"], seed=11, rate=1.0, workers=1, truth_prior=prior,
                         progress=False, noise="white")
    err = res.estimates["map"] - res.truths
    sd = res.stds["map"]
    ratio = np.sqrt(np.mean(err**2, axis=0)) / np.sqrt(np.mean(sd**2, axis=0))
    cov = res.stats("map")["coverage95"]
    assert np.all((ratio > 0.9) & (ratio < 1.1)), ratio
    assert np.all((cov > 0.93) & (cov < 0.97)), cov
    assert abs(np.mean(cov) - 0.95) < 0.005  # pooled over the 36 coefficients
    # against the scenario's one fixed truth the same MAP's coverage is not the Bayesian 0.95
    fixed = run_montecarlo("paper", runs=200, methods=["map"], seed=11, rate=1.0, workers=1, prior=prior,
                           progress=False, noise="white")
    assert np.max(np.abs(fixed.stats("map")["coverage95"] - 0.95)) > 0.03


def _cli(out: Path, *extra: str) -> list[str]:
    return [sys.executable, "-m", "casep", "montecarlo", "--scenario", "paper", "--rate", "1", "--runs", "12",
            "--methods", "ols,map", "--seed", "5", "--workers", "1", "--no-progress", "--out", str(out), "--noise",
            "white", *extra]


def test_resume_after_a_killed_campaign_gives_the_uninterrupted_result(tmp_path, capsys):
    disp = tmp_path / "disp.json"
    disp.write_text(json.dumps(DISP))
    out = tmp_path / "campaign"
    parts = out / "runs.parquet"
    proc = subprocess.Popen(_cli(out, "--dispersions", str(disp)), stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and not (parts.is_dir() and list(parts.glob("part-*.parquet"))):
            assert proc.poll() is None, proc.communicate()[1]
            time.sleep(0.02)
        os.kill(proc.pid, signal.SIGKILL)  # mid-campaign, no clean-up
    finally:
        proc.communicate()
    first = sorted(parts.glob("part-*.parquet"))
    assert 1 <= len(first) < 12, "the campaign was not interrupted mid-way"
    assert not (out / "summary.json").exists()
    stamps = {p.name: p.stat().st_mtime_ns for p in first}
    done = subprocess.run(_cli(out, "--dispersions", str(disp)), capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert {p.name: p.stat().st_mtime_ns for p in first} == stamps  # finished tasks not rerun
    assert len(list(parts.glob("part-*.parquet"))) == 12
    resumed = json.loads((out / "summary.json").read_text())
    whole = run_montecarlo("paper", runs=12, methods=["ols", "map"], seed=5, rate=1.0, workers=1,
                           dispersions=DISP, progress=False, noise="white")
    assert _no_seconds(resumed) == _no_seconds(whole.to_dict())
    import pandas as pd

    df = pd.read_parquet(parts)
    assert list(df.columns[:5]) == ["run", "method", "coefficient", "estimate", "std"]
    assert len(df) == 12 * 2 * 36 and sorted(df["run"].unique()) == list(range(12))
    ols = df[df["method"] == "ols"].sort_values(["run"], kind="stable")
    np.testing.assert_array_equal(ols["estimate"].to_numpy().reshape(12, 36), whole.estimates["ols"])
    # other settings in the same folder: refused, naming the difference (the CLI exits 2 on it)
    argv = _cli(out, "--dispersions", str(disp))[3:]
    argv[argv.index("--seed") + 1] = "6"  # the seed changed (an option given twice is an error of its own)
    assert main(argv) == 2
    assert "other settings (seed: 5 there, 6 now)" in capsys.readouterr().err


@pytest.mark.parametrize("content, key", [
    ({"thrust_scal": {"dist": "normal", "mean": 1, "std": 0.01}}, "thrust_scal"),
    ({"thrust_scale": {"dist": "gauss", "mean": 1, "std": 0.01}}, "thrust_scale"),
    ({"isp_scale": {"dist": "normal", "mean": 1, "std": -0.01}}, "isp_scale"),
    ({"launch_azimuth_deg": {"dist": "uniform", "low": 2, "high": -2}}, "launch_azimuth_deg"),
    ({"launch_azimuth_deg": {"dist": "uniform", "low": "a", "high": 2}}, "launch_azimuth_deg"),
    ({"stage3_thrust_scale": {"dist": "normal", "mean": 1, "std": 0.01}}, "stage3_thrust_scale"),
    ({"drag_area_scale": {"dist": "normal", "mean": 1, "std": 0.3}}, "drag_area_scale"),
    ({"kick_rate_scale": {"dist": "normal", "mean": 1, "sd": 0.1}}, "kick_rate_scale"),
])
def test_bad_dispersions_file_exits_2_naming_file_and_key(tmp_path, capsys, content, key):
    f = tmp_path / "disp.json"
    f.write_text(json.dumps(content))
    assert main(["montecarlo", "--noise", "white", "--runs", "2", "--rate", "1", "--methods", "ols", "--workers", "1",
                 "--dispersions", str(f)]) == 2
    err = capsys.readouterr().err
    assert str(f) in err and f"`{key}`" in err and err.startswith("casep: error: --dispersions")


def test_bad_dispersions_and_truth_prior_files(tmp_path, capsys):
    f = tmp_path / "disp.json"
    f.write_text("{not json")
    assert main(["montecarlo", "--noise", "white", "--runs", "2", "--methods", "ols", "--dispersions", str(f)]) == 2
    assert f"--dispersions {f}: not valid JSON" in capsys.readouterr().err
    f.write_text("{}")
    assert main(["montecarlo", "--noise", "white", "--runs", "2", "--methods", "ols", "--dispersions", str(f)]) == 2
    assert "no parameters" in capsys.readouterr().err
    p = tmp_path / "prior.json"
    p.write_text(json.dumps({"Kg0q": {"mean": 0, "std": 1}}))
    assert main(["montecarlo", "--noise", "white", "--runs", "2", "--methods", "map", "--truth-from-prior",
                 str(p)]) == 2
    err = capsys.readouterr().err
    assert f"--truth-from-prior {p}" in err and "Kg0q" in err


def test_dispersed_vehicle_follows_the_draw():
    from casep.simulation.dispersions import disperse_vehicle, parse_dispersions
    from casep.simulation.scenarios import get_scenario

    v = get_scenario("paper-pitch").vehicle
    assert v.yaw is None
    d = disperse_vehicle(v, {"thrust_scale": 1.01, "stage2_thrust_scale": 1.02, "launch_azimuth_deg": 1.5,
                             "liftoff_mass_scale": 0.99})
    assert d.stages[0].thrust == pytest.approx(1.01 * v.stages[0].thrust)
    assert d.stages[1].thrust == pytest.approx(1.01 * 1.02 * v.stages[1].thrust)
    assert d.yaw.offset == 1.5 and d.yaw.amplitude == 0.0
    assert d.liftoff_mass == pytest.approx(0.99 * v.liftoff_mass)
    assert list(parse_dispersions({"stage1_isp_scale": {"dist": "uniform", "low": 0.99, "high": 1.01},
                                   "thrust_scale": {"dist": "normal", "mean": 1, "std": 0}}, 2)) == \
        ["thrust_scale", "stage1_isp_scale"]  # canonical order, whatever the file's


def test_out_nominal_stages_resume_from_missing_parts(tmp_path):
    """Without dispersions (a batched stage, then a per-run stage): parts removed are rerun, the
    others read back; the summary and runs.parquet equal the first run's; other methods refused."""
    import pandas as pd

    kw = dict(runs=10, methods=["ols", "map", "bounded"], seed=4, rate=2.0, workers=1, progress=False)
    first = run_montecarlo("paper", out=tmp_path, **kw, noise="white")
    parts = sorted((tmp_path / "runs.parquet").glob("part-*.parquet"))
    assert len(parts) == 20  # 10 tasks of the batched stage, 10 of bounded
    before = pd.read_parquet(tmp_path / "runs.parquet")
    for p in parts[3:15:2]:
        p.unlink()
    again = run_montecarlo("paper", out=tmp_path, **kw, noise="white")
    assert _no_seconds(again.to_dict()) == _no_seconds(first.to_dict())
    assert json.loads((tmp_path / "summary.json").read_text()) == json.loads(json.dumps(again.to_dict()))
    after = pd.read_parquet(tmp_path / "runs.parquet")
    pd.testing.assert_frame_equal(after, before)
    st = json.loads((tmp_path / "state.json").read_text())["finished_tasks"]
    assert sorted(st) == [p.name for p in parts]
    with pytest.raises(ValueError, match=r"other settings \(methods: \["):
        run_montecarlo("paper", out=tmp_path, **{**kw, "methods": ["ols"]}, noise="white")


def test_a_draw_the_vehicle_cannot_fly_is_exit_2_naming_the_run_and_values(tmp_path, capsys):
    """Fresh-eyes review: isp_scale 0.85 burns stage 2's propellant before its burnout (the integration
    used to fail with a traceback, or crawl for minutes at 0.7). Now the vehicle is refused before
    integrating, and the campaign stops with exit 2 naming the run and the drawn values."""
    from casep.simulation.dispersions import disperse_vehicle
    from casep.simulation.scenarios import get_scenario
    from casep.simulation.trajectory import simulate_boost

    with pytest.raises(ValueError, match=r"stage 2 burns \d+ kg of propellant but carries \d+ kg"):
        simulate_boost(disperse_vehicle(get_scenario("paper").vehicle, {"isp_scale": 0.85}), 1.0)
    simulate_boost(disperse_vehicle(get_scenario("paper").vehicle, {"isp_scale": 0.9}), 1.0)  # flyable
    f = tmp_path / "disp.json"
    f.write_text(json.dumps({"isp_scale": {"dist": "uniform", "low": 0.84, "high": 0.85}}))
    assert main(["montecarlo", "--noise", "white", "--runs", "2", "--rate", "1", "--methods", "ols", "--workers", "1",
                 "--dispersions", str(f)]) == 2
    err = capsys.readouterr().err
    assert "run 0: the dispersed vehicle (isp_scale 0.84" in err and "cannot be flown" in err


def test_settings_difference_names_the_innermost_key():
    from casep.montecarlo.store import settings_diff as _settings_diff

    old = {"seed": 1, "dispersions": {"launch_azimuth_deg": {"dist": "uniform", "low": -2, "high": 2}}}
    new = {"seed": 1, "dispersions": {"launch_azimuth_deg": {"dist": "uniform", "low": -2, "high": 3}}}
    assert _settings_diff(old, new) == "dispersions.launch_azimuth_deg.high: 2 there, 3 now"
    assert _settings_diff({"seed": 5}, {"seed": 6}) == "seed: 5 there, 6 now"


def test_summary_records_the_rate():
    """Fresh-eyes review: the summary JSON says at which rate the flights were simulated."""
    from casep.montecarlo import run_montecarlo

    res = run_montecarlo("paper", runs=2, methods=["ols"], seed=1, rate=2.0, noise="white")
    assert res.to_dict()["rate_hz"] == 2.0
