"""strapdown12_window: strapdown12 for a window of a longer record, started from a tracked state (18).

A window of a long free-inertial record (a consumer MEMS IMU drifts out of the linear range within
tens of seconds) is navigated from the tracked position and velocity at its first sample and the
running attitude there. Its dv then starts from the tracking error at that sample and its attitude
from the error the running attitude has accumulated, so the window's model adds to strapdown12's
biases and scale factors (conventions: strapdown33, docs/reference/model.md):

- initial attitude error phi0_i (arcsec, navigation frame): INS attitude at the first sample
  (I - [phi0 x]) true (a heading from the tracked course, a tilt carried over from earlier windows);
- initial velocity error dv0_i (m/s, navigation frame): the tracking error of the starting state.

Flight columns: q_*, fb_*, w_* (strapdown33).
"""

import casadi as ca

import casep


def build() -> casep.ErrorModel:
    m = casep.build_model("strapdown12")  # unlocked: terms may still be added
    m.name = "strapdown12_window"
    m.description = "strapdown12 + initial attitude error phi0 (3) + initial velocity error dv0 (3)"
    c = m.declare(phi0_x=("arcsec", 3600.0), phi0_y=("arcsec", 3600.0), phi0_z=("arcsec", 3600.0),
                  dv0_x=("m/s", 0.05), dv0_y=("m/s", 0.05), dv0_z=("m/s", 0.05))
    m.set_initial_misalignment(ca.vertcat(c.phi0_x, c.phi0_y, c.phi0_z))  # rad
    m.set_initial_velocity_error(ca.vertcat(c.dv0_x, c.dv0_y, c.dv0_z))  # m/s
    return m
