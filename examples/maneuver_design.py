"""Which manoeuvre determines more coefficients? Optimal experiment design with casep.

For the paper scenario, designs the A-optimal yaw manoeuvre (trace of the covariance scaled by the
coefficients' declared magnitudes, IPOPT on the symbolic model) at several angle budgets, prints what
each design buys (objective, coefficients whose CRLB falls below their declared magnitude), writes the
figure of the largest budget, then flies that design (simulated, with noise) and separates it with
OLS: the estimates' std reported by OLS is the design's CRLB.

    python examples/maneuver_design.py [--quick] [--out DIR]   # --quick: 5 Hz flight, one start, one budget, 5 knots
"""

# %%
import argparse
import warnings
from pathlib import Path

import numpy as np

import casep
from casep.design.optimize import DEFAULTS, design
from casep.reporting.plots import plot_design
from casep.simulation.simulate import simulate_flight

ap = argparse.ArgumentParser()
ap.add_argument("--quick", action="store_true")
ap.add_argument("--out", default=".")
args = ap.parse_args()
out = Path(args.out)
out.mkdir(parents=True, exist_ok=True)
rate = 5.0 if args.quick else None  # None: the scenario's 100 Hz
budgets = (10.0,) if args.quick else (2.0, 5.0, 10.0, 20.0)
starts = 1 if args.quick else 4
knots = 5 if args.quick else DEFAULTS["knots"]

# %% designs at increasing angle budgets (lateral limit 2 g: the angle is the binding budget)
results = {}
for angle in budgets:
    r = design("paper", maneuver="yaw", objective="A", max_angle=angle, max_rate=2.0, max_lateral=2.0,
               rate=rate, starts=starts, knots=knots)
    results[angle] = r
    new = [n for n in r.identifiable("after") if n not in r.identifiable("before")]
    print(f"max {angle:4.1f} deg: A {r.before:8.1f} -> {r.after:8.1f} ({r.solver['return_status']}, "
          f"{r.timing['total']:.1f} s); identifiable {len(r.identifiable('before'))} -> "
          f"{len(r.identifiable('after'))}; new: {', '.join(new) or 'none'}; CRLB prediction error "
          f"{100 * r.verification['crlb_prediction_error_max']:.1f} %")

best = results[budgets[-1]]
print(f"figure: {plot_design(best, out / 'maneuver_design.png')}")

# %% fly the largest design and separate it: OLS std = the designed CRLB
sim = simulate_flight(best.scenario, seed=3)
with warnings.catch_warnings():
    warnings.simplefilter("ignore", casep.IllConditionedWarning)
    res = casep.separate(sim.flight, sim.model, "ols", sigma=sim.scenario.noise.sigma)
ratio = np.asarray(res.std) / best.crlb_after
print(f"designed flight separated (OLS, {sim.flight.n_samples} samples): reported std / design CRLB in "
      f"[{np.nanmin(ratio):.4f}, {np.nanmax(ratio):.4f}]")
for n in best.identifiable("after"):
    j = sim.model.index(n)
    print(f"  {n:<6} true {sim.truth[j]:9.4g}  estimate {res.estimate[j]:9.4g} +- {res.std[j]:.3g} "
          f"{sim.model.units[j]}")
