"""strapdown42_extended: strapdown33 plus the terms users add (9 more): an example to copy.

- accelerometer second order along its own axis, ka2_i (ug/g^2): delta_f_i += ka2_i (fb_i / g0)^2;
- initial attitude error phi0_i (arcsec, navigation frame): the INS attitude at the first sample is
  (I - [phi0 x]) true (an alignment error; a flight whose telemetry starts after lift-off needs it);
- tracking-point lever arm l_i (m, body axes, from the IMU): tracking follows a point at C l, whose
  velocity is v + C (w x l), so dv = v_tel - v_trk gains -C (w x l) (a direct velocity term).

Conventions and columns: strapdown33 (q_*, fb_*, w_*).
"""

import casadi as ca

import casep
from casep.model.strapdown import strapdown_inputs
from casep.units import G0


def build() -> casep.ErrorModel:
    m = casep.build_model("strapdown33")  # unlocked: terms may still be added
    m.name = "strapdown42_extended"
    m.description = "strapdown33 + accelerometer second order (3), initial attitude error (3), lever arm (3)"
    C, fb, w = strapdown_inputs(m)  # the same symbols strapdown33 used
    c = m.declare(ka2_x=("ug/g^2", 50.0), ka2_y=("ug/g^2", 50.0), ka2_z=("ug/g^2", 50.0),
                  phi0_x=("arcsec", 60.0), phi0_y=("arcsec", 60.0), phi0_z=("arcsec", 60.0),
                  l_x=("m", 0.5), l_y=("m", 0.5), l_z=("m", 0.5))
    second = ca.vertcat(c.ka2_x * fb[0] ** 2, c.ka2_y * fb[1] ** 2, c.ka2_z * fb[2] ** 2) / G0**2  # m/s^2
    m.set_accel_error(m.output("accel_error") + C @ second)
    m.set_initial_misalignment(ca.vertcat(c.phi0_x, c.phi0_y, c.phi0_z))  # rad
    m.set_velocity_error(-C @ ca.cross(w, ca.vertcat(c.l_x, c.l_y, c.l_z)))  # m/s
    return m
