"""The strapdown scenario: rolled attitude, strapdown telemetry, recovery, Monte Carlo std, raw IMU output."""

from __future__ import annotations

import dataclasses
import json
import warnings

import numpy as np
import pytest

import casep
from casep.frames import LaunchSite
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
    w_sim = np.column_stack([sim.flight.signals[f"w_{a}"] for a in "xyz"])
    k, c = np.nonzero(~np.isclose(w[~pad], w_sim))
    assert 1 <= np.unique(k).size <= 4, k  # the pitch kick's ends fall on samples: split there (split_steps)
    i = k + int(pad.sum())
    assert np.allclose(w[i, c], 0.5 * (w[i - 1, c] + w_sim[k, c]))  # the mean of the sample before and the one read


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


ROTATING_SITE = LaunchSite(28.5, -80.6, 3.0, 100.0, 0.0)  # t0 = 0: lift-off


@pytest.fixture(scope="module")
def rotating_imu():
    """The error-free raw IMU of the strapdown boost over the rotating Earth, 50 Hz, 30 s on the pad."""
    from casep.simulation.strapdown import imu_table

    sim = simulate_flight("strapdown-boost", seed=0, rate=50.0, truth={}, rotating_earth=True, site=ROTATING_SITE)
    tab = imu_table(sim.trajectory, sim.model, sim.truth, pad=30.0)
    return {k: np.column_stack([tab[f"{k}_{a}"] for a in ("wxyz" if k == "true_q" else "xyz")])
            for k in ("w", "fb", "true_q", "true_r", "true_v")} | {"t": tab["t"]}


def test_rotating_earth_pad_reads_the_earth_rate_and_wgs84_normal_gravity(rotating_imu):
    """On the pad the IMU turns with the Earth: |w| is omega_E and |fb| the closed-form WGS84 normal gravity at the
    site (casep.gravity.normal_gravity, Somigliana with the height), to rounding; the true velocity is the pad's,
    ``omega_E`` times the distance from the axis, continuous into the flight's first sample."""
    from casep.frames import OMEGA_EARTH
    from casep.gravity import normal_gravity

    d = rotating_imu
    pad = d["t"] < 0
    assert np.allclose(np.linalg.norm(d["w"][pad], axis=1), OMEGA_EARTH, rtol=1e-12, atol=0)
    assert np.allclose(np.linalg.norm(d["fb"][pad], axis=1), normal_gravity(28.5, 3.0), rtol=1e-12, atol=0)
    i0 = int(np.argmax(~pad))
    dist = np.linalg.norm(np.cross(ROTATING_SITE.earth_rate / OMEGA_EARTH, ROTATING_SITE.earth_centre))
    assert np.linalg.norm(d["true_v"][i0 - 1]) == pytest.approx(OMEGA_EARTH * dist, rel=1e-9)  # 408 m/s at 28.5 deg
    assert np.linalg.norm(d["true_v"][i0] - d["true_v"][i0 - 1]) < 1e-3  # 0.02 s of the Earth's turn


def test_error_free_rotating_earth_imu_navigates_back_to_its_truth(rotating_imu):
    """Two independent codes, one world: the simulator's error-free raw IMU, aligned on its pad and navigated by
    casep.navigation.navigate, gives the simulator's true velocity: on the pad to rounding (1e-8 m/s; measured
    1.2e-10), in flight within 0.05 m/s (measured 0.032 m/s, at the lift-off sample alone: |dF| h / 4 of its step
    split there, casep.navigation.imu.split_steps; 0.0053 m/s at the end, 2.2 m after 225 s). Read as sampled, the
    steps of the specific force at lift-off and of the pitch rate at the kick's start and end left 0.30 m/s at burnout
    and 28 m: a record of sampled rates cannot place a step within a sample, and the simulator's steps fall on
    samples, which read the value after them; the record holds none now (casep.navigation.imu.sample_steps)."""
    from casep.navigation import ImuData, check_imu, navigate

    d = rotating_imu
    imu = check_imu(ImuData(t=d["t"], w=d["w"], f=d["fb"], source="simulated"))
    res = navigate(imu, ROTATING_SITE, (-30.0, -1.0), heading_deg=280.0, heading_axis="y")  # body y uprange
    i = np.searchsorted(d["t"], res.t)
    err = np.linalg.norm(res.v - d["true_v"][i], axis=1)
    assert imu.steps is not None and imu.steps.k.size == 0
    before = res.t < -0.03  # the last pad interval already feels lift-off's step through the interpolation
    assert err[before].max() < 1e-8
    assert err.max() < 0.05 and err[-1] < 0.01  # (0.30 m/s with the steps read as sampled)
    assert np.linalg.norm(res.r[-1] - d["true_r"][i[-1]]) < 5.0  # m (measured 2.2 m; 28 m as sampled) after 225 s


