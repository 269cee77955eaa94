"""Simulated flights: injected truth, noise statistics, reproducibility, files (casep.simulation.simulate)."""

from __future__ import annotations

import json

import numpy as np
import pytest

import casep
from casep.cli import main
from casep.simulation.scenarios import SCENARIOS, get_scenario
from casep.simulation.simulate import simulate_flight, simulate_two_rate, truth_path, write_simulation


def _lag1(x):
    x = x - x.mean(0)
    return np.sum(x[1:] * x[:-1], 0) / np.sum(x * x, 0)


@pytest.mark.parametrize("name", ["paper", "paper-ar1"])
def test_dv_minus_truth_is_declared_noise(name):
    sim = simulate_flight(name, seed=11, rate=100.0)
    fl = sim.flight
    resid = fl.dv - casep.build_sv(sim.model, fl.t, fl.f) @ sim.truth
    np.testing.assert_allclose(resid, sim.noise, atol=1e-12)
    sc = get_scenario(name)
    if sc.noise.kind == "white":
        np.testing.assert_allclose(resid.std(0), sc.noise.sigma, rtol=0.05)
        assert np.all(np.abs(_lag1(resid)) < 0.05)
    else:
        # tau = 1 s over 195 s: few independent stretches, so the sample std is looser.
        assert np.all(np.abs(resid.std(0) / sc.noise.sigma - 1) < 0.25)
        np.testing.assert_allclose(_lag1(resid), sc.noise.lag1_at(0.01), atol=0.01)


def test_ar1_std_within_5_percent_over_seeds():
    stds = np.array([simulate_flight("paper-ar1", seed=s, rate=20.0).noise.std(0) for s in range(12)])
    np.testing.assert_allclose(np.sqrt(np.mean(stds**2)), 0.1, rtol=0.05)


def test_pitch_scenario_has_no_cross_range_force():
    sim = simulate_flight("paper-pitch", seed=0, rate=10.0)
    assert not np.any(sim.flight.f[:, 2])
    assert np.abs(simulate_flight("paper", seed=0, rate=10.0).flight.f[:, 2]).max() > 0.1


def test_same_seed_same_bytes_other_seed_other_noise(tmp_path):
    a, b, c = tmp_path / "a.csv", tmp_path / "b.csv", tmp_path / "c.csv"
    for path, seed in ((a, 5), (b, 5), (c, 6)):
        assert main(["simulate", "--scenario", "paper", "--seed", str(seed), "--rate", "10", "-o", str(path)]) == 0
    assert a.read_bytes() == b.read_bytes()
    assert truth_path(a).read_bytes() == truth_path(b).read_bytes()
    assert a.read_bytes() != c.read_bytes()
    fa, fc = casep.read_flight(a), casep.read_flight(c)
    np.testing.assert_array_equal(fa.f, fc.f)  # same trajectory
    assert not np.allclose(fa.dv, fc.dv)  # other noise


def test_truth_sidecar_content(tmp_path):
    sim = simulate_flight("paper", seed=2, rate=10.0)
    path, side = write_simulation(sim, tmp_path / "flight.csv")
    assert side.name == "flight.truth.json"
    data = json.loads(side.read_text())
    assert data["model"] == "platform36" and data["seed"] == 2
    assert data["coefficients"]["Kg0x"] == 0.5 and data["coefficients"]["Ka2zy"] == 0.003
    assert data["noise"]["kind"] == "white" and data["noise"]["sigma"] == 0.1
    assert data["trajectory"]["scenario"] == "paper" and "summary" in data["trajectory"]
    back = casep.read_flight(path)
    np.testing.assert_array_equal(back.dv, sim.flight.dv)


def test_parquet_output(tmp_path):
    sim = simulate_flight("paper-pitch", seed=1, rate=10.0)
    path, _ = write_simulation(sim, tmp_path / "f.parquet")
    np.testing.assert_array_equal(casep.read_flight(path).dv, sim.flight.dv)


def test_two_rate_pipeline_with_apparent_velocity(tmp_path):
    d = simulate_two_rate("paper", seed=4, telemetry_rate=50.0, tracking_rate=10.0)
    tel, trk = tmp_path / "tel.csv", tmp_path / "trk.csv"
    d.write(tel, trk, apparent=True)
    fl = casep.read_flight_pair(tel, trk)
    # f from differentiated W is within the O(dt^2) error of the true force away from the
    # thrust discontinuities.
    t = d.t_tel
    inside = np.isin(t, fl.t)
    smooth = (fl.t > 10) & (fl.t < 95)
    assert np.abs(fl.f[smooth] - d.f[inside][smooth]).max() < 1e-3 * np.abs(d.f).max()
    # dv = S_V D + interpolated tracking noise: a fit recovers sigma ~ 0.1 m/s.
    res = casep.separate(fl, "platform36")
    assert 0.05 < res.sigma < 0.12


