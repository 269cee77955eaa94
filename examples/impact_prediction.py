"""How well do test flights predict the impact miss of another trajectory? (the table of docs/results/impact.md)

Simulates the scenarios `paper`, `paper-yaw-late`, `paper-pitch-low`, `paper-azimuth` (white noise
0.1 m/s, the paper's true coefficients in every flight), estimates the coefficients from one, two or
three test flights (OLS jointly, and MAP with a loose ground-calibration prior of 3 x each
coefficient's declared magnitude, mean 0), and applies each estimate with its covariance to the
trajectories (``casep.impact_analysis(..., trajectory=...)``): the predicted instrument-error miss
and its std, against the true miss (the true coefficients through the same trajectory's miss
sensitivities). ``z`` is (predicted - true) / std per axis; over many seeds it is N(0, 1).

    python examples/impact_prediction.py [--quick] [--seeds K]   # --quick: 10 Hz instead of 20 Hz
"""

# %%
import argparse
import warnings

import numpy as np

import casep
from casep.simulation.simulate import simulate_flight

ap = argparse.ArgumentParser()
ap.add_argument("--quick", action="store_true")
ap.add_argument("--seeds", type=int, default=1, help="noise draws per row (RMS of z over them)")
args = ap.parse_args()
rate = 10.0 if args.quick else 20.0
model = casep.load_model("platform36")
SCEN = ("paper", "paper-yaw-late", "paper-pitch-low", "paper-azimuth")
TESTS = (("paper",), ("paper", "paper-yaw-late"), ("paper", "paper-yaw-late", "paper-azimuth"))
prior = {n: {"mean": 0.0, "std": 3.0 * model.scales[n]} for n in model.names}


def estimate(flights, with_prior):
    method, opts = ("map", {"prior": prior}) if with_prior else ("ols", {})
    if len(flights) == 1:
        return casep.separate(flights[0], model, method, **opts)
    return casep.separate_flights(flights, model, method, options=opts)[0]


# %%
rows = {}
with warnings.catch_warnings():
    warnings.simplefilter("ignore")  # ill-conditioning is the point here
    for seed in range(args.seeds):
        sims = {s: simulate_flight(s, seed=100 * seed + k + 1, rate=rate) for k, s in enumerate(SCEN)}
        truth = np.asarray(sims["paper"].truth, dtype=float)
        for tests in TESTS:
            for with_prior in (False, True):
                res = estimate([sims[s].flight for s in tests], with_prior)
                for target in SCEN:
                    ia = casep.impact_analysis(sims[tests[0]].flight, res, model, trajectory=sims[target].flight)
                    true = ia.sensitivity @ truth if ia.sensitivity.shape[0] == 2 else truth @ ia.sensitivity
                    std = np.sqrt(np.diag(ia.cov))
                    key = (" + ".join(tests), with_prior, target)
                    rows.setdefault(key, []).append((true, ia.miss, std))

# %%
print(f"rate {rate:g} Hz, white noise 0.1 m/s, model platform36, {args.seeds} seed(s); miss in m (down, cross)")
print("| test flights | prior | trajectory predicted | true miss | predicted std | RMS z |")
print("|---|---|---|---|---|---|")
for (tests, with_prior, target), v in rows.items():
    true = np.mean([r[0] for r in v], axis=0)
    std = np.mean([r[2] for r in v], axis=0)
    z = np.sqrt(np.mean([((r[1] - r[0]) / r[2]) ** 2 for r in v], axis=0))
    print(f"| {tests} | {'3 x magnitude' if with_prior else 'none'} | {target} | {true[0]:.0f}, {true[1]:.0f} "
          f"| {std[0]:.0f}, {std[1]:.0f} | {z[0]:.2f}, {z[1]:.2f} |")
