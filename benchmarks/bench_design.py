"""Benchmark: one ``casep design`` run on the paper scenario (target: <= 60 s).

Times :func:`casep.design.optimize.design` with its defaults (yaw manoeuvre, A-optimal, 5 deg, 2 deg/s,
1 g lateral, 10 knots, 2 Hz design grid, 4 IPOPT starts, re-simulated check at 100 Hz), phase by phase
(nominal trajectory and its S_V, building the CasADi problem, IPOPT, the check), and repeats for the
other objectives and manoeuvres given on the command line.

Run:  OPENBLAS_NUM_THREADS=1 python benchmarks/bench_design.py [--objective A D miss] [--maneuver yaw pitch both]
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from casep.design.optimize import design  # noqa: E402

ap = argparse.ArgumentParser()
ap.add_argument("--objective", nargs="+", default=["A"])
ap.add_argument("--maneuver", nargs="+", default=["yaw"])
ap.add_argument("--max-angle", type=float, default=5.0)
args = ap.parse_args()

print(f"{'objective':<9} {'maneuver':<8} {'total s':>8} {'nominal':>8} {'build':>7} {'ipopt':>7} {'check':>7} "
      f"{'status':<22} {'before':>10} {'after':>10} {'CRLB pred. err':>14}")
for obj in args.objective:
    for man in args.maneuver:
        t0 = time.perf_counter()
        r = design("paper", objective=obj, maneuver=man, max_angle=args.max_angle)
        wall = time.perf_counter() - t0
        t = r.timing
        v = r.verification
        print(f"{obj:<9} {man:<8} {wall:8.1f} {t['nominal_trajectory']:8.1f} {t['build']:7.1f} {t['solve']:7.1f} "
              f"{t['verify']:7.1f} {r.solver['return_status']:<22} {r.before:10.4g} {r.after:10.4g} "
              f"{100 * v['crlb_prediction_error_max']:13.1f}%")
