"""strapdown12: strapdown IMU with biases and scale factors only (12 coefficients).

The equations, frames and conventions of strapdown33 (docs/reference/model.md) with only
accelerometer bias ba_i (mg) and scale factor sa_i (ppm), gyro bias bg_i (deg/h) and scale
factor sg_i (ppm), i in x, y, z (body axes):

    delta_f_i = ba_i + sa_i fb_i,     delta_w_i = bg_i + sg_i w_i
    gyro_drift = -C delta_w,          accel_error = C delta_f

Flight columns: q_w, q_x, q_y, q_z (Hamilton, scalar first, body to navigation), fb_x, fb_y, fb_z
(m/s^2), w_x, w_y, w_z (rad/s).
"""

import casadi as ca

import casep
from casep.model.strapdown import strapdown_inputs


def build() -> casep.ErrorModel:
    m = casep.ErrorModel("strapdown12", "strapdown IMU, body axes: biases and scale factors (12)")
    C, fb, w = strapdown_inputs(m)
    c = vars(m.declare(**{f"ba_{i}": ("mg", 1.0) for i in "xyz"}, **{f"sa_{i}": ("ppm", 300.0) for i in "xyz"},
                       **{f"bg_{i}": ("deg/h", 1.0) for i in "xyz"}, **{f"sg_{i}": ("ppm", 100.0) for i in "xyz"}))
    df = ca.vertcat(*(c[f"ba_{i}"] + c[f"sa_{i}"] * fb[a] for a, i in enumerate("xyz")))
    dw = ca.vertcat(*(c[f"bg_{i}"] + c[f"sg_{i}"] * w[a] for a, i in enumerate("xyz")))
    m.set_accel_error(C @ df)  # m/s^2
    m.set_gyro_drift(-C @ dw)  # rad/s
    return m
