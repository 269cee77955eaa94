"""Strapdown telemetry with MEMS-grade errors: the iterated separation against the linear one, a seeded Monte Carlo.

The flight: the independent INS of ``tests/conftest.py`` (:func:`ins_telemetry`: an aircraft-like manoeuvre, the
INS integrating its measured rates and forces at 8 steps per 25 Hz telemetry sample), with strapdown12 errors of
MEMS size (gyro biases 1000, -800, 600 deg/h, scale factors 300-400 ppm, accelerometer biases 1-2.5 mg), tracking
with white noise (`--noise` m/s, default 0.02) at `--trk-rate` Hz, `--dur` s. Each seed is separated as ``casep
separate TEL --tracking TRK --model strapdown12 --noise white --robust none`` twice: the default (iterated when the
linear estimate's second-order remainder moves it by more than a tenth of its std:
:mod:`casep.workflows.telemetry_iterate`) and ``--no-iterate`` (the linear pass, flagged).

Printed per seed: the remainder shift (std), passes, status, and the RMS of z = (estimate - truth) / std and the
share within 1.96 std for both; then the pooled figures.

Run:  OPENBLAS_NUM_THREADS=1 python benchmarks/mc_telemetry_iterate.py [--seeds 1 2 3 4 5 6] [--dur 30]
"""

from __future__ import annotations

import argparse
import importlib.util
import math
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

import casep
from casep.io.files import write_table

#: The injected coefficients (natural units of strapdown12).
MEMS = {"ba_x": 1.05, "ba_y": 1.78, "ba_z": -2.55, "sa_x": -41.0, "sa_y": 304.0, "sa_z": 406.0,
        "bg_x": 1000.0, "bg_y": -800.0, "bg_z": 600.0, "sg_x": 400.0, "sg_y": -350.0, "sg_z": 300.0}


def _simulator():
    """``ins_telemetry`` of tests/conftest.py (the suite's independent INS)."""
    spec = importlib.util.spec_from_file_location("casep_tests_conftest",
                                                  Path(__file__).resolve().parents[1] / "tests" / "conftest.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.ins_telemetry


def mems_flights():
    """The strapdown12 model, its true coefficients (:data:`MEMS`, natural units) and ``flight(seed, directory, dur,
    trk_rate, noise, tracking_noise=None)``: one seed's telemetry and tracking (the INS of :func:`_simulator` with the
    MEMS errors, no IMU noise, white tracking noise `noise` m/s), written to `directory` and read back as a flight;
    ``tracking_noise(trk)``, if given, adds to the tracking columns before they are written."""
    ins = _simulator()
    model = casep.load_model("strapdown12")

    def flight(seed: int, directory, dur: float, trk_rate: float, noise: float, tracking_noise=None):
        tel, trk, _, _ = ins(seed=seed, errors=MEMS, imu_noise=False, growth=0.0, noise=noise, dur=dur,
                             trk_rate=trk_rate)
        if tracking_noise is not None:
            tracking_noise(trk)
        write_table(Path(directory) / "tel.csv", tel)
        write_table(Path(directory) / "trk.csv", trk)
        return casep.read_flight_pair(Path(directory) / "tel.csv", Path(directory) / "trk.csv")

    return model, np.array([MEMS[n] for n in model.names]), flight


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3, 4, 5, 6])
    ap.add_argument("--dur", type=float, default=30.0)
    ap.add_argument("--trk-rate", type=float, default=2.0)
    ap.add_argument("--noise", type=float, default=0.02)
    a = ap.parse_args()
    model, truth, make_flight = mems_flights()
    pooled: dict[str, list] = {"iterated": [], "linear": []}
    with tempfile.TemporaryDirectory() as tmp:
        for seed in a.seeds:
            flight = make_flight(seed, tmp, a.dur, a.trk_rate, a.noise)
            line = [f"seed {seed:3d}"]
            for kind, it in (("iterated", None), ("linear", False)):
                t0 = time.process_time()
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    res = casep.separate(flight, model, noise="white", robust="none", iterate=it)
                z = (res.estimate - truth) / res.std
                pooled[kind].append(z)
                lin = res.diagnostics["linearisation"]
                passes = len(res.diagnostics.get("iterations", {}).get("passes", [])) or 1
                line.append(f"{kind}: shift {lin['shift_std']:.3g} std, passes {passes}, status {res.status}, "
                            f"RMS z {math.sqrt(np.mean(z**2)):.3f}, within 1.96 std {np.mean(np.abs(z) < 1.96):.2f}, "
                            f"{time.process_time() - t0:.1f} s CPU")
            print(" | ".join(line), flush=True)
    for kind, zs in pooled.items():
        z = np.concatenate(zs)
        print(f"pooled {kind}: {len(zs)} flights, RMS z {math.sqrt(np.mean(z**2)):.3f}, coverage "
              f"{np.mean(np.abs(z) < 1.959964):.3f}, max |z| {np.abs(z).max():.2f}")


if __name__ == "__main__":
    main()
