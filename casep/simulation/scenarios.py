"""Built-in simulation scenarios (``casep simulate --scenario NAME``).

=============== ==========================================================================
``paper``        Table 1 truth (platform36), white tracking noise 0.1 m/s, 100 Hz, the
                 default two-stage vehicle (:data:`casep.simulation.trajectory.DEFAULT_VEHICLE`) with
                 a small yaw manoeuvre: psi(t) = 2 deg sin(2 pi (t - 20 s) / 80 s) for
                 20 s <= t <= 180 s (two periods), so the z-axis terms see excitation.
``paper-pitch``  The same without the yaw manoeuvre: a pitch-plane flight, f_z = 0, so the
                 12 coefficients driven only by W_z have zero columns.
``paper-ar1``    ``paper`` with first-order Gauss-Markov tracking noise: sigma 0.1 m/s,
                 correlation time 1 s (lag-1 correlation 0.990 at 100 Hz).
``paper-yaw-late`` the yaw manoeuvre in stage 2 only: 2 deg, period 45 s, 105-195 s (two periods).
``paper-pitch-low`` a depressed trajectory: pitch-over kick at 2.4 deg/s (paper: 1.6) for 8 s.
``paper-azimuth`` ``paper`` flown 10 deg off the platform's x axis (constant yaw offset): a
                 cross-range component of the specific force throughout.
``paper-range-gm`` ``paper`` at 20 Hz as a range delivers it: Gauss-Markov tracking noise (sigma
                 0.1 m/s, tau 1 s), tracking from 8 s, dropouts of 6 s at 95 s and 1.5 s at 140 s.
``paper-range``  ``paper-range-gm`` with glitches: 0.5 % of the values per axis off by N(0, 2 m/s).
``strapdown-boost`` a strapdown IMU (model ``strapdown33``, body-frame errors) on the ``paper`` boost with
                 a roll programme (:data:`STRAPDOWN_ROLL`: 60 deg/s from 15 s, 120 deg/s from 90 s,
                 stopped by 160 s), 50 Hz; tracking Gauss-Markov (0.1 m/s, tau 1 s) plus white
                 (0.05 m/s) noise, from 6 s (late start), a gap 110-115 s. Writes strapdown
                 telemetry: ``q_*``, ``fb_*``, ``w_*``, no ``f_*`` (:mod:`casep.simulation.strapdown`).
=============== ==========================================================================

The paper does not publish its trajectory; these are documented stand-ins with the figures
the paper's class of vehicle has (see :mod:`casep.simulation.trajectory`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from casep.simulation.noise import NoiseModel
from casep.simulation.paper import TABLE1_NOISE_SIGMA, TABLE1_TRUTH
from casep.simulation.strapdown import RollProgramme
from casep.simulation.trajectory import DEFAULT_VEHICLE, Vehicle, YawManoeuvre

__all__ = ["Scenario", "SCENARIOS", "get_scenario", "STRAPDOWN_ROLL", "STRAPDOWN_TRUTH"]


#: Highest simulated sample rate, Hz: a 200 s boost at 10 kHz is already 2 million samples (the
#: sample count, and the memory of S_V, grow with the rate; 1e308 Hz overflows the time grid).
MAX_RATE_HZ = 1e4


def check_rate(rate, what: str = "`rate`") -> float:
    """A sample rate in (0, :data:`MAX_RATE_HZ`] Hz, or ValueError naming `what` and the range."""
    if isinstance(rate, bool) or not isinstance(rate, (int, float, np.integer, np.floating)):
        raise ValueError(f"{what} must be a number of Hz, got {rate!r}")
    r = float(rate)
    if not (math.isfinite(r) and 0 < r <= MAX_RATE_HZ):
        raise ValueError(f"{what} must be in (0, {MAX_RATE_HZ:g}] Hz, got {rate:g} (a 200 s flight at {MAX_RATE_HZ:g} "
                         "Hz is already 2 million samples)")
    return r


@dataclass(frozen=True)
class Scenario:
    """A reproducible simulated flight: vehicle, rate, error model, truth and noise.

    Parameters
    ----------
    name, description : str
    vehicle : Vehicle
    rate : float
        Telemetry sample rate, Hz.
    model : str
        Error model name.
    truth : dict
        Coefficient name -> true value, natural units (missing names are 0).
    noise : NoiseModel
        Tracking noise.
    roll : RollProgramme, optional
        A strapdown flight: the roll programme flown (kinematic, :mod:`casep.simulation.strapdown`); the
        model's errors act in body axes and the flight carries strapdown telemetry. None: a platform flight.
    """

    name: str
    description: str
    vehicle: Vehicle = DEFAULT_VEHICLE
    rate: float = 100.0
    model: str = "platform36"
    truth: dict = field(default_factory=lambda: dict(TABLE1_TRUTH))
    noise: NoiseModel = field(default_factory=lambda: NoiseModel("white", TABLE1_NOISE_SIGMA))
    roll: RollProgramme | None = None

    @property
    def strapdown(self) -> bool:
        """A strapdown flight (strapdown telemetry, body-frame errors)?"""
        return self.roll is not None

    def without_noise(self) -> "Scenario":
        """The same scenario without tracking noise (:meth:`casep.simulation.noise.NoiseModel.without_noise`):
        a noise-free flight, the first check of a model file or a set-up (the truth recovered to rounding)."""
        return dataclasses.replace(self, noise=self.noise.without_noise())

    def with_rate(self, rate: float | None) -> "Scenario":
        """The same scenario at another sample rate (None keeps it); ValueError outside (0, MAX_RATE_HZ]."""
        if rate is None:
            return self
        check_rate(rate, "`rate`")
        return dataclasses.replace(self, rate=float(rate))


_PAPER_YAW = YawManoeuvre(amplitude=2.0, period=80.0, start=20.0, end=180.0)
#: Tracking gaps of the range scenarios: a late start (0-8 s) and two dropouts, (start, length) s.
_RANGE_GAPS = ((0.0, 8.0), (95.0, 6.0), (140.0, 1.5))
#: Roll programme of the strapdown scenario.
STRAPDOWN_ROLL = RollProgramme()
#: True body-frame errors of the strapdown scenario (strapdown33, natural units): a tactical-grade IMU.
STRAPDOWN_TRUTH = {
    "ba_x": 0.8, "ba_y": -0.5, "ba_z": 0.6, "sa_x": 250.0, "sa_y": -150.0, "sa_z": 100.0,
    "ma_xy": 40.0, "ma_xz": -30.0, "ma_yx": 20.0, "ma_yz": 50.0, "ma_zx": -40.0, "ma_zy": 30.0,
    "bg_x": 1.0, "bg_y": -0.8, "bg_z": 0.5, "sg_x": 80.0, "sg_y": -60.0, "sg_z": 50.0,
    "mg_xy": 30.0, "mg_xz": -20.0, "mg_yx": 40.0, "mg_yz": -30.0, "mg_zx": 20.0, "mg_zy": 50.0,
    "gg_xx": 0.5, "gg_xy": -0.3, "gg_xz": 0.2, "gg_yx": 0.4, "gg_yy": -0.5, "gg_yz": 0.3,
    "gg_zx": -0.2, "gg_zy": 0.6, "gg_zz": 0.3,
}

SCENARIOS: dict[str, Scenario] = {
    s.name: s
    for s in (
        Scenario("paper", "Table 1 truth, white noise 0.1 m/s, 100 Hz, pitch programme + small yaw manoeuvre",
                 vehicle=dataclasses.replace(DEFAULT_VEHICLE, yaw=_PAPER_YAW)),
        Scenario("paper-pitch", "as paper, no yaw manoeuvre (pitch-plane flight, f_z = 0)",
                 vehicle=DEFAULT_VEHICLE),
        Scenario("paper-ar1", "as paper, Gauss-Markov noise sigma 0.1 m/s, tau 1 s",
                 vehicle=dataclasses.replace(DEFAULT_VEHICLE, yaw=_PAPER_YAW),
                 noise=NoiseModel("ar1", TABLE1_NOISE_SIGMA, tau=1.0)),
        Scenario("paper-yaw-late", "as paper, yaw manoeuvre in stage 2 only (2 deg, 45 s period, 105-195 s)",
                 vehicle=dataclasses.replace(DEFAULT_VEHICLE, yaw=YawManoeuvre(2.0, 45.0, 105.0, 195.0))),
        Scenario("paper-pitch-low", "as paper, depressed trajectory (pitch-over kick 2.4 deg/s for 8 s)",
                 vehicle=dataclasses.replace(DEFAULT_VEHICLE, yaw=_PAPER_YAW,
                                             pitch=dataclasses.replace(DEFAULT_VEHICLE.pitch, kick_rate=2.4))),
        Scenario("paper-range-gm", "as paper at 20 Hz, Gauss-Markov noise 0.1 m/s tau 1 s, tracking from 8 s, "
                 "dropouts 95-101 s and 140-141.5 s", vehicle=dataclasses.replace(DEFAULT_VEHICLE, yaw=_PAPER_YAW),
                 noise=NoiseModel("ar1", TABLE1_NOISE_SIGMA, tau=1.0, gaps=_RANGE_GAPS), rate=20.0),
        Scenario("paper-range", "as paper-range-gm, with 0.5 % glitches of N(0, 2 m/s) per axis",
                 vehicle=dataclasses.replace(DEFAULT_VEHICLE, yaw=_PAPER_YAW),
                 noise=NoiseModel("ar1", TABLE1_NOISE_SIGMA, tau=1.0, gaps=_RANGE_GAPS, outlier_rate=0.005,
                                  outlier_sigma=2.0), rate=20.0),
        Scenario("strapdown-boost", "strapdown IMU (strapdown33) on the paper boost with a roll programme, "
                 "50 Hz by default, Gauss-Markov 0.1 m/s tau 1 s plus white 0.05 m/s tracking noise, tracking "
                 "from 6 s, gap 110-115 s",
                 vehicle=dataclasses.replace(DEFAULT_VEHICLE, yaw=_PAPER_YAW), rate=50.0, model="strapdown33",
                 truth=dict(STRAPDOWN_TRUTH), roll=STRAPDOWN_ROLL,
                 noise=NoiseModel("ar1", TABLE1_NOISE_SIGMA, tau=1.0, white_sigma=0.05,
                                  gaps=((0.0, 6.0), (110.0, 5.0)))),
        Scenario("paper-azimuth", "as paper, flown 10 deg off the platform x axis (cross-range component)",
                 vehicle=dataclasses.replace(DEFAULT_VEHICLE, yaw=dataclasses.replace(_PAPER_YAW, offset=10.0))),
    )
}


def get_scenario(name: str | Scenario) -> Scenario:
    """Look up a built-in scenario by name (a :class:`Scenario` is returned as is)."""
    if isinstance(name, Scenario):
        return name
    try:
        return SCENARIOS[name]
    except KeyError:
        raise ValueError(f"unknown scenario `{name}`. Use one of: {', '.join(SCENARIOS)}") from None
