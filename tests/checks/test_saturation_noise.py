"""A run of equal readings no noise makes (casep.checks.saturation.noise_cannot_hold): a clip whether or not the
record leaves it; noise-free, quantised or quiet columns keep their exemption."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from casep.checks.saturation import held_full_scale, noise_cannot_hold, resolution, white_noise
from casep.exceptions import SaturationWarning
from casep.units import G0

RATE, FS = 200.0, math.radians(100.0)


def _text(x: np.ndarray, digits: int = 12) -> np.ndarray:
    """`x` as a CSV written with `digits` significant digits reads it back."""
    return np.array([float(f"{v:.{digits}g}") for v in np.ravel(x)]).reshape(np.shape(x))


def _roll(n: int, rng, noise: float) -> np.ndarray:
    """Body rates at RATE Hz, rad/s: a pad, a roll of 60 deg/s from 2 s, 120 deg/s from 30 s to the end, small
    pitch and yaw oscillations, white noise of std `noise`."""
    t = np.arange(n) / RATE
    roll = np.radians(60.0) * np.clip(t / 2.0 - 1.0, 0.0, 1.0) * (1.0 + np.clip((t - 30.0) / 2.0, 0.0, 1.0))
    w = np.column_stack([roll, np.radians(2.0) * np.sin(0.5 * t), np.radians(1.5) * np.sin(0.3 * t)])
    return w + noise * rng.standard_normal(w.shape)


def _screened(w: np.ndarray):
    from casep.checks.saturation import screen_saturation
    from casep.io.flight import FlightData

    t = np.arange(w.shape[0]) / RATE
    fb = np.tile([G0, 0.0, 0.0], (t.size, 1)) + np.sin(t)[:, None] * [0.3, 0.2, 0.1]
    sig = {**{f"w_{a}": w[:, i] for i, a in enumerate("xyz")}, **{f"fb_{a}": fb[:, i] for i, a in enumerate("xyz")}}
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        out = screen_saturation(FlightData(t, fb, np.zeros_like(fb), signals=sig))
    return out, [str(x.message) for x in rec if issubclass(x.category, SaturationWarning)]


def test_a_noisy_gyro_clipped_to_the_end_of_the_record_is_a_clip():
    """Roll 120 deg/s clipped at exactly 100 deg/s (no nominal range) from 31.3 s to the end, noise 1e-4 rad/s,
    written with 12 digits: the run is never left, yet noise of that size never holds a reading; the telemetry's
    rows from the first clip on are left out, and the warning names the implied full scale."""
    rng = np.random.default_rng(11)
    true = _roll(8000, rng, 1e-4)
    w = _text(np.clip(true, -FS, FS))
    clipped = np.flatnonzero(true[:, 0] > FS)  # independent of the rule: where the roll exceeded the range
    assert clipped[-1] == w.shape[0] - 1 and np.all(np.diff(clipped) == 1)
    found = held_full_scale(w, "gyro")
    assert [(h.axis, h.side, h.runs) for h in found] == [(0, "maximum", [(clipped[0], w.shape[0])])]
    out, said = _screened(w)
    assert len(said) == 1 and "w_x at its maximum 100 deg/s (a full scale +-100 deg/s implied" in said[0]
    assert "--gyr-range 100 declares it" in said[0] and f"{clipped.size} in a row" in said[0]
    assert np.array_equal(out.observed, out.t < clipped[0] / RATE)
    from casep.navigation.imu import ImuData, check_imu  # casep navigate: the same rule, the rest marked

    f = np.tile([G0, 0.0, 0.0], (w.shape[0], 1)) + 2e-3 * rng.standard_normal(w.shape)
    with pytest.warns(SaturationWarning, match=rf"w_x: {clipped.size} samples at full scale \(a full scale \+-100 "):
        imu = check_imu(ImuData(out.t, w, f))
    assert imu.clipped is not None and np.array_equal(imu.clipped, np.arange(w.shape[0]) >= clipped[0])


def test_the_stated_bound_holds_for_quantised_noise():
    """The per-reading bound of the module notes, P(reading in the cell of the one before) <= q / (sigma sqrt(2
    pi)), against the frequency of equal neighbours in seeded white noise quantised to q = sigma / 3 (exact value
    sum of squared cell probabilities, about q / (2 sigma sqrt(pi)) = 0.094 < 0.133)."""
    rng = np.random.default_rng(3)
    sigma, q = 1.0, 1.0 / 3.0
    x = q * np.round((0.4 + sigma * rng.standard_normal(40000)) / q)
    freq = np.mean(x[1:] == x[:-1])
    assert 0.07 < freq < q / (sigma * math.sqrt(2 * math.pi))
    assert resolution(x, float(x.max())) == pytest.approx(q, rel=1e-9)
    assert 0.6 * sigma < white_noise(x, float(x.max())) < 1.2 * sigma  # the quietest of 156 stretches: low


def test_columns_whose_noise_says_nothing_keep_the_exemption():
    """Not a clip: a noise-free record held at its extreme to its last sample (a state: a spin held by a
    simulation); a quantised gyro (1/131 deg/s counts, noise 0.3 count) whose peak repeats; a gyro quiet on the pad
    (0.2 count: its counts repeat) at the column's maximum, vibrating in flight (30 counts); a noise-free record
    whose only scatter is floating-point rounding."""
    t = np.arange(6000) / RATE
    w = np.column_stack([0.3 * np.sin(2 * np.pi * t / 25), 0.2 * np.sin(2 * np.pi * t / 9), 0.1 * np.cos(t)])
    w[-800:, 0] = float(w[:, 0].max()) + 0.1
    assert noise_cannot_hold(w[:, 0], float(w[:, 0].max())) is None and white_noise(w[:, 0], 1.0) == 0.0
    assert held_full_scale(w, "gyro") == [] and _screened(w)[1] == []
    rng = np.random.default_rng(8)
    lsb = math.radians(1.0 / 131.0)
    turn = np.column_stack([np.radians(40.0) * np.sin(np.pi * t / 30.0), np.zeros((t.size, 2))])
    counts = np.round(turn / lsb + 0.3 * rng.standard_normal(turn.shape))
    assert _longest(counts[:, 0], float(counts[:, 0].max())) >= 3  # the quantised peak repeats
    assert held_full_scale(counts * lsb, "gyro") == []
    pad = 0.5 + 0.2 * rng.standard_normal(1500)  # counts 0 and 1 at random: the column's maximum, 1, repeats
    flight = -200.0 + 30.0 * rng.standard_normal(4500)  # vibration: 30 counts of noise
    col = np.round(np.concatenate([pad, flight])) * lsb
    top = float(col.max())
    assert _longest(col, top) >= 3 and white_noise(col, top) < lsb
    assert noise_cannot_hold(col, top) is None
    assert held_full_scale(np.column_stack([col, np.zeros((col.size, 2))]), "gyro") == []
    # a noise-free record computed in floating point (rates corrected by estimated errors): steady levels
    # scattered by rounding, a step or two of 2.2e-16, and one level, the column's minimum, held exactly
    level = np.concatenate([np.full(1500, -1.2), np.full(300, -1.4609491200171125), np.full(200, -1.3)])
    x = level + np.spacing(level) * np.round(1.5 * rng.standard_normal(level.size))  # a few units in the last place
    x[1500:1800] = level[1500]
    assert 0.0 < white_noise(x, float(x.min())) < 1e-15 and np.mean(x[:1500] != -1.2) > 0.5
    assert noise_cannot_hold(x, float(x.min())) is None
    assert held_full_scale(np.column_stack([x, np.zeros((x.size, 2))]), "gyro") == []


def _longest(x: np.ndarray, v: float) -> int:
    """The longest run of readings equal to `v` (plain loop, independent of the module)."""
    best = cur = 0
    for e in x:
        cur = cur + 1 if e == v else 0
        best = max(best, cur)
    return best


def test_a_noisy_gyro_clipped_at_a_round_value_for_most_of_the_record_is_a_clip():
    """Roll 60 deg/s then 120 deg/s, noise 2e-3 rad/s, clipped at exactly 1 rad/s (57.3 deg/s, no nominal range),
    written with all digits: the clipped value, written "1", is the column's median (most of the record is clipped)
    and one significant digit, yet every other reading carries 17; the run is a clip, found where the true roll
    exceeded 1 rad/s. The same record written to 4 significant digits (a reading near 1 rad/s resolved to 1e-3,
    half the noise) says nothing and is not flagged."""
    rng = np.random.default_rng(5)
    true = _roll(8000, rng, 2e-3)
    w = _text(np.clip(true, -1.0, 1.0), 17)
    assert np.median(w[:, 0]) == 1.0 and float(f"{w[:, 0].max():.1g}") == 1.0
    assert resolution(w[:, 0], 1.0) < 1e-6  # the readings' gaps, not the cell of "1"
    over = np.flatnonzero(true[:, 0] > 1.0)  # independent of the rule: where the roll exceeded the range
    found = held_full_scale(w, "gyro")
    assert [(h.axis, h.side) for h in found] == [(0, "maximum")]
    assert found[0].runs[0][0] == over[0] and found[0].runs[-1][1] == w.shape[0]
    assert sum(b - a for a, b in found[0].runs) >= 0.99 * over.size
    coarse = _text(np.clip(true, -1.0, 1.0), 4)
    assert resolution(coarse[:, 0], 1.0) == pytest.approx(1e-3) and held_full_scale(coarse, "gyro") == []


@pytest.mark.parametrize("session", range(5))
def test_real_mpu9150_sessions_at_rest_are_no_clip(session):
    """Five real MPU-9150 sessions (tests/data/mikoff_mpu9150: five decimals, at rest between hand turns, its
    quantised readings repeat) and the real car drive (tests/data/car_drive: at rest for 35 s): nothing is at full
    scale."""
    from pathlib import Path

    data = Path(__file__).resolve().parents[1] / "data"
    a = np.loadtxt(data / "mikoff_mpu9150" / f"imu{session}.log.gz")
    assert held_full_scale(a[:, 3:6], "gyro") == [] and held_full_scale(a[:, 0:3], "accelerometer") == []
    car = np.loadtxt(data / "car_drive" / "imu.csv.gz", delimiter=",", skiprows=1)
    assert held_full_scale(car[:, 1:4], "gyro") == [] and held_full_scale(car[:, 4:7], "accelerometer") == []
