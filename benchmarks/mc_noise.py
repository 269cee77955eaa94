"""Monte Carlo: are the reported std honest in range noise? Every method, default `--noise auto`.

The whole ``paper-range-gm`` flight (20 Hz, Gauss-Markov tracking noise sigma 0.1 m/s tau 1 s,
tracking from 8 s, dropouts of 6 s and 1.5 s), seeded draws; and the same with 0.5 % glitches of
2 m/s and ``robust="huber"``. z = (estimate - reference) / reported std over the 36 coefficients
and the draws, the reference being what each method's std describes (``tests/noise/test_noise_model.py``,
``_study``: the truth; the method's own noise-free answer for ridge and pcr; a truth drawn from
the prior for map, rls, rels). The test suite runs the same on a 90-s window with 60 draws.
Then the white / Gauss-Markov choice of ``noise="auto"`` on the first 40 s, over ``--choices`` seeds
of each kind of noise (the test suite runs 40).

Run:  python benchmarks/mc_noise.py [--runs 200] [--choices 100]
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np

_TESTS = Path(__file__).resolve().parents[1] / "tests"
sys.path[:0] = [str(_TESTS), str(_TESTS / "noise")]  # test_noise_model, and the conftest it imports


def main() -> None:
    from test_noise_model import _study  # the study the tests run, on the whole flight here

    import casep
    from casep.regression.problem import Problem
    from casep.simulation.simulate import simulate_flight

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=200)
    ap.add_argument("--choices", type=int, default=100)
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
    auto_choices(data, args.choices)


def auto_choices(data, seeds: int) -> None:
    """Right choices of ``noise="auto"`` on the first 40 s: white on white noise, Gauss-Markov on Gauss-Markov
    (the draws of ``test_auto_picks_white_on_white_noise_and_gauss_markov_on_gauss_markov``)."""
    from test_noise_model import _draw

    from casep.noise.fit import fit_noise

    S, t, truth = data[0][:800], data[1][:800], data[2]
    white = sum(fit_noise(_draw(S, t, truth, np.random.SeedSequence(11, spawn_key=(k,)), gm=False), "auto").is_white
                for k in range(seeds))
    gm = sum(all(tau is not None for tau in fit_noise(_draw(S, t, truth, np.random.SeedSequence(12, spawn_key=(k,))),
                                                       "auto").tau) for k in range(seeds))
    print(f"noise='auto' on 40 s, {seeds} seeds each: white chosen on white noise {white}, "
          f"Gauss-Markov on Gauss-Markov noise {gm}")


if __name__ == "__main__":
    main()
