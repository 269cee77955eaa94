"""How often :func:`casep.navigation.alignment.pad_rate_causes` names a set-up mistake, on synthetic pads.

Each pad: a site at a latitude uniform in -60..60 deg, a rail azimuth uniform in 0..360, the IMU's x axis at a
heading uniform in 0..360 and tilted up to 20 deg in pitch and roll; the mean gyro rate is the Earth rate in body
axes plus a gyro bias N(0, sigma^2) per axis (pads whose rate exceeds 3 times the Earth rate are skipped: the
pad-rate test is not made on them). For each pad, the largest evidence factor over the causes is taken for the
set-up as given (a false naming when it reaches a threshold) and for three mistakes: two gyro columns swapped (y,
z), the latitude's sign flipped, the heading given 90 deg off. :data:`casep.navigation.alignment.CAUSE_FACTOR` is
set to 1 here so that every factor is seen; the thresholds are ``--thresholds`` (the shipped factor is 300).

Printed per sigma: the false namings at each threshold out of the pads kept, and the namings of each mistake.

Run::

    OPENBLAS_NUM_THREADS=1 python benchmarks/pad_rate_causes_mc.py --seed 1 --sigma 1 3 6.6 10 [--pads 60]
"""

from __future__ import annotations

import argparse
import math

import numpy as np

DEG_H = math.radians(1.0 / 3600.0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--sigma", type=float, nargs="+", default=[1.0, 3.0, 6.6, 10.0], help="gyro bias std, deg/h")
    ap.add_argument("--pads", type=int, default=60, help="pads drawn per sigma")
    ap.add_argument("--thresholds", type=float, nargs="+", default=[100.0, 300.0, 1000.0, 3000.0])
    args = ap.parse_args()

    from scipy.spatial.transform import Rotation

    from casep.frames import OMEGA_EARTH, LaunchSite
    from casep.gravity import normal_gravity_ecef
    from casep.navigation import alignment as al

    al.CAUSE_FACTOR = 1.0
    rng = np.random.default_rng(args.seed)
    thr = np.array(args.thresholds)
    x_b = np.eye(3)[0]
    s = np.full(3, 1e-9)  # the mean's noise: negligible beside any bias
    for sigma in args.sigma:
        false = np.zeros(thr.size, int)
        named = {k: np.zeros(thr.size, int) for k in ("swap", "lat", "hdg90")}
        kept = 0
        for _ in range(args.pads):
            lat = rng.uniform(-60.0, 60.0)
            site = LaunchSite(lat, 10.0, 0.0, rng.uniform(0.0, 360.0), 0.0)
            C_tb = Rotation.from_euler("ZYX", [rng.uniform(0, 360), rng.uniform(-20, 20), rng.uniform(-20, 20)],
                                       degrees=True).as_matrix()
            g_t = site.C.T @ normal_gravity_ecef(site.r_site)
            up_t = -g_t / np.linalg.norm(g_t)
            up_b = C_tb.T @ up_t
            b = al.gyro_bias_allowance(site)
            hdg = al._azimuth(C_tb[:, 0], site)
            w = C_tb.T @ site.earth_rate + rng.normal(scale=sigma * DEG_H, size=3)
            if np.linalg.norm(w) > 3 * OMEGA_EARTH:
                continue
            kept += 1

            def best(w_, site_, h_, up_b=up_b, up_t=up_t, b=b):
                C = al._triad(up_b, x_b, up_t, al._horizontal(h_, site_))
                causes = al.pad_rate_causes(w_, s, C.T @ site_.earth_rate, b, site_, h_, up_b, up_t, x_b)
                return max([c.factor for c in causes], default=0.0)

            false += best(w, site, hdg) >= thr
            named["swap"] += best(w[[0, 2, 1]], site, hdg) >= thr
            named["lat"] += best(w, LaunchSite(-lat, 10.0, 0.0, site.azimuth_deg, 0.0), hdg) >= thr
            named["hdg90"] += best(w, site, (hdg + 90.0) % 360.0) >= thr
        print(f"bias {sigma:4.1f} deg/h/axis, factor >= {thr.astype(int).tolist()}: false {false.tolist()}/{kept}; "
              + "; ".join(f"{k} {v.tolist()}" for k, v in named.items()), flush=True)


if __name__ == "__main__":
    main()
