"""Benchmark: `casep.navigation.navigate` on 10 minutes of a stationary IMU at 800 Hz (480 000 samples).

The record is an ideal IMU at rest on the pad (the specific force minus the WGS84 normal gravity,
the rate the Earth's, in body axes tilted by 20, 5, -3 deg), given as rates and forces and as
angle and velocity increments. Printed: CPU seconds of each (process time, so a loaded machine
does not count), the largest speed relative to the Earth over the 10 minutes (zero up to the
mechanisation's rounding and the vertical channel), and the fixed-point passes of the gravity
iteration.

Run:  python benchmarks/bench_navigate.py [--rate 800] [--minutes 10]
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
from scipy.spatial.transform import Rotation

from casep.frames import LaunchSite
from casep.gravity import normal_gravity_ecef
from casep.navigation import ImuData, check_imu, navigate

SITE = LaunchSite(67.89, 21.1, 330.0, 30.0, 100.0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rate", type=float, default=800.0)
    ap.add_argument("--minutes", type=float, default=10.0)
    args = ap.parse_args()
    C_tb = Rotation.from_euler("ZYX", [20.0, 5.0, -3.0], degrees=True).as_matrix()
    t = np.arange(0.0, 60.0 * args.minutes, 1.0 / args.rate)
    n = len(t)
    w = np.tile(C_tb.T @ SITE.earth_rate, (n, 1))
    f = np.tile(C_tb.T @ -(SITE.C.T @ normal_gravity_ecef(SITE.r_site)), (n, 1))
    heading = (SITE.azimuth_deg + math.degrees(math.atan2(C_tb[2, 0], C_tb[0, 0]))) % 360.0
    h = np.full((n, 1), 1.0 / args.rate)
    inputs = {"rates": ImuData(t, w, f),
              "increments": ImuData(t, np.zeros_like(w), np.zeros_like(f), "increments", w * h, f * h)}
    print(f"{n} samples ({args.rate:g} Hz x {60 * args.minutes:g} s)")
    for name, imu in inputs.items():
        start = time.process_time()
        res = navigate(check_imu(imu), SITE, (0.0, 10.0), heading_deg=heading)
        cpu = time.process_time() - start
        _, v_e = res.earth_relative()
        print(f"  {name:10s} {cpu:6.2f} CPU s   largest speed relative to the Earth {np.abs(v_e).max():.2e} m/s   "
              f"gravity passes {res.passes}")


if __name__ == "__main__":
    main()
