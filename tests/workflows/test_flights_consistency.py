"""Several flights that disagree on the shared coefficients fail the joint result (casep.workflows.flights).

Noise-free flights: one joint least-squares fit must leave each flight at its rounding level
(:meth:`casep.regression.problem.Problem.is_noise_free`, the one rule); noisy ones: the Chow test at
:data:`casep.estimators.joint.FAIL_P`. Flights of one truth stay a success, on Gauss-Markov plus white
noise too (the test's size on that noise: benchmarks/mc_chow_size_gmw.py).
"""

import dataclasses
import json
import warnings

import numpy as np
import pytest

from casep.estimators.joint import FAIL_P, WARN_P
from casep.exceptions import ConsistencyWarning
from casep.simulation.scenarios import get_scenario
from casep.simulation.simulate import simulate_flight
from casep.workflows.flights import JOINT_ROUNDING_MARGIN, STATUS_DISAGREE, judge_consistency, separate_flights

RATE = 2.0  # Hz: 400 samples a flight, enough for 36 coefficients of the boost with its yaw manoeuvre
#: Ka0y of the second flight moved by this (mg): another instrument, or an unmodelled error (at 2 Hz with the
#: coloured noise below 20 mg gives p ~ 1e-126, 5 mg p ~ 2e-6: the test's power, not its threshold, is tested)
SHIFT_MG = 20.0
#: The same for noise-free flights: 10 ug, far below what noise of 0.1 m/s lets one see, leaves ~2e-5 m/s
NOISE_FREE_SHIFT_MG = 0.01


def _flight(name, seed, *, noisy, shift=0.0):
    sc = get_scenario(name)
    noise = (dataclasses.replace(sc.noise, kind="ar1", sigma=0.09, tau=1.0, white_sigma=0.045) if noisy
             else dataclasses.replace(sc.noise, sigma=0.0))
    truth = {**sc.truth, "Ka0y": sc.truth["Ka0y"] + shift}
    fl = simulate_flight(dataclasses.replace(sc, noise=noise), seed=seed, rate=RATE, truth=truth).flight
    return dataclasses.replace(fl, source=f"{name}{'-shifted' if shift else ''}.csv")


def _joint(flights):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # one boost flight alone is ill-conditioned, noise-free data: said elsewhere
        return separate_flights(flights, "platform36", "ols")


@pytest.fixture(scope="module")
def noise_free():
    """Two noise-free flights of one truth, and the second again with another Ka0y."""
    return _flight("paper", 1, noisy=False), _flight("paper-azimuth", 2, noisy=False), \
        _flight("paper-azimuth", 2, noisy=False, shift=NOISE_FREE_SHIFT_MG)


@pytest.fixture(scope="module")
def coloured():
    """The joint fits of two flights with Gauss-Markov (0.09 m/s, 1 s) plus white (0.045 m/s) noise: of one truth,
    and with the second flight's Ka0y moved."""
    first = _flight("paper", 11, noisy=True)
    return _joint([first, _flight("paper-azimuth", 12, noisy=True)]), \
        _joint([first, _flight("paper-azimuth", 12, noisy=True, shift=SHIFT_MG)])


def test_noise_free_flights_of_one_truth_agree(noise_free):
    res, jp = _joint(noise_free[:2])
    nf = res.diagnostics["consistency"]["noise_free"]
    assert res.success and nf["agree"]
    for p, lab in zip(jp.raw, jp.layout.labels):  # the joint fit at each flight's rounding level (measured: 1e-6 x)
        assert nf["residual_rms"][lab] <= 1e-3 * nf["rounding_level"][lab]
        assert nf["rounding_level"][lab] == p.rounding_floor()


def test_noise_free_flights_that_disagree_fail_naming_the_flights_and_the_misfit(noise_free):
    """Each flight alone is at its rounding level (so no noise to test against), but no one set of shared
    coefficients fits both: failed, with each flight's joint-fit residual RMS in m/s."""
    res, jp = _joint([noise_free[0], noise_free[2]])
    assert all(p.is_noise_free() for p in jp.raw)
    nf = res.diagnostics["consistency"]["noise_free"]
    assert not res.success and res.status == STATUS_DISAGREE and not nf["agree"]
    for lab in jp.layout.labels:
        rms = nf["residual_rms"][lab]
        assert rms > 10 * JOINT_ROUNDING_MARGIN * nf["rounding_level"][lab]
        assert f"{lab} {rms:.3g} m/s" in res.message
    assert "the flights disagree" in res.message
    assert np.all(np.isfinite(res.estimate))  # still there, for inspection


def test_coloured_flights_of_one_truth_pass_and_of_two_truths_fail(coloured):
    same, _ = coloured[0]
    ov = same.diagnostics["consistency"]["overall"]
    assert same.success and ov["p_value"] > WARN_P
    other, jp = coloured[1]
    ov = other.diagnostics["consistency"]["overall"]
    assert not other.success and other.status == STATUS_DISAGREE and ov["p_value"] < FAIL_P
    assert f"Chow test chi2 {ov['chi2']:.4g} on {ov['dof']} dof, p {ov['p_value']:.3g}" in other.message
    assert all(lab in other.message for lab in jp.layout.labels)
    per = other.diagnostics["consistency"]["per_coefficient"]
    worst = min(per, key=lambda m: per[m]["p_value"])
    assert "largest per coefficient: " + worst in other.message


def test_warning_between_the_levels_and_failure_below(coloured):
    same, _ = coloured[0]
    cons = same.diagnostics["consistency"]
    ov = cons["overall"]
    low = {**cons, "overall": {**ov, "p_value": np.sqrt(WARN_P * FAIL_P)}}
    with pytest.warns(ConsistencyWarning, match="the flights disagree: Chow test"):
        warned = judge_consistency(same, low)
    assert warned.success
    gone = judge_consistency(same, {**cons, "overall": {**ov, "p_value": FAIL_P / 2}})
    assert not gone.success and gone.status == STATUS_DISAGREE


def test_cli_exit_code_and_json_of_disagreeing_flights(noise_free, tmp_path):
    from casep.cli import main
    from casep.io.files import write_flight

    paths = []
    for k, fl in enumerate((noise_free[0], noise_free[2])):
        write_flight(fl, tmp_path / f"f{k}.csv")
        paths.append(str(tmp_path / f"f{k}.csv"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["separate", *paths, "--json", str(tmp_path / "j.json")]) == 1  # as every failed result
    d = json.loads((tmp_path / "j.json").read_text())
    assert d["success"] is False and d["status"] == STATUS_DISAGREE and "the flights disagree" in d["message"]
    assert d["consistency"]["noise_free"]["agree"] is False and "consistency" not in d["diagnostics"]
    assert len(d["estimates"]) == 36
