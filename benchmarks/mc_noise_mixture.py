"""Monte Carlo: are the reported std honest in Gauss-Markov plus white range noise? Every method,
default `--noise auto`, and the white / gm noise models on the same data for contrast.

The whole ``paper-range-gm`` flight (20 Hz, tracking from 8 s, dropouts of 6 s and 1.5 s) with
the tracking time offset ``dt_trk`` fitted (drawn N(0, 1) ms), noise Gauss-Markov tau 1 s std
0.09 m/s plus white 0.045 m/s per axis (``casep.simulation.noise.NoiseModel(white_sigma=...)``).
z = (estimate - reference) / reported std over the 37 coefficients and the draws, the reference
as in ``tests/workflows/test_noise_mixture_mc.py`` (which runs the same on a 90-s window with 8
draws). Then ols with noise "white" and "gm" on the same draws.

Run:  OPENBLAS_NUM_THREADS=1 python benchmarks/mc_noise_mixture.py [--runs 40]
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "workflows"))


def _line(name: str, z: np.ndarray) -> str:
    rms, cov = float(np.sqrt(np.mean(z**2))), float(np.mean(np.abs(z) <= 1.96))
    return f"{name:<12} RMS z {rms:6.3f}   95 % coverage {cov:6.3f}   max |z| {np.max(np.abs(z)):6.2f}"


def main() -> None:
    from test_noise_mixture_mc import draw, mixture_rows, study

    from casep.estimators.solve import solve_problem

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=40)
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    S, t, names = mixture_rows((0.0, 1e9))
    print(f"paper-range-gm, whole flight ({t.size} tracked samples), GM 1 s 0.09 m/s + white 0.045 m/s, "
          f"{args.runs} draws")
    t0 = time.perf_counter()
    stats = study(S, t, names, args.runs, seed=7)
    print("default workflow (noise auto):")
    for m, z in stats.items():
        print("  " + _line(m, z))
    for noise in ("white", "gm"):
        zs = []
        for k in range(args.runs):
            pb, tr = draw(S, t, names, np.random.SeedSequence(7, spawn_key=(k,)))
            res = solve_problem(pb, "ols", noise=noise).result
            z = (res.estimate - tr) / res.std
            zs.append(z[np.isfinite(z)])
        print(f"ols, noise {noise}:")
        print("  " + _line("ols", np.concatenate(zs)))
    print(f"({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
