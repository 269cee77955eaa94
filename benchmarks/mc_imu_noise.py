"""Monte Carlo of the IMU's own white noise in the std of ``casep separate --imu``: RMS z and coverage.

The flight of ``tests/workflows/test_imu_noise_budget.py``: a rail launch at Esrange, 10 s on the pad, then an
axial boost with a roll programme; no sensor error (truth 0: one linear pass is exact), an IMU (20 Hz) whose
every sample carries white noise (gyro 2e-3 rad/s, accelerometer 0.05 m/s^2), tracking at 5 Hz with
Gauss-Markov (tau 1 s, 0.03 m/s) plus white (0.015 m/s) noise. Each run draws both with its own seed and
separates with :func:`casep.workflows.imu_separate.separate_imu` in one pass: the noise kind and tau given
(``--spec gmw``, the test's) or the default fit (``--spec auto``: OLS, the noise model chosen by REML). z =
estimate / std over the 15 coefficients, with the std of the result (the IMU's random walks included and the
tracking noise fitted again by REML beside them, :func:`casep.workflows.imu_separate.imu_noise_budget`) and with
those of the fit's tracking noise alone. 12 runs: tau given RMS z 0.704, coverage 1.000; REML 0.716, 0.994
(conservative: the std average over each axis's tau, ea59a78, and carry the steps between samples the record keeps
since 1c94ff1, which this truth, the record's own navigation, does not hold: docs/guide/navigate.md; at a9fc540,
before both, 0.906, 0.972 and 0.949, 0.983, and 40 runs: tau given 0.937, 0.938; REML 0.908, 0.965).

Run:  OPENBLAS_NUM_THREADS=1 python benchmarks/mc_imu_noise.py [--runs 12] [--spec gmw|auto]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "workflows"))


def main() -> None:
    import test_imu_noise_budget as flight
    from mc_strapdown import _line  # the same summary line (benchmarks/ is the script's folder)

    from casep.estimators.spec import FitSpec
    from casep.navigation import ImuData, check_imu, navigate

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=12)
    ap.add_argument("--spec", choices=("gmw", "auto"), default="gmw")
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    spec = flight.SPEC if args.spec == "gmw" else FitSpec.build()
    t, w, f = flight.clean_record()
    clean = (t, w, f, navigate(check_imu(ImuData(t, w, f)), flight.SITE, flight.ALIGN,
                               heading_deg=flight.heading_of_x()))
    z: dict[str, list] = {"with IMU noise": [], "tracking only": []}
    factors, t0 = [], time.process_time()
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(1, args.runs + 1):
            res = flight.one_pass(*flight.noisy_imu_flight(Path(tmp), clean, seed), spec=spec).result
            imu = res.diagnostics["noise"]["imu"]
            z["with IMU noise"].append(res.estimate / res.std)
            z["tracking only"].append(res.estimate / np.array([imu["std_tracking_noise_only"][n] for n in res.names]))
            factors.append(imu["std_factor_max"])
    head = (f"{args.runs} runs, spec {args.spec}, {time.process_time() - t0:.0f} CPU s; the IMU's part raises the "
            f"largest std by {min(factors):.3g}-{max(factors):.3g} x")
    print("\n".join([head, *(_line(name, np.concatenate(zs)) for name, zs in z.items())]))


if __name__ == "__main__":
    main()
