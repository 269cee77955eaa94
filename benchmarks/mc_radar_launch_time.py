"""Seeded Monte Carlo: radar separation with the launch time given wrong, station terms and instrument terms.

An Andøya-like site (69.29 N, 16.02 E, azimuth 350 deg), two stations (A1 6.7 km from the pad, B2 30 km), the
``--launch-time`` given `offset` s late against a true 0. A launch-time correction enters the rows as
``h(t0 + dt) - h(t0)``; the linear ``dt_launch`` column carries its first order, the rest (25 m of Earth turn at
69 deg latitude for 150 ms, seen from 6.7 km) is re-solved at the correction found
(:func:`casep.workflows.radar._at_launch_time`). Prints, per seed, ``dt_launch`` (ms) with its std, the
re-solves and the worst station-term z, then the RMS z, 95 % coverage and max |z| of the station terms, the
instrument terms and all terms, for the right launch time and the wrong one; ``--linear`` fits the wrong one
with the linear column alone (the fit before the re-solve).

    OPENBLAS_NUM_THREADS=1 python benchmarks/mc_radar_launch_time.py [--seeds 6] [--offset 0.15] [--rate 10]
        [--radar-rate 20] [--noise-scale 1] [--linear]
"""

from __future__ import annotations

import argparse
import dataclasses
import time
import warnings

import numpy as np

import casep.regression.linearisation as lin_rule
from casep.frames import LaunchSite
from casep.radar.stations import Station
from casep.simulation.radar import DEFAULT_NOISE, simulate_radar
from casep.workflows.radar import separate_radar

SITE = LaunchSite(69.29, 16.02, 20.0, 350.0, 0.0)
STATIONS = (Station("A1", 69.35, 16.05, 50.0), Station("B2", 69.10, 15.70, 300.0))
TRUTH = {"A1": {"range_bias": 4.0, "azimuth_bias": 15.0}, "B2": {"time_bias": 3.0, "elevation_bias": -10.0}}


def run(sim, offset: float) -> tuple[dict[str, float], dict]:
    """``({name: z}, record)`` of one simulated flight separated with the launch time `offset` s off."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rr = separate_radar(sim.telemetry, list(sim.radars), dataclasses.replace(SITE, t0=offset), sim.model,
                            sim.tracking, diagnostics=False)
    res = rr.result
    n = sim.model.n_coefficients
    truth = {**dict(zip(res.names[:n], sim.truth[:n])),
             **{f"{st}.{k}": v for st, d in sim.tracking_truth.items() for k, v in d.items()},
             "dt_launch": -1e3 * offset}
    z = {nm: (e - truth.get(nm, 0.0)) / s for nm, e, s in zip(res.names, res.estimate, res.std)
         if np.isfinite(s) and s > 0}
    j = res.names.index("dt_launch")
    return z, {"success": rr.success, "dt": res.estimate[j], "sd": res.std[j],
               "passes": res.settings.get("launch_time_resolved", {}).get("passes", 0)}


def _summary(off: float, zs: list[dict[str, float]]) -> None:
    parts = (("station terms", lambda k: "." in k), ("instrument", lambda k: "." not in k and k != "dt_launch"),
             ("all", lambda k: True))
    for label, pick in parts:
        v = np.array([x for z in zs for k, x in z.items() if pick(k)])
        print(f"offset {off:g} s {label}: RMS z {np.sqrt(np.mean(v**2)):.3f}, coverage "
              f"{np.mean(np.abs(v) < 1.96):.3f}, max |z| {np.max(np.abs(v)):.2f} (n {v.size})")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=6)
    ap.add_argument("--first-seed", type=int, default=21)
    ap.add_argument("--offset", type=float, default=0.15)
    ap.add_argument("--rate", type=float, default=10.0, help="telemetry rate, Hz")
    ap.add_argument("--radar-rate", type=float, default=20.0, help="radar rate, Hz (casep simulate's default)")
    ap.add_argument("--noise-scale", type=float, default=1.0, help="the simulator's default radar noise times this")
    ap.add_argument("--linear", action="store_true", help="the linear dt_launch alone: no re-solve")
    a = ap.parse_args()
    if a.linear:
        lin_rule.LINEAR_OFFSET_SHARE = np.inf
    noise = {k: a.noise_scale * v for k, v in DEFAULT_NOISE.items()}
    sims = [simulate_radar(STATIONS, SITE, seed=seed, telemetry_rate=a.rate, radar_rate=a.radar_rate,
                           tracking_truth=TRUTH, noise=noise) for seed in range(a.first_seed, a.first_seed + a.seeds)]
    for off in (0.0, a.offset):
        zs, cpu = [], time.process_time()
        for sim in sims:
            z, rec = run(sim, off)
            zs.append(z)
            st = {k: v for k, v in z.items() if "." in k}
            worst = max(st, key=lambda k: abs(st[k]))
            print(f"offset {off:g} s seed {sim.seed}: success {rec['success']}, dt_launch {rec['dt']:.4g} +- "
                  f"{rec['sd']:.2g} ms (z {z['dt_launch']:+.2f}), re-solves {rec['passes']}, worst station term "
                  f"{worst} z {st[worst]:+.2f}")
        _summary(off, zs)
        print(f"offset {off:g} s: {time.process_time() - cpu:.1f} s CPU{', linear alone' if a.linear else ''}")


if __name__ == "__main__":
    main()
