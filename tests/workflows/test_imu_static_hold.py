"""A static hold on the pad: a GNSS receiver at rest reporting exactly zero Earth-fixed velocity, one position,
epoch after epoch, for 60 s before lift-off, while the IMU is levelled there (``--align``).

The flight is casep's simulator's (``casep simulate --scenario strapdown-boost --rotating-earth --tracking-frame ecef
--imu-output IMU --imu-pad 60``, its Python twin at 10 Hz with the tracking at 2 Hz): ``strapdown33`` errors, tracking
with Gauss-Markov plus white noise from 6 s, a gap at 110-115 s; the hold is the pad's tracking epochs before it. The
hold carries no measurement noise: weighted as the flight's epochs (one noise level per axis) it broke the fit (the
noise 611-fold between stretches, a failed result; a hold without the late start: runs of rejections). Now its epochs
are out of the fit's rows and are the pad's zero-velocity check of the estimate
(:func:`casep.checks.tracking_quality.static_hold`, :func:`casep.workflows.judging.judge_pad_hold`).
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from casep.frames import ECEF_COLUMNS, LaunchSite
from casep.io.files import write_table
from casep.simulation.earth_fixed import write_strapdown_earth_fixed
from casep.simulation.simulate import simulate_flight, truth_path
from casep.workflows.imu_separate import separate_imu

SITE = LaunchSite(67.89, 21.1, 330.0, 30.0, 0.0)  # lift-off at t = 0
PAD, ALIGN = 60.0, (-60.0, -1.0)
HEADING_Y = 210.232  # the azimuth of body y on the pad (body x up the rail, near vertical), deg


@pytest.fixture(scope="module")
def hold(tmp_path_factory):
    """IMU, tracking (the hold, then the simulator's ECEF tracking) and the truth (natural units)."""
    d = tmp_path_factory.mktemp("hold")
    sim = simulate_flight("strapdown-boost", seed=1, rate=10.0, tracking_rate=2.0, rotating_earth=True, site=SITE)
    tel, trk, imu = d / "sd.csv", d / "sd.tracking.csv", d / "imu.csv"
    write_strapdown_earth_fixed(sim, tel, trk, frame="ecef", imu=imu, imu_pad=PAD)
    flown = np.genfromtxt(trk, delimiter=",", skip_header=2)
    t = np.round(np.arange(-PAD, 0.0, 0.5), 9)
    pad = np.column_stack([t, np.tile(SITE.r_site, (t.size, 1)), np.zeros((t.size, 3))])  # exact: the hold
    rows = np.vstack([pad, flown])
    write_table(trk, dict(zip(ECEF_COLUMNS, rows.T)))
    truth = json.loads(truth_path(tel).read_text())["coefficients"]
    return imu, trk, truth


@pytest.fixture(scope="module")
def separated(hold):
    imu, trk, _ = hold
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # what the record leaves undetermined, said: not what this tests
        return separate_imu(imu, trk, SITE, ALIGN, "strapdown33", heading_deg=HEADING_Y, heading_axis="y",
                            tracking_frame="ecef")


def test_a_static_hold_on_the_pad_is_the_zero_velocity_check_not_rows_of_the_fit(hold, separated):
    """The 60 s hold (119 epochs at 2 Hz) is out of the fit's rows and its noise out of the stretches' (before: 611
    times quieter than the flight's, a failed result); the fit succeeds, the 14 combinations it states are within
    2.5 of their std of the truth (largest 2.0) and ``dt_trk`` within 2 of its own, and the pad check is said:
    the estimate predicts the hold's dv to within its std there."""
    _, _, truth = hold
    out = separated
    res = out.result
    screen = out.flight.meta["tracking_screen"]
    (a, b, n), = screen["static_hold"]
    assert (a, b, n) == (pytest.approx(-59.5), pytest.approx(-0.5), 119), screen["static_hold"]
    assert all(a >= 0.0 for a, _, _, _ in screen["stretches"]), screen["stretches"]  # the flight's stretches only
    assert out.success, res.message
    check = res.diagnostics["pad_check"]
    assert check["passed"] and check["epochs"] == 119 and check["largest_std"] < 2.0, check
    assert "pad zero-velocity check: the static hold -59.5..-0.5 s (119 epochs" in res.message
    det = res.diagnostics["determined"]
    names = list(det["scales"])
    t = np.array([truth.get(n, 0.0) / det["scales"][n] for n in names])
    z = np.array([(c["estimate"] - np.dot(c["weights"], t)) / c["std"] for c in det["combinations"]])
    assert len(z) >= 10 and np.all(np.abs(z) < 2.5), z
    j = res.names.index("dt_trk")
    assert abs(res.estimate[j]) < 2.0 * res.std[j]  # the simulated tags are on time
