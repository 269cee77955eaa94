"""Benchmark: Monte Carlo scaling on Dask: runs per second with 1 and 2 local workers,
cluster start-up, Dask's overhead per task against the work per flight.

Workloads (seeded, the same numbers on every engine):
  nominal    scenario paper at 20 Hz, methods rels,bounded (per-run solvers), fixed trajectory
  dispersed  scenario paper at 1 Hz, methods ols,map, thrust/Isp/azimuth dispersions: each run
             simulates its own trajectory and builds its S_V (the per-flight work)

Engines: "in process" (workers=1, no cluster), "dask 1" (LocalCluster of 1 worker), "dask 2"
(LocalCluster of 2 workers, one thread each). Times are wall seconds of run_montecarlo, cluster
start-up included ("runs/s") and without it ("runs/s after start", from the stages' seconds);
"work per flight": stage seconds x workers / runs (in process: the flight's own compute).

Run:  python benchmarks/bench_montecarlo_dask.py [--runs 64] [--repeat 1]
"""

from __future__ import annotations

import argparse
import os
import time
from contextlib import ExitStack

import numpy as np

from casep.montecarlo import run_montecarlo
from casep.montecarlo.engines import DaskEngine

DISP = {"thrust_scale": {"dist": "normal", "mean": 1.0, "std": 0.01},
        "isp_scale": {"dist": "normal", "mean": 1.0, "std": 0.005},
        "launch_azimuth_deg": {"dist": "uniform", "low": -2.0, "high": 2.0}}
WORKLOADS = {
    "nominal": dict(scenario="paper", rate=20.0, methods=["rels", "bounded"]),
    "dispersed": dict(scenario="paper", rate=1.0, methods=["ols", "map"], dispersions=DISP),
}


def _noop(x):
    return x


def startup_and_overhead(n_tasks: int = 200) -> None:
    for w in (1, 2):
        t0 = time.perf_counter()
        with ExitStack() as stack:
            eng = DaskEngine(stack, w, None)
            t1 = time.perf_counter()
            from distributed import as_completed

            futs = [eng.client.submit(_noop, i, pure=False) for i in range(n_tasks)]
            for f in as_completed(futs):
                f.result()
            t2 = time.perf_counter()
            t3 = time.perf_counter()
        t4 = time.perf_counter()
        print(f"LocalCluster {w} worker(s): start {t1 - t0:.2f} s, close {t4 - t3:.2f} s, "
              f"{n_tasks} empty tasks {1e3 * (t2 - t1) / n_tasks:.2f} ms each (wall, submit to result)")


def scaling(runs: int, repeat: int) -> None:
    print(f"\n| workload | engine | runs | wall s (median of {repeat}) | runs/s | runs/s after start | "
          "work per flight ms |")
    print("|---|---|---|---|---|---|---|")
    for name, wl in WORKLOADS.items():
        base = None
        for label, kw in (("in process", dict(workers=1, dask=False)), ("dask 1", dict(workers=1, dask=True)),
                          ("dask 2", dict(workers=2, dask=True))):
            walls, starts = [], []
            for _ in range(repeat):
                t0 = time.perf_counter()
                res = run_montecarlo(wl["scenario"], runs=runs, methods=wl["methods"], seed=1, rate=wl["rate"],
                                     dispersions=wl.get("dispersions"), progress=False, **kw)
                walls.append(time.perf_counter() - t0)
                starts.append(walls[-1] - sum(res.seconds.values()))  # set-up, cluster start, close
                est = np.concatenate([res.estimates[m] for m in wl["methods"]])
                if base is None:
                    base = est
                else:
                    assert np.array_equal(est, base, equal_nan=True), "numbers differ between engines"
            w, s = float(np.median(walls)), float(np.median(starts))
            # work per flight: compute seconds per run in this process (no Dask); on a cluster: worker time
            per = (w - s) / runs * (1 if label == "in process" else int(label[-1]))
            print(f"| {name} | {label} | {runs} | {w:.1f} | {runs / w:.2f} | {runs / (w - s):.2f} | {1e3 * per:.0f} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=64)
    ap.add_argument("--repeat", type=int, default=1)
    a = ap.parse_args()
    print(f"cores {os.cpu_count()}, load average {os.getloadavg()[0]:.1f}")
    startup_and_overhead()
    scaling(a.runs, a.repeat)
    print(f"load average at the end {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
