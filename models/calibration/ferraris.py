"""ferraris: the Ferraris et al. (1995) / imucal model of an IMU read in raw units.

Accelerometer reading ``y_a = M_a f + b_a`` with ``M_a = K_a R_a`` (scale times misalignment,
imucal's names), f the specific force in the sensor frame (m/s^2); gyro reading
``y_g = M_g omega + K_ga f + b_g`` with ``M_g = K_g R_g``, omega in deg/s and the g-sensitivity
``K_ga`` per m/s^2 of specific force, as imucal (which uses the calibrated acceleration there).
``a.u.`` is the unit the session's columns are recorded in (counts, or m/s^2 and deg/s if the
sensor already converts). Matrix entry ``Ma_ij``: reading axis i per unit of true axis j.
"""

import math

import casadi as ca

import casep.calibration as cc

_AX = "xyz"


def build() -> cc.CalibrationModel:
    m = cc.CalibrationModel("ferraris", "Ferraris/imucal: K_a R_a, b_a; K_g R_g, K_ga, b_g (raw readings)",
                            readings="raw")
    deg_s = 180.0 / math.pi  # a coefficient per deg/s times omega in rad/s: (180/pi) per rad/s
    Ma = [[m.coefficient(f"Ma_{i}{j}", "a.u./(m/s^2)", si_factor=1.0) for j in _AX] for i in _AX]
    ba = [m.coefficient(f"ba_{i}", "a.u.", si_factor=1.0) for i in _AX]
    Mg = [[m.coefficient(f"Mg_{i}{j}", "a.u./(deg/s)", si_factor=deg_s) for j in _AX] for i in _AX]
    Kga = [[m.coefficient(f"Kga_{i}{j}", "a.u./(m/s^2)", si_factor=1.0) for j in _AX] for i in _AX]
    bg = [m.coefficient(f"bg_{i}", "a.u.", si_factor=1.0) for i in _AX]
    f, w = m.f, m.omega  # m/s^2, rad/s
    # y_a = M_a f + b_a
    m.set_accel_reading(ca.vertcat(*[sum(Ma[i][j] * f[j] for j in range(3)) + ba[i] for i in range(3)]))
    # y_g = M_g omega + K_ga f + b_g
    m.set_gyro_reading(ca.vertcat(*[sum(Mg[i][j] * w[j] + Kga[i][j] * f[j] for j in range(3)) + bg[i]
                                    for i in range(3)]))
    return m
