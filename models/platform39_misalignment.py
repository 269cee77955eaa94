"""platform39_misalignment: platform36 plus the initial platform misalignment phi0.

phi(t) = phi0 + integral of phidot, so phi0 enters the velocity error through [f x] phi0
integrated once. Three extra coefficients, arcsec, appended after the 36 of platform36.
"""

import casadi as ca

import casep


def build() -> casep.ErrorModel:
    m = casep.build_model("platform36")  # unlocked: we may still add to it
    m.name = "platform39_misalignment"
    m.description = "platform36 + initial platform misalignment phi0 (3)"
    c = m.declare(phi0x="arcsec", phi0y="arcsec", phi0z="arcsec")  # initial misalignment, arcsec
    m.set_initial_misalignment(ca.vertcat(c.phi0x, c.phi0y, c.phi0z))  # rad
    return m
