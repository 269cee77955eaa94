"""Benchmark: S_V of models with signals against platform36, in one run (ratios, one table).

Models: platform36 (f only), platform36_timeoffset (+ a_x/a_y/a_z in a direct velocity term),
platform36_leverarm (+ 6 attitude/rate columns, 3 direct terms), platform36_drift_ramp (+ t in
the gyro drift). Each is built with one SVBuilder (set-up cost excluded) over the same N-sample
flight; the best of `--repeat` runs, interleaved. Target: a model with signals within
1.5x the time of platform36 at N = 1e6.

Run:  OPENBLAS_NUM_THREADS=1 python benchmarks/bench_sv_signals.py [--n 1000000] [--repeat 3]
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

import casep  # noqa: E402
from casep.simulation.synthetic import excitation_force  # noqa: E402

MODELS = ("platform36", "platform36_timeoffset", "platform36_leverarm", "platform36_drift_ramp")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=1_000_000)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    t = np.arange(args.n) * 0.01
    f = excitation_force(t)
    rng = np.random.default_rng(0)
    sig = {c: rng.standard_normal(args.n) for c in ("a_x", "a_y", "a_z", "att_pitch", "att_yaw", "att_roll",
                                                     "omega_x", "omega_y", "omega_z")}
    builders = {m: casep.SVBuilder(casep.load_model(m)) for m in MODELS}
    for b in builders.values():
        b.build(t[:5000], f[:5000], signals={k: v[:5000] for k, v in sig.items()})  # JIT / cache warm-up
    best = dict.fromkeys(MODELS, np.inf)
    for _ in range(args.repeat):
        for m, b in builders.items():
            out = np.empty((args.n, 3, b.model.n_coefficients))
            t0 = time.perf_counter()
            b.build(t, f, out, signals=sig)
            best[m] = min(best[m], time.perf_counter() - t0)
            del out
    print(f"N = {args.n}, best of {args.repeat}")
    print(f"{'model':<24} {'coefficients':>12} {'signals':>8} {'seconds':>8} {'vs platform36':>14}")
    for m in MODELS:
        b = builders[m]
        print(f"{m:<24} {b.model.n_coefficients:>12} {len(b.model.signals):>8} {best[m]:>8.3f} "
              f"{best[m] / best['platform36']:>14.2f}")


if __name__ == "__main__":
    main()
