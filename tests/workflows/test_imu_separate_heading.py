"""Raw-IMU separation with a given heading: its uncertainty is a consider parameter in the std.

On a rail launch the lateral terms cannot tell a heading error from the coefficients: the fit's residuals are as good
at a wrong heading as at the right one, and a heading taken as exact gives stated combinations many std off. The
heading's std (:data:`casep.workflows.imu_separate.HEADING_STD_DEG` by default) enters the std through the rows'
derivative along the heading (:meth:`casep.workflows.imu_separate._Run.heading_rows`).

The flight: a 20 s rail launch at 10 Hz (6 s on the pad, 6 g for 10 s, a roll programme) with ``strapdown15_axial``
errors drawn at their declared magnitudes, tracked at 5 Hz with white noise of 0.03 m/s.
"""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest

import casep
from casep.frames import LaunchSite
from casep.io.files import write_table
from casep.navigation import ImuData, check_imu, navigate
from casep.navigation.imu import split_steps
from casep.simulation.noise import white_noise
from casep.simulation.strapdown import rail_launch, with_drawn_errors
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
    rng = np.random.default_rng(0)
    w_m, f_m, z = with_drawn_errors(casep.load_model(MODEL), nav.q, w, f, t, rng)
    directory = tmp_path_factory.mktemp("heading")
    imu, trk = directory / "imu.csv", directory / "trk.csv"
    write_table(imu, {"t": t, **{f"w_{a}": w_m[:, i] for i, a in enumerate("xyz")},
                      **{f"fb_{a}": f_m[:, i] for i, a in enumerate("xyz")}})
    k = slice(None, None, 2)
    v = nav.v[k] + white_noise(t[k].size, WHITE_STD, rng)
    write_table(trk, {"t": t[k], **{f"v_trk_{a}": v[:, i] for i, a in enumerate("xyz")}})
    return imu, trk, z


@pytest.fixture(scope="module")
def separated(launch):
    """``separated(heading, std)``: the launch separated at that heading and heading std, each pair once per module
    (the tests read the results, never change them): the heading 0.5 deg off with its std of 0.5 deg is both a
    test's own separation and the other's step up in heading."""
    done: dict[tuple, object] = {}

    def get(heading: float, std: float | None):
        if (heading, std) not in done:
            done[heading, std] = _separate(launch, heading, std)
        return done[heading, std]

    return get


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


def test_a_heading_off_by_its_std_leaves_the_stated_combinations_within_their_std(launch, separated):
    """The heading given 0.5 deg off with a std of 0.5 deg: every stated combination within 3 of its std of the
    truth; the same heading taken as exact (std 0) states combinations more than 5 std off, with the same success."""
    truth = launch[2]
    z = _z(separated(HEADING + 0.5, 0.5), truth)
    assert z.size and np.all(np.abs(z) < 3.0), z
    z_exact = _z(separated(HEADING + 0.5, 0.0), truth)
    assert np.max(np.abs(z_exact)) > 5.0, z_exact


def test_the_heading_term_is_the_shift_of_re_navigated_separations(separated):
    """The consider term's signed shift per std of heading (``heading_shift`` of each stated combination, from the
    rows' derivative of one pass) against central differences of two whole separations at the heading plus and minus
    its std of 0.5 deg (each navigated, iterated to its own fixed point): the heading moves the combinations by more
    than their std without it, and where it moves them most (above a third of the largest) the two agree within
    15 %."""
    std = 0.5
    mid = separated(HEADING, std)
    rec = mid.result.diagnostics["heading"]
    assert rec["combinations"]["std_deg"] == std and rec["coefficients"]["max_shift_std_per_step"] > 0
    combos = _combinations(mid)
    names = list(mid.result.names)
    scale = np.array([mid.result.diagnostics["determined"]["scales"][n] for n in names])
    hi, lo = (separated(HEADING + s, std).result.estimate / scale for s in (std, -std))
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


@pytest.mark.parametrize("extra, said", [
    (["--heading", "30", "--heading-std", "-0.1"], r"--heading-std -0\.1 must be a finite number >= 0"),
    (["--heading-std", "0.1"], r"--heading-std 0\.1 is the std of --heading DEG")])
