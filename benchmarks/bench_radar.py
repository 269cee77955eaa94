"""Whole-process wall time of `casep separate` in the measurement domain (two radar stations) against
the velocity-domain separation of the same flight, and a Monte Carlo of the radar estimate.

The flight is the ``paper`` scenario on a rotating Earth (195 s powered flight), launch site
(28.5 N, 80.6 W, 3 m, azimuth 90 deg), stations S1 (28.9 N, 80.0 W) and S2 (28.1 N, 79.2 W),
station errors as in ``tests/radar/test_radar.py``; radar at 20 Hz with 3 m / 8 arcsec noise; telemetry
at 20 Hz and at 100 Hz. The velocity-domain file is the same flight's ``t, f_*, dv_*`` at the
telemetry rate with 0.1 m/s white noise (what ``casep separate FLIGHT.csv`` reads).

Each command runs as its own process (``python -m casep separate ...``, one BLAS thread), five
times; the table gives the median wall time and the ratio.

    python benchmarks/bench_radar.py            # timing table
    python benchmarks/bench_radar.py --mc 100   # plus a 100-run Monte Carlo (z RMS, 95 % coverage)
    python benchmarks/bench_radar.py --diagnostics  # station terms' CRLB, one station against two
    python benchmarks/bench_radar.py --mc-simulator 40  # Monte Carlo of the simulator's own noise
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def _setup(folder: Path, rate: float):
    import casep
    from casep.frames import LaunchSite
    from casep.io.files import write_table
    from casep.radar.stations import Station
    from casep.simulation.radar import simulate_radar, write_radar_simulation

    site = LaunchSite(28.5, -80.6, 3.0, 90.0, 0.0)
    stations = [Station("S1", 28.9, -80.0, 20.0), Station("S2", 28.1, -79.2, 15.0)]
    truth = {"S1": {"range_bias": 5.0, "range_scale": 10.0, "azimuth_bias": 15.0, "elevation_bias": -20.0},
             "S2": {"range_bias": -3.0, "range_scale": -5.0, "azimuth_bias": -10.0, "elevation_bias": 12.0}}
    sim = simulate_radar(stations, site, seed=1, telemetry_rate=rate, radar_rate=20.0, tracking_truth=truth)
    tel = folder / f"tel{rate:g}.csv"
    write_radar_simulation(sim, tel)
    t = sim.telemetry
    dv = casep.build_sv(sim.model, t.t, t.f) @ sim.truth + np.random.default_rng(2).normal(0, 0.1, t.v.shape)
    vel = folder / f"vel{rate:g}.csv"
    write_table(vel, {"t": t.t, **{f"f_{a}": t.f[:, i] for i, a in enumerate("xyz")},
                      **{f"dv_{a}": dv[:, i] for i, a in enumerate("xyz")}})
    radar = []
    for s in stations:
        radar += ["--radar", str(folder / f"{tel.stem}.{s.name}.json"), str(folder / f"{tel.stem}.{s.name}.csv")]
    return ([sys.executable, "-m", "casep", "separate", str(vel)],
            [sys.executable, "-m", "casep", "separate", str(tel), *radar, "--launch-site", "28.5", "-80.6", "3", "90",
             "--launch-time", "0"], sim)


def _time(cmd, repeats: int) -> float:
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    out = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, env=env)
        out.append(time.perf_counter() - t0)
    return statistics.median(out)


def _monte_carlo(runs: int) -> None:
    """The same flight without noise, then fresh noise per run (the simulator's noise model), OLS."""
    import dataclasses
    import warnings

    from threadpoolctl import threadpool_limits

    from casep.frames import LaunchSite
    from casep.radar.stations import Station
    from casep.simulation.radar import simulate_radar
    from casep.units import ARCSEC
    from casep.workflows.radar import separate_radar

    threadpool_limits(1, user_api="blas")  # one BLAS thread, as the timed processes
    warnings.simplefilter("ignore")
    rng = np.random.default_rng(2026)
    zs = []
    stations = [Station("S1", 28.9, -80.0, 20.0), Station("S2", 28.1, -79.2, 15.0)]
    tt = {"S1": {"range_bias": 5.0, "range_scale": 10.0, "azimuth_bias": 15.0, "elevation_bias": -20.0},
          "S2": {"range_bias": -3.0, "range_scale": -5.0, "azimuth_bias": -10.0, "elevation_bias": 12.0}}
    base = simulate_radar(stations, LaunchSite(28.5, -80.6, 3.0, 90.0, 0.0), seed=1, telemetry_rate=20.0,
                          radar_rate=20.0, tracking_truth=tt, noise={"range": 0, "azimuth": 0, "elevation": 0})
    for _ in range(runs):
        radars = [dataclasses.replace(m, range=m.range + rng.normal(0, 3.0, m.t.size),
                                      azimuth=m.azimuth + rng.normal(0, 8 * ARCSEC, m.t.size),
                                      elevation=m.elevation + rng.normal(0, 8 * ARCSEC, m.t.size))
                  for m in base.radars]
        r = separate_radar(base.telemetry, radars, base.site, base.model, base.tracking, "ols", diagnostics=False)
        zs.append((r.result.estimate - base.truth_vector()) / r.result.std)
    z = np.array(zs)
    nD = base.model.n_coefficients
    print(f"\nMonte Carlo, {runs} runs, 2 stations, 20 Hz, range 3 m, angles 8 arcsec, noise std estimated per "
          "station and type, OLS:")
    print("| terms | values | RMS z | 95 % coverage |\n|---|---|---|---|")
    for part, zz in (("instrument", z[:, :nD]), ("tracking", z[:, nD:])):
        print(f"| {part} | {zz.size} | {np.sqrt(np.mean(zz**2)):.3f} | {np.mean(np.abs(zz) < 1.959964):.3f} |")


def _monte_carlo_simulator(runs: int) -> None:
    """Seeds 10 .. 10 + runs - 1 of simulate_radar itself (its own noise; S2 tagged 1 ms late, applied exactly)."""
    import warnings

    from threadpoolctl import threadpool_limits

    from casep.frames import LaunchSite
    from casep.radar.stations import Station
    from casep.simulation.radar import simulate_radar
    from casep.workflows.radar import separate_radar

    threadpool_limits(1, user_api="blas")
    warnings.simplefilter("ignore")
    site = LaunchSite(28.5, -80.6, 3.0, 90.0, 0.0)
    st = [Station("S1", 28.9, -80.0, 20.0), Station("S2", 28.1, -79.2, 15.0)]
    zs = []
    for seed in range(10, 10 + runs):
        sim = simulate_radar(st, site, seed=seed, telemetry_rate=20, radar_rate=20,
                             tracking_truth={"S2": {"time_bias": 1.0}})
        r = separate_radar(sim.telemetry, sim.radars, site, sim.model, sim.tracking, diagnostics=False).result
        zs.append((r.estimate - sim.truth_vector()) / r.std)
    z = np.array(zs)
    nD = sim.model.n_coefficients
    print(f"\nMonte Carlo of the simulator, seeds 10..{9 + runs}, S2 time bias 1 ms (exact), noise estimated, OLS:")
    print("| terms | values | RMS z | 95 % coverage |\n|---|---|---|---|")
    for part, zz in (("instrument", z[:, :nD]), ("tracking", z[:, nD:])):
        print(f"| {part} | {zz.size} | {np.sqrt(np.mean(zz**2)):.3f} | {np.mean(np.abs(zz) < 1.959964):.3f} |")


def _diagnostics() -> None:
    """CRLB of the station terms and the price of freeing them, one station against two (noise given)."""
    import warnings

    from threadpoolctl import threadpool_limits

    from casep.frames import LaunchSite
    from casep.radar.stations import Station
    from casep.simulation.radar import simulate_radar
    from casep.units import ARCSEC
    from casep.workflows.radar import diagnose_radar

    threadpool_limits(1, user_api="blas")
    warnings.simplefilter("ignore")
    site = LaunchSite(28.5, -80.6, 3.0, 90.0, 0.0)
    st = [Station("S1", 28.9, -80.0, 20.0), Station("S2", 28.1, -79.2, 15.0)]
    sim = simulate_radar(st, site, seed=0, telemetry_rate=20, radar_rate=20,
                         noise={"range": 0, "azimuth": 0, "elevation": 0})
    sig = {(s.name, ty): v for s in st for ty, v in (("range", 3.0), ("azimuth", 8 * ARCSEC),
                                                     ("elevation", 8 * ARCSEC))}
    out = {}
    for k in (1, 2):
        radars = list(sim.radars[:k])
        out[k] = diagnose_radar(sim.telemetry, radars, site, sim.model, sim.tracking,
                                sigma={g: v for g, v in sig.items() if g[0] in [m.station.name for m in radars]})
    print("\nStation terms, CRLB std (range 3 m, angles 8 arcsec, 20 Hz, platform36):")
    print("| term | S1 alone | S1 alone, instruments known | S1 + S2 | correlated with (S1 alone) |")
    print("|---|---|---|---|---|")
    two = {r["name"]: r for r in out[2]["tracking"]}
    for r in out[1]["tracking"]:
        cw = ", ".join(f"{a} {v:+.2f}" for a, v in r["correlated_with"].items())
        print(f"| {r['name']} ({r['unit']}) | {r['crlb_std']:.4g} | {r['crlb_std_instrument_fixed']:.4g} | "
              f"{two[r['name']]['crlb_std']:.4g} | {cw} |")
    for k in (1, 2):
        ratios = [r["ratio"] for r in out[k]["instrument"] if r["ratio"] is not None]
        print(f"{k} station(s): instrument CRLB free / fixed: median {np.median(ratios):.3g}, max {max(ratios):.3g}; "
              f"aliased (> 2): {sum(r['aliased'] for r in out[k]['instrument'] if r['ratio'] is not None)}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--mc", type=int, default=0, help="Monte Carlo runs (0: none)")
    ap.add_argument("--rates", default="20,100", help="telemetry rates, Hz")
    ap.add_argument("--diagnostics", action="store_true", help="only the one- vs two-station diagnostics table")
    ap.add_argument("--mc-simulator", type=int, default=0, help="only a Monte Carlo of simulate_radar's own noise")
    args = ap.parse_args()
    if args.diagnostics:
        _diagnostics()
        return
    if args.mc_simulator:
        _monte_carlo_simulator(args.mc_simulator)
        return
    if not args.rates:  # --rates "": the Monte Carlo only
        _monte_carlo(args.mc)
        return
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for rate in (float(r) for r in args.rates.split(",")):
            vel, rad, sim = _setup(Path(tmp), rate)
            tv, tr = _time(vel, args.repeats), _time(rad, args.repeats)
            rows.append((rate, sim.telemetry.t.size, sum(m.t.size for m in sim.radars), tv, tr))
    print("| telemetry | telemetry samples | radar samples (2 stations) | velocity domain, s | radar, s | ratio |")
    print("|---|---|---|---|---|---|")
    for rate, n_tel, n_rad, tv, tr in rows:
        print(f"| {rate:g} Hz | {n_tel} | {n_rad} | {tv:.2f} | {tr:.2f} | {tr / tv:.2f} |")
    print(json.dumps({"rows": rows}))
    if args.mc:
        _monte_carlo(args.mc)


if __name__ == "__main__":
    main()
