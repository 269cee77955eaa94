"""Run the one full-scale rule (:func:`casep.fullscale.held_full_scale`) on IMU records; print what it flags.

Each record is read as a table with columns ``w_x, w_y, w_z, fb_x, fb_y, fb_z`` (casep's raw IMU layout;
``#`` comments, gzip by suffix), or with ``--layout mikoff`` as a whitespace log whose columns 0-2 are the
specific force and 3-5 the rate (the mikoff/imu-calib MPU-9150 sessions, ``tests/data/mikoff_mpu9150``).
``--digits N`` also screens the record as written to N significant digits (a conversion's rounding can make
a column's extreme repeat). Printed per record: its rows and the flags, each ``(sensor, axis, side, value, held
samples)``, and the seconds taken; a real record should show none, a clipped one its clip.

Run::

    python benchmarks/fullscale_screen.py tests/data/car_drive/imu.csv.gz examples/data/imu/*imu.csv
    python benchmarks/fullscale_screen.py --layout mikoff tests/data/mikoff_mpu9150/imu*.log.gz
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np


def read(path: Path, layout: str) -> tuple[np.ndarray, np.ndarray]:
    """Rates and specific force, (N, 3) each, of one record."""
    if layout == "mikoff":
        a = np.loadtxt(path)
        return a[:, 3:6], a[:, 0:3]
    import pandas as pd

    d = pd.read_csv(path, comment="#")
    return d[["w_x", "w_y", "w_z"]].to_numpy(float), d[["fb_x", "fb_y", "fb_z"]].to_numpy(float)


def screen(name: str, w: np.ndarray, f: np.ndarray) -> list[tuple]:
    """Print and return the flags of one record."""
    from casep.fullscale import held_full_scale

    t0 = time.process_time()
    flags = [(kind, h.axis, h.side, h.value, sum(b - a for a, b in h.runs))
             for kind, x, sensor in (("w", w, "gyro"), ("f", f, "accelerometer"))
             for h in held_full_scale(x, sensor)]
    print(f"{name:60s} {len(w):7d} rows  flags={flags}  ({time.process_time() - t0:.2f} s)", flush=True)
    return flags


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("records", nargs="+", type=Path)
    ap.add_argument("--layout", choices=("casep", "mikoff"), default="casep")
    ap.add_argument("--digits", type=int, help="also screen each record rounded to this many significant digits")
    args = ap.parse_args()
    for p in args.records:
        w, f = read(p, args.layout)
        screen(str(p), w, f)
        if args.digits:
            r = np.vectorize(lambda v: float(f"{v:.{args.digits}g}"))
            screen(f"{p} (to {args.digits} digits)", r(w), r(f))


if __name__ == "__main__":
    main()
