"""Strapdown inputs of a model file: the INS attitude, body specific force and body rate as symbols.

A strapdown flight carries, beside ``t`` and ``v_tel_*`` / ``dv_*``, the columns of
:data:`STRAPDOWN_COLUMNS` (``docs/reference/file-formats.md``):

- ``q_w, q_x, q_y, q_z``: the INS attitude, a Hamilton unit quaternion, scalar first, rotating
  body vectors into the navigation frame (casep's launch-inertial frame, :mod:`casep.frames`):
  ``v_nav = C(q) v_body``;
- ``fb_x, fb_y, fb_z``: the measured body specific force, m/s^2;
- ``w_x, w_y, w_z``: the measured body rate (inertial, in body axes), rad/s.

A model file reads them with ``model.signal(name)``; :func:`strapdown_inputs` does it once and
returns the body-to-navigation matrix, built from the quaternion in its homogeneous form::

    C(q) = (1 / |q|^2) [[w^2+x^2-y^2-z^2, 2(xy - wz),       2(xz + wy)      ],
                        [2(xy + wz),       w^2-x^2+y^2-z^2, 2(yz - wx)      ],
                        [2(xz - wy),       2(yz + wx),       w^2-x^2-y^2+z^2]]

(q and -q give the same C, so a sign flip of the quaternion changes nothing here). The errors act
in body axes and reach the navigation frame through C; the model's slots take them as

    gyro_drift  = phidot = -C delta_w        (attitude error, INS attitude = (I - [phi x]) true)
    accel_error = Delta  =  C delta_f        (so dv_dot = C delta_f + f_nav x phi)

with the navigation-frame specific force ``f_nav = C fb`` as the model's ``m.f``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from casep.io.strapdown import BODY_FORCE_COLUMNS, BODY_RATE_COLUMNS, QUATERNION_COLUMNS, STRAPDOWN_COLUMNS

if TYPE_CHECKING:
    import casadi as ca

__all__ = ["QUATERNION_COLUMNS", "BODY_FORCE_COLUMNS", "BODY_RATE_COLUMNS", "STRAPDOWN_COLUMNS",
           "quaternion_dcm", "strapdown_inputs"]



def quaternion_dcm(w: Any, x: Any, y: Any, z: Any) -> ca.SX:
    """Body-to-navigation matrix C(q) of a Hamilton quaternion (scalar first), 3 x 3 CasADi expression.

    The homogeneous form divided by ``|q|^2`` (see the module notes): exact for a unit quaternion,
    a proper rotation for any non-zero one.
    """
    import casadi as ca

    n = w * w + x * x + y * y + z * z
    return ca.vertcat(
        ca.horzcat(w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)),
        ca.horzcat(2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)),
        ca.horzcat(2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z),
    ) / n


def strapdown_inputs(m: Any) -> tuple[ca.SX, ca.SX, ca.SX]:
    """``(C, fb, w)`` of an :class:`~casep.model.error_model.ErrorModel` from its strapdown signal columns.

    C (3 x 3) rotates body vectors into the navigation frame (:func:`quaternion_dcm`), fb (3 x 1) is
    the measured body specific force (m/s^2), w (3 x 1) the measured body rate (rad/s).
    """
    import casadi as ca

    C = quaternion_dcm(*(m.signal(c) for c in QUATERNION_COLUMNS))
    fb = ca.vertcat(*(m.signal(c) for c in BODY_FORCE_COLUMNS))
    w = ca.vertcat(*(m.signal(c) for c in BODY_RATE_COLUMNS))
    return C, fb, w
