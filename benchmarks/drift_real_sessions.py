"""The bias drift the real calibration sessions show (casep.calibration.drift), and what it does to the biases' std.

MPU-9150 (Mikov et al., five hand-turned sessions, tests/data/mikoff_mpu9150): ``casep calibrate --segments
auto`` per session; per sensor the drift's share of a pose mean's variance, its std and correlation time, the
bias std, and (no prior) the largest drift of correlation time the session's length the session allows (95 %)
with the bias std it would give; whether DriftWarning fires.

imucal's annotated session (tests/data/imucal, a Ferraris session in raw counts at 204.8 Hz: six static poses
of ~5 s cut out of a longer recording, the ``samples`` column keeping the recording's sample numbers): the six
poses are too few for the multiposition fit, so its gyro pose means (the Ferraris model's gyro bias) are put
through the same drift fit (``pose_mean_bias``, times from ``samples``) and their scatter set beside what white
noise predicts (chi-square), with the poses' pooled Allan deviation (allantools) against white noise's slope;
counts in deg/s by the labelled calibration's gyro scale.

    .venv/bin/python benchmarks/drift_real_sessions.py
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np

DATA = Path(__file__).resolve().parents[1] / "tests" / "data"


def mpu() -> None:
    from casep.calibration.handturned import DriftWarning, calibrate_multiposition_file

    for i in range(5):
        with warnings.catch_warnings(record=True) as held:
            warnings.simplefilter("always")
            cal = calibrate_multiposition_file(DATA / "mikoff_mpu9150" / f"imu{i}.log.gz", rate=100.0,
                                               acc_unit="m/s^2", gyr_unit="rad/s", gravity=9.81)
        warned = {k for k in ("accelerometer", "gyro") for w in held
                  if isinstance(w.message, DriftWarning) and f"the {k}" in str(w.message)}
        t = np.array([np.mean([a, b]) for a, b in cal.segmentation.poses]) / 100.0
        print(f"imu{i}: {len(cal.segmentation.poses)} poses over {np.ptp(t):.0f} s")
        for k, v in cal.settings["drift"].items():
            b = v["slow_bound"]
            print(f"  {k:<13} drift {100 * v['share']:3.0f} % of a pose mean's variance, std "
                  f"{np.mean(v['sigma_d']):.2e} {v['unit']}, tau ~{v['tau_s']:.0f} s; bias std "
                  f"{np.mean(v['bias_std']):.2e}; a drift of tau {b['tau_s']:.0f} s up to "
                  f"{'>=' if b['at_grid_end'] else ''}{np.mean(b['sigma_d']):.2e} allowed, bias std then "
                  f"{np.mean(b['bias_std']):.2e} {v['bias_unit']}; DriftWarning {'yes' if k in warned else 'no'}")


def imucal() -> None:
    import allantools

    from casep.calibration.calibrate import calibrate_files
    from casep.calibration.handturned import pose_mean_bias
    from casep.calibration.session import read_session, segments_from_labels

    path = DATA / "imucal" / "annotated_session.csv"
    rate = 204.8
    ses = read_session(path, rate=rate, label_column="part")
    lab = calibrate_files(path, rate=rate, label_column="part", gravity=9.81, angle_deg=360.0)
    k = np.array([lab.value(f"Mg_{a}{a}") for a in "xyz"])  # counts per deg/s
    samples = np.loadtxt(path, delimiter=",", skiprows=1, usecols=1)
    poses = [(int(s.rows[0]), int(s.rows[-1]) + 1) for s in segments_from_labels(ses) if s.kind == "static"]
    gm = np.array([ses.gyr[a:b].mean(axis=0) for a, b in poses])
    n = np.array([b - a for a, b in poses])
    t = np.array([samples[a:b].mean() for a, b in poses]) / rate
    within = np.array([ses.gyr[a:b].var(axis=0, ddof=1) for a, b in poses])  # white noise per sample
    chi2 = np.sum((gm - np.average(gm, axis=0, weights=n)) ** 2 / (within / n[:, None]), axis=0)
    bias, std, fit = pose_mean_bias(gm, t, n, rate)
    dps = 1.0  # counts / k: deg/s
    print(f"imucal annotated session: {len(poses)} static poses of {n.min() / rate:.1f}-{n.max() / rate:.1f} s over "
          f"{np.ptp(t):.0f} s of the recording")
    print("  gyro pose means (deg/s): " + "; ".join(", ".join(f"{v:+.3f}" for v in row / k * dps) for row in gm))
    print(f"  scatter against white noise: chi-square {', '.join(f'{c:.1f}' for c in chi2)} on {len(poses) - 1} dof "
          f"(x, y, z); drift fit: {100 * fit.drift_share:.0f} % of a pose mean's variance, std "
          f"{', '.join(f'{v:.3g}' for v in fit.sigma_d / k * dps * 3600)} deg/h, -2 ln Lambda {fit.lr_stat:.1f}; "
          f"bias std {', '.join(f'{v:.3g}' for v in std / k * dps * 3600)} deg/h")
    b = fit.bound
    print(f"  a drift of tau {b['tau_s']:.0f} s (the poses' span) up to {'>=' if b['at_grid_end'] else ''}"
          f"{', '.join(f'{v:.3g}' for v in b['sigma_d'] / k * dps * 3600)} deg/h allowed (95 %), bias std then "
          f"{', '.join(f'{v:.3g}' for v in np.sqrt(b['covariance'][:, 0, 0]) / k * dps * 3600)} deg/h")
    taus = np.array([0.05, 0.1, 0.3, 1.0])
    num = np.zeros((len(taus), 3))
    den = np.zeros((len(taus), 3))
    for a, b in poses:
        for j in range(3):
            tt, ad, _, cnt = allantools.oadev(ses.gyr[a:b, j] / k[j] * dps * 3600, rate=rate, data_type="freq",
                                              taus=taus)
            for tau, v, c in zip(tt, ad, cnt):
                i = int(np.argmin(np.abs(taus - tau)))
                num[i, j] += c * v * v
                den[i, j] += c
    ad = np.sqrt(num / den).mean(axis=1)
    print("  gyro Allan deviation (deg/h, pooled over the poses): " + "  ".join(
        f"{t:g} s {v:.0f} (white {ad[0] * math.sqrt(taus[0] / t):.0f})" for t, v in zip(taus, ad)))


if __name__ == "__main__":
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        imucal()
    mpu()