def test_strapdown_scenario_writes_earth_fixed_tracking(tmp_path, capsys):
    """--tracking-frame ecef with a strapdown scenario: the flight, its raw IMU and the tracking in ECEF, which
    casep.frames.ecef_to_launch turns back into the flight file's tracked r_*, v_* (a round trip through the
    rotation by omega_E t and the launch triad: to 1e-6 m and m/s); --tracking-rate 2.5 (a GNSS slower than the
    IMU) tracks every second sample, and a rate that does not divide the flight's (2 Hz) is refused before any file
    is written. Without --rotating-earth the raw IMU says it is of a non-rotating Earth."""
    import pandas as pd

    from casep.cli.app import main
    from casep.frames import ecef_to_launch

    base = ["simulate", "--scenario", "strapdown-boost", "--rate", "5", "--rotating-earth", "--launch-site", "28.5",
            "-80.6", "3", "100", "--tracking-frame", "ecef", "-o", str(tmp_path / "t.csv")]
    assert main(base + ["--tracking-rate", "2"]) == 2
    assert "tracking rate 2 Hz must divide the flight's rate 5 Hz" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())
    assert main(base + ["--imu-output", str(tmp_path / "imu.csv"), "--tracking-rate", "2.5"]) == 0
    assert "t.tracking.csv" in capsys.readouterr().out
    flight, trk = (pd.read_csv(tmp_path / name, comment="#") for name in ("t.csv", "t.tracking.csv"))
    t = trk["t"].to_numpy()
    r_l, v_l = ecef_to_launch(ROTATING_SITE, t, *(trk[[f"{p}_ecef_{a}" for a in "xyz"]].to_numpy()
                                                   for p in ("r", "v")))
    tf = flight["t"].to_numpy()
    rows = np.searchsorted(tf, t)
    assert t.size < tf.size and np.array_equal(tf[rows], t)  # the observed samples: from 6 s, not in the gap
    assert np.all(rows % 2 == 0) and np.array_equal(np.flatnonzero(flight["dv_x"].notna()), rows)  # every 2nd
    assert json.loads((tmp_path / "t.truth.json").read_text())["tracking"]["rate_hz"] == 2.5
    for p, got in (("r", r_l), ("v", v_l)):
        assert np.max(np.abs(got - flight[[f"{p}_{a}" for a in "xyz"]].to_numpy()[rows])) < 1e-6
    assert (tmp_path / "imu.csv").exists()
    assert main(["simulate", "--scenario", "strapdown-boost", "--rate", "5", "-o", str(tmp_path / "n.csv"),
                 "--imu-output", str(tmp_path / "n_imu.csv")]) == 0
    assert "non-rotating Earth" in capsys.readouterr().out


