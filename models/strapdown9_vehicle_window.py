"""strapdown9_vehicle_window: a window of a ground vehicle's record, biases and the terms its turns excite (15).

A car or a ship stays nearly level: the body z axis is near the vertical, the specific force on it stays near
gravity and the rates are mostly about it. strapdown6_window's constant biases then leave out the terms such a
vehicle excites most, and which a consumer MEMS IMU has at percent level (cross-axis sensitivity): the level
gyros' response to the yaw rate (mg_xz, mg_yz: a turn of 50 deg/s through a 1 % cross-axis term is 0.5 deg/s of
apparent x or y bias, and it comes and goes with the turns) and the yaw gyro's scale factor (sg_z). Left out:

- terms whose column is the near-constant fb_z (ma_xz, ma_yz, sa_z, gg_iz): within a window they are the biases;
- the vertical accelerometer's response to the horizontal specific force (ma_zx, ma_zy): on a level vehicle it is
  the level gyros' yaw-rate terms less a rotation of the whole IMU about a level axis (by e about y: mg_xz = e,
  ma_zx = -e, ba_x = e g and an attitude error), which no record of a level vehicle tells from the attitude: with
  both, a window is nearly singular in that direction (the simulated car window of
  tests/model/test_vehicle_window.py: std of 37000 arcsec on ma_zx, mg_xz, phi0_z). The gyro terms carry it.

Names, units and equations as strapdown33 (docs/reference/model.md):

    delta_f_i = ba_i
    delta_w_x = bg_x + mg_xz w_z,  delta_w_y = bg_y + mg_yz w_z,  delta_w_z = bg_z + sg_z w_z
    phi0_i (arcsec), dv0_i (m/s): initial attitude and velocity errors (navigation frame), as strapdown6_window

Declared magnitudes: a consumer MEMS IMU after its biases were estimated at rest (10 mg, 360 deg/h, 1 % scale,
cross-axis 1 % = 2063 arcsec). Flight columns: q_*, fb_*, w_*.
"""

import casadi as ca

import casep
from casep.model.strapdown import strapdown_inputs


def build() -> casep.ErrorModel:
    m = casep.ErrorModel("strapdown9_vehicle_window", "strapdown biases (6) + a level vehicle's yaw-rate cross-axis "
                                                      "and scale terms (3) + phi0 (3) + dv0 (3)")
    C, _fb, w = strapdown_inputs(m)
    c = vars(m.declare(**{f"ba_{i}": ("mg", 10.0) for i in "xyz"}, **{f"bg_{i}": ("deg/h", 360.0) for i in "xyz"},
                       mg_xz=("arcsec", 2000.0), mg_yz=("arcsec", 2000.0), sg_z=("ppm", 10000.0),
                       **{f"phi0_{i}": ("arcsec", 3600.0) for i in "xyz"},
                       **{f"dv0_{i}": ("m/s", 0.05) for i in "xyz"}))
    df = ca.vertcat(c["ba_x"], c["ba_y"], c["ba_z"])
    dw = ca.vertcat(c["bg_x"] + c["mg_xz"] * w[2], c["bg_y"] + c["mg_yz"] * w[2], c["bg_z"] + c["sg_z"] * w[2])
    m.set_accel_error(C @ df)  # m/s^2
    m.set_gyro_drift(-C @ dw)  # rad/s
    m.set_initial_misalignment(ca.vertcat(*(c[f"phi0_{i}"] for i in "xyz")))  # rad
    m.set_initial_velocity_error(ca.vertcat(*(c[f"dv0_{i}"] for i in "xyz")))  # m/s
    return m
