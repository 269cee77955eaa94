"""Monte Carlo: what wavelet de-noising does to each method's coefficient errors.

Seeded runs on the `paper` trajectory (the trajectory is fixed; each run draws new tracking
noise): white noise (sigma 0.1 m/s) and Gauss-Markov noise (sigma 0.1 m/s, tau 1 s). For each
method, with and without de-noising (sym8, default level, symmetric extension, sln scaling,
universal soft threshold unless stated), it prints:

- median over the 36 coefficients of RMS(error) / CRLB std, with the bound of the actual
  noise (white: sigma^2 (S^T S)^-1; Gauss-Markov: the GLS bound);
- the same for four well-determined coefficients (Ka0x, Ka1x, Ka0y, Ka0z);
- RMS of (error / reported std) pooled over coefficients: 1 means the std is honest.

Run:  OPENBLAS_NUM_THREADS=1 python benchmarks/mc_denoise.py [--runs 100] [--rate 100] [--seed 1]
"""

from __future__ import annotations

import argparse
import os
import time
import warnings

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

import casep  # noqa: E402
from casep.checks.diagnostics import crlb_covariance  # noqa: E402
from casep.exceptions import IllConditionedWarning  # noqa: E402
from casep.noise.denoise import denoise  # noqa: E402
from casep.simulation.noise import NoiseModel  # noqa: E402
from casep.simulation.simulate import simulate_flight  # noqa: E402

KEY = ("Ka0x", "Ka1x", "Ka0y", "Ka0z")


def run(args) -> None:
    warnings.simplefilter("ignore", IllConditionedWarning)
    sim = simulate_flight("paper", seed=0, rate=args.rate)
    model, t = sim.model, sim.flight.t
    S = casep.build_sv(model, t, sim.flight.f)
    clean = S @ sim.truth
    key = [model.index(k) for k in KEY]
    variants = {
        "none": None,
        "wavelet (sqtwolog soft)": {},
        "wavelet (rigrsure soft)": {"rule": "rigrsure"},
        "wavelet (sqtwolog hard)": {"mode": "hard"},
    }
    methods = {
        "ols": lambda y, s: casep.solve_ols(S, y, sigma=s),
        "rls p0=1e6": lambda y, s: casep.solve_rls(S, y, sigma=s),
        "rels n_c=1": lambda y, s: casep.solve_rls(S, y, noise_order=1, sigma=s),
        "ridge gcv": lambda y, s: casep.solve_ridge(S, y, sigma=s),
    }
    print(f"paper trajectory, {t.size} samples at {args.rate:g} Hz, {args.runs} runs per noise, seed {args.seed}")
    print(f"{'noise':<6} {'method':<12} {'de-noising':<24} {'median RMS/CRLB':>16} "
          + " ".join(f"{k:>6}" for k in KEY) + f" {'RMS(err/std)':>13}")
    for kind in ("white", "ar1"):
        noise = NoiseModel(kind, 0.1, tau=1.0 if kind == "ar1" else None)
        bound = np.sqrt(np.diag(crlb_covariance(S, 0.1, t=t if kind == "ar1" else None,
                                                tau=1.0 if kind == "ar1" else None)))
        rng = np.random.default_rng(args.seed)
        ys = [clean + noise.sample(t, rng) for _ in range(args.runs)]
        for mname, solve in methods.items():
            for vname, opts in variants.items():
                if mname != "ols" and vname not in ("none", "wavelet (sqtwolog soft)"):
                    continue
                err, z = [], []
                for y in ys:
                    if opts is None:
                        res = solve(y, None)
                    else:
                        d = denoise(y, **opts)
                        res = solve(d.dv, float(np.sqrt(np.mean(d.sigma**2))))  # as casep separate does
                    e = res.estimate - sim.truth
                    err.append(e)
                    z.append(e / res.std)
                err, z = np.array(err), np.array(z)
                ratio = np.sqrt(np.mean(err**2, axis=0)) / bound
                print(f"{kind:<6} {mname:<12} {vname:<24} {np.median(ratio):>16.3f} "
                      + " ".join(f"{ratio[k]:>6.2f}" for k in key) + f" {np.sqrt(np.mean(z**2)):>13.2f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=100)
    ap.add_argument("--rate", type=float, default=100.0)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    t0 = time.perf_counter()
    run(args)
    print(f"({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
