"""A strapdown telemetry whose INS ran on a clock that drifts against the tracking's (GPS) time.

The INS integrated its samples over its own clock's steps and tagged its states with it: a clock fast by ``d``
stretches every integration step (:func:`casep.io.strapdown.clock_stretch`) and tags the states ``d t`` late. The
separation of the telemetry pair tests the drift as one more coefficient with that exact effect
(:mod:`casep.workflows.telemetry_clock`), and a drift given is taken out of the tags and the velocity.

The flight: the 40 s rail launch of ``tests/workflows/test_imu_clock_drift.py`` (10 Hz, 6 s on the pad, a 6 g boost,
a weaving coast) with ``strapdown15_axial`` errors at their declared magnitudes, navigated by ``casep navigate``'s
navigator on the IMU's tags ``t (1 + d)``, tracked in true time at 5 Hz with 0.03 m/s of white noise.
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

import casep
from casep.gravity import launch_gravitation
from casep.io.files import read_flight_pair, write_table
from casep.io.strapdown import clock_stretch
from casep.model.strapdown import body_errors
from casep.navigation import ImuData, check_imu, navigate
from casep.simulation.noise import white_noise
from tests.workflows.test_imu_clock_drift import ALIGN, HEADING, MODEL, SITE, WHITE_STD, _given, _truth

DRIFT = 104e-6
DRIFT80 = 80e-6
ORIGIN = 3e5  # s: a GPS time of week
LOUD, LOUD_AFTER = 20.0, 25.0  # the tracking noise this many times larger after a 4 s gap about this time (s)


def _nav(t, w, f, d):
    return navigate(check_imu(ImuData(t * (1.0 + d), w, f)), SITE, tuple(a * (1.0 + d) for a in ALIGN),
                    heading_deg=HEADING)


def test_the_stretch_is_what_a_drifting_clock_does_to_the_navigation():
    """Navigated on tags ``t (1 + d)``, each sample's velocity is the one navigated on true time plus ``d`` times
    :func:`clock_stretch` (the velocity's change, the gyros' common scale factor through the attitude, the gravity
    gradient through the position error), on a rolling, turning flight, to 1 % of the effect (the second order:
    ``d`` times the attitude error it makes); without the gyros' and the gradient's parts it is 15 % off."""
    t, w, f = _truth(30.0)
    d = 1e-4
    true, stretched = _nav(t, w, f, 0.0), _nav(t, w, f, d)
    E = clock_stretch(true.t, true.q, true.fb, true.w, true.v, true.r, launch_gravitation(SITE))
    dv = stretched.v - true.v
    scale = np.max(np.abs(d * E))
    assert np.max(np.abs(dv - d * E)) < 0.01 * scale
    assert np.max(np.abs(dv - d * (true.v - true.v[0]))) > 0.1 * scale


@pytest.fixture(scope="module")
def pairs(tmp_path_factory):
    """``pairs(d, seed, given, origin, loud)``: the separation of the telemetry navigated on tags ``t (1 + d)`` (all
    times `origin` later: 80 ppm only), paired with the tracking of `seed`'s noise (`loud`: :data:`LOUD` times larger
    after a gap about :data:`LOUD_AFTER`), `given` the drift stated (ppm)."""
    t, w, f = _truth()
    nav0 = _nav(t, w, f, 0.0)
    m = casep.load_model(MODEL)
    z = np.random.default_rng(0).standard_normal(len(m.names))
    df, dw = body_errors(m, nav0.q, f, w, t - t[0], z * np.array([m.scales[n] for n in m.names]))
    directory = tmp_path_factory.mktemp("telclock")
    tel = {}
    for d in (DRIFT, 0.0, DRIFT80):
        nav = _nav(t, w + dw, f + df, d)
        tel[d, 0.0] = directory / f"tel{d:+g}.csv"
        write_table(tel[d, 0.0], nav.columns(), comments=nav.comments("imu.csv"))
        if d == DRIFT80:  # the same flight tagged from the GPS week's start: its times and launch time later
            late = dataclasses.replace(nav, t=nav.t + ORIGIN, site=dataclasses.replace(SITE, t0=SITE.t0 + ORIGIN))
            tel[d, ORIGIN] = directory / f"tel{d:+g}_late.csv"
            write_table(tel[d, ORIGIN], late.columns(), comments=late.comments("imu.csv"))
    done: dict = {}

    def get(d: float, seed: int = 0, given: float = 0.0, origin: float = 0.0, loud: bool = False, **kw):
        key = (d, seed, given, origin, loud, *sorted(kw.items()))
        if key not in done:
            trk = directory / f"trk{seed}_{origin:g}{'_loud' if loud else ''}.csv"
            if not trk.exists():
                k = slice(None, None, 2)
                v = nav0.v[k] + white_noise(t[k].size, WHITE_STD, np.random.default_rng(100 + seed)) \
                    * np.where(loud & (t[k] > LOUD_AFTER), LOUD, 1.0)[:, None]
                kept = (np.abs(t[k] - LOUD_AFTER) > 2.0) | (not loud)  # a 4 s gap between the two
                write_table(trk, {"t": t[k][kept] + origin, **{f"v_trk_{a}": v[kept, i] for i, a in enumerate("xyz")}})
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # conditioning, what the record leaves undetermined: said by it
                flight = read_flight_pair(tel[d, origin], trk, clock_drift=given, **kw)
                done[key] = casep.separate(flight, MODEL, method="ols"), flight
        return done[key]

    return get


def test_a_clock_on_the_tracking_rate_is_within_its_std(pairs):
    """No drift: the drift's estimate within 3 of its std of 0 on each of two tracking noise draws, not determined
    (the fuller Monte Carlo: ``benchmarks/telemetry_clock_mc.py``)."""
    zs = []
    for seed in range(2):
        res, _ = pairs(0.0, seed)
        rec = res.diagnostics["clock_drift"]["telemetry"]
        assert not rec["determined"], rec
        zs.append(rec["ppm"] / rec["std_ppm"])
    assert np.all(np.abs(zs) < 3.0), zs


def test_a_drift_given_takes_it_out_of_the_tags_and_the_velocity(pairs):
    """The drift given (casep's sign: -104 for a clock 104 ppm fast): the estimates those of the same flight on a
    clock without drift to 0.2 of their std, the drift beyond the one given within 3 std of 0, success kept."""
    res0, _ = pairs(0.0)
    res, flight = pairs(DRIFT, 0, _given(DRIFT))
    assert flight.meta["clock_drift_of"] == "telemetry"
    ok = np.isfinite(res0.std) & (res0.std > 0)
    assert np.all(np.abs(res.estimate - res0.estimate)[ok] < 0.2 * res0.std[ok])
    rec = res.diagnostics["clock_drift"]["telemetry"]
    assert abs(rec["beyond_given_ppm"]) < 3.0 * rec["std_ppm"] and not rec["determined"], rec
    assert res.success == res0.success


def test_a_drift_not_given_is_estimated_and_a_wrong_sign_fails(pairs):
    """Not given: the estimate holds the true drift within 3 std, and a drift that large is warned about or within
    what the record says goes unseen. Given with the wrong sign: where the data determine the difference, the result
    fails naming the sign."""
    res, _ = pairs(DRIFT)
    rec = res.diagnostics["clock_drift"]["telemetry"]
    assert abs(rec["ppm"] - _given(DRIFT)) < 3.0 * rec["std_ppm"], rec
    assert rec["determined"] or rec["unseen_ppm"] >= abs(_given(DRIFT)) - 3.0 * rec["std_ppm"]
    wrong, _ = pairs(DRIFT, 0, -_given(DRIFT))
    rec = wrong.diagnostics["clock_drift"]["telemetry"]
    if rec["determined"]:
        assert not wrong.success and "opposite of the one given" in wrong.message, wrong.message


def test_what_an_unmodelled_drift_moves_is_said_for_determined_coefficients(pairs):
    """The record's ``moves``: what a drift at the test's edge, not modelled, does to the coefficients the flight
    determines (std below the declared magnitude), beyond 1 std, largest first, at most MOVES_SAID. (Scaled to the
    true drift they are first-order predictions of how far the estimates move between the drift not given and
    given: on the simulated 195 s boost, dt_trk -9.6 ms predicted, -10.4 ms moved; on this flight ba_y 0.23
    predicted, 0.52 moved, 0.4 std apart: not asserted.)"""
    from casep.workflows.telemetry_clock import MOVES_SAID

    res, _ = pairs(DRIFT)
    rec = res.diagnostics["clock_drift"]["telemetry"]
    fit, _ = pairs(DRIFT, clock_drift_std=0.0)  # the fit's std: before the drift is carried
    m = casep.load_model(MODEL)
    zs = [abs(x["z"]) for x in rec["moves"]]
    assert 0 < len(zs) <= MOVES_SAID and zs == sorted(zs, reverse=True) and min(zs) > 1.0, rec
    assert rec["moves"] == fit.diagnostics["clock_drift"]["telemetry"]["moves"]
    for x in rec["moves"]:
        k = res.names.index(x["name"])
        assert fit.std[k] < m.scales.get(x["name"], np.inf) and x["z"] == pytest.approx(x["shift"] / fit.std[k])


def test_without_the_fits_time_offset_one_is_estimated_beside_the_drift(pairs, tmp_path):
    """A fit without ``dt_trk``: the tags' drift counts from an origin a constant offset moves, so the test estimates
    one beside it; the drift's estimate holds the true one within 3 std."""
    _, flight = pairs(DRIFT)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = casep.separate(flight, MODEL, method="ols", fit_time_offset=False)
    assert "dt_trk" not in res.names
    rec = res.diagnostics["clock_drift"]["telemetry"]
    assert abs(rec["ppm"] - _given(DRIFT)) < 3.0 * rec["std_ppm"], rec


def test_a_drift_not_given_is_carried_in_the_std(pairs):
    """An IMU clock 80 ppm fast, not given, the tracking offset fitted (``time_offset="auto"``): the coefficients
    the record says a drift moves (``moves``) are off by up to 4.8 std with the rate taken as exact
    (``clock_drift_std=0``: the std before the carry) and within 3 std with the drift carried at the --imu path's
    default (50 ppm: sa_x 4.78 -> 2.70 std, dt_trk 1.47 -> 0.62, its drift counted from the launch time); the
    estimates themselves unchanged. The carry is
    the rank-one term of the drift's column: the covariances differ by ``g g^T`` (``g`` the record's shift per
    effective std). A clean record: the same estimates, and the record's drift not determined."""
    m = casep.load_model(MODEL)
    z = np.random.default_rng(0).standard_normal(len(m.names))  # the fixture's errors
    truth = dict(zip(m.names, z * np.array([m.scales[n] for n in m.names])))
    off = {}
    for std in (None, 0.0):
        res, _ = pairs(DRIFT80, time_offset="auto", clock_drift_std=std)
        rec = res.diagnostics["clock_drift"]["telemetry"]
        moved = [x["name"] for x in rec["moves"]]
        assert "dt_trk" in moved, rec["moves"]
        off[std] = {nm: (res.estimate[res.names.index(nm)] - truth.get(nm, 0.0)) / res.std[res.names.index(nm)]
                    for nm in moved}
        assert ("carried" in res.diagnostics["clock_drift"]) == (std is None) and "carried" not in rec  # one place
    assert max(abs(v) for v in off[0.0].values()) > 4.0, off
    assert max(abs(v) for v in off[None].values()) < 3.0, off
    carried, _ = pairs(DRIFT80, time_offset="auto")
    exact, _ = pairs(DRIFT80, time_offset="auto", clock_drift_std=0.0)
    rec = carried.diagnostics["clock_drift"]["carried"]  # the --imu path's key
    assert rec["std_ppm"] == 50.0 and not rec["given"] and "a telemetry clock drift not given" in rec["said"]
    from casep.reporting.noise_text import noise_lines

    assert any(line.endswith("; " + rec["said"]) for line in noise_lines(carried.diagnostics))  # the printed line
    assert carried.to_dict()["diagnostics"]["clock_drift"]["carried"]["said"] == rec["said"]  # the JSON
    np.testing.assert_array_equal(carried.estimate, exact.estimate)
    g = np.array([rec["shift_per_std"][nm] for nm in carried.names])
    ok = np.isfinite(exact.std)
    C, C0 = np.asarray(carried.covariance), np.asarray(exact.covariance)
    np.testing.assert_allclose((C - C0)[np.ix_(ok, ok)], np.outer(g, g)[np.ix_(ok, ok)],
                               atol=1e-9 * np.max(np.abs(np.outer(g, g))))
    clean, _ = pairs(0.0, time_offset="auto")
    clean0, _ = pairs(0.0, time_offset="auto", clock_drift_std=0.0)
    np.testing.assert_array_equal(clean.estimate, clean0.estimate)
    assert not clean.diagnostics["clock_drift"]["telemetry"]["determined"]
    assert np.all(clean.std[ok] >= clean0.std[ok])


def test_the_drift_carried_counts_from_the_flight_not_the_clocks_zero(pairs):
    """The carried drift's column counts the tags' drift from the launch time where the fit has its time offset
    (:func:`casep.io.pair.drift_pivot`): the same flight tagged 3e5 s later (a GPS time of week) gives the same
    carried shifts and std to 1e-6 (float rounding of the later tags is near 1e-11 s). Counted from 0, the later
    flight's dt_trk widened 2560x under 50 ppm (its offset at the GPS week's start, 15 s)."""
    res, _ = pairs(DRIFT80, time_offset="auto")
    late, _ = pairs(DRIFT80, time_offset="auto", origin=ORIGIN)
    assert "dt_trk" in res.names and late.names == res.names
    a, b = res.diagnostics["clock_drift"]["carried"], late.diagnostics["clock_drift"]["carried"]
    ok = np.isfinite(res.std) & (res.std > 0)
    np.testing.assert_allclose(late.std[ok], res.std[ok], rtol=1e-6)
    assert np.all(np.abs(late.estimate - res.estimate)[ok] <= 1e-6 * res.std[ok])
    for k, nm in enumerate(res.names):
        assert abs(b["shift_per_std"][nm] - a["shift_per_std"][nm]) <= 1e-6 * res.std[k], nm
        assert b["std_factor"][nm] == pytest.approx(a["std_factor"][nm], rel=1e-6)


def test_combinations_stated_from_a_result_that_carries_the_drift(pairs, monkeypatch):
    """A pair whose tracking noise differs between stretches: the tracking's judgement states combinations from the
    result it is given, their std with the consider terms its covariance holds; the telemetry clock's drift is carried
    before it (not after, where the combinations stated missed it), once: the result's covariance is the one judged,
    the carried record that of the clean stretch's pair's rule (:func:`carry_telemetry_clock`)."""
    import casep.workflows.separate as separate_module
    from casep.workflows.judging import judge_tracking

    judged = []

    def spy(res, *args, **kw):
        judged.append(res)
        return judge_tracking(res, *args, **kw)

    monkeypatch.setattr(separate_module, "judge_tracking", spy)
    res, _ = pairs(DRIFT80, time_offset="auto", loud=True)
    assert "determined" in res.diagnostics and res.diagnostics["determined"]["combinations"]
    assert len(judged) == 1 and "carried" in judged[0].diagnostics["clock_drift"]
    np.testing.assert_array_equal(np.asarray(res.covariance), np.asarray(judged[0].covariance))
    assert res.diagnostics["clock_drift"]["carried"] == judged[0].diagnostics["clock_drift"]["carried"]


def test_the_command_line_takes_the_drift_std_for_a_telemetry(tmp_path, capsys):
    """``casep separate TEL --tracking TRK --clock-drift-std PPM``: checked by the --imu path's rule
    (given_clock_std) before any file is read, exit 2 for a negative one; without --tracking refused."""
    from casep.cli import main

    args = ["separate", str(tmp_path / "no-such.csv"), "--tracking", str(tmp_path / "no-such-trk.csv")]
    assert main([*args, "--clock-drift-std", "-5"]) == 2
    assert "--clock-drift-std must be a finite number >= 0" in capsys.readouterr().err
    assert main([args[0], args[1], "--clock-drift-std", "5"]) == 2
    assert "--clock-drift-std is used only with --imu IMU.csv or a telemetry with --tracking" in \
        capsys.readouterr().err
