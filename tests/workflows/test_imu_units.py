"""The rates' unit of a raw IMU record judged by its separation (casep.workflows.imu_units): a tactical gyro whose
rates are in deg/s, its bias (about the Earth rate) hiding the unit from the pad, is named by the tracking; the same
record in rad/s is not read as deg/s."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from casep.frames import LaunchSite
from casep.navigation import ImuData, navigate
from casep.navigation.imu import check_imu

SITE = LaunchSite(51.0, 0.0, 10.0, 30.0, 10.0)
#: a tactical gyro's bias, rad/s (8, -12, 6 deg/h: 1 Earth rate in size, so that the pad's rate divided by 57.3 misses
#: the Earth-rate match, and 57.3 times it is within the bias of a MEMS gyro read in rad/s)
BIAS = np.radians(np.array([8.0, -12.0, 6.0]) / 3600.0)


@pytest.fixture(scope="module")
def flight(tmp_path_factory):
    """A 30 s rail launch (the pad 0..9 s) at 20 Hz, its true rates plus the tactical bias; the tracking the true
    navigation's velocity with 0.02 m/s of white noise every 4th sample."""
    from casep.io.files import write_table
    from casep.simulation.noise import white_noise
    from casep.simulation.strapdown import rail_launch

    t = np.round(np.arange(0.0, 30.0, 0.05), 10)
    w, f = rail_launch(SITE, t, elevation_deg=80.0, boost_g=4.0, burn_s=15.0, coast_g=-0.2, roll=(0.3, 5.0))
    nav = navigate(check_imu(ImuData(t, w, f)), SITE, (0.0, 9.0), heading_deg=30.0)
    k = slice(None, None, 4)
    v = nav.v[k] + white_noise(t[k].size, 0.02, np.random.default_rng(1))
    path = tmp_path_factory.mktemp("units") / "trk.csv"
    write_table(path, {"t": t[k], **{f"v_trk_{a}": v[:, i] for i, a in enumerate("xyz")}})
    return t, w + BIAS, f, path


def _separate(t, w, f, path):
    from casep.estimators.spec import FitSpec
    from casep.workflows.imu_separate import separate_imu

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = separate_imu(check_imu(ImuData(t, w, f)), path, SITE, (0.0, 9.0), "strapdown12", heading_deg=30.0,
                           iterate=False, spec=FitSpec.build("ols", noise="white", robust="none"))
    return res, [str(c.message) for c in caught]


def test_rates_in_deg_s_the_pad_cannot_tell_are_named_first_by_the_tracking(flight):
    """In deg/s: the pad's rate divided by 57.3 misses the Earth rate by about its size (the tactical bias), 57.3
    times it is a MEMS bias in rad/s; the separation as read misfits, the deg/s reading's one pass fits the tracking
    to its noise (independent: the simulated 0.02 m/s): status STATUS_SETUP, the unit first, both residuals and the
    pad under both readings in the message, no heading given as the cause."""
    from casep.estimators.registry import STATUS_SETUP
    from casep.navigation.alignment import OMEGA_EARTH, deg_s_chance

    t, w, f, path = flight
    deg = math.degrees(1.0)
    pad = (t >= 0.0) & (t <= 9.0)
    ratio = float(np.linalg.norm(w[pad].mean(axis=0))) / OMEGA_EARTH  # the pad's rate in deg/s, in Earth rates
    assert 0.3 < ratio < 3.0 and deg_s_chance(1.0, SITE.lat_deg, True) > 0.05  # a MEMS bias lands there often
    sep, said = _separate(t, deg * w, f, path)
    res = sep.result
    unit = res.diagnostics["rate_unit"]
    assert not res.success and res.status == STATUS_SETUP
    first = res.message.split("\n")[0]
    assert first.startswith("failed: <ImuData>: the rates look like deg/s") or "the rates look like deg/s" in \
        first.split(";")[0], res.message
    assert unit["residual_rms_reading"] < 0.05 and unit["ratio"] >= 10.0, unit  # the tracking's noise: 0.02 m/s
    for part in ("times 0.0174533", f"{unit['residual_rms_reading']:.3g} m/s", "give rad/s (multiply by pi/180)",
                 "the pad cannot tell them apart"):
        assert part in first, first
    assert "--heading" not in first, first
    assert any("the rates look like deg/s" in m for m in said), said


@pytest.mark.parametrize("mems", [False, True])
def test_rates_in_rad_s_are_not_read_as_deg_s(flight, mems):
    """The same record in rad/s (with the tactical bias, or a consumer MEMS gyro's 0.19 deg/s, the real car drive's,
    in its place), its separation's residuals taken 1 m/s (a misfit far beyond the noise): the deg/s reading's pass
    fits worse, and no unit is named."""
    from types import SimpleNamespace

    import casep.workflows.imu_separate as sep
    from casep.workflows.imu_units import rate_unit_reading

    t, w, f, path = flight
    if mems:
        w = w - BIAS + np.radians(0.19) * np.array([0.6, -0.64, 0.48])
    runs = []

    def capture(self, *args):
        runs.append(self)
        raise StopIteration

    mp = pytest.MonkeyPatch()
    mp.setattr(sep._Run, "iterate", capture)
    try:
        with pytest.raises(StopIteration):
            _separate(t, w, f, path)
    finally:
        mp.undo()
    run = runs[0]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        spec = sep._fast_spec(run.spec) or run.spec
        res, nav, flight_data, _, _ = run.solve(None, spec)
    assert float(np.sqrt(np.mean(np.asarray(res.residuals) ** 2))) < 0.05  # rad/s: the right reading fits
    misfit = SimpleNamespace(residuals=np.ones_like(np.asarray(res.residuals)))
    assert rate_unit_reading(run, misfit, flight_data, spec) is None