def test_the_command_line_checks_the_heading_std_with_the_same_rule(tmp_path, capsys, extra, said):
    """``casep separate --imu`` refuses the same std by the same rule (given_heading_std), naming its flags, exit 2,
    before any file is read."""
    from casep.cli import main

    rc = main(["separate", "--imu", str(tmp_path / "no-such-imu.csv"), "--tracking", str(tmp_path / "no-such.csv"),
               "--launch-site", "67.89", "21.1", "330", "30", "--launch-time", "10", "--align", "0", "9", *extra])
    assert rc == 2
    assert re.search(said, capsys.readouterr().err)


def _gls_problem(c_true: float, seed: int = 3):
    """A linear problem ``y = S x + d c + e`` on 60 epochs (5 Hz) with Gauss-Markov noise per axis (tau 1, 2, 0.5 s,
    scales 1, 1.5, 0.8, sigma 0.05 m/s), the fakes :func:`heading_conflict` reads, and the design and covariance
    written out whole (3N x 3N, axis-interleaved) for an independent GLS."""
    from types import SimpleNamespace

    from casep.noise.model import NoiseModel

    rng = np.random.default_rng(seed)
    N, n, sigma = 60, 4, 0.05
    t = np.arange(N) * 0.2
    tau, scale = (1.0, 2.0, 0.5), (1.0, 1.5, 0.8)
    S, d = rng.standard_normal((N, 3, n)), rng.standard_normal((N, 3))
    cov = np.zeros((3 * N, 3 * N))
    for j in range(3):  # AR(1) of unit stationary variance on the times, times the axis's scale
        cov[j::3, j::3] = scale[j] ** 2 * np.exp(-np.abs(t[:, None] - t[None, :]) / tau[j])
    e = np.linalg.cholesky(cov) @ rng.standard_normal(3 * N) * sigma
    y = np.einsum("ijk,k->ij", S, rng.standard_normal(n)) + d * c_true + e.reshape(N, 3)
    noise = NoiseModel(kind="gm", tau=tau, scale=scale).to_dict()
    res = SimpleNamespace(names=[f"c{k}" for k in range(n)], sigma=sigma, diagnostics={"noise": noise})
    problem = SimpleNamespace(t=t, y=y, sv=lambda: S)
    X = np.column_stack([S.reshape(3 * N, n), d.reshape(-1)])
    return res, problem, d, X, y.reshape(-1), cov * sigma**2


