"""strapdown15_phi0: strapdown12 plus the initial attitude error (15 coefficients).

What a navigation computed from raw IMU data and levelled on the pad (``casep navigate``) needs at the
least: the levelling turns the horizontal accelerometer biases into a tilt and the given heading is
known only so well, so the attitude at the first sample is off by phi0:

    delta_f_i = ba_i + sa_i fb_i,     delta_w_i = bg_i + sg_i w_i      (strapdown12, body axes)
    INS attitude at the first sample = (I - [phi0 x]) true,  phi0_i (arcsec, navigation frame)

phi0 is free here because the navigation's alignment is not casep's to differentiate (telemetry from
elsewhere); ``casep separate --imu`` adds the levelling's own phi0 = A D instead, and a window model frees
phi0 per window (docs/reference/model.md, "The initial attitude error").

Flight columns: q_w, q_x, q_y, q_z (Hamilton, scalar first, body to navigation), fb_x, fb_y, fb_z
(m/s^2), w_x, w_y, w_z (rad/s).
"""

import casadi as ca

import casep


def build() -> casep.ErrorModel:
    m = casep.build_model("strapdown12")  # unlocked: terms may still be added
    m.name = "strapdown15_phi0"
    m.description = "strapdown12 + initial attitude error phi0_i (arcsec, navigation frame)"
    c = m.declare(phi0_x=("arcsec", 60.0), phi0_y=("arcsec", 60.0), phi0_z=("arcsec", 60.0))
    m.set_initial_misalignment(ca.vertcat(c.phi0_x, c.phi0_y, c.phi0_z))  # rad
    return m
