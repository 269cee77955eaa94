"""platform36_dv0: platform36 plus the initial velocity error dv0.

dv(t) = dv0 + integral of dWdot: for a flight whose data begin after lift-off, dv0 is the
velocity error accumulated before the first sample (the model then no longer forces
dv(t0) = 0). Three extra coefficients, m/s, appended after the 36 of platform36. For the
misalignment accumulated before t0 as well, add phi0 as in platform39_misalignment.
"""

import casadi as ca

import casep


def build() -> casep.ErrorModel:
    m = casep.build_model("platform36")  # unlocked: we may still add to it
    m.name = "platform36_dv0"
    m.description = "platform36 + initial velocity error dv0 (3)"
    c = m.declare(dv0x="m/s", dv0y="m/s", dv0z="m/s")  # initial velocity error, m/s
    m.set_initial_velocity_error(ca.vertcat(c.dv0x, c.dv0y, c.dv0z))  # m/s
    return m