@pytest.mark.parametrize("c_true", [0.0, 3.0])
def test_the_heading_test_is_the_gls_coefficient_of_the_heading_column(c_true):
    """:func:`heading_conflict`'s estimate of the heading's error and its std (the fit's noise, the flight holding no
    IMU samples) against GLS written out with the full covariance (``(X^T C^-1 X)^-1 X^T C^-1 y``, ``X = [S, d]``):
    equal to rounding; its sign is the heading given less the true (the rows at ``H`` are ``y(H_true) + d (H -
    H_true)``), the suggestion ``H - c``, and z the prior predictive ``|c| / sqrt(stated^2 + std^2)``."""
    from types import SimpleNamespace

    from casep.estimators.rls import PRIOR_CONFLICT_Z
    from casep.workflows.imu_separate import heading_conflict

    res, problem, d, X, y, cov = _gls_problem(c_true)
    Ci = np.linalg.inv(cov)
    M = np.linalg.inv(X.T @ Ci @ X)
    beta = M @ X.T @ Ci @ y
    rec = heading_conflict(res, problem, SimpleNamespace(signals={}, meta={}), d, 95.0, 0.1)
    assert rec is not None
    np.testing.assert_allclose(rec["estimate_deg"], beta[-1], rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(rec["std_deg"], np.sqrt(M[-1, -1]), rtol=1e-8)
    assert rec["z"] == pytest.approx(abs(beta[-1]) / np.hypot(0.1, np.sqrt(M[-1, -1])), rel=1e-8)
    assert rec["suggested_heading_deg"] == pytest.approx(95.0 - rec["estimate_deg"])
    assert rec["conflict"] == (rec["z"] > PRIOR_CONFLICT_Z)
    if c_true:  # 3 deg off, known to about 0.01 deg: the data contradict a std of 0.1 deg
        assert rec["std_deg"] < 0.05 and rec["conflict"] and abs(rec["estimate_deg"] - c_true) < 5 * rec["std_deg"]
    else:
        assert not rec["conflict"]


def test_what_a_result_says_of_the_heading_test():
    """The failure's message (a conflict) gives the data's estimate and std, the stated std and both suggestions;
    a record that knows the heading less well than its stated std says that no error of it would show; one that knows
    it better gives the data's own estimate and the heading they point to."""
    from casep.workflows.imu_separate import heading_message, heading_said

    rec = {"heading_deg": 32.0, "stated_std_deg": 0.1, "estimate_deg": 2.04, "std_deg": 0.21, "z": 8.6,
           "limit_z": 5.0, "suggested_heading_deg": 29.96, "conflict": True}
    said = heading_message(rec, "x")
    for part in ("--heading 32 deg", "+2.04 +- 0.21 deg", "--heading-std 0.1 deg", "--heading 29.96",
                 "--heading-std 2"):
        assert part in said, said
    assert heading_said(rec) is None  # the failure says it
    loose = {**rec, "estimate_deg": -19.2, "std_deg": 55.5, "z": 0.35, "conflict": False}
    assert "the record does not check the heading given (--heading 32 deg): its own estimate of the heading's " \
           "error, with the coefficients free, is -19.2 +- 55.5 deg" in heading_said(loose)[0]
    some = {**loose, "std_deg": 1.5}
    assert "the record checks the heading given (--heading 32 deg) only to 7.52 deg" in heading_said(some)[0]
    # known better than its stated std: the data's own estimate and the heading they point to, a turn within the
    # stated std but beyond 5 of the data's std warned of (the residuals keep it: heading 3 deg off, --heading-std 5)
    agrees = {**loose, "estimate_deg": 0.02, "std_deg": 0.05, "z": 0.18, "suggested_heading_deg": 31.98}
    line, misfit = heading_said(agrees)
    assert not misfit and "+0.02 +- 0.05 deg" in line and "--heading 31.98 --heading-std 0.05" in line, line
    off = {**rec, "stated_std_deg": 5.0, "heading_deg": 3.0, "estimate_deg": 2.91, "std_deg": 0.19, "z": 0.58,
           "suggested_heading_deg": 0.09, "conflict": False}
    line, misfit = heading_said(off)
    assert misfit and "+2.91 +- 0.19 deg (z 15.3 against its own std" in line and "--heading 0.09" in line, line
    assert "better than its stated std (--heading-std 5 deg)" in line and "the residuals hold it" in line, line
    assert heading_said({**off, "judged": False}) is None  # beyond the small-angle reach: the test says nothing


def test_a_turn_beyond_the_linear_test_says_its_heading_is_approximate():
    """Where the rows navigated at the heading the test points to still hold a turn beyond HEADING_SETTLED_Z of its
    std (``settled`` False), the message says the test is linear and that heading approximate, and points to the
    heading's axis and reference first; a settled record (or one from before the rule) keeps the plain advice. The
    numbers: the aircraft with launch-frame tracking and the heading 25 deg off (read as +24.1, 1.8 deg left at
    70.9)."""
    from casep.workflows.imu_separate import heading_message

    rec = {"heading_deg": 95.0, "stated_std_deg": 0.1, "estimate_deg": 24.1, "std_deg": 0.26, "z": 86.9,
           "limit_z": 5.0, "suggested_heading_deg": 70.9, "conflict": True, "at_suggested_deg": 1.77,
           "settled": False}
    said = heading_message(rec, "x")
    assert "beyond its reach" in said and "70.9 deg, the rows still hold +1.8 deg" in said, said
    assert "approximate" in said and "--heading-axis" in said and "magnetic" in said
    for settled in ({**rec, "settled": True}, {k: v for k, v in rec.items() if k != "settled"}):
        plain = heading_message(settled, "x")
        assert "beyond its reach" not in plain and "--heading 70.9 is what the data point to" in plain


@pytest.fixture(scope="module")
def aircraft(tmp_path_factory):
    """A flight whose data determine the heading: the tactical aircraft of ``benchmarks/aircraft_flight.py`` (its own
    strapdown generator) cut to 2.8 min (60 s on the ground, a take-off roll, a climb, one coordinated turn), its IMU
    at 25 Hz with ``strapdown12``'s errors (the benchmark's draw of seed 1, the other terms of ``strapdown33`` zero),
    GNSS velocity and position at 2 Hz (the benchmark's 5 Hz: the same turn and heading tests, the noise fits of the
    passes on 40 % of the rows) with Gauss-Markov plus white noise."""
    from conftest import benchmark_module

    with benchmark_module("aircraft_flight") as af:
        af.GNSS_HZ = 2
        full = af.with_errors
        kept = ("ba_", "sa_", "bg_", "sg_")
        af.with_errors = lambda fb, wb, c: full(fb, wb, {k: v if k.startswith(kept) else 0.0 for k, v in c.items()})
        imu, trk, _ = af.flight(1, 2.8, 25, tmp_path_factory.mktemp("aircraft"))
        site, align, heading = LaunchSite(*af.SITE, af.T_REST), (1.0, af.T_REST - 5.0), af.SITE[3]
    return imu, trk, site, align, heading


def test_a_heading_the_data_contradict_fails_the_result(aircraft):
    """Where the turns determine the heading (to 0.11 deg here), the test holds at the true heading (a success, z well
    below the limit of 5; the message says to what the record checks the heading) and, with the heading given 2 deg
    off at its default std of 0.1 deg, finds it: the estimated offset within 2 of its std of +2 deg, a SetupWarning
    with the numbers and the heading to try, and the result failed (status -10), not a success whose estimate
    carries the turn."""
    from casep.estimators.registry import STATUS_PRIOR_CONFLICT
    from casep.exceptions import SetupWarning

    imu, trk, site, align, heading = aircraft

    def run(h):
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            out = separate_imu(imu, trk, site, align, "strapdown12", heading_deg=h, tracking_frame="geodetic")
        return out, [str(w.message) for w in seen if w.category is SetupWarning]

    right, said = run(heading)
    test = right.result.diagnostics["heading"]["test"]
    assert right.success and not said and not test["conflict"] and test["z"] < 3.0, (test, right.message)
    assert test["std_deg"] < 0.5 and "the record checks the heading given (--heading 70 deg) only to" in right.message
    wrong, said = run(heading + 2.0)
    test = wrong.result.diagnostics["heading"]["test"]
    assert not wrong.success and wrong.result.status == STATUS_PRIOR_CONFLICT, wrong.message
    assert test["conflict"] and abs(test["estimate_deg"] - 2.0) < 2 * test["std_deg"], test
    assert abs(test["at_suggested_deg"]) < test["std_deg"], test  # navigated at the heading it points to: no turn left
    assert len(said) == 1 and "the data contradict the heading given" in said[0], said
    assert f"--heading {test['suggested_heading_deg']:.4g}" in said[0] and "--heading-std" in said[0]
    assert said[0] in wrong.message


def test_a_rail_launch_says_the_record_does_not_check_the_heading(separated):
    """On the rail launch the lateral terms fit a heading error: the data's own std of it is many degrees, the test
    holds (no failure), and the result says the record does not check the heading given (the separation at the true
    heading of the shift's test above; the default std of the heading is the aircraft's below)."""
    out = separated(HEADING, 0.5)
    test = out.result.diagnostics["heading"]["test"]
    assert not test["conflict"] and test["std_deg"] > 1.0, test
    assert "the record does not check the heading given (--heading 95 deg)" in out.message


def test_a_step_that_fails_on_a_wrong_heading_blames_the_heading(aircraft, tmp_path):
    """Launch-frame tracking (the aircraft's GNSS velocity turned into the launch-inertial frame) and the heading given
    10 deg off: the iteration's step leaves the linear model (the coefficients cannot take the turn). The failure
    blames the heading the data contradict (its reading within 2 std of +10 deg), not errors too large for the model
    (what it said before, the heading only further on)."""
    import pandas as pd

    from casep.frames import ecef_to_launch, geodetic_to_ecef

    imu, trk, site, align, heading = aircraft
    g = pd.read_csv(trk, comment="#")
    r, v = geodetic_to_ecef(g.lat, g.lon, g.h, g.v_east, g.v_north, g.v_up)
    v_l = ecef_to_launch(site, g.t.to_numpy(), r, v)[1]
    launch = tmp_path / "launch.csv"
    write_table(launch, {"t": g.t.to_numpy(), **{f"v_trk_{a}": v_l[:, i] for i, a in enumerate("xyz")}})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = separate_imu(imu, launch, site, align, "strapdown12", heading_deg=heading + 10.0)
    test = out.result.diagnostics["heading"]["test"]
    assert not out.success and test["conflict"] and abs(test["estimate_deg"] - 10.0) < 2 * test["std_deg"], test
    assert "leaves the linear model" in out.message, out.message  # the step failed ...
    assert "the errors are too large for the model, or the data are inconsistent" not in out.message
    assert f"the heading given is the likelier cause: the data put it {test['estimate_deg']:+.3g} deg off" \
        in out.message, out.message
