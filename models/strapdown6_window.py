"""strapdown6_window: accelerometer and gyro biases for a window of a longer record (12 coefficients).

The window model of strapdown12_window (a window navigated from the tracked state at its first
sample and the running attitude) with the biases only: a vehicle whose specific force stays near
gravity on one axis and whose rates are small (a car, a ship) cannot tell the scale factors from
the biases within a window. Declared magnitudes are a consumer MEMS IMU's after its biases were
estimated at rest (10 mg, 360 deg/h). Coefficients, conventions as strapdown33 (docs/reference/model.md):

    delta_f_i = ba_i (mg),  delta_w_i = bg_i (deg/h),  i in x, y, z (body axes)
    phi0_i (arcsec), dv0_i (m/s): initial attitude and velocity errors (navigation frame)

phi0 and dv0 are free per window: a window starts from the attitude carried from the one before, not from a
levelling whose derivative would tie phi0 to the coefficients (docs/reference/model.md, "The initial attitude
error").
"""

import casadi as ca

import casep
from casep.model.strapdown import strapdown_inputs


def build() -> casep.ErrorModel:
    m = casep.ErrorModel("strapdown6_window", "strapdown biases (6) + initial attitude error phi0 (3) + initial "
                                              "velocity error dv0 (3)")
    C, _fb, _w = strapdown_inputs(m)
    # declared magnitudes: a consumer MEMS IMU after a bias estimate at rest (10 mg, 0.1 deg/s)
    c = vars(m.declare(**{f"ba_{i}": ("mg", 10.0) for i in "xyz"}, **{f"bg_{i}": ("deg/h", 360.0) for i in "xyz"},
                       **{f"phi0_{i}": ("arcsec", 3600.0) for i in "xyz"},
                       **{f"dv0_{i}": ("m/s", 0.05) for i in "xyz"}))
    m.set_accel_error(C @ ca.vertcat(*(c[f"ba_{i}"] for i in "xyz")))  # m/s^2
    m.set_gyro_drift(-C @ ca.vertcat(*(c[f"bg_{i}"] for i in "xyz")))  # rad/s
    m.set_initial_misalignment(ca.vertcat(*(c[f"phi0_{i}"] for i in "xyz")))  # rad
    m.set_initial_velocity_error(ca.vertcat(*(c[f"dv0_{i}"] for i in "xyz")))  # m/s
    return m
