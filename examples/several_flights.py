"""Several flights: how many of the 36 coefficients each combination determines.

The table of docs/results/several-flights.md.

Simulates the scenarios `paper`, `paper-yaw-late`, `paper-pitch-low`, `paper-azimuth` (white noise
0.1 m/s, each flight's sigma estimated from its own residuals) and counts the coefficients whose
Cramer-Rao std is below the model's declared typical magnitude ("identifiable" in `casep diagnose`),
for one flight, the flights jointly, and jointly with a ground-calibration prior (std = 3 x the
declared magnitude, an uninformative-ish prior that bounds only the worst-determined terms).

    python examples/several_flights.py [--quick]     # --quick: 10 Hz instead of 50 Hz
"""

# %%
import argparse
import warnings

import numpy as np

import casep
from casep.simulation.simulate import simulate_flight
from casep.workflows.flights import diagnose_flights

ap = argparse.ArgumentParser()
ap.add_argument("--quick", action="store_true")
rate = 10.0 if ap.parse_args().quick else 50.0
model = casep.load_model("platform36")
SCEN = ("paper", "paper-yaw-late", "paper-pitch-low", "paper-azimuth")
flights = {s: simulate_flight(s, seed=k + 1, rate=rate).flight for k, s in enumerate(SCEN)}
prior_std = np.array([3.0 * model.scales[n] for n in model.names])

# %%
rows = []
with warnings.catch_warnings():
    warnings.simplefilter("ignore")  # ill-conditioning is the point here
    for combo in (("paper",), ("paper-yaw-late",), ("paper-pitch-low",), ("paper-azimuth",),
                  ("paper", "paper-yaw-late"), ("paper", "paper-azimuth"), ("paper", "paper-pitch-low"),
                  ("paper", "paper-yaw-late", "paper-azimuth"), SCEN):
        fl = [flights[s] for s in combo]
        d = diagnose_flights(fl, model)
        dp = diagnose_flights(fl, model, prior_std=prior_std)
        rows.append((" + ".join(combo), d["identifiable_joint"], dp["identifiable_joint"]))
print(f"rate {rate:g} Hz, white noise 0.1 m/s, model platform36 (36 coefficients)")
print("| flights | identifiable | with a prior (3 x magnitude) |")
print("|---|---|---|")
for name, a, b in rows:
    print(f"| {name} | {a} | {b} |")
