"""Benchmark: the Monte Carlo study's command against its 60 s target, and batched OLS against a per-run loop.

The study of docs/results/cramer-rao.md (target: <= 60 s on a 2-core machine):
`casep montecarlo --scenario paper --runs 200 --seed 1 --methods ols,rls,rels,wavelet+rels,ridge,pcr,map,bounded`,
timed as a whole process (one run: it is long), with each method's seconds from its JSON.

Batched: one QR of the scaled S_V and a matrix of right-hand sides (casep.montecarlo.run_montecarlo).
Naive: per run, draw the noise and call casep.solve_ols (its own QR each time), timed on
`--naive-runs` runs and scaled. Same noise in both (per-run seeds), one run of this script.
Target: 1000 OLS runs of a 20k-sample flight in under 5 s.

Run:  OPENBLAS_NUM_THREADS=1 python benchmarks/bench_montecarlo.py [--runs 1000] [--naive-runs 50] [--only readme|ols]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
import warnings

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

import casep  # noqa: E402
from casep.exceptions import IllConditionedWarning  # noqa: E402
from casep.montecarlo import run_montecarlo  # noqa: E402
from casep.simulation.simulate import simulate_flight  # noqa: E402

README_METHODS = "ols,rls,rels,wavelet+rels,ridge,pcr,map,bounded"
README_TARGET_S = 60.0


def readme_command() -> None:
    """The Monte Carlo study's command, whole process, one run; a table row (measured, target)."""
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "mc.json")
        cmd = [sys.executable, "-m", "casep", "montecarlo", "--scenario", "paper", "--runs", "200", "--seed", "1",
               "--methods", README_METHODS, "--json", out, "--no-progress"]
        env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}  # as a user runs it
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, capture_output=True, env=env)
        wall = time.perf_counter() - t0
        secs = {m: d["seconds"] for m, d in json.load(open(out))["methods"].items()}
    print(f"README Monte Carlo command ({os.cpu_count()} cores, one run)")
    print("| command | measured (s) | target (s) | met |")
    print("|---|---|---|---|")
    print(f"| `casep montecarlo --scenario paper --runs 200 --seed 1 --methods {README_METHODS}` | {wall:.1f} | "
          f"<= {README_TARGET_S:g} | {'yes' if wall <= README_TARGET_S else 'NO'} |")
    print("per method (s): " + ", ".join(f"{m} {s:.2f}" for m, s in secs.items()))
    print()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=1000)
    ap.add_argument("--naive-runs", type=int, default=50)
    ap.add_argument("--only", choices=("readme", "ols"), default=None)
    args = ap.parse_args()
    if args.only != "ols":
        readme_command()
    if args.only == "readme":
        return
    warnings.simplefilter("ignore", IllConditionedWarning)
    run_montecarlo("paper", runs=2, methods=["ols"], seed=1)  # warm-up (imports, JIT cache)
    t0 = time.perf_counter()
    res = run_montecarlo("paper", runs=args.runs, methods=["ols"], seed=1)
    t_batched = time.perf_counter() - t0
    sim = simulate_flight("paper", seed=1)
    S = casep.build_sv(sim.model, sim.trajectory.t, sim.trajectory.specific_force)
    clean = S @ sim.truth
    seqs = np.random.SeedSequence(1).spawn(args.runs)
    t0 = time.perf_counter()
    naive = []
    for k in range(args.naive_runs):
        y = clean + sim.scenario.noise.sample(sim.trajectory.t, np.random.default_rng(seqs[k]))
        naive.append(casep.solve_ols(S, y).estimate)
    t_naive = (time.perf_counter() - t0) * args.runs / args.naive_runs
    dev = np.max(np.abs(np.array(naive) - res.estimates["ols"][: args.naive_runs]) / res.stats("ols")["rms"])
    n = sim.trajectory.t.size
    print(f"Monte Carlo of OLS, paper flight ({n} samples), {args.runs} runs, "
          f"OPENBLAS_NUM_THREADS={os.environ['OPENBLAS_NUM_THREADS']}")
    print(f"{'path':<44} {'time (s)':>9} {'runs/s':>8} {'time / batched':>15}")
    print(f"{'batched (one QR, matrix of right-hand sides)':<44} {t_batched:>9.2f} "
          f"{args.runs / t_batched:>8.0f} {1.0:>15.1f}")
    print(f"{f'naive per-run solve_ols ({args.naive_runs} runs, scaled)':<44} {t_naive:>9.2f} "
          f"{args.runs / t_naive:>8.0f} {t_naive / t_batched:>15.1f}")
    print(f"max |batched - naive| / RMS error on the first {args.naive_runs} runs: {dev:.1e}")
    print(f"OLS median efficiency {np.median(res.stats('ols')['efficiency']):.3f}, "
          f"median coverage95 {np.median(res.stats('ols')['coverage95']):.3f}")
    print(f"target: 1000 runs of a 20k-sample flight < 5 s: {'met' if t_batched < 5 * args.runs / 1000 else 'NOT met'}")


if __name__ == "__main__":
    main()