def test_time_offset_shows_in_dv():
    d0 = simulate_two_rate("paper-pitch", seed=1, telemetry_rate=20.0, tracking_rate=20.0)
    d1 = simulate_two_rate("paper-pitch", seed=1, telemetry_rate=20.0, tracking_rate=20.0, time_offset=0.05)
    # Tracking tagged 0.05 s late reads v(t - 0.05): v_trk differs by ~ a * 0.05.
    common = np.intersect1d(d0.t_trk, d1.t_trk)
    i0, i1 = np.searchsorted(d0.t_trk, common), np.searchsorted(d1.t_trk, common)
    diff = d0.v_trk[i0] - d1.v_trk[i1]
    assert 0.5 < np.abs(diff).max() < 3.0  # 5 g * 0.05 s = 2.5 m/s at most


def test_bad_arguments(tmp_path, capsys):
    with pytest.raises(ValueError, match="unknown scenario `nope`"):
        simulate_flight("nope")
    with pytest.raises(ValueError, match="`seed` must be a non-negative int"):
        simulate_flight("paper", seed=-1)
    assert main(["simulate", "--seed", "-3", "-o", str(tmp_path / "x.csv")]) == 2
    assert "`--seed` must be >= 0" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())
    assert set(SCENARIOS) == {"paper", "paper-pitch", "paper-ar1", "paper-yaw-late", "paper-pitch-low", "paper-azimuth",
                              "paper-range-gm", "paper-range", "strapdown-boost"}


def test_two_rate_tracking_start():
    d = simulate_two_rate("paper", seed=1, telemetry_rate=20.0, tracking_rate=10.0, tracking_start=10.0)
    assert d.t_tel[0] == 0.0 and d.t_trk[0] == 10.0 and np.all(np.diff(d.t_trk) > 0)
    full = simulate_two_rate("paper", seed=1, telemetry_rate=20.0, tracking_rate=10.0)
    np.testing.assert_array_equal(d.t_trk, full.t_trk[full.t_trk >= 10.0])
    for bad in (-1.0, 1e9, float("nan")):
        with pytest.raises(ValueError, match="`tracking_start` must be in"):
            simulate_two_rate("paper", telemetry_rate=20.0, tracking_start=bad)


def test_simulate_any_model_and_truth(tmp_path, capsys):
    """`casep simulate --model FILE --truth FILE`: another model's truth is injected
    (the dv0 terms come back within 5 std) and the sidecar names model and truth."""
    import json

    from casep.cli import main
    from casep.simulation.paper import TABLE1_TRUTH

    truth = {**TABLE1_TRUTH, "dv0x": 0.3, "dv0y": -0.2, "dv0z": 0.1}
    tfile = tmp_path / "truth.json"
    tfile.write_text(json.dumps(truth))
    out = tmp_path / "f.csv"
    assert main(["simulate", "--rate", "20", "--seed", "2", "--model", "platform36_dv0", "--truth", str(tfile),
                 "-o", str(out)]) == 0
    side = json.loads(out.with_name("f.truth.json").read_text())
    assert side["model"] == "platform36_dv0" and side["coefficients"]["dv0x"] == 0.3
    with pytest.warns(casep.LateStartWarning, match="or it starts at lift-off with an initial velocity error"):
        res = casep.separate(out, "platform36_dv0", "ols")  # dv(t0) != 0 by design here
    for n in ("dv0x", "dv0y", "dv0z"):
        j = res.names.index(n)
        assert abs(res.estimate[j] - truth[n]) < 5 * res.std[j], n
    # a sidecar is accepted as --truth; a misspelt name is refused with a suggestion
    assert main(["simulate", "--rate", "20", "--model", "platform36_dv0", "--truth", str(out.with_name("f.truth.json")),
                 "-o", str(tmp_path / "g.csv")]) == 0
    tfile.write_text(json.dumps({"dv0X": 1.0}))
    capsys.readouterr()
    assert main(["simulate", "--rate", "20", "--model", "platform36_dv0", "--truth", str(tfile), "-o",
                 str(tmp_path / "h.csv")]) == 2
    err = capsys.readouterr().err
    assert f"--truth {tfile}" in err and "did you mean `dv0x`" in err and not (tmp_path / "h.csv").exists()
