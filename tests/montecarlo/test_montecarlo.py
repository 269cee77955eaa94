"""Monte Carlo (casep.montecarlo): statistics, batched = per-run, CLI in reduced size."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

import casep
from casep.cli import main
from casep.montecarlo import run_montecarlo


@pytest.mark.montecarlo
def test_ols_efficiency_and_coverage_on_seeded_run():
    res = run_montecarlo("paper", runs=300, methods=["ols"], seed=3, rate=20.0, noise="white")
    st = res.stats("ols")
    assert 0.93 < np.median(st["efficiency"]) < 1.07
    assert 0.93 < np.median(st["coverage95"]) < 0.97
    assert np.all((st["coverage95"] > 0.88) & (st["coverage95"] < 0.995))
    assert np.all(np.abs(st["bias"]) < 4 * res.crlb_std / np.sqrt(300))


def test_batched_equals_per_run():
    methods = ["ols", "rls", "ridge:1e-5", "pcr", "map"]
    fast = run_montecarlo("paper", runs=4, methods=methods, seed=5, rate=10.0, noise="white")
    slow = run_montecarlo("paper", runs=4, methods=methods, seed=5, rate=10.0, batched=False, workers=1, noise="white")
    for m in methods:
        sd = slow.stds[m]
        ok = np.isfinite(sd)
        assert np.max(np.abs(fast.estimates[m] - slow.estimates[m])[ok] / sd[ok]) < 1e-8, m
        np.testing.assert_allclose(fast.stds[m][ok], sd[ok], rtol=1e-8)


def test_per_run_methods_in_processes_match_serial():
    a = run_montecarlo("paper-pitch", runs=3, methods=["rels", "wavelet+ols"], seed=2, rate=10.0, workers=2,
                       noise="white")
    b = run_montecarlo("paper-pitch", runs=3, methods=["rels", "wavelet+ols"], seed=2, rate=10.0, workers=1,
                       noise="white")
    for m in ("rels", "wavelet+ols"):
        np.testing.assert_array_equal(a.estimates[m], b.estimates[m])
    assert np.isnan(a.estimates["rels"][:, a.names.index("Kg1xz")]).all()  # zero column on a pitch flight


def test_cli_json_csv_figure(tmp_path, capsys):
    out, csv, fig = tmp_path / "mc.json", tmp_path / "mc.csv", tmp_path / "mc.png"
    assert main(["montecarlo", "--noise", "white", "--scenario", "paper", "--runs", "5", "--rate", "10",
                 "--methods", "ols,rls,bounded",
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
    printed = capsys.readouterr().out
    assert "median efficiency" in printed
    # the noise simulated and the noise model the methods assumed: what the coverage column means
    assert "noise: simulated white 0.1 m/s; the methods fit white noise, no robust fit" in printed
    assert data["noise"]["fit"] == {"noise": "white", "tau": None, "robust": None}
    assert data["noise"]["simulated"]["kind"] == "white" and data["noise"]["simulated"]["sigma"] == 0.1
    assert data["warnings"] == []  # the run's warnings (none)


def test_output_says_the_noise_model(capsys):
    """Gauss-Markov noise simulated, the default noise model (auto, robust auto): both named."""
    assert main(["montecarlo", "--scenario", "paper-range-gm", "--runs", "1", "--rate", "5", "--methods", "ols",
                 "--workers", "1", "--no-progress"]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if x.startswith("noise:"))
    assert line.startswith("noise: simulated Gauss-Markov tau 1 s 0.1 m/s") and "tracking gap(s)" in line, line
    assert line.endswith("the methods fit noise auto, robust auto (each run's own noise model, REML)"), line


def test_bad_arguments(capsys):
    with pytest.raises(ValueError, match="unknown method `foo`"):
        run_montecarlo(runs=2, methods=["foo"], noise="white")
    with pytest.raises(ValueError, match=r"option --runs \(`runs`\) must be an int >= 1"):
        run_montecarlo(runs=0, noise="white")
    assert main(["montecarlo", "--noise", "white", "--runs", "2", "--methods", "ols,ridge:abc"]) == 2
    assert "ridge:<lambda> needs a number" in capsys.readouterr().err


def test_gls_chunks_match_public_solver():
    """GLS runs share one REML lattice per chunk: tau within 1e-3 relative and estimates within
    1e-3 std of solve_gls per run, exactly solve_gls at that tau, the same for any `workers`."""
    import casep
    from casep.estimators.gls import estimate_tau_many
    from casep.simulation.simulate import scenario_setup

    runs, seed = 3, 4
    a = run_montecarlo("paper-ar1", runs=runs, methods=["gls"], seed=seed, rate=5.0, workers=1, noise="white")
    sc, traj, model, truth = scenario_setup("paper-ar1", 5.0)
    S = casep.build_sv(model, traj.t, traj.specific_force)
    Y = np.stack([S @ truth + sc.noise.sample(traj.t, np.random.default_rng(q))
                  for q in np.random.SeedSequence(seed).spawn(runs)], axis=-1)
    taus = estimate_tau_many(S, Y, traj.t)  # one chunk
    for k in range(runs):
        r = casep.solve_gls(S, Y[..., k], traj.t)  # its own REML search
        assert abs(taus[k] / r.extras.tau - 1) < 1e-3
        assert np.max(np.abs(a.estimates["gls"][k] - r.estimate) / r.std) < 1e-3
        np.testing.assert_allclose(a.stds["gls"][k], r.std, rtol=1e-3)
        g = casep.solve_gls(S, Y[..., k], traj.t, tau=float(taus[k]))  # at the shared lattice's tau
        assert np.max(np.abs(a.estimates["gls"][k] - g.estimate) / g.std) < 1e-6
    b = run_montecarlo("paper-ar1", runs=runs, methods=["gls"], seed=seed, rate=5.0, workers=2, noise="white")
    np.testing.assert_array_equal(a.estimates["gls"], b.estimates["gls"])


def test_progress_lines_off_a_terminal_count_runs_per_method(capsys):
    """Defect 6: no progress at all when stderr was not a terminal; the bar said 20/40 for 20 runs."""
    assert main(["montecarlo", "--noise", "white", "--scenario", "paper", "--runs", "3", "--rate", "5",
                 "--methods", "ols,rls,bounded",
                 "--workers", "1", "--progress"]) == 0
    err = capsys.readouterr().err.splitlines()
    assert err[-1].startswith("montecarlo: bounded 3/3 runs (method 2 of 2, 100 % of all)")
    assert "s elapsed, ETA 0 s" in err[-1]
    assert main(["montecarlo", "--noise", "white", "--scenario", "paper", "--runs", "3", "--rate", "5",
                 "--methods", "ols",
                 "--workers", "1", "--no-progress"]) == 0
    assert capsys.readouterr().err == ""


def test_progress_bar_total_is_runs(monkeypatch, capsys):
    from casep.montecarlo.progress import Progress as _Progress

    p = _Progress(20, ["ols,rls", "rels"], "bar")
    p(20)
    assert "ols,rls 20/20 runs (method 1 of 2)" in capsys.readouterr().err
    p.next_stage()
    p(5)
    out = capsys.readouterr().err
    assert "rels 5/20 runs (method 2 of 2)" in out and "/40" not in out
    p(15)
    assert capsys.readouterr().err.endswith("\n")  # the bar's line ends with the last run


def test_workers_have_one_blas_thread_and_parent_is_unchanged():
    """Workers run BLAS with one thread each (oversubscription made a 2-core Monte Carlo ~6-30x
    slower); the parent's thread pools are left as they were. (Dask workers.)"""
    from contextlib import ExitStack

    from threadpoolctl import threadpool_info

    from casep.montecarlo.engines import DaskEngine as _Dask

    before = [p["num_threads"] for p in threadpool_info()]
    with ExitStack() as stack:
        seen = _Dask(stack, 1, None).client.submit(_blas_threads, pure=False).result()
    assert seen and all(n == 1 for n in seen)
    assert [p["num_threads"] for p in threadpool_info()] == before


