"""casep's checks on casep's own output: a real car drive navigated in windows, merged with its tracking.

What :func:`casep.workflows.windows.separate_windows` does to each window before separating it,
without the separation: navigate the window (:func:`casep.navigation.navigate_from`, from the tracked
state and the pad's levelled attitude), write the strapdown telemetry, read it back with the tracking
(:func:`casep.io.files.read_flight_pair`: the strapdown check, the merge on the tracking grid) and
run the plausibility check (:func:`casep.checks.plausibility.check_flight`: the near-duplicate time
tag). Counts the warnings casep raises on its own output, and prints the attitude check's figures
beside those of a trapezoid of the body rate (the comparison the check made before).

Data: the whole drive (``--data``, as benchmarks/car_drive.py; /work/shared/data/rtklibexplorer_car)
or the test suite's 70 s cut (default, tests/data/car_drive/).

    OPENBLAS_NUM_THREADS=1 python benchmarks/car_drive_self_checks.py
    OPENBLAS_NUM_THREADS=1 python benchmarks/car_drive_self_checks.py --data /work/shared/data/rtklibexplorer_car
"""

from __future__ import annotations

import argparse
import gzip
import os
import shutil
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

CUT = Path(__file__).resolve().parents[1] / "tests" / "data" / "car_drive"


def _files(data: str | None, tmp: str) -> tuple[str, str]:
    if data is None:
        imu_path = os.path.join(tmp, "imu.csv")
        with gzip.open(CUT / "imu.csv.gz", "rb") as src, open(imu_path, "wb") as dst:
            shutil.copyfileobj(src, dst)
        return imu_path, str(CUT / "tracking.csv")
    import sys

    sys.path.insert(0, os.path.dirname(__file__))
    from car_drive import convert  # the benchmark's conversion of the raw files

    imu_path, trk_path, _ = convert(data, tmp)
    return imu_path, trk_path


def _trapezoid(t: np.ndarray, q: np.ndarray, w: np.ndarray) -> tuple[float, float]:
    """RMS |quaternion step - trapezoid of w| / dt (rad/s) and relative to the RMS trapezoid."""
    from casep.rotations import quat_conjugate, quat_multiply, quat_to_rotvec

    rv = quat_to_rotvec(quat_multiply(quat_conjugate(q[:-1]), q[1:]))
    trap = 0.5 * (w[1:] + w[:-1]) * np.diff(t)[:, None]
    err = np.linalg.norm(rv - trap, axis=1) / np.diff(t)
    return float(np.sqrt(np.mean(err**2))), float(np.sqrt(np.sum((rv - trap) ** 2) / np.sum(trap**2)))


def main() -> None:
    import pandas as pd

    from casep.checks.plausibility import check_flight
    from casep.frames import LaunchSite, ecef_to_launch, geodetic_to_ecef
    from casep.io.files import read_flight_pair, write_table
    from casep.io.strapdown import StrapdownWarning
    from casep.navigation.imu import ImuData, read_imu
    from casep.navigation.navigator import navigate, navigate_from

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=None, help="the raw drive's folder (default: the test suite's cut)")
    ap.add_argument("--length", type=float, default=15.0, help="window length, s")
    args = ap.parse_args()
    c0 = time.process_time()
    with tempfile.TemporaryDirectory() as tmp:
        imu_path, trk_path = _files(args.data, tmp)
        imu = read_imu(imu_path)
        trk = pd.read_csv(trk_path)
        site0 = LaunchSite(float(trk.lat[0]), float(trk.lon[0]), float(trk.h[0]), 0.0, 0.0)
        moving = float(trk.t[np.hypot(trk.v_east, trk.v_north) > 0.3].iloc[0])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the pad's own alignment warnings are not what is counted
            nav0 = navigate(imu, site0, (0.0, moving - 5.0), heading_deg=0.0)
        r_e, v_e = geodetic_to_ecef(trk.lat.to_numpy(), trk.lon.to_numpy(), trk.h.to_numpy(),
                                    trk.v_east.to_numpy(), trk.v_north.to_numpy(), trk.v_up.to_numpy())
        counts = {"windows": 0, "strapdown": 0, "near_duplicate": 0}
        first: dict[str, str] = {}
        rate_err, trap_err, trap_rel = [], [], []
        t_a = moving + 1.0
        while t_a + args.length <= min(imu.t[-1], trk.t.iloc[-1]):
            j = int(np.searchsorted(nav0.t, t_a))
            t_a = float(nav0.t[j])
            site = LaunchSite(float(np.interp(t_a, trk.t, trk.lat)), float(np.interp(t_a, trk.t, trk.lon)),
                              float(np.interp(t_a, trk.t, trk.h)), 0.0, t_a)
            at = [np.array([[np.interp(t_a, trk.t, x[:, c]) for c in range(3)]]) for x in (r_e, v_e)]
            r0, v0 = ecef_to_launch(site, np.array([t_a]), at[0], at[1])
            sel = (imu.t >= t_a) & (imu.t <= t_a + args.length)
            nav = navigate_from(ImuData(imu.t[sel], imu.w[sel], imu.f[sel]), site, nav0.q[j], r0[0], v0[0])
            tel = os.path.join(tmp, "window.parquet")
            write_table(tel, nav.columns())
            with warnings.catch_warnings(record=True) as rec:
                warnings.simplefilter("always")
                flight = read_flight_pair(tel, trk_path, tracking_frame="geodetic", site=site)
                check_flight(flight)
            for w in rec:
                kind = ("strapdown" if issubclass(w.category, StrapdownWarning)
                        else "near_duplicate" if "near-duplicate" in str(w.message) else None)
                if kind:
                    counts[kind] += 1
                    first.setdefault(kind, str(w.message)[:240])
            info = flight.meta.get("strapdown", {})
            rate_err.append(info.get("rms_rate_error_rad_s", np.nan))
            a, b = _trapezoid(nav.t, nav.q, nav.w)
            trap_err.append(a)
            trap_rel.append(b)
            counts["windows"] += 1
            t_a = float(nav.t[-1])
    print(f"{counts['windows']} windows of {args.length:g} s; warnings on casep's own output: "
          f"StrapdownWarning {counts['strapdown']}, near-duplicate time tag {counts['near_duplicate']} "
          f"({time.process_time() - c0:.1f} CPU s)")
    for k, m in first.items():
        print(f"  e.g. {k}: {m}")
    print(f"attitude steps against the navigator's increments: {np.degrees(np.nanmax(rate_err)):.3g} deg/s RMS "
          f"(worst window); against a trapezoid of w: {np.degrees(np.sqrt(np.mean(np.square(trap_err)))):.3g} "
          f"deg/s RMS, {100 * np.max(trap_rel):.3g} % of the step rotation (worst window)")


if __name__ == "__main__":
    main()
