"""The five real MPU-9150 sessions (Mikov et al., ICINS 2020), calibrated by --segments auto, against their table."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from casep.calibration.handturned import calibrate_multiposition_file
from casep.calibration.mikov import mikov_accelerometer, mikov_gyro, table_si
from casep.calibration.multiposition import acc_matrix, gyro_matrix

DATA = Path(__file__).resolve().parents[1] / "data" / "mikoff_mpu9150"


def test_mikov_parameters_from_imu_tk_round_trip():
    # build their model from known parameters, read it as imu_tk's T K, map back
    s, no, b = np.array([0.004, 0.003, 0.007]), np.array([0.002, 0.0004, 0.0055]), np.array([0.1, 0.09, 0.34])
    M = np.diag(1 + s)
    M[1, 2], M[0, 1], M[0, 2] = no
    TK = np.linalg.inv(M)  # upper triangular: T_a (unit diagonal) times K_a
    k = np.diag(TK)
    T = TK / k[None, :]
    x = np.r_[-T[0, 1], T[0, 2], -T[1, 2], k, b]
    np.testing.assert_allclose(acc_matrix(x), TK, rtol=1e-14, atol=1e-16)
    np.testing.assert_allclose(mikov_accelerometer(x), np.r_[s, no, b], rtol=1e-12, atol=1e-15)
    # gyro: w_cal = M_g^-1 (R_m w - b_m), R_m = (I + [eps]x)^-1 with I + [eps]x replaced by its exact rotation
    from scipy.spatial.transform import Rotation

    eps, bm = np.array([0.0005, -0.0063, -0.0015]), np.array([0.0196, -0.0067, 0.0217])
    Mg = np.diag(1 + np.array([0.0002, 0.0045, 0.0082]))
    Mg[1, 2], Mg[0, 1], Mg[0, 2] = -0.0006, -0.0023, 0.014
    Q = Rotation.from_rotvec(eps).as_matrix()
    A = np.linalg.inv(Q @ Mg)  # w_cal = A (w - b), A^-1 = Q M_g
    # A = T_g K_g: K = diag(A) / diag(T) with T's unit diagonal; solve for the 9 parameters by least squares
    from scipy.optimize import least_squares

    xg = least_squares(lambda p: (gyro_matrix(p) - A).ravel(), np.r_[np.zeros(6), np.ones(3)], xtol=1e-15,
                       ftol=1e-15, gtol=1e-15).x
    got = mikov_gyro(xg, np.linalg.solve(np.linalg.inv(Q), bm))  # b_g = R_m^-1 b_m
    np.testing.assert_allclose(got[:9], np.r_[np.diag(Mg) - 1, Mg[1, 2], Mg[0, 1], Mg[0, 2], bm], atol=1e-12)
    # Q is a rotation: its skew part is eps to first order (|eps|^2 ~ 4e-5)
    np.testing.assert_allclose(got[9:], eps, atol=1e-4)


def _mapped_std(fun, x, C, seed=0, n=2000):
    """Std of fun(x) under N(x, C) (seeded sampling: the maps are nonlinear only at second order)."""
    draws = np.random.default_rng(seed).multivariate_normal(x, C, n)
    return np.std([fun(d) for d in draws], axis=0)


@pytest.mark.parametrize("session", range(5))
def test_mpu9150_session_against_the_published_table(session):
    """Session imu<session> against column #<session + 1> of the paper's table, within the tolerance argued here.

    The table is not a converged least-squares optimum: its optimiser stops after 25 (accelerometer) and 50
    (gyro) evaluations with a soft-l1 loss, and it prints 3 decimals (s in %, m and eps in deg, gyro b in
    deg/s rounded from 1e-3 rad/s). The data's notes argue a tolerance of ~1e-3 on that ground. Per group:

    - accelerometer scales and misalignments: 1e-3 (the notes' tolerance; found: at most 3e-4), and within
      3 std + 1e-4 (the table's rounding at 3 decimals of % and deg is below 1e-4);
    - accelerometer biases: within 3 std + 1e-4 only. Their std on these sessions is 5e-4 to 1.7e-3 m/s^2
      (22 poses, each mean's noise ~1e-3), so a fixed 1e-3 would demand more than the data holds; found:
      up to 1.9e-3 m/s^2 (imu4 b_z) at z <= 2.2;
    - gyro scales, misalignments and eps: within 3 std (~1e-3 from 21 motions) plus the table's rounding
      5e-4; found: z <= 3.1 (imu1, the session the authors' own fit found poor: residual 2.07 against
      0.2-0.4 for the others);
    - gyro biases: 1e-3 rad/s. The table rounds them to 1e-3 rad/s, and theirs are fitted to the motions,
      casep's are the mean of the poses (std ~1e-4), which the motions cannot move; found: at most 9.5e-4.

    Each session takes 0.3-0.5 s (calibration and the std mapped by 2 x 2000 seeded draws; 2.5 s for the file).
    """
    with warnings.catch_warnings():
        # imu0's last pose turns by ~1 deg in 10 s (gyro bias drift): below the 2-deg warning; nothing expected
        warnings.simplefilter("error")
        cal = calibrate_multiposition_file(DATA / f"imu{session}.log.gz", rate=100.0, acc_unit="m/s^2",
                                           gyr_unit="rad/s", gravity=9.81)  # theirs: 9.81 hard-coded
    seg = cal.segmentation
    assert 20 <= len(seg.poses) <= 24 and seg.spread > 0.3
    a = mikov_accelerometer(cal.acc.x)
    sa = _mapped_std(mikov_accelerometer, cal.acc.x, cal.acc.covariance)
    ref = table_si("accelerometer", session)
    assert np.all(np.abs(a - ref)[:6] <= 1e-3), (a - ref)
    assert np.all(np.abs(a - ref) <= 3 * sa + 1e-4), (a - ref) / sa
    xg = np.r_[cal.gyro.x, cal.gyro.bias]
    fun = lambda p: mikov_gyro(p[:9], p[9:])  # noqa: E731
    g = fun(xg)
    sg = _mapped_std(fun, xg, cal.result.covariance[9:, 9:])
    ref = table_si("gyro", session)
    d = np.abs(g - ref)
    assert np.all(d[6:9] <= 1e-3), d[6:9]
    keep = np.r_[0:6, 9:12]
    assert np.all(d[keep] <= 3 * sg[keep] + 5e-4), d[keep] / sg[keep]
