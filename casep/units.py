"""Natural units of instrument error coefficients and their SI factors.

Inside casep everything is SI (rad, rad/s, m/s, m/s^2). Error coefficients are declared,
reported and read from files in the natural units analysts use (deg/h, mg, ug/g, arcsec).
A coefficient's SI factor converts its natural-unit value into the SI value of the term it
multiplies. Specific force enters the error models in g (``W = f / G0``), so a coefficient
in ``mg/g`` multiplies ``W`` (in g) and yields ``1e-3 * G0`` m/s^2 per unit: its SI factor
is ``1e-3 * G0``, the same as ``mg``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

__all__ = ["G0", "DEG_PER_HOUR", "ARCSEC", "UNITS", "si_factor", "ACC_RANGES_G", "GYR_RANGES_DPS",
           "FULL_SCALE_TOLERANCE", "LINEAR_LIMITS", "RATE_UNIT_MISTAKES", "FORCE_UNIT_MISTAKES", "unit_mistakes",
           "unit_factorisation"]

#: Standard gravity, m/s^2 (the "g" of every unit below).
G0 = 9.80665
#: One degree per hour in rad/s.
DEG_PER_HOUR = math.pi / 180.0 / 3600.0
#: One arcsecond in rad.
ARCSEC = math.pi / 180.0 / 3600.0

#: Nominal ranges (+-) of MEMS accelerometers, g, and gyros, deg/s: a reading held at one of them clipped.
ACC_RANGES_G = (1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0, 10.0, 12.0, 16.0, 24.0, 30.0, 32.0, 50.0, 100.0, 200.0, 400.0)
GYR_RANGES_DPS = (125.0, 150.0, 245.0, 250.0, 300.0, 400.0, 450.0, 500.0, 1000.0, 2000.0, 4000.0)
#: A physical reading within this fraction of a nominal range is at full scale.
FULL_SCALE_TOLERANCE = 0.03
#: The largest accelerometer bias of consumer MEMS, m/s^2 (80 mg): a specific force off by up to this much is an
#: instrument error the separation estimates, not a unit mistake or a wrong column.
MEMS_ACCEL_BIAS = 0.08 * G0
#: The largest gyro bias of consumer MEMS, rad/s (1500 deg/h, 0.42 deg/s, about 100 times the Earth rate): a mean
#: rate at rest up to this much is an instrument error the separation estimates, not a unit mistake.
MEMS_GYRO_BIAS = 1500.0 * DEG_PER_HOUR

_MG = 1e-3 * G0  # one milli-g in m/s^2
_UG = 1e-6 * G0  # one micro-g in m/s^2

#: Known natural units -> SI factor. ``/g`` and ``/g^2`` do not change the factor because
#: the specific force they divide by is already expressed in g inside the error model.
UNITS: dict[str, float] = {
    # gyro drift rates -> rad/s
    "deg/h": DEG_PER_HOUR,
    "deg/h/g": DEG_PER_HOUR,
    "deg/h/g^2": DEG_PER_HOUR,
    "rad/s": 1.0,
    "rad/s/g": 1.0,
    "rad/s/g^2": 1.0,
    # accelerometer errors -> m/s^2
    "mg": _MG,
    "mg/g": _MG,
    "mg/g^2": _MG,
    "ug": _UG,
    "ug/g": _UG,
    "ug/g^2": _UG,
    "m/s^2": 1.0,
    # angles -> rad
    "arcsec": ARCSEC,
    "arcmin": 60.0 * ARCSEC,
    "deg": math.pi / 180.0,
    "mrad": 1e-3,
    "rad": 1.0,
    # velocities -> m/s
    "m/s": 1.0,
    # model signals: time offsets -> s, lever arms -> m, drift ramps -> rad/s per s
    "ms": 1e-3,
    "s": 1.0,
    "m": 1.0,
    "deg/h/s": DEG_PER_HOUR,
    # scale factors (tracking range scale): parts per million -> dimensionless
    "ppm": 1e-6,
}


def si_factor(unit: str) -> float:
    """Return the SI factor of a natural unit.

    Parameters
    ----------
    unit : str
        A key of :data:`UNITS`, e.g. ``"deg/h"`` or ``"ug/g^2"``.

    Returns
    -------
    float
        Multiply a value in `unit` by this to get SI.
    """
    if not isinstance(unit, str):
        raise TypeError(f"`unit` must be a str, got {type(unit).__name__}")
    try:
        return UNITS[unit]
    except KeyError:
        known = ", ".join(sorted(UNITS))
        raise ValueError(
            f"unknown unit `{unit}`. Use one of: {known}; or pass `si_factor` explicitly"
        ) from None


#: Magnitudes (SI) no coefficient of a linear error model can have: a scale factor or
#: misalignment of 0.1 (1e5 ppm, 20600 arcsec) leaves second-order terms of 1 % of the signal, beyond what the
#: first-order model describes; a gyro bias of 0.1 rad/s (5.7 deg/s, 20600 deg/h) turns the attitude by
#: 0.1 rad within a second, where the small-angle attitude error of the model no longer holds. Such an
#: estimate says the model does not describe the data (rates in deg/s in rad/s columns, a set-up or model
#: mistake), not that the instrument is that bad: the result fails (status -5) when the estimate is beyond
#: the limit by more than ``LINEAR_Z`` std (casep.estimators), even when a large std hides it from the
#: ``|estimate| - 5 std`` rule; a record corrected by coefficients beyond it may not invert
#: (:func:`casep.model.strapdown.not_inverted`).
#: An accelerometer bias of 1 g is gravity itself: levelled with it, the attitude is off by 45 deg (the
#: alignment's small-angle tilt ``b / g`` is 1 rad), and no accelerometer is that far off. Per-g terms (the unit
#: divided by g: the error at 1 g) have the limit of their kind: 0.1 as a scale factor, 0.1 rad/s as a drift.
#: By natural unit (SI): dimensionless and angle units 0.1, rates 0.1 rad/s, biases 1 g.
LINEAR_LIMITS: dict[str, float] = {"ppm": 0.1, "arcsec": 0.1, "arcmin": 0.1, "mrad": 0.1, "deg/h": 0.1, "rad/s": 0.1,
                                   "mg": G0, "ug": G0, "mg/g": 0.1 * G0, "ug/g": 0.1 * G0, "deg/h/g": 0.1,
                                   "rad/s/g": 0.1}

#: A body rate given in another unit than rad/s: (the unit with what turns it into rad/s, the SI value of one unit).
RATE_UNIT_MISTAKES: tuple[tuple[str, float], ...] = (("deg/s (multiply by pi/180)", math.pi / 180.0),)
#: A specific force given in another unit than m/s^2: (the unit with what turns it into m/s^2, its SI value).
FORCE_UNIT_MISTAKES: tuple[tuple[str, float], ...] = (("g (multiply by 9.80665)", G0),)


def unit_mistakes(groups: Sequence[Sequence[tuple[str, float]]]) -> list[tuple[tuple[str, float], ...]]:
    """Every choice of at most one ``(unit, SI value of one unit)`` of each group (none: that quantity in SI), at
    least one, fewest first: the unit mistakes a factor between columns can be made of (:func:`unit_factorisation`)."""
    import itertools

    picks = (tuple(u for u in pick if u is not None) for pick in itertools.product(*([None, *g] for g in groups)))
    return sorted((p for p in picks if p), key=len)


def unit_factorisation(gain: float, groups: Sequence[Sequence[tuple[str, float]]],
                       tol: float = 0.1) -> tuple[tuple[str, float], ...] | None:
    """The unit mistakes a gain between two columns is made of: the choice of :func:`unit_mistakes` whose SI values
    multiply to `gain` within `tol` (``|gain / product - 1|``), the closest when several do; ``()`` when `gain` is 1
    within `tol` (no mistake), None when no product is.

    The one rule for a factor found between columns: a time in ms whose body rate is in deg/s turns the attitude
    by ``(pi/180) / 1000`` of the rate integrated over the file's time (groups: the time units of
    :func:`casep.io.flight.time_unit_factors`, :data:`RATE_UNIT_MISTAKES`), each factor named.
    """
    if not (gain > 0 and math.isfinite(gain)):
        return None
    best: tuple[float, tuple[tuple[str, float], ...]] | None = None
    for chosen in [(), *unit_mistakes(groups)]:
        off = abs(gain / math.prod(k for _, k in chosen) - 1.0)
        if off < tol and (best is None or off < best[0]):
            best = (off, chosen)
    return None if best is None else best[1]
