"""strapdown15_axial: the strapdown33 terms an axial-thrust rolling boost excites (test model)."""
import casadi as ca
import casep
from casep.model.strapdown import strapdown_inputs
from casep.units import G0


def build() -> casep.ErrorModel:
    m = casep.ErrorModel("strapdown15_axial", "strapdown terms excited by an axial-thrust rolling boost")
    C, fb, w = strapdown_inputs(m)
    c = m.declare(ba_x="mg", ba_y="mg", ba_z="mg", sa_x="ppm", ma_yx="arcsec", ma_zx="arcsec",
                  bg_x="deg/h", bg_y="deg/h", bg_z="deg/h", sg_x="ppm", mg_yx="arcsec", mg_zx="arcsec",
                  gg_xx="deg/h/g", gg_yx="deg/h/g", gg_zx="deg/h/g")
    df = ca.vertcat(c.ba_x + c.sa_x * fb[0], c.ba_y + c.ma_yx * fb[0], c.ba_z + c.ma_zx * fb[0])
    dw = ca.vertcat(c.bg_x + c.sg_x * w[0] + c.gg_xx * fb[0] / G0, c.bg_y + c.mg_yx * w[0] + c.gg_yx * fb[0] / G0,
                    c.bg_z + c.mg_zx * w[0] + c.gg_zx * fb[0] / G0)
    m.set_accel_error(C @ df)
    m.set_gyro_drift(-C @ dw)
    return m
