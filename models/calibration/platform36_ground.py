"""platform36_ground: the flight model platform36's 36 terms on a test stand, plus gyro scale.

Readings in SI (the session states its units): accelerometer ``y_a = f + Delta(W, D)`` with
Delta exactly platform36's accelerometer error (Eq. 3: bias mg, scale mg/g, cross-axis ug/g,
second order ug/g^2); gyro ``y_g = omega + eps(W, D) + S omega`` with eps exactly platform36's
drift rate (Eq. 1: bias deg/h, g-sensitivity deg/h/g, deg/h/g^2) and S the gyro scale (ppm) and
misalignment (arcsec) that rotations excite (a stabilised platform's gyros see no rate in
flight, so these are ground-only and are not part of the prior). Sign convention: eps is the
gyro's rate error (reading minus true) and is the platform's drift rate phidot of the flight
model, so a ground Kg0x is the flight Kg0x. The names and units of the 36 shared coefficients
are platform36's: a ground result is a flight prior (``casep separate --method map --prior``).
"""

import casadi as ca

import casep
import casep.calibration as cc

_AX = "xyz"


def build() -> cc.CalibrationModel:
    flight = casep.build_model("platform36")  # the flight equations, not re-typed
    m = cc.CalibrationModel("platform36_ground", "platform36's 36 terms + gyro scale/misalignment (SI readings)",
                            readings="si", flight_model="platform36")
    for name, unit in zip(flight.names, flight.units):
        m.coefficient(name, unit, scale=flight.scales.get(name))  # same name, unit and SI factor
    eps = m.flight_output(flight, "gyro_drift")     # rad/s, platform36 Eq. 1 in this model's symbols
    delta = m.flight_output(flight, "accel_error")  # m/s^2, platform36 Eq. 3
    w = m.omega
    S = [[m.coefficient(f"Sg_{i}{j}", "ppm" if i == j else "arcsec", si_factor=1e-6 if i == j else casep.units.ARCSEC)
          for j in _AX] for i in _AX]
    m.set_accel_reading(m.f + delta)
    m.set_gyro_reading(w + eps + ca.vertcat(*[sum(S[i][j] * w[j] for j in range(3)) for i in range(3)]))
    return m
