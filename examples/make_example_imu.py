"""Make ``examples/data/imu/example_imu.csv``: the raw IMU record docs/guide/navigate.md navigates.

#%% What it is
# A rocket on a rail at Esrange (67.89 N, 21.10 E, 330 m), body x along the rail: 85 deg elevation
# towards azimuth 30 deg. 10 s at rest on the pad (the specific force is minus the WGS84 normal
# gravity and the rate is the Earth's, both in body axes), then 6 s of boost at 8 g along body x
# with a roll programme rising to 2 rad/s, at 50 Hz, with white sensor noise (0.01 m/s^2,
# 1e-4 rad/s per sample, seed 1).
# It is a test record, not a measured flight.
#
# Run:  python examples/make_example_imu.py   (rewrites the file byte for byte)
"""

import argparse
import math
from pathlib import Path

import numpy as np

from casep.frames import LaunchSite
from casep.gravity import normal_gravity_ecef

#%% Build and write
SEED = 1
OUT = Path(__file__).resolve().parent / "data" / "imu" / "example_imu.csv"
SITE = LaunchSite(67.89, 21.10, 330.0, 30.0, 10.0)  # launch azimuth 30 deg, launch time 10 s


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=OUT, help=f"output file (default {OUT.name} in examples/data/imu)")
    out = ap.parse_args().out
    rng = np.random.default_rng(SEED)
    el = math.radians(85.0)
    x = np.array([math.cos(el), math.sin(el), 0.0])  # body x in the launch triad (x downrange, y up)
    y = np.array([-math.sin(el), math.cos(el), 0.0])
    C_tb = np.column_stack([x, y, np.cross(x, y)])  # body -> launch triad
    t = np.round(np.arange(0.0, 16.0, 0.02), 10)
    n = len(t)
    w = np.tile(C_tb.T @ SITE.earth_rate, (n, 1))
    f = np.tile(C_tb.T @ -(SITE.C.T @ normal_gravity_ecef(SITE.r_site)), (n, 1))
    boost = t >= SITE.t0
    f[boost] = [8 * 9.80665, 0.0, 0.0]
    w[boost, 0] += np.minimum(2.0, 0.5 * (t[boost] - SITE.t0))  # the roll programme
    w += rng.normal(scale=1e-4, size=w.shape)
    f += rng.normal(scale=0.01, size=f.shape)
    cols = np.column_stack([t, w, f])
    with open(out, "w") as fh:
        fh.write("# example IMU record (examples/make_example_imu.py): a rail launch, body x along the rail\n")
        fh.write("t,w_x,w_y,w_z,fb_x,fb_y,fb_z\n")
        np.savetxt(fh, cols, delimiter=",", fmt="%.10g")
    print(f"wrote {out}: {n} samples, {t[-1] - t[0]:.2f} s")


if __name__ == "__main__":
    main()
