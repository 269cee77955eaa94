"""Monte Carlo of the IMU's own white noise in the std of a navigated strapdown telemetry read from one file.

The flight of ``tests/workflows/test_imu_noise_budget.py`` (a rail launch, an axial boost with a roll programme, no
sensor error: truth 0), its IMU (20 Hz) with white noise (gyro 2e-3 rad/s, accelerometer 0.05 m/s^2 per sample)
navigated by casep's navigator from the clean navigation's first state (``v_tel`` carries the random walks), its
tracking (5 Hz, Gauss-Markov tau 1 s 0.03 m/s plus white 0.015 m/s) in the same file (``v_tel_*`` and ``v_trk_*``,
the rows without a fix empty): ``one_file_telemetry`` of that test. Each seed is fitted in one linear pass (the noise
kind and tau given) and its std taken twice: the fit's (tracking noise alone) and with the IMU's noise
(:func:`casep.workflows.imu_separate.with_imu_noise`, the densities measured on the file's rows). z = estimate /
std along the combinations each covariance calls determined (std below the declared magnitudes: ``determined_z``),
pooled. 12 seeds: tracking noise alone RMS z 78.9 over 73 combinations (coverage 0.14); with the IMU's noise 1.06
over 57 (0.91). Over the 15 coefficients (undetermined ones included): 1.735 (0.78) and 0.756 (0.98).

:func:`casep.separate` end to end (its linear result carries the IMU term when it widens a determined combination's
std by more than ``IMU_NOISE_SHARE``, 5 %: :func:`casep.workflows.imu_separate.with_imu_noise_beyond`), on the one
file and on the same flight as a telemetry + tracking pair: 12 seeds, the one file 1.060 over 57 (0.912), every
seed linear with the term carried (before: the tracking noise's std alone); the pair 1.047 over 56 (0.929): 3 seeds
linear with the term carried, 9 iterated (their remainder, judged in the tracking noise's std, 0.42-2.97 std; the
passes carry the noise as before).

Run:  OPENBLAS_NUM_THREADS=1 python benchmarks/mc_telemetry_one_file.py [--seeds 1 .. 12]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "workflows"))


def main() -> None:
    import test_imu_noise_budget as flight
    from test_imu_separate import ALIGN, MODEL, SITE, clean_record, heading_of_x

    from casep.estimators.solve import fit
    from casep.navigation import ImuData, check_imu, navigate
    from casep.workflows.imu_separate import with_imu_noise
    from casep.workflows.separate import _problem

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=list(range(1, 13)))
    a = ap.parse_args()
    t, w, f = clean_record()
    clean = (t, w, f, navigate(check_imu(ImuData(t, w, f)), SITE, ALIGN, heading_deg=heading_of_x()))
    z: dict[str, list] = {"tracking noise alone": [], "with the IMU's noise": [], "casep.separate, one file": [],
                          "casep.separate, pair": []}
    c: dict[str, list] = {k: [] for k in z}
    with tempfile.TemporaryDirectory() as tmp:
        for seed in a.seeds:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                fl, problem, model = _problem(flight.one_file_telemetry(Path(tmp) / f"tel{seed}.csv", clean, seed),
                                              MODEL, None)
                res = fit(problem, flight.SPEC, checks=False)
                out = with_imu_noise(res, problem, fl)
                sep = [flight._separated(clean, Path(tmp), seed, form) for form in ("one file", "pair")]
            for form, r in zip(("one file", "pair"), sep):
                imu, lin = r.diagnostics["noise"]["imu"], r.diagnostics.get("linearisation", {})
                print(f"seed {seed}, {form}: iterated {lin.get('iterated')}, linear remainder {lin.get('shift_std')} "
                      f"std, IMU noise carried (linear result) {imu.get('carried')}, widening "
                      f"{imu.get('determined_std_factor_max')}")
            for key, r in zip(z, (res, out, *sep)):
                ok = np.isfinite(r.std) & (r.std > 0)
                z[key].append((r.estimate / r.std)[ok])
                c[key].append(flight.determined_z(r, r.covariance, model.scales))
    for key in z:
        zz, cc = np.concatenate(z[key]), np.concatenate(c[key])
        print(f"{key}: determined combinations {cc.size}, RMS z {np.sqrt(np.mean(cc**2)):.3f}, coverage "
              f"{np.mean(np.abs(cc) < 1.96):.3f}; coefficients {zz.size}, RMS z {np.sqrt(np.mean(zz**2)):.3f}, "
              f"coverage {np.mean(np.abs(zz) < 1.96):.3f}")


if __name__ == "__main__":
    main()
