"""The radar rows through the noise layer (Gauss-Markov, robust weights per station and type), a
noise-free radar flight through the default path, and the launch time with one station."""

from __future__ import annotations

import dataclasses
import math
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from conftest import dishonest_whitened
from test_radar import SITE, STATIONS, TRUTH

from casep.cli import main
from casep.estimators.spec import FitSpec
from casep.exceptions import NoiseNotWhiteWarning
from casep.simulation.radar import DEFAULT_NOISE, simulate_radar, write_radar_simulation
from casep.workflows.radar import separate_radar

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))


# ----------------------------------------------------------------------------- Gauss-Markov noise
def test_simulated_gauss_markov_radar_noise_has_its_std_and_correlation():
    """The simulator's Gauss-Markov part: stationary std and lag-one correlation exp(-dt / tau)."""
    from casep.simulation.radar import _gauss_markov

    t = np.arange(200_000) * 0.1
    g = _gauss_markov(t, 2.0, 1.0, np.random.default_rng(5))
    assert np.std(g) == pytest.approx(2.0, rel=0.03)
    rho = np.corrcoef(g[1:], g[:-1])[0, 1]
    assert rho == pytest.approx(math.exp(-0.1), abs=0.01)
    with pytest.raises(ValueError, match="gauss_markov.*elevation"):
        simulate_radar(STATIONS, SITE, gauss_markov={"elevation": -1.0})


@pytest.mark.montecarlo
def test_gauss_markov_plus_white_radar_noise_is_honest_and_white_only_is_not():
    """GM (tau 1 s: 3 m, 8 arcsec) + white (1.5 m, 4 arcsec) per station and type, 2 stations, telemetry and
    radar at 5 Hz (2 s of CPU a draw). The reduced Monte Carlo of ``benchmarks/mc_radar_noise.py --whitened`` (its
    6 draws, seeds 100-105, are the full check; 12 draws, seeds 100-111: RMS w 1.108).

    Default (noise auto): the noise is found per group (tau within a factor 2 of 1 s, Gauss-Markov plus
    white) and the stated covariance is honest over 3 seeded draws (seeds 100-102): each draw's error whitened
    by it (:func:`conftest.whitened_error`, 36 instrument terms, 47 with the tracking ones), checked by
    :func:`conftest.dishonest_whitened`.
    The per-coefficient z (RMS z in [0.6, 1.3], coverage >= 0.85) is the benchmark's, over its 6 draws: the 36 z of
    one draw are strongly correlated, so over 3 draws their RMS has no stated scatter (1.32 here, 1.19 over 6) and
    cannot tell a std 0.7x too small; the whitened check below asserts more (``e ~ N(0, C)`` whole, of which each
    ``z ~ N(0, 1)`` is a marginal). The whitened w are independent: ``sum w^2`` over the 108 instrument w is
    chi2_108 when the covariance is honest, ``c^2 chi2_108`` when its std are c times too small. The noise
    parameters are estimated (REML), which leaves the covariance slightly small: c = 1.108 over 12 draws. The band
    [0.80, 1.30] on RMS w (the full run's): at c = 1.108 RMS w falls above 1.30 with probability
    P(chi2_108 > 108 * 1.30^2 / 1.108^2) = 0.6 % and below 0.80 with 1e-5 (exactly honest, c = 1: 1e-5 above,
    0.13 % below); a std 0.7x too small (c = 1.108 / 0.7) passes with probability 0.4 %. And the count of draws
    whose ``w^T w`` passes its chi2_36 95 % point (51.0) at most 2 of 3 (``false_alarm`` 1e-3): all 3 pass it with
    probability 1.25e-4 when honest, 1.4 % at c = 1.108, 95 % at std 0.7x. For the 47 (c = 1.102 over the 12
    draws): 0.15 % above the band, 1.8 % all 3 over. Here: RMS w 1.140 (sums 58.4, 37.2, 44.6), 1 draw over; all
    47: 1.130, 1 over (64.0); with std and covariance scaled to 0.7x, RMS w 1.63 (1.61) and 3 draws over: fails
    both checks.
    White only on the same data: overconfident (RMS z > 2) and never a plain success (a whiteness warning naming
    the station, or a failed result).
    """
    from mc_radar_noise import run, whitened_errors

    runs: dict = {}
    seeds = range(100, 103)
    res = run(seeds, 5.0, 1.0, noises=("auto",), separations=runs)["auto"]
    assert res["successes"] == res["runs"] and "NoiseNotWhiteWarning" not in res["warnings"], res
    ws = whitened_errors(seeds, runs)
    assert not (bad := dishonest_whitened(ws, rms=(0.80, 1.30), false_alarm=1e-3)), bad
    sim, rr = runs[100], runs[100, "auto"]  # the first seed's flight and its separation with noise auto
    kinds = [g["kind"] for g in rr.summary["noise"]]
    assert "white" not in kinds and kinds.count("gmw") >= 4, rr.summary["noise"]
    assert all(0.5 < g["tau_s"] < 2.0 for g in rr.summary["noise"]), rr.summary["noise"]
    assert set(rr.result.diagnostics["noise"]) == {"S1", "S2"}  # the noise account, per station
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        white = separate_radar(sim.telemetry, list(sim.radars), SITE, sim.model, sim.tracking, noise="white",
                               diagnostics=False)
    # never a plain success: a whiteness warning naming the station, or (its too-small std make the set-up or
    # residual checks significant) a failed result, whose residuals are then not tested for whiteness
    said = any(issubclass(w.category, NoiseNotWhiteWarning) and "residuals are not white (range Q" in str(w.message)
               for w in rec)
    assert said or not white.success, [str(w.message) for w in rec]
    n = sim.model.n_coefficients
    z = (white.result.estimate[:n] - sim.truth[:n]) / white.result.std[:n]
    assert np.sqrt(np.mean(z[np.isfinite(z)] ** 2)) > 2.0


