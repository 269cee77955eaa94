"""Diagnose collinearity on the paper flight and cross-check ridge and bounded QP.

Shows what the flight can and cannot determine (condition number, near-dependency groups,
best-determined combinations), then solves ridge by its SVD closed form and by cvxpy +
Clarabel on the 36 x 36 QR reduction, and a bounded least squares with a spec-sheet box.

Run:  python examples/collinearity_ridge_qp.py [--quick]
"""

#%% Imports and options
import argparse

import numpy as np

import casep
from casep.checks.diagnostics import diagnose
from casep.simulation.paper import demo_bounds
from casep.simulation.simulate import simulate_flight

ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
ap.add_argument("--quick", action="store_true", help="10 Hz instead of 100 Hz (for CI)")
args = ap.parse_args()

#%% The flight and its regression
sim = simulate_flight("paper", seed=1, rate=10.0 if args.quick else 100.0)
model = sim.model
S = casep.build_sv(model, sim.flight.t, sim.flight.f)
dv = sim.flight.dv

#%% Diagnostics: what the flight can tell
d = diagnose(S, dv, names=model.names, units=model.units, scales=model.scales)
print(d.text())

#%% Ridge: closed form vs cvxpy + Clarabel (same lambda)
svd = casep.solve_ridge(S, dv, lam="gcv", names=model.names)
cvx = casep.solve_ridge(S, dv, lam=svd.extras.lam, solver="cvxpy", names=model.names)
rel = np.max(np.abs(svd.estimate - cvx.estimate) / np.maximum(np.abs(svd.estimate), 1e-300))
print(f"ridge lambda (GCV) {svd.extras.lam:.3g}; closed form vs cvxpy/Clarabel max rel. diff {rel:.1e}")

#%% Bounded least squares in a spec-sheet box
bnd = casep.solve_bounded(S, dv, demo_bounds(model.names), names=model.names)
print(f"bounded: {len(bnd.extras.active_bounds)} coefficients on a bound; polished: "
      f"{bnd.diagnostics['polished']}")
for n in ("Ka0x", "Ka1x", "Ka0y", "Kg0z"):
    j = model.index(n)
    print(f"  {n:<6} true {sim.truth[j]:>7.3g}  OLS-ridge {svd.estimate[j]:>8.3g}  bounded {bnd.estimate[j]:>8.3g}  "
          f"CRLB std {d.crlb_std[j]:.3g}")