def test_a_tracking_rate_dividing_the_flights_tracks_every_kth_sample_as_the_full_rate_would(sim):
    """tracking_rate 5 Hz of a 20 Hz flight: the same flight (seed, model, truth) tracked at its samples 0, 4, 8, ...
    (those the full-rate flight tracks there), dv and the tracked state exactly the full-rate flight's there, and
    untracked (NaN) in between; the force is the full flight's at every sample."""
    from casep.io.pair import STATE_SIGNALS

    model = casep.load_model(AXIAL)
    truth = {k: v for k, v in STRAPDOWN_TRUTH.items() if k in model.names}
    slow = simulate_flight("strapdown-boost", seed=0, model=AXIAL, truth=truth, rate=RATE, tracking_rate=RATE / 4)
    a, b = sim.flight, slow.flight
    every = np.arange(a.t.size) % 4 == 0
    assert np.array_equal(b.observed, a.observed & every) and b.observed.sum() > 0.2 * a.observed.sum()
    assert np.array_equal(b.dv[b.observed], a.dv[b.observed]) and np.isnan(b.dv[~b.observed]).all()
    for name in STATE_SIGNALS:
        assert np.array_equal(b.signals[name][b.observed], a.signals[name][b.observed])
    assert np.array_equal(b.f, a.f) and slow.truth_dict()["tracking"]["rate_hz"] == RATE / 4
    with pytest.raises(ValueError, match="tracking rate 3 Hz must divide the flight's rate 20 Hz"):
        simulate_flight("strapdown-boost", rate=RATE, tracking_rate=3.0)


def test_with_drawn_errors_draws_declared_magnitudes_first_and_applies_strapdown12_by_hand():
    """strapdown12's errors written out by hand (``delta_f_i = ba_i + sa_i fb_i``, ``delta_w_i = bg_i + sg_i w_i``,
    mg, ppm, deg/h at declared magnitudes 1, 300, 1, 100) at a turning attitude: the measured record, the ``z``
    drawn first from the generator (its next draw is a fresh generator's 13th), and ``z`` given leaving it untouched."""
    from scipy.spatial.transform import Rotation

    from casep.simulation.strapdown import with_drawn_errors
    from casep.units import G0

    model = casep.load_model("strapdown12")
    n = 50
    t = 3.0 + 0.1 * np.arange(n)
    q = Rotation.from_rotvec(np.outer(t, [0.3, -0.2, 0.5])).as_quat(scalar_first=True)
    w = np.column_stack([0.3 + 0 * t, -0.2 + 0.01 * t, np.sin(t)])
    fb = np.column_stack([60.0 - t, 2.0 * np.cos(t), -9.0 + 0 * t])
    rng = np.random.default_rng(7)
    w_m, fb_m, z = with_drawn_errors(model, q, w, fb, t, rng)
    fresh = np.random.default_rng(7).standard_normal(13)
    np.testing.assert_array_equal(z, fresh[:12])
    assert rng.standard_normal() == fresh[12]
    assert model.names == tuple(f"{k}_{a}" for k in ("ba", "sa", "bg", "sg") for a in "xyz")
    c = dict(zip(model.names, z * np.repeat([1.0, 300.0, 1.0, 100.0], 3)))
    for i, a in enumerate("xyz"):
        np.testing.assert_allclose(fb_m[:, i] - fb[:, i], c[f"ba_{a}"] * 1e-3 * G0 + c[f"sa_{a}"] * 1e-6 * fb[:, i],
                                   rtol=1e-9, atol=1e-14)
        np.testing.assert_allclose(w_m[:, i] - w[:, i],
                                   np.radians(c[f"bg_{a}"] / 3600.0) + c[f"sg_{a}"] * 1e-6 * w[:, i],
                                   rtol=1e-9, atol=1e-16)
    rng = np.random.default_rng(7)
    w_g, fb_g, z_g = with_drawn_errors(model, q, w, fb, t, rng, z=z)
    np.testing.assert_array_equal(w_g, w_m)
    np.testing.assert_array_equal(fb_g, fb_m)
    assert rng.standard_normal() == fresh[0]
    with pytest.raises(ValueError, match="one number per coefficient"):
        with_drawn_errors(model, q, w, fb, t, rng, z=z[:5])
