"""strapdown15_axial: the strapdown33 terms a rolling boost with axial thrust can determine (15).

A rocket whose specific force is along its body x axis (thrust minus drag; fb_y = fb_z = 0) and which
rolls about it excites only some of strapdown33's terms: the accelerometer bias of each axis, the x
scale factor and the y, z accelerometers' misalignment to x (ma_yx, ma_zx: they see fb_x), and for
each gyro the bias, the response to the roll rate w_x (sg_x, mg_yx, mg_zx) and the g-sensitivity to
fb_x (gg_ix). Every term in fb_y, fb_z has a zero column, and the pitch and yaw rates (a degree per
second) leave the other rate terms weak: `casep diagnose FLIGHT --model strapdown33` shows it on a
flight. Same names, units, equations and columns as strapdown33 (docs/reference/model.md).
"""
import casadi as ca

import casep
from casep.model.strapdown import strapdown_inputs
from casep.units import G0


def build() -> casep.ErrorModel:
    m = casep.ErrorModel("strapdown15_axial", "strapdown33's terms a rolling boost with axial thrust determines (15)")
    C, fb, w = strapdown_inputs(m)
    c = m.declare(ba_x=("mg", 1.0), ba_y=("mg", 1.0), ba_z=("mg", 1.0), sa_x=("ppm", 300.0),
                  ma_yx=("arcsec", 60.0), ma_zx=("arcsec", 60.0),
                  bg_x=("deg/h", 1.0), bg_y=("deg/h", 1.0), bg_z=("deg/h", 1.0), sg_x=("ppm", 100.0),
                  mg_yx=("arcsec", 60.0), mg_zx=("arcsec", 60.0),
                  gg_xx=("deg/h/g", 1.0), gg_yx=("deg/h/g", 1.0), gg_zx=("deg/h/g", 1.0))
    df = ca.vertcat(c.ba_x + c.sa_x * fb[0], c.ba_y + c.ma_yx * fb[0], c.ba_z + c.ma_zx * fb[0])
    dw = ca.vertcat(c.bg_x + c.sg_x * w[0] + c.gg_xx * fb[0] / G0, c.bg_y + c.mg_yx * w[0] + c.gg_yx * fb[0] / G0,
                    c.bg_z + c.mg_zx * w[0] + c.gg_zx * fb[0] / G0)
    m.set_accel_error(C @ df)  # Delta = C delta_f, m/s^2
    m.set_gyro_drift(-C @ dw)  # phidot = -C delta_w, rad/s
    return m
