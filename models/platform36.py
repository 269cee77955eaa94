"""platform36: the paper's 36-coefficient platform IMU error model (docs/reference/model.md, Eq. 1 and 3).

Gyro drift rates (5 per gyro) and accelerometer errors (7 per accelerometer); W is the
platform specific force in g. Coefficient order and units are the contract of
``docs/reference/model.md``.
"""

import casadi as ca

import casep


def build() -> casep.ErrorModel:
    m = casep.ErrorModel("platform36", "paper's gyro (15) + accelerometer (21) error model")
    Wx, Wy, Wz = m.W[0], m.W[1], m.W[2]  # specific force, g
    # name=(unit, typical magnitude): the magnitudes of the paper's Table 1, the yardstick of
    # casep diagnose's "weak" verdict (a CRLB std above it)
    c = m.declare(
        # gyro x, y, z: bias deg/h, first order deg/h/g, second order deg/h/g^2
        Kg0x=("deg/h", 0.5), Kg1x=("deg/h/g", 0.1), Kg1xy=("deg/h/g", 0.01), Kg1xz=("deg/h/g", 0.02),
        Kg2x=("deg/h/g^2", 1e-4),
        Kg0y=("deg/h", 0.3), Kg1y=("deg/h/g", 0.01), Kg1yz=("deg/h/g", 0.02), Kg1yx=("deg/h/g", 0.01),
        Kg2y=("deg/h/g^2", 1e-4),
        Kg0z=("deg/h", 0.5), Kg1z=("deg/h/g", 0.01), Kg1zx=("deg/h/g", 0.02), Kg1zy=("deg/h/g", 0.02),
        Kg2z=("deg/h/g^2", 1e-4),
        # accelerometer x, y, z: bias mg, scale mg/g, cross-axis ug/g, second order ug/g^2
        Ka0x=("mg", 2.0), Ka1x=("mg/g", 0.5), Ka1xy=("ug/g", 50.0), Ka1xz=("ug/g", 50.0),
        Ka2x=("ug/g^2", 3e-3), Ka2xy=("ug/g^2", 3e-3), Ka2xz=("ug/g^2", 3e-3),
        Ka0y=("mg", 2.0), Ka1y=("mg/g", 0.5), Ka1yz=("ug/g", 50.0), Ka1yx=("ug/g", 50.0),
        Ka2y=("ug/g^2", 3e-3), Ka2yz=("ug/g^2", 3e-3), Ka2yx=("ug/g^2", 3e-3),
        Ka0z=("mg", 1.0), Ka1z=("mg/g", 0.5), Ka1zx=("ug/g", 50.0), Ka1zy=("ug/g", 50.0),
        Ka2z=("ug/g^2", 3e-3), Ka2zx=("ug/g^2", 3e-3), Ka2zy=("ug/g^2", 3e-3),
    )
    # Eq. (1): platform drift rate, rad/s
    m.set_gyro_drift(ca.vertcat(
        c.Kg0x + c.Kg1x * Wx + c.Kg1xy * Wy + c.Kg1xz * Wz + c.Kg2x * Wx**2,
        c.Kg0y + c.Kg1y * Wy + c.Kg1yz * Wz + c.Kg1yx * Wx + c.Kg2y * Wy**2,
        c.Kg0z + c.Kg1z * Wz + c.Kg1zx * Wx + c.Kg1zy * Wy + c.Kg2z * Wz**2,
    ))
    # Eq. (3): accelerometer measurement error, m/s^2
    m.set_accel_error(ca.vertcat(
        c.Ka0x + c.Ka1x * Wx + c.Ka1xy * Wy + c.Ka1xz * Wz + c.Ka2x * Wx**2 + c.Ka2xy * Wx * Wy + c.Ka2xz * Wx * Wz,
        c.Ka0y + c.Ka1y * Wy + c.Ka1yz * Wz + c.Ka1yx * Wx + c.Ka2y * Wy**2 + c.Ka2yz * Wy * Wz + c.Ka2yx * Wy * Wx,
        c.Ka0z + c.Ka1z * Wz + c.Ka1zx * Wx + c.Ka1zy * Wy + c.Ka2z * Wz**2 + c.Ka2zx * Wz * Wx + c.Ka2zy * Wz * Wy,
    ))
    return m