def test_radar_takes_the_fit_request_noise_options_and_refuses_what_does_not_apply():
    """noise, tau, robust build the one FitSpec; a given tau is the noise model's; HAC std still refused."""
    sim = simulate_radar(STATIONS, SITE, seed=2, telemetry_rate=5, radar_rate=5, tracking_truth=TRUTH,
                         noise={"range": 1.0, "azimuth": 3.0, "elevation": 3.0},
                         gauss_markov={"range": 3.0, "azimuth": 8.0, "elevation": 8.0}, gm_tau=1.0)
    spec = FitSpec.build("ols", noise="gm", tau=1.0, robust="none")
    with pytest.warns(NoiseNotWhiteWarning, match=r"whitened by the noise model \(gm\) are still correlated"):
        rr = separate_radar(sim.telemetry, list(sim.radars), SITE, sim.model, sim.tracking, spec=spec,
                            diagnostics=False)  # the white part that gm leaves out: said
    for g in rr.summary["noise"]:
        assert g["kind"] == "gm" and g["tau_s"] == 1.0 and "tau given" in g["source"], g
    assert "GM tau 1 s" in rr.text()
    with pytest.raises(ValueError, match=r"`std='hac'` is not available with `radar`"):
        separate_radar(sim.telemetry, list(sim.radars), SITE, sim.model, sim.tracking,
                       spec=FitSpec.build("ols", noise="white", std="hac", robust="none"))
    with pytest.raises(ValueError, match="noise std .*given std are white noise"):
        separate_radar(sim.telemetry, list(sim.radars), SITE, sim.model, sim.tracking, noise="gmw",
                       sigma={("S1", "range"): 3.0})


def test_radar_robust_fit_removes_glitches_per_station():
    """Ten 300 m range glitches on S1: the robust filter of the noise layer rejects them (auto engages Huber),
    the account names station S1, and the instrument estimate stays within 3 std of the clean one."""
    sim = simulate_radar(STATIONS, SITE, seed=4, telemetry_rate=5, radar_rate=5, tracking_truth=TRUTH)
    m = sim.radars[0]
    bad = np.arange(100, 600, 50)
    glitched = dataclasses.replace(m, range=m.range.copy())
    glitched.range[bad] += 300.0
    clean = separate_radar(sim.telemetry, list(sim.radars), SITE, sim.model, sim.tracking, diagnostics=False)
    rr = separate_radar(sim.telemetry, [glitched, sim.radars[1]], SITE, sim.model, sim.tracking, diagnostics=False)
    acc = rr.result.diagnostics["noise"]["S1"]
    assert acc["robust"]["rejected_count"] >= len(bad), acc["robust"]
    assert "robust" not in rr.result.diagnostics["noise"]["S2"]
    n = sim.model.n_coefficients
    d = (rr.result.estimate[:n] - clean.result.estimate[:n]) / clean.result.std[:n]
    assert np.nanmax(np.abs(d)) < 3.0


# ----------------------------------------------------------------------------- noise-free, default path
def _finite_json(path) -> dict:
    from conftest import finite_json

    return finite_json(path)


