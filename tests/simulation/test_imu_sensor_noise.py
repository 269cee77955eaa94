"""The simulated raw IMU's white sensor noise and full scales (casep.simulation.strapdown.SensorNoise)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import casep
from casep.fullscale import held_full_scale
from casep.simulation.scenarios import STRAPDOWN_TRUTH
from casep.simulation.simulate import simulate_flight
from casep.simulation.strapdown import SensorNoise, imu_table

AXIAL = "strapdown15_axial"
RATE = 20.0  # Hz
ARW, VRW = 0.3, 0.05  # deg/sqrt(h), m/s/sqrt(h): a MEMS grade


@pytest.fixture(scope="module")
def tables():
    model = casep.load_model(AXIAL)
    sim = simulate_flight("strapdown-boost", seed=0, model=AXIAL, rate=RATE,
                          truth={k: v for k, v in STRAPDOWN_TRUTH.items() if k in model.names})

    def table(sensor):
        tab = imu_table(sim.trajectory, sim.model, sim.truth, pad=10.0, sensor=sensor)
        return {k: np.column_stack([tab[f"{k}_{a}"] for a in "xyz"]) for k in ("w", "fb")} | {"t": tab["t"]}

    return table(None), table(SensorNoise(ARW, VRW, seed=5)), table


def test_noise_std_is_the_stated_density_per_sample(tables):
    clean, noisy, _ = tables
    h = float(np.median(np.diff(clean["t"])))
    # independent of the code: deg/sqrt(h) -> rad/sqrt(s) is pi/180/60, a density N per sqrt(s) at step h is N/sqrt(h)
    expect = {"w": ARW * math.pi / 180 / 60 / math.sqrt(h), "fb": VRW / 60 / math.sqrt(h)}
    for k in ("w", "fb"):
        d = noisy[k] - clean[k]
        n = d.shape[0]
        # the sample std of n normal draws has a relative std 1/sqrt(2 (n - 1)): 5 of them is a seeded 1-in-1e6 bound
        tol = 5.0 / math.sqrt(2 * (n - 1))
        assert np.all(np.abs(d.std(axis=0) / expect[k] - 1) < tol), (k, d.std(axis=0), expect[k])
        assert np.all(np.abs(d.mean(axis=0)) < 5 * expect[k] / math.sqrt(n))
        assert abs(np.corrcoef(d.T)[0, 1]) < 5 / math.sqrt(n)  # axes independent
    assert np.array_equal(tables[2](SensorNoise(ARW, VRW, seed=5))["w"], noisy["w"])  # seeded
    assert not np.array_equal(tables[2](SensorNoise(ARW, VRW, seed=6))["w"], noisy["w"])


def test_full_scale_clips_and_the_clip_is_found_in_the_noisy_record(tables):
    clean, _, table = tables
    fs = math.radians(20.0)
    assert np.abs(clean["w"][:, 0]).max() > 1.5 * fs  # the roll programme exceeds it
    clipped = table(SensorNoise(ARW, VRW, seed=5, gyr_range_rad_s=fs))["w"]
    assert np.abs(clipped).max() == pytest.approx(fs, rel=1e-15)
    held = held_full_scale(clipped, "gyro")  # no full scale declared: noise cannot hold a reading that long
    assert [(h.axis, h.side) for h in held] == [(0, "maximum")]
    assert held[0].runs[0][1] - held[0].runs[0][0] >= 10
    assert held_full_scale(table(SensorNoise(ARW, VRW, seed=5))["w"], "gyro") == []


def test_sensor_noise_refuses_negative_or_infinite_densities():
    with pytest.raises(ValueError, match="arw_deg_sqrt_h"):
        SensorNoise(arw_deg_sqrt_h=-1.0)
    with pytest.raises(ValueError, match="acc_range_m_s2"):
        SensorNoise(acc_range_m_s2=math.inf)


def test_cli_noise_needs_imu_output_and_is_said_in_the_header(tmp_path, capsys):
    from casep.cli.app import main

    assert main(["simulate", "--scenario", "strapdown-boost", "--rate", "5", "-o", str(tmp_path / "a.csv"),
                 "--imu-arw", "0.3"]) != 0
    assert "need --imu-output" in capsys.readouterr().err
    assert not (tmp_path / "a.csv").exists()
    assert main(["simulate", "--scenario", "strapdown-boost", "--rate", "10", "-o", str(tmp_path / "b.csv"),
                 "--imu-output", str(tmp_path / "imu.csv"), "--imu-arw", "0.3", "--imu-vrw", "0.05",
                 "--gyr-range", "20"]) == 0
    head = [line for line in (tmp_path / "imu.csv").read_text().splitlines() if line.startswith("#")]
    assert any("angle random walk 0.3 deg/sqrt(h), velocity random walk 0.05 m/s/sqrt(h)" in line
               and "gyros +-20 deg/s" in line for line in head), head


def test_the_separation_measures_the_stated_density_on_the_moving_record(tables):
    """The telemetry path measures the IMU's white noise on the record itself (second differences, MAD:
    casep.checks.tracking_quality.white_sample_std) beside the boost's motion, as drawn: the MAD's relative std on
    3900 samples is ~2 % (efficiency 0.37; the second differences' correlation raises it to ~2.5 %): 4 of them."""
    from casep.checks.tracking_quality import white_sample_std

    _, noisy, _ = tables
    h = float(np.median(np.diff(noisy["t"])))
    flight = noisy["t"] > 0
    measured = white_sample_std(np.column_stack([noisy["fb"][flight], noisy["w"][flight]]))
    expect = np.repeat([VRW / 60 / math.sqrt(h), ARW * math.pi / 180 / 60 / math.sqrt(h)], 3)
    assert np.all(np.abs(measured / expect - 1) < 0.10), measured / expect
