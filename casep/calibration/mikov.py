"""The parameters of Mikov, Reginya and Moschevikin (ICINS 2020) from the ``multiposition`` model's, and their table.

Their model (imu-calib, ``imu_model.py``): ``raw = M true + b`` with ``M = [[1+S_X, NO_Y, NO_Z],
[0, 1+S_Y, NO_X], [0, 0, 1+S_Z]]`` for both sensors, and for the gyro also the rotation
``R_m = (I + [eps]x)^-1`` to the accelerometer frame: ``w_cal = M_g^-1 (R_m w - b_g)``.

From imu_tk's ``T K`` (:mod:`casep.calibration.multiposition`):

- accelerometer: ``M_a = (T_a K_a)^-1`` is upper triangular, as theirs: ``S = diag(M_a) - 1``,
  ``NO_X = M_a[1, 2]``, ``NO_Y = M_a[0, 1]``, ``NO_Z = M_a[0, 2]``; ``b`` the same;
- gyro: ``(T_g K_g)^-1 = (I + [eps]x) M_g``, a QR decomposition (Q = I + [eps]x to first order, R =
  M_g with a positive diagonal); ``b_m = R_m b_g``.

Their table (``real_imu.png``): s in %, misalignments and eps in deg, gyro bias in deg/s (rounded
to 0.001 rad/s before conversion: the values are multiples of 0.0573 deg/s).
"""

from __future__ import annotations

import math

import numpy as np

from casep.calibration.multiposition import acc_matrix, gyro_matrix

__all__ = ["mikov_accelerometer", "mikov_gyro", "MIKOV_TABLE", "MIKOV_ACC_NAMES", "MIKOV_GYRO_NAMES",
           "table_si"]

MIKOV_ACC_NAMES = ("s_x", "s_y", "s_z", "m_yz", "m_xy", "m_xz", "b_x", "b_y", "b_z")
MIKOV_GYRO_NAMES = MIKOV_ACC_NAMES + ("eps_x", "eps_y", "eps_z")
#: The paper's table, columns #1..#5 = imu0..imu4 (s %, m deg, acc b m/s^2, gyro b deg/s, eps deg).
MIKOV_TABLE = {
    "accelerometer": np.array([
        [0.363, 0.471, 0.382, 0.263, 0.251], [0.315, 0.482, 0.355, 0.448, 0.286], [0.647, 0.932, 0.78, 0.721, 0.804],
        [0.123, -0.284, 0.26, -0.009, 0.056], [0.02, -0.01, -0.012, -0.028, 0.0], [0.317, 0.145, 0.282, -0.104, 0.191],
        [0.103, 0.09, 0.096, 0.065, 0.07], [0.097, 0.07, 0.008, 0.092, 0.036], [0.344, 0.338, -0.045, -0.009, 0.182]]),
    "gyro": np.array([
        [0.041, 0.007, -0.058, 0.227, 0.226], [0.457, 0.26, 0.277, 0.599, 0.57], [0.826, -0.179, 0.242, 0.308, 0.853],
        [-0.034, -0.639, 0.15, -0.105, 0.08], [-0.12, 0.21, -0.072, 0.025, 0.178], [0.806, 0.262, 0.876, 0.072, 0.497],
        [1.146, -0.573, 0.573, -1.261, -1.031], [-0.401, 1.089, -0.344, 1.031, 0.401],
        [1.261, 0.286, 1.261, 4.813, 1.432], [0.03, -0.565, 0.142, -0.102, 0.077],
        [-0.364, 0.013, -0.482, -0.129, -0.223], [-0.074, 0.069, -0.079, 0.015, 0.075]]),
}
_D = math.pi / 180.0
_SI = {"accelerometer": np.r_[[0.01] * 3, [_D] * 3, [1.0] * 3], "gyro": np.r_[[0.01] * 3, [_D] * 3, [_D] * 3, [_D] * 3]}


def table_si(sensor: str, column: int) -> np.ndarray:
    """Column `column` (0 = imu0) of the table in SI: s and m dimensionless/rad, b m/s^2 or rad/s, eps rad."""
    return MIKOV_TABLE[sensor][:, column] * _SI[sensor]


def mikov_accelerometer(x: np.ndarray) -> np.ndarray:
    """Their 9 accelerometer parameters (MIKOV_ACC_NAMES, SI) from imu_tk's (ACC_NAMES)."""
    M = np.linalg.inv(acc_matrix(x))
    return np.r_[np.diag(M) - 1.0, M[1, 2], M[0, 1], M[0, 2], x[6:9]]


def mikov_gyro(x: np.ndarray, bias: np.ndarray) -> np.ndarray:
    """Their 12 gyro parameters (MIKOV_GYRO_NAMES, SI) from imu_tk's (GYRO_NAMES) and the bias."""
    Q, R = np.linalg.qr(np.linalg.inv(gyro_matrix(x)))
    s = np.sign(np.diag(R))
    Q, R = Q * s, R * s[:, None]  # R with a positive diagonal (QR is unique up to these signs)
    eps = np.array([Q[2, 1], Q[0, 2], Q[1, 0]])  # Q = I + [eps]x to first order
    return np.r_[np.diag(R) - 1.0, R[1, 2], R[0, 1], R[0, 2], np.linalg.solve(Q, bias), eps]
