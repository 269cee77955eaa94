"""Seeded Monte Carlo: radar separation with the launch time given wrong, station terms and instrument terms.

An Andøya-like site (69.29 N, 16.02 E, azimuth 350 deg), two stations (A1 6.7 km away, B2 30 km), the
``--launch-time`` given `offset` s late against a true 0. Prints, per seed, ``dt_launch`` (ms) with its std
and the worst station-term z, then the RMS z and 95 % coverage of the station terms, the instrument terms
and all terms, for the right launch time and the wrong one.

    OPENBLAS_NUM_THREADS=1 python benchmarks/mc_radar_launch_time.py [--seeds 6] [--offset 0.15] [--rate 10]
"""

from __future__ import annotations

import argparse
import dataclasses
import time
import warnings

import numpy as np

from casep.frames import LaunchSite
from casep.radar.stations import Station
from casep.simulation.radar import simulate_radar
from casep.workflows.radar import separate_radar

SITE = LaunchSite(69.29, 16.02, 20.0, 350.0, 0.0)
STATIONS = (Station("A1", 69.35, 16.05, 50.0), Station("B2", 69.10, 15.70, 300.0))
TRUTH = {"A1": {"range_bias": 4.0, "azimuth_bias": 15.0}, "B2": {"time_bias": 3.0, "elevation_bias": -10.0}}


def run(seed: int, offset: float, rate: float) -> tuple[dict[str, float], dict]:
    """``({name: z}, record)`` of one seeded flight separated with the launch time `offset` s off."""
    sim = simulate_radar(STATIONS, SITE, seed=seed, telemetry_rate=rate, radar_rate=rate, tracking_truth=TRUTH)
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


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=6)
    ap.add_argument("--first-seed", type=int, default=21)
    ap.add_argument("--offset", type=float, default=0.15)
    ap.add_argument("--rate", type=float, default=10.0)
    a = ap.parse_args()
    for off in (0.0, a.offset):
        zs, cpu = [], time.process_time()
        for seed in range(a.first_seed, a.first_seed + a.seeds):
            z, rec = run(seed, off, a.rate)
            zs.append(z)
            st = {k: v for k, v in z.items() if "." in k}
            worst = max(st, key=lambda k: abs(st[k]))
            print(f"offset {off:g} s seed {seed}: success {rec['success']}, dt_launch {rec['dt']:.4g} +- {rec['sd']:.2g} ms"
                  f" (z {z['dt_launch']:+.2f}), re-solves {rec['passes']}, worst station term {worst} z {st[worst]:+.2f}")
        for label, pick in (("station terms", lambda k: "." in k), ("instrument", lambda k: "." not in k
                                                                     and k != "dt_launch"), ("all", lambda k: True)):
            v = np.array([x for z in zs for k, x in z.items() if pick(k)])
            print(f"offset {off:g} s {label}: RMS z {np.sqrt(np.mean(v**2)):.3f}, coverage {np.mean(np.abs(v) < 1.96):.3f}"
                  f", max |z| {np.max(np.abs(v)):.2f} (n {v.size})")
        print(f"offset {off:g} s: {time.process_time() - cpu:.1f} s CPU")


if __name__ == "__main__":
    main()
