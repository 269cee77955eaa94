"""The pad alignment's options of a raw IMU record (``casep navigate``, ``casep separate --imu``)."""

from __future__ import annotations

from typing import Any

from casep.cli.types import finite_float, positive_float

__all__ = ["add_alignment", "bias_tolerances"]


def add_alignment(parser: Any, *, required: bool = False, what: str = "") -> None:
    """``--align T1 T2``, ``--heading DEG``, ``--heading-axis AXIS``: the pad alignment of a raw IMU record."""
    parser.add_argument("--align", type=finite_float, nargs=2, required=required, default=None, metavar=("T1", "T2"),
                        help=f"{what}the span at rest on the pad, s (the IMU's time scale): levelling by the mean "
                             "specific force, and the start of the navigation")
    parser.add_argument("--heading", type=finite_float, default=None, metavar="DEG",
                        help=f"{what}azimuth of the horizontal projection of the body axis --heading-axis, deg from "
                             "north, clockwise (a rail launch: the rail azimuth); default: gyrocompassing, with a "
                             "warning saying how well the heading is known")
    parser.add_argument("--heading-axis", choices=("x", "y", "z"), default="x", help="--heading's axis (default x)")
    parser.add_argument("--accel-bias-tolerance", type=positive_float, default=None, metavar="MG",
                        help="the accelerometer bias, mg, by which the mean specific force over --align may differ "
                             "from the normal gravity (a warning beyond 49 mg, 5 %% of g; beyond it an error saying "
                             "what fits: units, a vehicle that moved); default 80 mg, the largest of consumer MEMS")
    parser.add_argument("--gyro-bias-tolerance", type=positive_float, default=None, metavar="DEG_S",
                        help="the gyro bias, deg/s, the pad rate may reach (navigated, warned of: an MPU-9150's is "
                             "up to 20 deg/s); default 2.9 deg/s: beyond it no gyro navigates")


def bias_tolerances(args: Any) -> dict[str, Any]:
    """``--accel-bias-tolerance MG`` (m/s^2), ``--gyro-bias-tolerance DEG_S`` (rad/s) given: align's keywords."""
    from casep.units import DEG_PER_HOUR, G0
    given = (("accel_bias_tolerance", 1e-3 * G0), ("gyro_bias_tolerance", 3600.0 * DEG_PER_HOUR))
    return {k: float(getattr(args, k)) * si for k, si in given if getattr(args, k, None) is not None}
