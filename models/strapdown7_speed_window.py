"""strapdown7_speed_window: strapdown6_window + a vertical accelerometer error proportional to the ground speed (13).

For a window of a ground vehicle's record (``casep.workflows.windows``, whose window flights carry the tracked
ground speed as the column ``ground_speed``, m/s): the body z accelerometer's bias is ``ba_z + kv_z * speed``.
An empirical term, not a sensor law: it describes a vertical accelerometer error that grows with the vehicle's
speed whatever its cause (vibration of the road and the wheels rectified by the sensor, air flow over a roof
mount), which a constant bias takes as a different ``ba_z`` in every window driven at a different speed. A window
that holds its speed cannot tell kv_z from ba_z (the same column up to a constant); one that speeds up and slows
down can. Conventions as strapdown6_window and strapdown33 (docs/reference/model.md):

    delta_f_x = ba_x,  delta_f_y = ba_y,  delta_f_z = ba_z + kv_z ground_speed,  delta_w_i = bg_i
    kv_z in mg per m/s; phi0_i (arcsec), dv0_i (m/s) as strapdown6_window

Flight columns: q_*, fb_*, w_*, ground_speed.
"""

import casadi as ca

import casep
from casep.model.strapdown import strapdown_inputs


def build() -> casep.ErrorModel:
    m = casep.ErrorModel("strapdown7_speed_window", "strapdown biases (6) + vertical accelerometer error per m/s of "
                                                    "ground speed (1) + phi0 (3) + dv0 (3)")
    C, _fb, _w = strapdown_inputs(m)
    c = vars(m.declare(**{f"ba_{i}": ("mg", 10.0) for i in "xyz"}, kv_z=("mg", 0.5),
                       **{f"bg_{i}": ("deg/h", 360.0) for i in "xyz"},
                       **{f"phi0_{i}": ("arcsec", 3600.0) for i in "xyz"},
                       **{f"dv0_{i}": ("m/s", 0.05) for i in "xyz"}))
    speed = m.signal("ground_speed")  # m/s
    m.set_accel_error(C @ ca.vertcat(c["ba_x"], c["ba_y"], c["ba_z"] + c["kv_z"] * speed))  # m/s^2
    m.set_gyro_drift(-C @ ca.vertcat(*(c[f"bg_{i}"] for i in "xyz")))  # rad/s
    m.set_initial_misalignment(ca.vertcat(*(c[f"phi0_{i}"] for i in "xyz")))  # rad
    m.set_initial_velocity_error(ca.vertcat(*(c[f"dv0_{i}"] for i in "xyz")))  # m/s
    return m
