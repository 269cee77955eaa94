"""``casep simulate``'s raw IMU output: ``--imu-output``, ``--imu-pad``, the sensors' white noise (``--imu-arw``,
``--imu-vrw``) and full scales (``--acc-range``, ``--gyr-range``: clipped), in
:class:`casep.simulation.strapdown.SensorNoise`."""

from __future__ import annotations

import argparse
import math
from typing import Any

from casep.cli.flight_options import add_full_scales, full_scales

#: The stream of ``--seed`` the IMU noise is drawn from (independent of the tracking noise's draws).
IMU_NOISE_STREAM = 0x1A4


def add_imu_output(p: Any) -> None:
    """The raw IMU output options of ``casep simulate``."""
    p.add_argument("--imu-output", metavar="FILE", default=None,
                   help="with a strapdown scenario (strapdown-boost): also write the raw IMU data, t, w_x/y/z (rad/s) "
                        "and fb_x/y/z (m/s^2) as measured, with the truth true_q_*, true_r_*, true_v_*; with "
                        "--rotating-earth the record casep navigate navigates back to the truth; noise-free unless "
                        "--imu-arw/--imu-vrw are given")
    p.add_argument("--imu-pad", type=float, default=0.0, metavar="SECONDS",
                   help="with --imu-output: SECONDS standing on the pad before lift-off (t < 0), for an alignment")
    p.add_argument("--imu-arw", type=float, default=0.0, metavar="DEG_SQRT_H",
                   help="with --imu-output: the gyros' white noise as an angle random walk, deg/sqrt(h) (default 0: "
                        "noise-free; a consumer MEMS gyro 0.3-1, a tactical one 0.05-0.3, a navigation-grade one "
                        "< 0.005): per sample std ARW (rad/sqrt(s)) / sqrt(step), drawn from --seed")
    p.add_argument("--imu-vrw", type=float, default=0.0, metavar="M_S_SQRT_H",
                   help="with --imu-output: the accelerometers' white noise as a velocity random walk, m/s/sqrt(h) "
                        "(1 m/s/sqrt(h) = 1700 ug/sqrt(Hz); default 0: noise-free; a consumer MEMS accelerometer "
                        "0.05-0.2, a tactical one 0.01-0.05)")
    add_full_scales(p, "with --imu-output, simulate clips the raw IMU's readings (noise included) to it")


def imu_sensor(args: argparse.Namespace) -> Any:
    """The :class:`casep.simulation.strapdown.SensorNoise` of the options (None: none given), checked; a noise or
    full scale without ``--imu-output`` is a ValueError."""
    from casep.simulation.strapdown import SensorNoise

    given = [f for f, v in (("--imu-arw", args.imu_arw), ("--imu-vrw", args.imu_vrw)) if v != 0.0]
    given += [f for f, v in (("--acc-range", args.acc_range), ("--gyr-range", args.gyr_range)) if v is not None]
    if not given:
        return None
    if args.imu_output is None:
        raise ValueError(f"{', '.join(given)}: the raw IMU's noise and full scales need --imu-output")
    for flag, v in (("--imu-arw", args.imu_arw), ("--imu-vrw", args.imu_vrw)):
        if not (math.isfinite(v) and v >= 0):
            raise ValueError(f"{flag} must be a finite number >= 0, got {v}")
    fs = full_scales(args)
    import numpy as np

    seed = int(np.random.default_rng([args.seed, IMU_NOISE_STREAM]).integers(2**63))
    return SensorNoise(arw_deg_sqrt_h=args.imu_arw, vrw_m_s_sqrt_h=args.imu_vrw, seed=seed,
                       gyr_range_rad_s=fs["gyr_range"], acc_range_m_s2=fs["acc_range"])
