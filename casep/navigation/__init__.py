"""Strapdown navigation from raw IMU data in casep's launch-inertial frame.

:mod:`casep.navigation.strapdown` (the mechanisation: attitude by the rotation vector with coning
correction, velocity with rotation compensation and sculling, WGS84 gravitation at the vehicle's
position), :mod:`casep.navigation.alignment` (levelling, heading given or by gyrocompassing),
:mod:`casep.navigation.imu` (IMU files and their checks), :mod:`casep.navigation.navigator`
(:func:`navigate`) and :mod:`casep.navigation.result` (:class:`NavigationResult`, the strapdown
telemetry).

Layer 2: uses :mod:`casep.frames`, :mod:`casep.gravity` and :mod:`casep.io`.
"""

from casep._lazy import attach

__getattr__, __dir__ = attach(__name__, {
    "casep.navigation.navigator": ("navigate", "navigate_from", "pad_state"),
    "casep.navigation.imu": ("ImuData", "read_imu", "check_imu"),
    "casep.navigation.alignment": ("Alignment", "align"),
    "casep.navigation.result": ("NavigationResult", "TELEMETRY_COLUMNS"),
}, globals())

__all__ = ["navigate", "navigate_from", "pad_state",
           "ImuData", "read_imu", "check_imu", "Alignment", "align", "NavigationResult",
           "TELEMETRY_COLUMNS"]
