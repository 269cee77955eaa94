"""The simulated sounding rocket at full size, from raw files to the separation: what is masked, said, determined.

Each seed simulates the full :class:`casep.simulation.rocket.RocketSpec` flight (800 Hz IMU with lost
packets and a 75 ms gap at burnout, the gyro clipped at 2000 deg/s in the tumble after apogee, the GNSS
repeating its fix for 26 s after lift-off, 1 s of wrong epochs, a lagged 1 Hz solution with Gauss-Markov
errors of 3 m/s, a clock 104 ppm fast), navigates it (``--gyr-range 2000``, the heading given 0.2 deg
off), and separates it by the default path with ``strapdown15_phi0``. Printed per seed: the status, the
epochs left out (stale, physics check, clipped), whether every pad epoch was kept, the clock drift the
screen measured, and the combinations the failed result says the flight determines with their z
against the truth (the injected coefficients and the navigation's initial attitude error). Then the
RMS z and the 95 % coverage over all combinations. ``--small`` divides the biases by 10 (a contrast:
what is left of the excess z is the linear model's second-order error with a 0.2-0.5 deg initial attitude);
``--set FIELD=VALUE`` changes the flight (``clock_ppm=0``: the clock drift's effect, the same draws).
Measured (24 seeds): RMS z 1.163, coverage 0.906; ``--small`` 0.958, 0.969; before the determined
combinations carried the IMU's noise and each stretch's long-run variance, 1.45 and 0.83 (12 seeds).
``tests/workflows/test_rocket_separation.py`` runs one quick flight.

``--imu iterate`` separates the same raw files by ``casep separate --imu`` instead (navigated, paired,
screened once, iterated along the determined combinations: :mod:`casep.workflows.imu_separate`), ``--imu
one-pass`` by its one linear pass (``--no-iterate``); the truth of the free ``phi0`` is then the attitude
error the levelling of the truly corrected IMU leaves (:func:`_imu_truth`), since the model carries the
levelling's own ``A D``. Printed per seed besides: the passes, whether they converged, each pass's largest
correction in std. Measured figures: ``docs/results/rocket.md``.

Run:  OPENBLAS_NUM_THREADS=1 python benchmarks/rocket_rawlog.py [--seeds 1 2 3 4 5 6] [--small] [--set clock_ppm=0]
                                                                [--imu iterate|one-pass]
"""

from __future__ import annotations

import argparse
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np


def _one(seed: int, small: bool, d: Path, changes: dict | None = None) -> tuple[dict, list[float]]:
    import dataclasses

    from casep.simulation.rocket import RocketSpec, simulate_rocket
    from casep.workflows.separate import separate

    spec = dataclasses.replace(RocketSpec(), **(changes or {}))
    if small:
        spec = dataclasses.replace(spec, acc_bias_mg=spec.acc_bias_mg / 10, gyr_bias_dph=spec.gyr_bias_dph / 10)
    fl = simulate_rocket(seed, spec)
    nav, flight = fl.navigated(d)
    res = separate(flight, "strapdown15_phi0")
    truth = fl.truth(nav.q[0])
    det = res.diagnostics.get("determined") if not res.success else None
    z = []
    if det:
        x = np.array([truth[n] / s for n, s in det["scales"].items()])
        z = [(c["estimate"] - np.dot(c["weights"], x)) / c["std"] for c in det["combinations"]]
    from casep.checks.tracking_quality import screen_tracking

    screened = screen_tracking(flight)
    scr = screened.meta["tracking_screen"]
    pad = flight.observed & (flight.t < fl.site.t0)
    row = {"seed": seed, "status": res.status, "stale": sum(n for *_, n in scr["stale"]),
           "rejected": sum(n for *_, n in scr["rejected"]), "clipped_rows": flight.meta["ins_invalid"]["rows_left_out"],
           "pad_kept": bool(screened.observed[pad].all()), "drift_ppm": scr["drift_ppm"],
           "combinations": len(z)}
    return row, z


def _imu_truth(fl, spec_changes: dict | None = None) -> dict[str, float]:
    """The true coefficients of ``casep separate --imu`` with ``strapdown15_phi0``: the injected ones and, as the free
    ``phi0``, the attitude error of the levelling of the IMU corrected by the true coefficients (the simulator's
    law inverted by hand: ``f = (f_m - ba) / (1 + sa)``, ``w = (w_m - bg) / (1 + sg)``), which is what is left of
    the start attitude's error once the model carries the levelling's own ``A D`` (the given heading's error)."""
    import math

    from casep.navigation import ImuData
    from casep.navigation.navigator import pad_state
    from casep.units import G0

    c = fl.coefficients
    ba = np.array([c[f"ba_{a}"] for a in "xyz"]) * 1e-3 * G0
    sa = np.array([c[f"sa_{a}"] for a in "xyz"]) * 1e-6
    bg = np.radians(np.array([c[f"bg_{a}"] for a in "xyz"]) / 3600.0)
    sg = np.array([c[f"sg_{a}"] for a in "xyz"]) * 1e-6
    w = np.column_stack([fl.imu[f"w_{a}"] for a in "xyz"])
    f = np.column_stack([fl.imu[f"fb_{a}"] for a in "xyz"])
    t = fl.imu["t"]
    pad = t <= fl.align_window[1] + 0.5
    imu = ImuData(t[pad], (w[pad] - bg) / (1 + sg), (f[pad] - ba) / (1 + sa))
    q0 = pad_state(imu, fl.site, fl.align_window, heading_deg=fl.events["heading_deg"],
                   heading_axis=fl.events["heading_axis"])[0]
    assert math.isfinite(q0[0])
    return fl.truth(q0)