def _blas_threads():
    from threadpoolctl import threadpool_info

    return [p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"]


# ------------------------------------------------------------------ shutdown (defect 11)
def _stat(pid: int | str) -> list[str] | None:
    """The fields of /proc/PID/stat after the command name (state, ppid, ...), or None when it is gone
    (psutil is not a dependency)."""
    from pathlib import Path

    try:
        return (Path("/proc") / str(pid) / "stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return None


def _children(pid: int) -> list[int]:
    """Direct children of `pid`."""
    from pathlib import Path

    return [int(d.name) for d in Path("/proc").iterdir()
            if d.name.isdigit() and (f := _stat(d.name)) is not None and int(f[1]) == pid]


def _cpu_seconds(pid: int) -> float:
    """User + system CPU seconds of `pid` so far (0 when it is gone)."""
    f = _stat(pid)
    return 0.0 if f is None else (int(f[11]) + int(f[12])) / os.sysconf("SC_CLK_TCK")


def _alive(pid: int) -> bool:
    f = _stat(pid)
    return f is not None and f[0] != "Z"


def _ctrl_c_deliverable() -> None:
    """In the child before exec: SIGINT to its default action. A command started in the background of a shell
    without job control (``nohup sh -c '... &'``, as CI may run the suite) inherits SIGINT ignored, and an
    ignored SIGINT stays ignored across exec (Unix's rule for background jobs, which casep keeps): the test is of
    a Ctrl-C in a terminal, where SIGINT is delivered."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@contextlib.contextmanager
def _montecarlo_running():
    """A CLI Monte Carlo with 2 workers at work; yields (process, its children); kills leftovers."""
    proc = subprocess.Popen([sys.executable, "-m", "casep", "montecarlo", "--scenario", "paper", "--rate", "10",
                             "--methods", "bounded", "--runs", "5000", "--workers", "2", "--no-progress"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=_ctrl_c_deliverable)
    children: list[int] = []
    try:
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline and len(children) < 2:
            assert proc.poll() is None, proc.communicate()
            children = _children(proc.pid)  # the 2 workers
            time.sleep(0.1)
        assert len(children) >= 2, "the workers did not start"
        # At work means past the cluster's start-up, during which the parent holds a signal until the cluster is
        # up (engines._deferred_signals), so that the time measured is that of ending a running campaign, on a
        # loaded machine too. Forked workers (Python < 3.12) start with casep loaded and use little CPU before
        # their first task (measured: 0.03 s each when the cluster is up, then 0.02 s a second idle), so 0.5 s of
        # CPU each is work; spawned ones import it again (about 3 s of CPU each).
        busy = 0.5 if sys.version_info < (3, 12) else 5.0
        while time.monotonic() < deadline + 60 and min(_cpu_seconds(c) for c in children) < busy:
            assert proc.poll() is None, proc.communicate()
            time.sleep(0.1)
        assert min(_cpu_seconds(c) for c in children) >= busy, "the workers did not take work"
        children = _children(proc.pid)
        yield proc, children
    finally:
        for pid in [proc.pid] + children:  # only what this test started
            if _alive(pid):
                os.kill(pid, signal.SIGKILL)
        proc.communicate()


def _cmdline(pid: int) -> bytes:
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as fh:
            return fh.read()
    except OSError:
        return b""


def _gone_within(pids, seconds: float) -> bool:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if not any(_alive(p) for p in pids):
            return True
        time.sleep(0.1)
    return False


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
@pytest.mark.parametrize("sig, status", [("SIGTERM", 143), ("SIGINT", 130)])
def test_signal_ends_parent_and_workers_cleanly(sig, status):
    """Defect 11: SIGTERM orphaned the workers (hanging forever); Ctrl-C took 73 s and a traceback."""
    with _montecarlo_running() as (proc, children):
        proc.send_signal(getattr(signal, sig))
        try:
            out, err = proc.communicate(timeout=8)
        except subprocess.TimeoutExpired:
            pytest.fail(f"{sig}: the parent did not exit within 8 s")
        assert proc.returncode == status, err
        assert err.strip() == "casep: interrupted" and "Traceback" not in err
        assert out == ""  # no half-written report
        assert _gone_within(children, 5), f"{sig}: workers left behind"


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_sigkill_of_parent_ends_workers():
    with _montecarlo_running() as (proc, children):
        proc.kill()
        proc.wait()
        # Dask's nanny notices the dead parent through its pipe and then stops the worker: about 1-3 s
        # alone, once over 5 s with the suite in two processes on two cores; the assertion is that they end
        assert _gone_within(children, 15), "workers orphaned by SIGKILL of the parent"


def test_prior_and_bounds_files_replace_the_demo_values(tmp_path, capsys):
    """`--prior`/`--bounds` (no hard-wired demo values): the batched MAP and per-run
    bounded use the given files; batched MAP equals the per-run public solver with that prior."""
    import json

    from casep.simulation.paper import TABLE1_TRUTH

    names = casep.load_model("platform36").names
    prior = {n: {"mean": 0.0, "std": 2.0 * max(abs(TABLE1_TRUTH[n]), 1e-3)} for n in names}
    bounds = {n: [-3.0 * abs(TABLE1_TRUTH[n]) - 1e-3, 3.0 * abs(TABLE1_TRUTH[n]) + 1e-3] for n in names}
    fast = run_montecarlo("paper", runs=3, methods=["map"], seed=3, rate=10.0, prior=prior, noise="white")
    slow = run_montecarlo("paper", runs=3, methods=["map"], seed=3, rate=10.0, prior=prior, batched=False,
                          workers=1, noise="white")
    demo = run_montecarlo("paper", runs=3, methods=["map"], seed=3, rate=10.0, noise="white")
    sd = slow.stds["map"]
    assert np.max(np.abs(fast.estimates["map"] - slow.estimates["map"]) / sd) < 1e-8
    assert np.max(np.abs(fast.estimates["map"] - demo.estimates["map"]) / sd) > 0.1  # not the demo prior
    pfile, bfile = tmp_path / "prior.json", tmp_path / "bounds.json"
    pfile.write_text(json.dumps(prior))
    bfile.write_text(json.dumps(bounds))
    out = tmp_path / "mc.json"
    assert main(["montecarlo", "--noise", "white", "--runs", "2", "--rate", "10", "--methods", "map,bounded",
                 "--seed", "3",
                 "--workers", "1", "--prior", str(pfile), "--bounds", str(bfile), "--json", str(out)]) == 0
    got = json.loads(out.read_text())["methods"]["map"]["coefficients"]
    mine = run_montecarlo("paper", runs=2, methods=["map"], seed=3, rate=10.0, prior=prior, noise="white")
    np.testing.assert_allclose([c["rms"] for c in got], mine.stats("map")["rms"], rtol=1e-10)
    bfile.write_text(json.dumps({"KaOy": [0, 1]}))
    assert main(["montecarlo", "--noise", "white", "--runs", "2", "--rate", "10", "--methods", "bounded",
                 "--bounds", str(bfile)]) == 2
    assert "did you mean `Ka0y`" in capsys.readouterr().err


def test_batched_methods_use_the_estimators_linear_maps():
    """The batched path applies the estimators' own linear maps (no second
    implementation of their formulas): the maps it builds are those of the public functions."""
    from casep.estimators.map import map_linear_map
    from casep.estimators.ols import LinearMap, ols_linear_map
    from casep.estimators.rls import rls_linear_map
    from casep.model.sv import build_sv
    from casep.montecarlo.methods import linear_maps as _linear_maps
    from casep.simulation.paper import demo_prior
    from casep.simulation.simulate import scenario_setup

    sc, traj, model, _ = scenario_setup("paper", 5.0)
    S2 = build_sv(model, traj.t, traj.specific_force).reshape(-1, model.n_coefficients)
    maps = _linear_maps(S2, model.names, sc.noise.sigma, ["ols", "rls", "map", "ridge:1e-4"])
    assert all(isinstance(m, LinearMap) for m in maps.values())
    np.testing.assert_array_equal(maps["ols"].K, ols_linear_map(S2).K)
    np.testing.assert_array_equal(maps["rls"].K, rls_linear_map(S2).K)
    np.testing.assert_array_equal(maps["map"].b, map_linear_map(S2, demo_prior(model.names), sc.noise.sigma,
                                                                names=model.names).b)


_ORPHAN = """
import multiprocessing as mp, sys, time

def child(w):
    from casep.montecarlo.dask_worker import end_with_parent
    end_with_parent()
    w.send("ready")
    time.sleep(60)

if __name__ == "__main__":
    ctx = mp.get_context("fork")
    keep = [ctx.Pipe(duplex=False) for _ in range(2)]  # both exist before either fork, as Dask's on loaded cores
    procs = []
    for r, w in keep:
        procs.append(ctx.Process(target=child, args=(w,)))
        procs[-1].start()
    for (r, w), p in zip(keep, procs):
        if not r.poll(30):
            sys.exit("a child did not start")
    print(*[p.pid for p in procs], flush=True)
    time.sleep(60)
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc; fork")
def test_forked_workers_holding_each_others_pipes_end_with_a_sigkilled_parent(tmp_path):
    """The cause of the random orphans: forked workers inherit each other's write ends of Dask's
    parent-alive pipes (each holds the other's open), so only the preload's own watch ends them."""
    script = tmp_path / "orphan.py"
    script.write_text(_ORPHAN)
    proc = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, text=True)
    children: list[int] = []
    try:
        children = [int(p) for p in proc.stdout.readline().split()]
        assert len(children) == 2
        proc.kill()
        proc.wait()
        assert _gone_within(children, 5), "children orphaned by SIGKILL of the parent"
    finally:
        for pid in [proc.pid] + children:
            if _alive(pid):
                os.kill(pid, signal.SIGKILL)
        proc.communicate()
