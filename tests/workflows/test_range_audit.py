"""Bad or extreme range inputs that were accepted silently: a tracking gap bridged by interpolation,
an RLS prior the data contradict, Monte Carlo dispersions that hang or never lift off."""

from __future__ import annotations

import warnings

import pandas as pd
import pytest

import casep
from casep.estimators.registry import STATUS_PRIOR_CONFLICT
from casep.exceptions import GapWarning, IllConditionedWarning, NoiseNotWhiteWarning


@pytest.fixture(scope="module")
def gapped(tmp_path_factory):
    """Paper flight, telemetry 20 Hz, tracking 10 Hz with 50 s missing (60-110 s)."""
    from casep.simulation.simulate import simulate_two_rate

    d = simulate_two_rate("paper", seed=2, telemetry_rate=20.0, tracking_rate=10.0)
    folder = tmp_path_factory.mktemp("gap")
    tel, trk = folder / "tel.csv", folder / "trk.csv"
    d.write(tel, trk)
    frame = pd.read_csv(trk, comment="#")
    frame = frame[(frame["t"] < 60.0) | (frame["t"] > 110.0)]
    frame.to_csv(trk, index=False, float_format="%.17g")
    return tel, trk, d


@pytest.mark.parametrize("grid", ["telemetry", "tracking"])
def test_tracking_gap_is_not_bridged(gapped, grid):
    """--grid telemetry interpolated tracking across the 50 s gap: exit 0, no warning, Ka2x 43 std off. Now the
    rows inside the gap are left out with a warning giving the gap; the estimate is within 4 std of the truth."""
    tel, trk, d = gapped
    if grid == "telemetry":
        with pytest.warns(GapWarning, match=r"tracking has 1 gap\(s\) \(50\.\d+ s from t = 59\.9 s.*the 100\d "
                                            r"telemetry samples inside are left out"):
            fl = casep.read_flight_pair(tel, trk, grid=grid)
        assert fl.meta["gap_rows_left_out"] > 990
        inside = (fl.t > 60.0) & (fl.t < 110.0)
        assert not fl.observed[inside].any()
    else:  # one row per tracking sample: nothing to bridge, nothing said
        with warnings.catch_warnings():
            warnings.simplefilter("error", GapWarning)
            fl = casep.read_flight_pair(tel, trk, grid=grid)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IllConditionedWarning)
        # tracking interpolated to the telemetry grid: a moving-average noise the Gauss-Markov family only
        # approximates, so its whitened residuals may stay correlated (said by that warning, not this test)
        warnings.simplefilter("ignore", NoiseNotWhiteWarning)
        res = casep.separate(fl, d.model, "gls" if grid == "telemetry" else "ols")
    j = list(res.names).index("Ka2x")
    assert abs(res.estimate[j] - d.truth[j]) < 4 * res.std[j], (res.estimate[j], d.truth[j], res.std[j])


def test_rls_prior_the_data_contradict_fails():
    """RLS with a prior std far below the truth (p0 = 0.01: prior std 0.01, Ka1x 0.5 mg/g): main reported success
    with estimates thousands of std off; now a failed result naming the coefficients and their z."""
    from casep.simulation.simulate import simulate_flight

    sim = simulate_flight("paper", seed=1, rate=20.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IllConditionedWarning)
        warnings.simplefilter("ignore", NoiseNotWhiteWarning)  # the prior's pull leaves correlated residuals too
        res = casep.separate(sim.flight, "platform36", "rls", p0=0.01)
        ok = casep.separate(sim.flight, "platform36", "rls")  # the paper's p0 = 1e6: no conflict
    assert not res.success and res.status == STATUS_PRIOR_CONFLICT
    assert "prior-data conflict" in res.message and "z = " in res.message
    assert res.diagnostics["prior_conflict"][0]["z"] > 5
    assert ok.success and "prior_conflict" not in ok.diagnostics


def test_rls_on_a_noise_free_flight_is_no_success_when_its_prior_pulls_the_estimate():
    """A noise-free flight through RLS at the paper's p0: the prior N(0, (sigma sqrt(p0))^2), sigma estimated from the
    prior-biased residuals, pulled Ka1xy 200 std off and the result was a success (the conflict test was skipped on
    noise-free data). It fails now, naming the coefficients and the way out (give sigma); with sigma given the prior
    is wide and the estimate within its std of the truth."""
    from casep.exceptions import NoiseFreeWarning, NoiseLevelWarning
    from casep.simulation.scenarios import get_scenario
    from casep.simulation.simulate import simulate_flight

    sim = simulate_flight(get_scenario("paper").without_noise(), seed=1, rate=20.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IllConditionedWarning)
        warnings.simplefilter("ignore", NoiseFreeWarning)
        res = casep.separate(sim.flight, "platform36", "rls")
        with pytest.warns(NoiseLevelWarning, match="disagrees with the least-squares residual std"):
            ok = casep.separate(sim.flight, "platform36", "rls", sigma=0.1)  # std then too large, and said
    assert not res.success and res.status == STATUS_PRIOR_CONFLICT
    assert "prior-data conflict" in res.message and "give sigma" in res.message
    assert ok.success
    assert abs((ok.estimate - sim.truth) / ok.std).max() < 1.0  # the prior N(0, 100^2) pulls it within its std


# ------------------------------------------------------------------ Monte Carlo inputs refused at the edge
@pytest.mark.parametrize("disp, message", [
    ({"launch_azimuth_deg": {"dist": "normal", "mean": 1e300, "std": 1.0}},
     r"`launch_azimuth_deg`: draws must stay within \+-180 deg, got \[1e\+300, 1e\+300\]"),
    ({"launch_azimuth_deg": {"dist": "uniform", "low": -200.0, "high": 0.0}}, r"within \+-180 deg"),
    ({"thrust_scale": {"dist": "normal", "mean": 0.01, "std": 0.0}},
     r"lift-off thrust-to-weight of 0\.0178 \(nominal 1\.78\), below 1\.05: that vehicle does not lift off"),
    ({"thrust_scale": {"dist": "uniform", "low": 0.9, "high": 1.1},
      "liftoff_mass_scale": {"dist": "uniform", "low": 1.0, "high": 1.8}}, r"thrust-to-weight of 0\.89"),
])
def test_montecarlo_dispersions_that_hang_or_never_lift_off_are_refused(disp, message):
    """An azimuth of 1e300 hung main (still running after 120 s); a thrust scale of 0.01 ran without lift-off."""
    from casep.montecarlo import run_montecarlo

    with pytest.raises(ValueError, match=message):
        run_montecarlo("paper", runs=1, methods=["ols"], rate=5.0, workers=1, progress=False, dispersions=disp,
                       noise="white")


def test_montecarlo_truth_prior_beyond_any_instrument_is_refused():
    """--truth-from-prior with std 1e308 printed nan; beyond 1e6 x the declared magnitude is refused too."""
    from casep.montecarlo import run_montecarlo

    for std, message in ((1e308, r"`Kg0x`(: draws reach \|mean\| \+ 6 std = inf deg/h| std must be > 0, within "
                                 r"\[1e-30, 1e\+30\])"),  # the prior reader's magnitude limit comes first
                         (1e5, r"`Kg0x`: draws reach \|mean\| \+ 6 std = 6e\+05 deg/h, beyond 1e\+06 x its declared "
                               r"magnitude 0\.5")):
        with pytest.raises(ValueError, match=message):
            run_montecarlo("paper", runs=1, methods=["ols"], rate=5.0, workers=1, progress=False,
                           truth_prior={"Kg0x": {"mean": 0.0, "std": std}}, noise="white")
