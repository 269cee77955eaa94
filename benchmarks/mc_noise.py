"""Monte Carlo: are the reported std honest in range noise? Every method, default `--noise auto`.

The whole ``paper-range-gm`` flight (20 Hz, Gauss-Markov tracking noise sigma 0.1 m/s tau 1 s,
tracking from 8 s, dropouts of 6 s and 1.5 s), seeded draws; and the same with 0.5 % glitches of
2 m/s and ``robust="huber"``. z = (estimate - reference) / reported std over the 36 coefficients
and the draws, the reference being what each method's std describes (``tests/noise/test_noise_model.py``,
``_study``: the truth; the method's own noise-free answer for ridge and pcr; a truth drawn from
the prior for map, rls, rels). The test suite runs the same on a 90-s window with 60 draws.

Run:  python benchmarks/mc_noise.py [--runs 200]
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))


def main() -> None:
    from test_noise_model import _study  # the study the tests run, on the whole flight here

    import casep
    from casep.regression.problem import Problem
    from casep.simulation.simulate import simulate_flight

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=200)
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    sim = simulate_flight("paper-range-gm", seed=0)
    pb = Problem.from_flight(sim.flight, casep.load_model("platform36"))
    data = (pb.sv(), pb.t, np.asarray(sim.truth))
    print(f"paper-range-gm, whole flight ({pb.n_samples} tracked samples), {args.runs} draws per row")
    print("| noise | method | RMS z | 95 % coverage |")
    print("|---|---|---|---|")
    for label, glitches, robust, seed in (("GM + gaps, `--noise auto`", 0.0, None, 40),
                                          ("GM + gaps + 0.5 % glitches, `--robust`", 0.005, "huber", 41)):
        t0 = time.time()
        stats = _study(data, args.runs, glitches, robust, seed)
        for m, z in stats.items():
            print(f"| {label} | {m} | {np.sqrt(np.mean(z**2)):.3f} | {np.mean(np.abs(z) <= 1.96):.3f} |", flush=True)
        print(f"({time.time() - t0:.0f} s)", file=sys.stderr)


if __name__ == "__main__":
    main()
