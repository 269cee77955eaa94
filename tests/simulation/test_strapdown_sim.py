"""The strapdown scenario: rolled attitude, strapdown telemetry, recovery, Monte Carlo std, raw IMU output."""

from __future__ import annotations

import dataclasses
import json
import warnings

import numpy as np
import pytest

import casep
from casep.io.strapdown import quaternion_dcm_array
from casep.simulation.scenarios import STRAPDOWN_TRUTH
from casep.simulation.simulate import simulate_flight, write_simulation
from casep.simulation.strapdown import RollProgramme

#: The strapdown33 terms an axial-thrust boost excites (fb_y = fb_z = 0 leaves the others unseen).
AXIAL = "strapdown15_axial"
RATE = 20.0  # Hz: fast enough for the suite


@pytest.fixture(scope="module")
def sim():
    model = casep.load_model(AXIAL)
    truth = {k: v for k, v in STRAPDOWN_TRUTH.items() if k in model.names}
    return simulate_flight("strapdown-boost", seed=0, model=AXIAL, truth=truth, rate=RATE)


def test_roll_programme_angle_is_the_integral_of_its_rate():
    roll = RollProgramme()
    t = np.linspace(0.0, 200.0, 200001)
    angle, rate = roll.angle_rate(t)
    trapz = np.concatenate([[0.0], np.cumsum(0.5 * (rate[1:] + rate[:-1]) * np.diff(t))])
    assert np.max(np.abs(angle - trapz)) < 1e-6
    assert rate.max() == pytest.approx(np.radians(120.0))


def test_attitude_and_body_rate_agree(sim):
    """C_dot = C [w x]: the telemetered quaternions' derivative against the true body rate (central
    differences, error O(dt^2))."""
    fl, traj = sim.flight, sim.trajectory
    q = np.column_stack([fl.signals[f"q_{a}"] for a in "wxyz"])
    C = quaternion_dcm_array(q)
    dt = np.diff(fl.t)[0]
    Cdot = (C[2:] - C[:-2]) / (2 * dt)
    W = np.einsum("kji,kjl->kil", C[1:-1], Cdot)  # C^T C_dot = [w x]
    w_est = np.column_stack([W[:, 2, 1], W[:, 0, 2], W[:, 1, 0]])
    w = traj.body_rate[1:-1]
    smooth = np.all(np.abs(np.diff(traj.body_rate, 2, axis=0)) < 1e-3, axis=1)  # away from the kinks of the laws
    err = np.abs(w_est - w)[smooth]
    top = np.max(np.abs(w))
    assert top > 1.0
    assert err.max() < 2 * top * (top * dt) ** 2 / 6  # twice the central difference's w^3 dt^2 / 6


def test_file_has_no_force_and_reads_back_to_the_same_flight(sim, tmp_path):
    path, side = write_simulation(sim, tmp_path / "sd.csv")
    header = [ln for ln in path.read_text().splitlines() if not ln.startswith("#")][0].split(",")
    assert "f_x" not in header and {"q_w", "fb_x", "w_z"} <= set(header)
    fl = casep.read_flight(path)
    assert fl.meta["force"] == "q, fb"
    assert np.allclose(fl.f, sim.flight.f, rtol=0, atol=1e-9)
    assert np.array_equal(fl.observed, sim.flight.observed)
    assert json.loads(side.read_text())["roll_programme"]["rates_deg_s"][2] == 60.0


def test_noise_free_recovery_within_a_hundredth_of_the_crlb(sim):
    """dv without noise, through the file's reader: every coefficient within 0.01 CRLB std."""
    fl = sim.flight
    clean = dataclasses.replace(fl, dv=np.where(fl.observed[:, None], fl.dv - sim.noise, np.nan))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # noise-free data: the noise-free and conditioning warnings
        res = casep.separate(clean, sim.model, method="ols", noise="white", sigma=0.1)
    crlb = np.array([res.diagnostics["crlb_std"][n] for n in sim.model.names])
    err = np.abs(res.estimate - sim.truth) / crlb
    assert err.max() <= 0.01, dict(zip(sim.model.names, err))


def test_seeded_monte_carlo_std_hold_under_gauss_markov_plus_white_noise(sim):
    """Reduced campaign (12 flights): RMS z and 95 % coverage of OLS with the default noise model
    (benchmarks/mc_strapdown.py runs 200 flights for the figures)."""
    fl = sim.flight
    clean = fl.dv - sim.noise
    z = []
    for seed in range(1, 13):
        noise = sim.scenario.noise.sample(fl.t, np.random.default_rng(seed))
        run = dataclasses.replace(fl, dv=np.where(fl.observed[:, None], clean + noise, np.nan))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = casep.separate(run, sim.model, method="ols")
        z.append((res.estimate - sim.truth) / res.std)
    z = np.array(z)
    rms, cover = float(np.sqrt(np.mean(z**2))), float(np.mean(np.abs(z) < 1.959964))
    assert 0.8 <= rms <= 1.25 and 0.88 <= cover <= 0.99, (rms, cover)


