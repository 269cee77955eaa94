"""Raw-IMU separation with a given heading: its uncertainty is a consider parameter in the std.

On a rail launch the lateral terms cannot tell a heading error from the coefficients: the fit's residuals are as good
at a wrong heading as at the right one, and a heading taken as exact gives stated combinations many std off. The
heading's std (:data:`casep.workflows.imu_separate.HEADING_STD_DEG` by default) enters the std through the rows'
derivative along the heading (:meth:`casep.workflows.imu_separate._Run.heading_rows`).

The flight: a 20 s rail launch at 10 Hz (6 s on the pad, 6 g for 10 s, a roll programme) with ``strapdown15_axial``
errors drawn at their declared magnitudes, tracked at 5 Hz with white noise of 0.03 m/s.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import casep
from casep.frames import LaunchSite
from casep.io.files import write_table
from casep.model.strapdown import body_errors
from casep.navigation import ImuData, check_imu, navigate
from casep.navigation.imu import split_steps
from casep.simulation.noise import white_noise
from casep.simulation.strapdown import rail_launch
from casep.workflows.imu_separate import separate_imu

SITE = LaunchSite(28.46, -80.53, 3.0, 95.0, 6.0)  # lift-off at t = 6 s
ALIGN, HEADING, MODEL = (0.0, 5.5), 95.0, "strapdown15_axial"
WHITE_STD = 0.03


@pytest.fixture(scope="module")
def launch(tmp_path_factory):
    """IMU and tracking files of the launch (seed 0), and the truth in declared magnitudes."""
    t = np.round(np.arange(0.0, 20.0, 0.1), 10)
    w, f = rail_launch(SITE, t, elevation_deg=84.0, boost_g=6.0, burn_s=10.0, coast_g=-0.3, roll=(1.5, 3.0))
    # the tracking is this record's own navigation: lift-off and burn-out split at their samples (the mean of their
    # sides), which the integration takes exactly, so the heading is the only consider parameter
    w, f = split_steps(t, w, f)
    nav = navigate(check_imu(ImuData(t, w, f)), SITE, ALIGN, heading_deg=HEADING)
    m = casep.load_model(MODEL)
    rng = np.random.default_rng(0)
    z = rng.standard_normal(len(m.names))
    df, dw = body_errors(m, nav.q, f, w, t - t[0], z * np.array([m.scales[n] for n in m.names]))
    directory = tmp_path_factory.mktemp("heading")
    imu, trk = directory / "imu.csv", directory / "trk.csv"
    write_table(imu, {"t": t, **{f"w_{a}": (w + dw)[:, i] for i, a in enumerate("xyz")},
                      **{f"fb_{a}": (f + df)[:, i] for i, a in enumerate("xyz")}})
    k = slice(None, None, 2)
    v = nav.v[k] + white_noise(t[k].size, WHITE_STD, rng)
    write_table(trk, {"t": t[k], **{f"v_trk_{a}": v[:, i] for i, a in enumerate("xyz")}})
    return imu, trk, z


def _separate(launch, heading: float, std: float | None):
    imu, trk, _ = launch
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # conditioning, what the record leaves undetermined: said by the result
        out = separate_imu(imu, trk, SITE, ALIGN, MODEL, heading_deg=heading, heading_std_deg=std)
    assert out.success, out.message
    return out


def _combinations(out) -> list[dict]:
    det = out.result.diagnostics.get("determined") or {}
    return det.get("combinations") or out.result.diagnostics["iterations"]["passes"][-1]["determined"]


def _z(out, truth) -> np.ndarray:
    return np.array([(c["estimate"] - np.dot(c["weights"], truth)) / c["std"] for c in _combinations(out)])


def test_a_heading_off_by_its_std_leaves_the_stated_combinations_within_their_std(launch):
    """The heading given 0.5 deg off with a std of 0.5 deg: every stated combination within 3 of its std of the
    truth; the same heading taken as exact (std 0) states combinations more than 5 std off, with the same success."""
    truth = launch[2]
    z = _z(_separate(launch, HEADING + 0.5, 0.5), truth)
    assert z.size and np.all(np.abs(z) < 3.0), z
    z_exact = _z(_separate(launch, HEADING + 0.5, 0.0), truth)
    assert np.max(np.abs(z_exact)) > 5.0, z_exact


def test_the_heading_term_is_the_shift_of_re_navigated_separations(launch):
    """The consider term's signed shift per std of heading (``heading_shift`` of each stated combination, from the
    rows' derivative of one pass) against central differences of two whole separations at the heading plus and minus
    its std of 0.5 deg (each navigated, iterated to its own fixed point): the heading moves the combinations by more
    than their std without it, and where it moves them most (above a third of the largest) the two agree within
    15 %."""
    std = 0.5
    mid = _separate(launch, HEADING, std)
    rec = mid.result.diagnostics["heading"]
    assert rec["combinations"]["std_deg"] == std and rec["coefficients"]["max_shift_std_per_step"] > 0
    combos = _combinations(mid)
    names = list(mid.result.names)
    scale = np.array([mid.result.diagnostics["determined"]["scales"][n] for n in names])
    hi, lo = (_separate(launch, HEADING + s, std).result.estimate / scale for s in (std, -std))
    fd = np.array([c["weights"] for c in combos]) @ (hi - lo) / 2  # each combination's shift per std of heading
    said = np.array([c["heading_shift"] for c in combos])
    alone = np.array([c["std_tracking_noise_only"] for c in combos])
    assert np.max(np.abs(said) / alone) > 1.0, (said, alone)
    big = np.abs(said) > np.abs(said).max() / 3
    np.testing.assert_allclose(fd[big], said[big], rtol=0.15, err_msg=f"{said} {fd}")


@pytest.mark.parametrize("heading, std, said", [(HEADING, -0.1, "finite number >= 0"),
                                                (HEADING, float("nan"), "finite number >= 0"),
                                                (None, 0.1, "give the heading")])
def test_the_heading_std_is_checked(heading, std, said):
    """A negative or non-finite std, or a std without a heading (the alignment gyrocompasses): a clear error naming
    the parameter, before the record is read."""
    with pytest.raises(ValueError, match="heading_std_deg.*" + said):
        separate_imu("no-such-imu.csv", "no-such-trk.csv", SITE, ALIGN, MODEL, heading_deg=heading,
                     heading_std_deg=std)