def _one_imu(seed: int, small: bool, d: Path, changes: dict | None, iterate: bool) -> tuple[dict, list[float]]:
    """The same flight separated from its raw files by ``casep separate --imu`` (iterated or one linear pass)."""
    import dataclasses
    import math

    from casep.simulation.rocket import HEADING_AXIS, RocketSpec, simulate_rocket
    from casep.workflows.imu_separate import separate_imu

    spec = dataclasses.replace(RocketSpec(), **(changes or {}))
    if small:
        spec = dataclasses.replace(spec, acc_bias_mg=spec.acc_bias_mg / 10, gyr_bias_dph=spec.gyr_bias_dph / 10)
    fl = simulate_rocket(seed, spec)
    fl.write(d / "imu.parquet", d / "gps.parquet")
    out = separate_imu(d / "imu.parquet", d / "gps.parquet", fl.site, fl.align_window, "strapdown15_phi0",
                       heading_deg=fl.events["heading_deg"], heading_axis=HEADING_AXIS, tracking_frame="ecef",
                       gyr_range=math.radians(spec.gyr_range_dps), iterate=iterate)
    res = out.result
    truth = _imu_truth(fl)
    it = res.diagnostics["iterations"]
    det = res.diagnostics.get("determined")
    z = []
    if det:
        x = np.array([truth[n] / s for n, s in det["scales"].items()])
        z = [(c["estimate"] - np.dot(c["weights"], x)) / c["std"] for c in det["combinations"]]
    flight = out.flight
    scr = flight.meta["tracking_screen"]
    pad = (np.asarray(flight.meta["rows_index"]) >= 0) & (flight.t < fl.site.t0)
    row = {"seed": seed, "status": res.status, "stale": sum(n for *_, n in scr["stale"]),
           "rejected": sum(n for *_, n in scr["rejected"]),
           "clipped_rows": (flight.meta.get("ins_invalid") or {}).get("rows_left_out", 0),
           "pad_kept": bool(flight.observed[pad].all()),
           "drift_ppm": scr["drift_ppm"], "combinations": len(z), "passes": len(it["passes"]),
           "converged": it["converged"], "max_z": [round(p["max_z"], 3) for p in it["passes"]]}
    return row, z


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3, 4, 5, 6])
    ap.add_argument("--small", action="store_true", help="biases / 10")
    ap.add_argument("--set", nargs="*", default=[], metavar="FIELD=VALUE",
                    help="change RocketSpec fields (floats), e.g. gps_gm_std=0 gps_lag_s=0")
    ap.add_argument("--imu", choices=["iterate", "one-pass"], default=None,
                    help="separate from the raw files (casep separate --imu): iterated, or one linear pass")
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    zs: list[float] = []
    unconverged: list[int] = []
    changes = {k: float(v) for k, v in (a.split("=", 1) for a in args.set)}
    c0 = time.process_time()
    with tempfile.TemporaryDirectory() as tmp:
        for seed in args.seeds:
            if args.imu:
                row, z = _one_imu(seed, args.small, Path(tmp), changes, args.imu == "iterate")
                print(f"seed {seed}: {row['passes']} passes, converged {row['converged']}, largest correction per "
                      f"pass (std) {row['max_z']}")
                if not row["converged"]:
                    unconverged.append(seed)
            else:
                row, z = _one(seed, args.small, Path(tmp), changes)
            zs += z
            print(f"seed {row['seed']}: status {row['status']}, left out {row['stale']} stale + {row['rejected']} "
                  f"impossible epochs and {row['clipped_rows']} clipped rows, pad kept {row['pad_kept']}, drift "
                  f"{row['drift_ppm']} ppm; {row['combinations']} combinations determined, z "
                  + " ".join(f"{v:+.2f}" for v in z))
    z_arr = np.asarray(zs)
    if z_arr.size:
        print(f"RMS z {np.sqrt(np.mean(z_arr**2)):.3f}, 95 % coverage {np.mean(np.abs(z_arr) <= 1.959964):.3f}, "
              f"max |z| {np.max(np.abs(z_arr)):.2f} over {z_arr.size} combinations of {len(args.seeds)} flights "
              f"({time.process_time() - c0:.1f} CPU s)")
    if args.imu == "iterate":
        print(f"not converged (a failed result): {len(unconverged)} of {len(args.seeds)} flights {unconverged}")


if __name__ == "__main__":
    main()
