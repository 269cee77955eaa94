"""Seeded Monte Carlo of the radar path in Gauss-Markov plus white measurement noise.

Two stations track the test flight (``tests/radar/test_radar.py``'s geometry and station errors) at
``--rate`` Hz; every station's range, azimuth and elevation carry a first-order Gauss-Markov noise
(tau ``--tau`` s; 3 m, 8 arcsec) plus a white one (1.5 m, 4 arcsec), simulated through the seeded
``rng`` of :func:`casep.simulation.radar.simulate_radar`. Each flight is separated with the default
noise model (``auto``: white / Gauss-Markov / Gauss-Markov plus white per station and type by REML)
and with white noise only. Printed per noise model: RMS of z = (estimate - truth) / std over the
instrument coefficients, the coverage of their 95 % intervals, the largest |z|, and the successes.

``--whitened``: also each draw's error whitened by its stated covariance (``tests/conftest.py``'s
``whitened_error``; instrument terms, and all with the tracking ones): the RMS of w, the draws whose ``w^T w`` passes
its chi2 95 % point, and the verdict of ``dishonest_whitened`` (band [0.80, 1.30], false alarm 1e-4). The full
honesty check of the suite's reduced one: ``--runs 6 --rate 5 --whitened`` (seeds 100-105; the test runs 100-102).

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/mc_radar_noise.py --runs 20`` (about 15 CPU s a run at 10 Hz, 2 at 5).
The test suite runs a reduced version (``tests/radar/test_radar_noise.py``).
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "radar"))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from test_radar import SITE, STATIONS, TRUTH  # noqa: E402

from casep.simulation.radar import simulate_radar  # noqa: E402
from casep.workflows.radar import separate_radar  # noqa: E402

WHITE = {"range": 1.5, "azimuth": 4.0, "elevation": 4.0}
GM = {"range": 3.0, "azimuth": 8.0, "elevation": 8.0}


def draw(seed: int, rate: float, tau: float):
    """One simulated two-station flight in Gauss-Markov plus white noise."""
    return simulate_radar(STATIONS, SITE, seed=seed, telemetry_rate=rate, radar_rate=rate, tracking_truth=TRUTH,
                          noise=WHITE, gauss_markov=GM, gm_tau=tau)


def instrument_z(sim, noise: str):
    """z of the instrument coefficients of one separation, its success, the warnings' classes, and the
    separation."""
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        rr = separate_radar(sim.telemetry, list(sim.radars), SITE, sim.model, sim.tracking, noise=noise,
                            diagnostics=False)
    n = sim.model.n_coefficients
    z = (rr.result.estimate[:n] - sim.truth[:n]) / rr.result.std[:n]
    kinds = sorted({type(w.message).__name__ for w in rec if type(w.message).__name__ != "IllConditionedWarning"})
    return z[np.isfinite(z)], bool(rr.success), kinds, rr


def run(seeds, rate: float, tau: float, noises=("auto", "white"), separations: dict | None = None) -> dict[str, dict]:
    """The figures per noise model over the seeds; `separations`, when given, receives each separation by
    ``(seed, noise)`` (and each simulated flight by ``seed``)."""
    zs: dict[str, list] = {k: [] for k in noises}
    ok = dict.fromkeys(noises, 0)
    warned: dict[str, set] = {k: set() for k in noises}
    for seed in seeds:
        sim = draw(seed, rate, tau)
        if separations is not None:
            separations[seed] = sim
        for k in noises:
            z, success, kinds, rr = instrument_z(sim, k)
            if separations is not None:
                separations[seed, k] = rr
            zs[k].append(z)
            ok[k] += success
            warned[k].update(kinds)
    out = {}
    for k in noises:
        z = np.concatenate(zs[k])
        out[k] = {"rms_z": float(np.sqrt(np.mean(z**2))), "coverage": float(np.mean(np.abs(z) < 1.959964)),
                  "max_abs_z": float(np.max(np.abs(z))), "successes": ok[k], "runs": len(zs[k]),
                  "warnings": sorted(warned[k])}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--rate", type=float, default=10.0, help="telemetry and radar rate, Hz (default 10)")
    ap.add_argument("--tau", type=float, default=1.0, help="Gauss-Markov correlation time, s (default 1)")
    ap.add_argument("--seed", type=int, default=100, help="first seed (default 100)")
    ap.add_argument("--whitened", action="store_true", help="also the errors whitened by the stated covariance")
    a = ap.parse_args()
    t0 = time.process_time()
    seeds = range(a.seed, a.seed + a.runs)
    runs: dict = {}
    res = run(seeds, a.rate, a.tau, separations=runs)
    print(f"radar, 2 stations, {a.rate:g} Hz, GM tau {a.tau:g} s (3 m, 8 arcsec) + white (1.5 m, 4 arcsec), "
          f"{a.runs} seeded runs, instrument coefficients")
    print(f"{'noise':<8} {'RMS z':>7} {'coverage':>9} {'max |z|':>8} {'successes':>10}  warnings")
    for k, r in res.items():
        print(f"{k:<8} {r['rms_z']:7.3f} {r['coverage']:9.3f} {r['max_abs_z']:8.2f} "
              f"{r['successes']:>4}/{r['runs']:<5}  {', '.join(r['warnings']) or '-'}")
    if a.whitened:
        whitened(seeds, runs)
    print(f"CPU {time.process_time() - t0:.1f} s")


def whitened_errors(seeds, runs: dict) -> dict[str, list]:
    """The noise-auto separations' errors whitened by their stated covariance (``conftest.whitened_error``), per seed:
    ``{"all": [...], "instrument": [...]}`` (every coefficient, the instrument's alone)."""
    from conftest import whitened_error

    ws: dict[str, list] = {"all": [], "instrument": []}
    for seed in seeds:
        r, n = runs[seed, "auto"].result, runs[seed].model.n_coefficients
        err = r.estimate - runs[seed].truth_vector()
        ws["all"].append(whitened_error(err, r.covariance))
        ws["instrument"].append(whitened_error(err[:n], r.covariance[:n, :n]))
    return ws


def whitened(seeds, runs: dict) -> None:
    """Print the whitened-error check of the noise-auto separations (the suite's reduced test, full size)."""
    from conftest import dishonest_whitened
    from scipy.stats import chi2

    ws = whitened_errors(seeds, runs)
    bad = dishonest_whitened(ws, rms=(0.80, 1.30), false_alarm=1e-4)
    print("noise auto, errors whitened by the stated covariance")
    for k, w in ws.items():
        q = [float(x @ x) for x in w]
        over = sum(qk > chi2.ppf(0.95, x.size) for qk, x in zip(q, w))
        print(f"{k:<11} RMS w {np.sqrt(sum(q) / sum(x.size for x in w)):.3f}  w^T w {' '.join(f'{v:.1f}' for v in q)}"
              f"  over chi2 95 %: {over}/{len(w)}  {'DISHONEST ' + str(bad[k]) if k in bad else 'honest'}")


if __name__ == "__main__":
    main()
