"""platform36_leverarm: platform36 plus the tracking point's offset from the platform (m, body frame).

Tracking follows a point (antenna, reflector) at l = (lx, ly, lz) in the body frame from the
platform (the telemetry velocity's reference point). Its velocity is v + C (omega x l), C the
body-to-platform rotation and omega the body rate (body frame), so dv = v_tel - v_trk gains
-C (omega x l). Flight columns (``casep simulate`` writes them): att_pitch, att_yaw, att_roll
(rad; C = Rz(pitch) Ry(-yaw) Rx(roll), body x axis (cos yaw cos pitch, cos yaw sin pitch, sin yaw))
and omega_x, omega_y, omega_z (body rate, rad/s, body frame).
"""

import casadi as ca

import casep


def body_to_platform(m: casep.ErrorModel) -> ca.SX:
    """C = Rz(pitch) Ry(-yaw) Rx(roll) from the attitude columns (rad), 3 x 3."""
    th, ps, ph = m.signal("att_pitch"), m.signal("att_yaw"), m.signal("att_roll")
    Rz = ca.vertcat(ca.horzcat(ca.cos(th), -ca.sin(th), 0), ca.horzcat(ca.sin(th), ca.cos(th), 0), ca.horzcat(0, 0, 1))
    Ry = ca.vertcat(ca.horzcat(ca.cos(ps), 0, -ca.sin(ps)), ca.horzcat(0, 1, 0), ca.horzcat(ca.sin(ps), 0, ca.cos(ps)))
    Rx = ca.vertcat(ca.horzcat(1, 0, 0), ca.horzcat(0, ca.cos(ph), -ca.sin(ph)), ca.horzcat(0, ca.sin(ph), ca.cos(ph)))
    return Rz @ Ry @ Rx


def build() -> casep.ErrorModel:
    m = casep.build_model("platform36")
    m.name = "platform36_leverarm"
    m.description = "platform36 + tracking-point lever arm lx, ly, lz (m, body frame)"
    c = m.declare(lx="m", ly="m", lz="m")  # tracking point from the platform, m, body frame
    omega = ca.vertcat(m.signal("omega_x"), m.signal("omega_y"), m.signal("omega_z"))  # body rate, rad/s
    lever = ca.vertcat(c.lx, c.ly, c.lz)
    m.set_velocity_error(-body_to_platform(m) @ ca.cross(omega, lever))  # dv -= C (omega x l), m/s
    return m
