"""Benchmark: GLS (REML tau) Monte Carlo runs, per-run public solver against the shared REML lattice.

Per run: ``casep.solve_gls(S, y, t)`` (its own bounded REML search, ~15 factorisations).
Shared: what ``run_montecarlo`` does for a chunk of runs: ``casep.estimators.gls.estimate_tau_many``
(one lattice of ln tau, one factorisation per lattice point for all runs of the chunk) and
then ``solve_gls(S, y, t, tau=tau_k)``. Same noise in both; one process, one BLAS thread.
Also prints the largest |tau difference| (relative) and estimate difference (in std).

Run:  python benchmarks/bench_gls_montecarlo.py [--runs 20] [--rate 20] [--chunk 16]
"""

from __future__ import annotations

import argparse
import os
import time
import warnings

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

import casep  # noqa: E402
from casep.estimators.gls import estimate_tau_many  # noqa: E402
from casep.exceptions import IllConditionedWarning  # noqa: E402
from casep.simulation.simulate import scenario_setup  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--rate", type=float, default=20.0)
    ap.add_argument("--chunk", type=int, default=16)
    ap.add_argument("--scenario", default="paper-ar1")
    args = ap.parse_args()
    warnings.simplefilter("ignore", IllConditionedWarning)
    sc, traj, model, truth = scenario_setup(args.scenario, args.rate)
    t = traj.t
    S = casep.build_sv(model, t, traj.specific_force)
    seqs = np.random.SeedSequence(0).spawn(args.runs)
    Y = np.stack([S @ truth + sc.noise.sample(t, np.random.default_rng(q)) for q in seqs], axis=-1)

    t0 = time.perf_counter()
    ref = [casep.solve_gls(S, Y[..., k], t) for k in range(args.runs)]
    t_per_run = time.perf_counter() - t0

    t0 = time.perf_counter()
    taus = np.concatenate([estimate_tau_many(S, Y[..., k:k + args.chunk], t)
                           for k in range(0, args.runs, args.chunk)])
    new = [casep.solve_gls(S, Y[..., k], t, tau=float(taus[k])) for k in range(args.runs)]
    t_shared = time.perf_counter() - t0

    dtau = max(abs(n.extras.tau / r.extras.tau - 1) for n, r in zip(new, ref))
    dest = max(float(np.nanmax(np.abs(n.estimate - r.estimate) / r.std)) for n, r in zip(new, ref))
    print(f"{args.scenario} at {args.rate:g} Hz, {S.shape[0]} samples, {args.runs} GLS runs")
    print(f"per-run solve_gls      {t_per_run:7.2f} s")
    print(f"shared REML lattice    {t_shared:7.2f} s   ({t_per_run / t_shared:.1f}x)")
    print(f"max |tau ratio - 1| {dtau:.1e}, max |estimate difference| / std {dest:.1e}")


if __name__ == "__main__":
    main()
