"""Monte Carlo: are the reported std honest in range noise? Every method, default `--noise auto`.

The whole ``paper-range-gm`` flight (20 Hz, Gauss-Markov tracking noise sigma 0.1 m/s tau 1 s,
tracking from 8 s, dropouts of 6 s and 1.5 s), seeded draws; and the same with 0.5 % glitches of
2 m/s and ``robust="huber"``. z = (estimate - reference) / reported std over the 36 coefficients
and the draws, the reference being what each method's std describes (``tests/noise/test_noise_model.py``,
``_study``: the truth; the method's own noise-free answer for ridge and pcr; a truth drawn from
the prior for map, rls, rels), its RMS and 95 % coverage; and the error whitened by the stated covariance
(``w``, ``conftest.whitened_error``): its RMS and how many draws pass their chi2 95 % point. The test suite
runs the same on the 90-s window (``--window``) with 4 draws and asserts the whitened figures; the
per-coefficient z of the 36 coefficients of one draw are strongly correlated, so their figures need
many draws (60 on that window, which this script prints with ``--window --runs 60 --seeds 30 31``).
Then the white / Gauss-Markov choice of ``noise="auto"`` on the first 40 s, over ``--choices`` seeds
of each kind of noise (the test suite runs 40 white, 10 Gauss-Markov).

Then REML tau on 0.5 % glitches with and without the robust filter over ``--glitch-seeds`` seeds (the test suite
runs 10).

Run:  python benchmarks/mc_noise.py [--runs 200] [--choices 100] [--window] [--seeds 40 41] [--glitch-seeds 20]
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
    from scipy.stats import chi2
    from test_noise_model import _study  # the study the tests run, on the whole flight here

    import casep
    from casep.regression.problem import Problem
    from casep.simulation.simulate import simulate_flight

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=200)
    ap.add_argument("--choices", type=int, default=100)
    ap.add_argument("--window", action="store_true", help="the test's rows only: 60 to 150 s")
    ap.add_argument("--seeds", type=int, nargs=2, default=(40, 41), help="of the two rows (the tests: 30 31)")
    ap.add_argument("--glitch-seeds", type=int, default=20,
                    help="REML tau with and without the robust filter on 0.5 %% glitches (the tests: 10)")
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    sim = simulate_flight("paper-range-gm", seed=0)
    pb = Problem.from_flight(sim.flight, casep.load_model("platform36"))
    keep = (pb.t >= 60.0) & (pb.t <= 150.0) if args.window else np.ones(pb.t.size, dtype=bool)
    whole = (pb.sv(), pb.t, np.asarray(sim.truth))
    data = (whole[0][keep], whole[1][keep], whole[2])
    print(f"paper-range-gm, {'60-150 s' if args.window else 'whole flight'} ({int(keep.sum())} tracked samples), "
          f"{args.runs} draws per row")
    print("| noise | method | RMS z | 95 % coverage | RMS w | draws over chi2 95 % |")
    print("|---|---|---|---|---|---|")
    for label, glitches, robust, seed in (("GM + gaps, `--noise auto`", 0.0, None, args.seeds[0]),
                                          ("GM + gaps + 0.5 % glitches, `--robust`", 0.005, "huber", args.seeds[1])):
        t0 = time.time()
        zs, ws = _study(data, args.runs, glitches, robust, seed)
        for m, z in zs.items():
            q = [w @ w for w in ws[m]]
            over = sum(qk > chi2.ppf(0.95, w.size) for qk, w in zip(q, ws[m]))
            print(f"| {label} | {m} | {np.sqrt(np.mean(z**2)):.3f} | {np.mean(np.abs(z) <= 1.96):.3f} "
                  f"| {np.sqrt(sum(q) / sum(w.size for w in ws[m])):.3f} | {over} of {len(q)} |", flush=True)
        print(f"({time.time() - t0:.0f} s)", file=sys.stderr)
    auto_choices(whole, args.choices)
    glitch_taus(whole, args.glitch_seeds)


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


def glitch_taus(data, seeds: int) -> None:
    """REML tau on 0.5 % glitches of 2 m/s, without and with the robust filter, per axis and seed (the draws of
    ``test_reml_tau_with_glitches_is_robust``, which runs the first 10): the mean and std over the seeds that
    its bounds are computed from."""
    from test_noise_model import _draw

    from casep.estimators.solve import prepare_rows
    from casep.noise.fit import fit_noise

    S, t, truth = data
    plain, robust = [], []
    for k in range(seeds):
        pb = _draw(S, t, truth, np.random.SeedSequence(21, spawn_key=(k,)), glitches=0.005)
        plain.append([v or 0.0 for v in fit_noise(pb, "gm").tau])
        robust.append(prepare_rows(pb, "gm", robust="huber").noise.tau)
    p, r = np.array(plain, dtype=float), np.array(robust, dtype=float)
    mean, std = np.round(r.mean(axis=0), 3).tolist(), np.round(r.std(axis=0, ddof=1), 3).tolist()
    med = np.median(r, axis=1)
    print(f"REML tau on 0.5 % glitches, {seeds} seeds: without the filter mean {p.mean():.3f} s (max {p.max():.3f});"
          f" with it per axis mean {mean} std {std}, seed medians {med.min():.3f}-{med.max():.3f}"
          f" (std {med.std(ddof=1):.3f})")


if __name__ == "__main__":
    main()
