"""Monte Carlo on simulated strapdown flights: are the std honest in Gauss-Markov plus white noise?

The ``strapdown-boost`` scenario (roll programme, tracking from 6 s, gap 110-115 s, Gauss-Markov
0.1 m/s tau 1 s plus white 0.05 m/s per axis) with the 15 strapdown33 terms an axial-thrust boost
excites (the shipped ``strapdown15_axial``, truth from the scenario's). One trajectory, one
noise-free dv; each run draws its noise with its own seed (as ``simulate_flight(seed=k)`` does) and
separates with OLS and the default noise model (REML). z = (estimate - truth) / reported std over
the 15 coefficients and the runs. Also the noise-free recovery against the CRLB std, and the white
noise model on the same draws for contrast. ``tests/simulation/test_strapdown_sim.py`` runs 12 draws.

Run:  OPENBLAS_NUM_THREADS=1 python benchmarks/mc_strapdown.py [--runs 200] [--rate 20]
"""

from __future__ import annotations

import argparse
import dataclasses
import time
import warnings

import numpy as np

MODEL = "strapdown15_axial"


def _line(name: str, z: np.ndarray) -> str:
    rms, cov = float(np.sqrt(np.mean(z**2))), float(np.mean(np.abs(z) <= 1.959964))
    return f"{name:<14} RMS z {rms:6.3f}   95 % coverage {cov:6.3f}   max |z| {np.max(np.abs(z)):6.2f}   ({z.size} z)"


def setup(rate: float):
    """The ``strapdown-boost`` flight at `rate` with :data:`MODEL` and the scenario's truth; its noise-free dv."""
    import casep
    from casep.simulation.scenarios import STRAPDOWN_TRUTH
    from casep.simulation.simulate import simulate_flight

    model = casep.load_model(MODEL)
    truth = {k: v for k, v in STRAPDOWN_TRUTH.items() if k in model.names}
    sim = simulate_flight("strapdown-boost", seed=0, model=MODEL, truth=truth, rate=rate)
    return sim, sim.flight.dv - sim.noise


def main() -> None:
    import casep

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=200)
    ap.add_argument("--rate", type=float, default=20.0)
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    sim, clean = setup(args.rate)
    fl = sim.flight
    names = sim.model.names
    res = casep.separate(dataclasses.replace(fl, dv=np.where(fl.observed[:, None], clean, np.nan)), sim.model,
                         method="ols", noise="white", sigma=0.1)
    crlb = np.array([res.diagnostics["crlb_std"][n] for n in names])
    print(f"strapdown-boost at {args.rate:g} Hz, {fl.n_observed} tracked samples, model {sim.model.name}")
    worst = np.max(np.abs(res.estimate - sim.truth) / crlb)
    print(f"noise-free recovery: max |estimate - truth| / CRLB std = {worst:.2e}")
    z = {"ols (default)": [], "ols white": []}
    t0 = time.process_time()
    for seed in range(1, args.runs + 1):
        noise = sim.scenario.noise.sample(fl.t, np.random.default_rng(seed))
        run = dataclasses.replace(fl, dv=np.where(fl.observed[:, None], clean + noise, np.nan))
        for key, opts in (("ols (default)", {}), ("ols white", {"noise": "white"})):
            r = casep.separate(run, sim.model, method="ols", **opts)
            z[key].append((r.estimate - sim.truth) / r.std)
    print(f"{args.runs} runs, {time.process_time() - t0:.0f} CPU s")
    for key, zs in z.items():
        print(_line(key, np.array(zs)))
    zs = np.array(z["ols (default)"])
    print("per coefficient (default): " + ", ".join(f"{n} {np.sqrt(np.mean(zs[:, j] ** 2)):.2f}"
                                                      for j, n in enumerate(names)))


if __name__ == "__main__":
    main()
