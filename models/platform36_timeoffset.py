"""platform36_timeoffset: platform36 plus a tracking time offset dt_trk (ms, per flight).

Tracking time tags are late by dt_trk: v_trk(t) = v_true(t - dt_trk) ~ v_true(t) - a(t) dt_trk,
so dv = v_tel - v_trk gains a(t) * dt_trk, with a the kinematic acceleration (specific force +
gravity, m/s^2, platform frame): flight columns a_x, a_y, a_z (``casep simulate`` writes them).
First order in dt_trk: the neglected term is da/dt * dt_trk^2 / 2.
"""

import casadi as ca

import casep


def build() -> casep.ErrorModel:
    m = casep.build_model("platform36")  # unlocked: we add to it
    m.name = "platform36_timeoffset"
    m.description = "platform36 + tracking time offset dt_trk (ms, per flight)"
    c = m.declare(dt_trk=("ms", 20.0), per_flight=True)  # tracking time-tag delay, ms (SI: s)
    a = ca.vertcat(m.signal("a_x"), m.signal("a_y"), m.signal("a_z"))  # kinematic acceleration, m/s^2
    m.set_velocity_error(a * c.dt_trk)  # dv += a(t) dt_trk, m/s (not integrated)
    return m
