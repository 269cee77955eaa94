"""Allan deviation of the static poses of the real hand-turned sessions: what drift sizes are realistic.

For each MPU-9150 session of Mikov et al. (tests/data/mikoff_mpu9150, SI, 100 Hz) the poses are found
by ``casep.calibration.segment.detect_static``; allantools' overlapping Allan deviation of each pose
(``allantools.oadev``) is pooled over the poses (weighted by the number of terms) at 0.1-3 s, and set
beside the white noise's own ``adev(0.1 s) sqrt(0.1 / tau)``; the excess at the pose length bounds the
drift. The pose means' scatter over the session and their lag-1 correlation show the drift at the
session's scale (a slow drift correlates neighbouring poses).

    .venv/bin/python benchmarks/allan_real_sessions.py
"""

from __future__ import annotations

import gzip
import warnings
from pathlib import Path

import allantools
import numpy as np

from casep.calibration.segment import detect_static

DATA = Path(__file__).resolve().parents[1] / "tests" / "data" / "mikoff_mpu9150"
TAUS = np.array([0.1, 0.3, 1.0, 2.0, 3.0])


def pooled_oadev(x: np.ndarray, poses, rate: float) -> np.ndarray:
    """Overlapping Allan deviation per axis at TAUS, pooled over the poses (allantools per pose)."""
    num, den = np.zeros((len(TAUS), 3)), np.zeros((len(TAUS), 3))
    for a, b in poses:
        for j in range(3):
            t, ad, _, n = allantools.oadev(x[a:b, j], rate=rate, data_type="freq", taus=TAUS)
            for tau, v, k in zip(t, ad, n):
                i = int(np.argmin(np.abs(TAUS - tau)))
                num[i, j] += k * v * v
                den[i, j] += k
    return np.sqrt(num / np.where(den > 0, den, np.nan))


def main() -> None:
    for i in range(5):
        with gzip.open(DATA / f"imu{i}.log.gz", "rt") as f:
            a = np.loadtxt(f)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            seg = detect_static(a[:, :3], a[:, 3:], 100.0, gravity=9.81)
        lens = np.array([b - c for c, b in seg.poses]) / 100.0
        print(f"imu{i}: {len(seg.poses)} poses, {lens.min():.1f}-{lens.max():.1f} s (median {np.median(lens):.1f} s)")
        for name, cols, unit in (("acc", slice(0, 3), "m/s^2"), ("gyro", slice(3, 6), "rad/s")):
            ad = np.nanmean(pooled_oadev(a[:, cols], seg.poses, 100.0), axis=1)
            white = ad[0] * np.sqrt(TAUS[0] / TAUS)
            print(f"  {name:<4} ADEV {unit}: " + "  ".join(f"{t:g} s {v:.2e} (white {w:.2e})"
                                                         for t, v, w in zip(TAUS, ad, white)))
            means = np.array([a[c:b, cols].mean(axis=0) for c, b in seg.poses])
            if name == "gyro":
                d = means - means.mean(axis=0)
                lag1 = np.sum(d[1:] * d[:-1], axis=0) / np.sum(d * d, axis=0)
                print(f"       pose means' std {np.std(means, axis=0, ddof=1).mean():.2e} {unit}, lag-1 correlation "
                      + ", ".join(f"{v:+.2f}" for v in lag1))


if __name__ == "__main__":
    main()
