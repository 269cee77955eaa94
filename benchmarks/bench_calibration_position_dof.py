"""Std of platform36_ground on a six-position (Ferraris) test: the position error from 3 degrees of freedom.

Seeded sessions with positions tilted by TILT deg rms; per coefficient RMS(error / std), the coverage of
95 % normal and t(3) intervals, and RMS(error / std) with the std rescaled to the true position error.

    python benchmarks/bench_calibration_position_dof.py [TILT_DEG] [SESSIONS]
"""

from __future__ import annotations

import sys
import warnings

import numpy as np
from scipy import stats

from casep.calibration.calibrate import calibrate, load_calibration_model
from casep.calibration.simulate import ferraris_design, simulate_session

SIZE = {"mg": 5.0, "mg/g": 0.5, "ug/g": 200.0, "ug/g^2": 50.0, "deg/h": 10.0, "deg/h/g": 5.0, "deg/h/g^2": 2.0,
        "ppm": 500.0, "arcsec": 60.0}
NAMES = ("Ka0z", "Ka2z", "Ka1yz", "Ka1xz", "Ka1z", "Ka1x", "Ka0x")


def main(tilt: float = 0.5, sessions: int = 60) -> None:
    m = load_calibration_model("platform36_ground")
    rng = np.random.default_rng(0)
    # the cross-quadratic accelerometer terms are 0: six positions cannot determine them
    truth = {n: SIZE.get(u, 1.0) * rng.normal() for n, u in zip(m.names, m.units) if not (n.startswith("Ka2")
                                                                                           and len(n) > 4)}
    z, z_true, tilts, dofs = [], [], [], []
    for seed in range(sessions):
        ses, segs = simulate_session(m, truth, ferraris_design(200, 200), rate=100.0, noise=(2e-3, 1e-4),
                                     position_error_deg=tilt, seed=seed)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            cal = calibrate(ses, segs, m, "ols")
        d = cal.sensors["accelerometer"].diagnostics
        tilts.append(d["position_error_deg"])
        dofs.append(d["position_error_dof"])
        zz = np.array([(cal.value(n) - truth[n]) / cal.std(n) for n in NAMES])
        z.append(zz)
        z_true.append(zz * d["position_error_deg"] / tilt)  # the std that the true position error gives
    z, z_true = np.array(z), np.array(z_true)
    q = stats.t.ppf(0.975, dofs[0])
    print(f"{sessions} sessions, positions {tilt} deg rms: estimated {np.mean(tilts):.3f} deg mean, "
          f"{dofs[0]} degrees of freedom")
    print(f"{'coefficient':<12} {'RMS z':>6} {'cover N':>8} {'cover t':>8} {'RMS z (true tilt)':>18}")
    for j, n in enumerate(NAMES):
        print(f"{n:<12} {np.sqrt(np.mean(z[:, j] ** 2)):>6.2f} {np.mean(np.abs(z[:, j]) < 1.96):>8.2f} "
              f"{np.mean(np.abs(z[:, j]) < q):>8.2f} {np.sqrt(np.mean(z_true[:, j] ** 2)):>18.2f}")


if __name__ == "__main__":
    main(*(float(sys.argv[1]),) if len(sys.argv) > 1 else (), *(int(sys.argv[2]),) if len(sys.argv) > 2 else ())