def test_imu_output_with_pad_and_truth(sim, tmp_path):
    write_simulation(sim, tmp_path / "sd.csv", imu=tmp_path / "imu.csv", imu_pad=5.0)
    from casep.io.tables import Table

    tab = Table(tmp_path / "imu.csv")
    cols = list(tab.frame.columns)
    assert cols[:7] == ["t", "w_x", "w_y", "w_z", "fb_x", "fb_y", "fb_z"]
    t = tab.numeric("t")
    pad = t < 0
    assert pad.sum() == round(5.0 * RATE) and t[0] == pytest.approx(-5.0)
    fb = np.column_stack([tab.numeric(f"fb_{a}") for a in "xyz"])
    q = np.column_stack([tab.numeric(f"true_q_{a}") for a in "wxyz"])
    f_nav = np.einsum("kij,kj->ki", quaternion_dcm_array(q[pad]), fb[pad])
    g = sim.trajectory.acceleration[0] - sim.trajectory.specific_force[0]
    assert np.allclose(f_nav, -g, atol=0.02)  # standing: the specific force holds gravity up, within the biases
    w = np.column_stack([tab.numeric(f"w_{a}") for a in "xyz"])
    assert np.max(np.abs(w[pad])) < 1e-4  # the gyro biases only
    assert np.allclose(w[~pad], np.column_stack([sim.flight.signals[f"w_{a}"] for a in "xyz"]))


def test_imu_output_needs_a_strapdown_scenario(tmp_path):
    plat = simulate_flight("paper", seed=0, rate=5.0)
    with pytest.raises(ValueError, match="--imu-output needs a strapdown scenario"):
        write_simulation(plat, tmp_path / "p.csv", imu=tmp_path / "imu.csv")
    assert not (tmp_path / "p.csv").exists()


def test_cli_simulate_then_diagnose_says_which_body_terms_the_roll_programme_reaches(tmp_path, capsys):
    """casep simulate --scenario strapdown-boost, then casep diagnose with strapdown33: the terms driven by
    fb_y, fb_z (zero for an axial thrust) are unidentifiable, the roll-rate terms are not."""
    from casep.cli import main

    out = tmp_path / "sd.csv"
    assert main(["simulate", "--scenario", "strapdown-boost", "--rate", "10", "-o", str(out),
                 "--imu-output", str(tmp_path / "imu.csv")]) == 0
    assert "wrote" in capsys.readouterr().out and (tmp_path / "imu.csv").exists()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["diagnose", str(out), "--model", "strapdown33"]) == 0
    text = capsys.readouterr().out
    verdict = {ln.split()[0]: ln for ln in text.splitlines() if ln.split() and ln.split()[0] in STRAPDOWN_TRUTH}
    assert len(verdict) == 33
    for name in ("sa_y", "sa_z", "ma_xy", "gg_xy", "gg_zz"):  # fb_y, fb_z terms
        assert "unidentifiable" in verdict[name], verdict[name]
    for name in ("sg_x", "mg_yx", "mg_zx"):  # the roll rate reaches the gyros' x-rate terms
        assert "unidentifiable" not in verdict[name], verdict[name]


def test_all_33_terms_on_an_axial_boost_report_what_is_exactly_dependent_only_on_unseen_terms():
    """With the whole strapdown33 model, fb_y and fb_z are the instrument's own errors, an affine function of fb_x:
    12 terms (the lateral misalignments and gyro g-sensitivities times fb_y, fb_z, and sa_y, sa_z) are exactly
    dependent on the biases and axial terms. Those 12 stay without an estimate; the 12 they are dependent on get
    one, their partners moving them by far less than their std within the declared magnitudes, and the estimates
    agree with the truth (benchmarks/mc_strapdown.py --model strapdown33: RMS z and coverage over 100 flights)."""
    sim = simulate_flight("strapdown-boost", seed=3, model="strapdown33", rate=10.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = casep.separate(sim.flight, sim.model)
    names = list(sim.model.names)
    unseen = {"ma_xy", "ma_xz", "sa_y", "ma_yz", "sa_z", "ma_zy", "gg_xy", "gg_xz", "gg_yy", "gg_yz", "gg_zy", "gg_zz"}
    assert set(res.diagnostics["unidentifiable"]) == unseen
    reported = [j for j, n in enumerate(names) if "within their declared magnitudes" in res.reasons.get(n, "")]
    assert {names[j] for j in reported} == {"ba_x", "sa_x", "ba_y", "ma_yx", "ba_z", "ma_zx", "bg_x", "gg_xx",
                                            "bg_y", "gg_yx", "bg_z", "gg_zx"}
    z = (res.estimate - sim.truth) / res.std
    assert np.all(np.abs(z[reported]) < 4.0), dict(zip(names, z))
    assert res.std[names.index("ba_x")] < sim.model.scales["ba_x"]  # determined, not only reported
