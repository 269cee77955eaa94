"""The bias drift priors of ``casep calibrate --segments auto`` (casep.calibration.drift.fit_drift_prior)."""

from __future__ import annotations

import argparse
from typing import Any


def add_drift_priors(parser: Any) -> None:
    """``--acc-drift MG,TAU``, ``--gyr-drift DEG_H,TAU``: a hand-turned calibration's bias drift priors."""
    parser.add_argument("--acc-drift", metavar="MG,TAU", default=None, dest="acc_drift",
                        help="accelerometer bias drift prior: a Gauss-Markov std (mg) and correlation time (s), in "
                             "the biases' std (a drift as slow as the session is otherwise a bias it cannot tell); "
                             "from a datasheet's bias instability B: MG = B / 0.62, TAU = the Allan floor's "
                             "averaging time / 1.89")
    parser.add_argument("--gyr-drift", metavar="DEG_H,TAU", default=None, dest="gyr_drift",
                        help="gyro bias drift prior: a Gauss-Markov std (deg/h) and correlation time (s), as "
                             "--acc-drift")


def drift_priors(args: argparse.Namespace) -> dict[str, tuple[float, float] | None]:
    """``--acc-drift``, ``--gyr-drift``: ``{"acc_drift": (std m/s^2, tau s), "gyr_drift": (std rad/s, tau s)}``
    (None: not given); calibrate_multiposition checks the values."""
    from casep.calibration.session import ACC_UNITS, GYR_UNITS

    out: dict[str, tuple[float, float] | None] = {}
    for key, unit, factor in (("acc_drift", "mg", ACC_UNITS["mg"]), ("gyr_drift", "deg/h", GYR_UNITS["deg/h"])):
        text = getattr(args, key)
        v: tuple[float, ...] = ()
        if text is not None:
            try:
                v = tuple(float(x) for x in text.split(","))
            except ValueError:
                v = ()
            if len(v) != 2:
                raise ValueError(f"--{key.replace('_', '-')} {text!r}: give STD,TAU (std in {unit}, correlation "
                                 f"time in s), e.g. {'0.2,100' if unit == 'mg' else '10,100'}")
        out[key] = (v[0] * factor, v[1]) if len(v) == 2 else None
    return out
