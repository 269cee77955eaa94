"""casep's checks on casep's own output: the car cut navigated and merged, the warnings it raises on itself.

Runs the chain of tests/workflows/test_windows.py on the vendored 70 s cut (tests/data/car_drive/) and
counts the StrapdownWarning (attitude against the integrated body rate) and the near-duplicate time
tag warnings; then the strapdown check's disagreement on each window's navigate output, against the
navigator's own increments and against a trapezoid of the body rate.

    python benchmarks/car_drive_self_checks.py
"""

from __future__ import annotations

import gzip
import shutil
import tempfile
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from casep.frames import LaunchSite
from casep.io.strapdown import StrapdownWarning, check_strapdown
from casep.navigation.imu import read_imu
from casep.rotations import quat_conjugate, quat_multiply, quat_to_rotvec
from casep.workflows.windows import separate_windows

DATA = Path(__file__).resolve().parents[1] / "tests" / "data" / "car_drive"


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        with gzip.open(DATA / "imu.csv.gz", "rb") as src, open(Path(tmp) / "imu.csv", "wb") as dst:
            shutil.copyfileobj(src, dst)
        imu = read_imu(Path(tmp) / "imu.csv")
    trk = pd.read_csv(DATA / "tracking.csv")
    site = LaunchSite(float(trk.lat[0]), float(trk.lon[0]), float(trk.h[0]), 0.0, 0.0)
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        res = separate_windows(imu, DATA / "tracking.csv", site, (0.0, 30.0), length=15.0, start=36.0,
                               attitude_passes=2, fit_options={"noise": "gmw", "robust": None})
    strap = [str(w.message) for w in rec if issubclass(w.category, StrapdownWarning)]
    dup = [str(w.message) for w in rec if "near-duplicate" in str(w.message)]
    print(f"windows: {len(res.windows)}; StrapdownWarning: {len(strap)}; near-duplicate time tag: {len(dup)}")
    for m in (strap[:1] + dup[:1]):
        print("  e.g.", m[:300])
    from casep.navigation.navigator import navigate

    nav = navigate(imu, site, (0.0, 30.0), heading_deg=0.0)
    sel = nav.t >= 36.0
    t, q, w = nav.t[sel], nav.q[sel], nav.w[sel]
    _, info = check_strapdown("car", t, q, nav.fb[sel], w)
    rv = quat_to_rotvec(quat_multiply(quat_conjugate(q[:-1]), q[1:]))
    trap = 0.5 * (w[1:] + w[:-1]) * np.diff(t)[:, None]
    err = np.linalg.norm(rv - trap, axis=1) / np.diff(t)
    rel = np.sqrt(np.sum((rv - trap) ** 2) / np.sum(trap**2))
    print(f"navigate output from 36 s ({t.size} samples at {1 / np.median(np.diff(t)):.0f} Hz): "
          f"against the navigator's increments {np.degrees(info['rms_rate_error_rad_s']):.3g} deg/s RMS; "
          f"against a trapezoid {np.degrees(np.sqrt(np.mean(err**2))):.3g} deg/s RMS ({100 * rel:.3g} %)")


if __name__ == "__main__":
    main()
