"""Local gravity from latitude and height: the WGS84 normal gravity, from :mod:`casep.gravity`.

The formula lives in :mod:`casep.gravity` (one place, shared with the strapdown navigation); this
module keeps the calibration package's name for it.
"""

from __future__ import annotations

from casep.gravity import GAMMA_E, GAMMA_P, WGS84_A, WGS84_F, normal_gravity

__all__ = ["normal_gravity", "WGS84_A", "WGS84_F", "GAMMA_E", "GAMMA_P"]
