"""strapdown33: body-axis error model of a strapdown IMU, 33 coefficients (docs/reference/model.md).

The sensors are fixed to the body: their errors act in body axes and reach the navigation frame
(casep's launch-inertial frame) through the INS attitude C(q), q the Hamilton quaternion of the
flight's columns q_w, q_x, q_y, q_z (scalar first, body to navigation). Inputs: fb (fb_x, fb_y, fb_z,
measured body specific force, m/s^2) and w (w_x, w_y, w_z, measured body rate, rad/s); the model's
m.f is the navigation-frame specific force f_nav = C fb (read or computed from them). g0 = 9.80665.

Accelerometer error, axis i (m/s^2), j, k the other two axes:

    delta_f_i = ba_i + sa_i fb_i + ma_ij fb_j + ma_ik fb_k

Gyro error, axis i (rad/s):

    delta_w_i = bg_i + sg_i w_i + mg_ij w_j + mg_ik w_k + sum_j gg_ij fb_j / g0

Units: ba mg (times g0), sa ppm, ma arcsec, bg deg/h, sg ppm, mg arcsec, gg deg/h/g.

Attitude error phi: INS attitude = (I - [phi x]) true attitude, so phidot = -C delta_w; the
velocity error dv_dot = C delta_f + f_nav x phi. In casep's slots: gyro_drift = -C delta_w,
accel_error = C delta_f, and the f x phi term is the one every model gets (S_V's [f x] Phi).
The navigation frame is inertial, so no Earth-rate or transport-rate terms appear.
"""

import casadi as ca

import casep
from casep.model.strapdown import strapdown_inputs
from casep.units import G0

AX = "xyz"


def build() -> casep.ErrorModel:
    m = casep.ErrorModel("strapdown33", "strapdown IMU, body axes: accelerometer (12) + gyro (21) errors")
    C, fb, w = strapdown_inputs(m)
    spec = {}
    for i in AX:  # accelerometers: bias, scale factor, misalignment (typical magnitudes of a tactical IMU)
        spec[f"ba_{i}"] = ("mg", 1.0)
        spec[f"sa_{i}"] = ("ppm", 300.0)
        spec.update({f"ma_{i}{j}": ("arcsec", 60.0) for j in AX if j != i})
    for i in AX:  # gyros: bias, scale factor, misalignment, g-sensitivity
        spec[f"bg_{i}"] = ("deg/h", 1.0)
        spec[f"sg_{i}"] = ("ppm", 100.0)
        spec.update({f"mg_{i}{j}": ("arcsec", 60.0) for j in AX if j != i})
        spec.update({f"gg_{i}{j}": ("deg/h/g", 1.0) for j in AX})
    c = vars(m.declare(**spec))
    df, dw = [], []
    for a, i in enumerate(AX):
        df.append(c[f"ba_{i}"] + c[f"sa_{i}"] * fb[a]
                  + sum(c[f"ma_{i}{j}"] * fb[b] for b, j in enumerate(AX) if j != i))
        dw.append(c[f"bg_{i}"] + c[f"sg_{i}"] * w[a]
                  + sum(c[f"mg_{i}{j}"] * w[b] for b, j in enumerate(AX) if j != i)
                  + sum(c[f"gg_{i}{j}"] * fb[b] / G0 for b, j in enumerate(AX)))
    m.set_accel_error(C @ ca.vertcat(*df))   # Delta = C delta_f, m/s^2
    m.set_gyro_drift(-C @ ca.vertcat(*dw))   # phidot = -C delta_w, rad/s
    return m