def test_noise_free_radar_flight_default_path_json(tmp_path, capsys):
    """Noise-free two-station flight, no noise given, `casep separate --radar ... --json`: exit 0, nothing rejected
    as a glitch, recovery within 0.01 of the CRLB std at the simulator's default noise, every JSON number finite.
    On main the linearisation did not converge (steps measured against a floored std of 1e-9 m)."""
    sim = simulate_radar(STATIONS, SITE, seed=0, telemetry_rate=5, radar_rate=5, tracking_truth=TRUTH,
                         noise={"range": 0.0, "azimuth": 0.0, "elevation": 0.0})
    tel, out = tmp_path / "tel.csv", tmp_path / "r.json"
    write_radar_simulation(sim, tel)
    code = main(["separate", str(tel), "--radar", str(tmp_path / "tel.S1.json"), str(tmp_path / "tel.S1.csv"),
                 "--radar", str(tmp_path / "tel.S2.json"), str(tmp_path / "tel.S2.csv"),
                 "--launch-site", "28.5", "-80.6", "3", "90", "--launch-time", "0", "--json", str(out)])
    printed = capsys.readouterr()
    assert code == 0, printed.err
    assert "glitch" not in printed.out + printed.err
    data = _finite_json(out)
    for st in data["diagnostics"]["noise"].values():
        assert st.get("robust", {}).get("rejected_count", 0) == 0
        assert st["rule"].startswith("noise-free")
    # the CRLB std at the simulator's default noise (3 m, 8 arcsec): what noisy data would allow
    from casep.radar.regression import RadarRegression
    from casep.units import ARCSEC

    reg = RadarRegression(sim.telemetry, list(sim.radars), sim.model, sim.tracking, SITE, fit_launch_time=True)
    sig = {g: DEFAULT_NOISE[g[1]] * (ARCSEC if g[1] != "range" else 1.0) for g in reg.groups}
    crlb = separate_radar(sim.telemetry, list(sim.radars), SITE, sim.model, sim.tracking, sigma=sig,
                          diagnostics=False).result
    truth = dict(zip(crlb.names, sim.truth_vector()))
    est = {c["name"]: c["estimate"] for c in data["coefficients"]}
    rec = np.array([abs(est[n] - truth[n]) / s for n, s in zip(crlb.names, crlb.std)])
    assert np.max(rec) <= 0.01, dict(zip(crlb.names, rec))


# ----------------------------------------------------------------------------- launch time, one station
@pytest.mark.parametrize("offset", [0.05, 2.0])
def test_one_station_launch_time_off_is_said_with_its_numbers(offset):
    """One station, --launch-time 50 ms or 2 s late. dt_launch is not estimated (it aliases with the station's
    terms): the output says which combination is determined (dt_launch alone with its std, the station terms it
    moves per ms, the instrument shift for 10 ms) and the instrument terms stay honest (RMS z < 1.6). At 2 s the
    azimuth bias it moves is named with the launch time that would explain it."""
    sim = simulate_radar(STATIONS[:1], SITE, seed=0, telemetry_rate=5, radar_rate=5,
                         tracking_truth={"S1": TRUTH["S1"]})
    late = dataclasses.replace(SITE, t0=offset)
    if offset < 1:
        rr = separate_radar(sim.telemetry, list(sim.radars), late, sim.model, sim.tracking, diagnostics=False)
    else:
        with pytest.warns(Warning, match=r"S1.azimuth_bias .* \(or a launch time \+\d+ ms off: with one station it "
                                         r"moves S1.azimuth_bias by -0.\d+ arcsec per ms; check --launch-time\)"):
            rr = separate_radar(sim.telemetry, list(sim.radars), late, sim.model, sim.tracking, diagnostics=False)
    assert "dt_launch" not in rr.result.names
    al = rr.summary["setup"]["aliased"]
    assert al["term"] == "dt_launch" and al["std_ms"] > 100.0  # alone it is not determined
    assert "S1.azimuth_bias" in al["absorbed_per_ms"]
    line = next(x for x in rr.text().splitlines() if x.startswith("launch time: not estimated with one station"))
    assert "S1.azimuth_bias" in line and "ms error moves the instrument coefficients by up to" in line
    n = sim.model.n_coefficients
    z = (rr.result.estimate[:n] - sim.truth[:n]) / rr.result.std[:n]
    assert np.sqrt(np.nanmean(z**2)) < 1.6


def test_radar_result_reports_one_noise_per_group_when_a_station_is_wrong():
    """A station 40 m too high (a failed fit): the diagnostics table's noise per group is the `noise:` line's
    (the REML noise the rows were whitened by), not the linearisation's misfit-inflated group std, and the
    CRLB rows are divided by it; the residual RMS, a different statistic, is above it."""
    from casep.radar.diagnostics import diagnostics_table

    sim = simulate_radar(STATIONS, SITE, seed=3, telemetry_rate=10, radar_rate=2, tracking_truth=TRUTH)
    up = dataclasses.replace(sim.radars[0], station=dataclasses.replace(sim.radars[0].station,
                                                                        h_m=sim.radars[0].station.h_m + 40.0))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rr = separate_radar(sim.telemetry, [up, sim.radars[1]], SITE, sim.model, sim.tracking)
    line = {f"{g['station']}.{g['type']}": g["sigma"] for g in rr.summary["noise"]}
    table = {f"{g['station']}.{g['type']}": g["sigma"] for g in rr.diagnostics["noise"]}
    assert table == pytest.approx(line, rel=1e-12)
    lin_sigma = {f"{g['station']}.{g['type']}": g["sigma"] for g in rr.linearised.noise_table()}
    assert max(lin_sigma[k] / line[k] for k in line) > 1.5, (lin_sigma, line)  # the two statistics differ here
    text = diagnostics_table(rr.diagnostics)
    assert f"{line['S1.elevation']:10.4g}" in text and "REML" in text
