"""platform36_drift_ramp: platform36 with an x gyro bias that drifts linearly in time (warm-up).

The x gyro bias becomes Kg0x + Kg0x_dot * t, t the time since the flight's first sample (s).
Any term may use ``m.t`` or a flight column ``m.signal(name)`` (a temperature, say) this way.
"""

import casadi as ca

import casep


def build() -> casep.ErrorModel:
    m = casep.build_model("platform36")
    m.name = "platform36_drift_ramp"
    m.description = "platform36 + x gyro bias ramp Kg0x_dot (deg/h per s)"
    c = m.declare(Kg0x_dot=("deg/h/s", 0.01))  # x gyro bias rate of change, deg/h per s (SI: rad/s^2)
    m.set_gyro_drift(m.output("gyro_drift") + ca.vertcat(c.Kg0x_dot * m.t, 0, 0))  # + Kg0x_dot t, rad/s
    return m
