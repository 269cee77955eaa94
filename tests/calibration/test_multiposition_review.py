"""``casep calibrate --segments auto`` on the sessions a calibration engineer's review found misjudged.

Each test fails on the code before its fix: a quantised count repeated at a smooth turn's peak called
saturation; an accelerometer clipped in static poses not named as such; poses in a narrow cone and swapped
gyro columns blamed on the unit; a ``t`` column in ms a raw NumPy error; a wrong --rate on raw counts
without a word of the full scale it implies.
"""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest

from casep.calibration.handsim import TRUTH_SI, simulate_hand_session
from casep.calibration.multiposition import acc_matrix, gyro_matrix
from casep.cli import main

G = 9.80665
HEADER = "t,acc_x,acc_y,acc_z,gyr_x,gyr_y,gyr_z"


def _run(args, out, capsys):
    rc = main(["calibrate", *args, "--segments", "auto", "--json", str(out)])
    std = capsys.readouterr()
    return rc, std.out, std.err


def _counts(h, ka: float, kg: float) -> np.ndarray:
    """16-bit unsigned counts (mid-scale 32768) of a simulated session, `ka` m/s^2 and `kg` rad/s per count."""
    return np.clip(np.column_stack([np.round(h.acc / ka), np.round(h.gyr / kg)]) + 32768, 0, 65535)


def test_quantised_counts_repeating_at_a_smooth_peak_are_no_saturation(tmp_path, capsys):
    # a +-2000 deg/s gyro (16.4 counts per deg/s): the peak of a smooth turn holds one count for 3-6 samples
    h = simulate_hand_session(14, seed=33, gyr_noise=2e-4, motion_s=(1.5, 2.5))
    raw = _counts(h, G / 16384.0, math.radians(1 / 16.4))
    g = raw[:, 3:]
    top = [int(np.max(np.convolve(((g[:, j] == g[:, j].max()) & h.moving).astype(int), np.ones(3), "valid")))
           for j in range(3)]
    assert max(top) == 3  # a run of three at the column's extreme, far from the converter's limit
    assert g.max() < 40000 and g.min() > 25000
    p = tmp_path / "raw.txt"
    np.savetxt(p, raw, fmt="%d")
    rc, out, err = _run([str(p), "--rate", "100"], tmp_path / "c.json", capsys)
    assert rc == 0 and "saturat" not in out + err, out[-2000:] + err


def test_a_gyro_at_its_nominal_range_in_deg_s_is_saturation(tmp_path, capsys):
    # a +-250 deg/s gyro written in deg/s: fast turns hold +-250 for many samples
    h = simulate_hand_session(16, seed=24, motion_s=(0.8, 1.0), angle_deg=(140.0, 170.0))
    gyr = np.clip(np.degrees(h.gyr), -250.0, 250.0)
    p = tmp_path / "clip.txt"
    np.savetxt(p, np.column_stack([h.acc, gyr]), fmt="%.10g")
    rc, out, err = _run([str(p), "--rate", "100", "--acc-unit", "m/s^2", "--gyr-unit", "deg/s"],
                        tmp_path / "c.json", capsys)
    assert rc == 1 and re.search(r"gyro [xyz]: \d+ samples at its (maximum 250|minimum -250) \(the nominal "
                                 r"\+-250 deg/s range\)", err), err[-2000:]  # a warning: on stderr


def test_an_accelerometer_clipped_in_static_poses_is_named_and_those_poses_left_out(tmp_path, capsys):
    # a +-0.96 g accelerometer (34000 counts per g): poses with an axis within ~18 deg of vertical clip
    h = simulate_hand_session(30, seed=35)
    ka, kg = G / 34000.0, math.radians(1 / 65.5)
    raw = _counts(h, ka, kg)
    p = tmp_path / "raw.txt"
    np.savetxt(p, raw, fmt="%d")
    out_json = tmp_path / "c.json"
    rc, out, err = _run([str(p), "--rate", "100"], out_json, capsys)
    m = re.search(r"the accelerometer saturates in (\d+) of (\d+) static poses, left out of the fit: pose rows "
                  r"\d+-\d+: [xyz] at its (maximum 65535 \(the unsigned 16-bit converter's limit 65535\)|minimum 0 "
                  r"\(the unsigned converter's limit 0\)) in \d+% of its samples", err)
    assert m and int(m.group(1)) >= 2, out[-3000:] + err  # a warning: on stderr
    assert "inside motions" not in out + err and "turns inside" not in out + err
    # the poses left, the coefficients within 4 std of the truth
    assert rc == 0, err
    d = json.loads(out_json.read_text())
    est, std = dict(zip(d["names"], d["estimates"])), dict(zip(d["names"], d["std"]))
    for i, a in enumerate("xyz"):
        assert abs(est[f"sa_{a}"] / (TRUTH_SI["acc"][3 + i] * ka) - 1) < 4 * std[f"sa_{a}"] / est[f"sa_{a}"]
        assert abs(est[f"ba_{a}"] - (TRUTH_SI["acc"][6 + i] / ka + 32768)) < 4 * std[f"ba_{a}"] + 0.5


def _cone_session(cone_deg: float, seed: int, n: int = 25, rate: float = 100.0) -> np.ndarray:
    """SI readings ``ax ay az wx wy wz`` of poses whose gravity directions lie within `cone_deg` of one direction,
    joined by smooth slerped turns (scipy's rotations, not casep's), TRUTH_SI's errors and white noise."""
    from scipy.spatial.transform import Rotation, Slerp

    rng = np.random.default_rng(seed)
    tilt = [Rotation.from_euler("z", rng.uniform(-180, 180), degrees=True)
            * Rotation.from_rotvec(np.r_[np.cos(p), np.sin(p), 0.0] * math.radians(rng.uniform(0, cone_deg)))
            for p in rng.uniform(0, 2 * math.pi, n)]
    att = [Rotation.concatenate([tilt[0]] * int(8 * rate))]
    for a, b in zip(tilt, tilt[1:]):
        k = int(rng.uniform(1.0, 2.0) * rate)
        att.append(Slerp([0, 1], Rotation.concatenate([a, b]))((1 - np.cos(np.pi * np.arange(1, k + 1) / k)) / 2))
        att.append(Rotation.concatenate([b] * int(rng.uniform(1.5, 3.0) * rate)))
    R = Rotation.concatenate(att)
    f = R.inv().apply([0.0, 0.0, G])
    w = np.vstack([(R[:-1].inv() * R[1:]).as_rotvec() * rate, np.zeros(3)])
    acc = np.linalg.solve(acc_matrix(TRUTH_SI["acc"]), f.T).T + TRUTH_SI["acc"][6:9] + rng.normal(0, 0.02, f.shape)
    gyr = np.linalg.solve(gyro_matrix(TRUTH_SI["gyro"]), w.T).T + TRUTH_SI["gyro_bias"] + rng.normal(0, 0.002, w.shape)
    return np.column_stack([acc, gyr])


def test_poses_in_a_narrow_cone_name_the_spread_not_the_unit(tmp_path, capsys):
    # within 20 deg of one direction: scale and bias along it cannot be separated (it was blamed on the unit)
    p = tmp_path / "cone.txt"
    np.savetxt(p, _cone_session(20.0, seed=3))
    rc, out, err = _run([str(p), "--rate", "100", "--acc-unit", "m/s^2", "--gyr-unit", "rad/s"],
                        tmp_path / "c.json", capsys)
    m = re.search(r"the 25 poses' gravity directions lie within ([\d.]+) deg of one direction \(smallest singular "
                  r"value / sqrt\(n\) [\d.]+; 0\.577: spread evenly\): the accelerometer's scale and bias along it "
                  r"cannot be separated", err)
    assert rc == 2 and m, err
    assert 14.0 < float(m.group(1)) <= 20.5
    assert "--acc-unit" not in err and "raw counts" not in err


def test_poses_in_a_30_deg_cone_calibrate_with_honest_std_and_their_near_dependencies(tmp_path, capsys):
    # within 30 deg: the fit converges from the physical unit's start (it was refused as a unit mistake)
    p = tmp_path / "cone.txt"
    np.savetxt(p, _cone_session(30.0, seed=3))
    out_json = tmp_path / "c.json"
    rc, out, err = _run([str(p), "--rate", "100", "--acc-unit", "m/s^2", "--gyr-unit", "rad/s"], out_json, capsys)
    assert rc == 0, err
    assert re.search(r"accelerometer: condition number [\d.e+]+ \(equilibrated\); near-dependencies: .*ba_z", out), out
    d = json.loads(out_json.read_text())
    z = (np.array(d["estimates"][:18]) - np.r_[TRUTH_SI["acc"], TRUTH_SI["gyro"]]) / np.array(d["std"][:18])
    assert np.max(np.abs(z)) < 4.0, z


@pytest.mark.parametrize("order, unit", [((1, 0, 2), "rad/s"), ((2, 1, 0), "a.u.")])
def test_swapped_gyro_columns_are_named_not_blamed_on_the_unit(tmp_path, capsys, order, unit):
    h = simulate_hand_session(16, seed=41)
    if unit == "a.u.":
        rows = _counts(h, G / 16384.0, math.radians(1 / 65.5))
    else:
        rows = np.column_stack([h.acc, h.gyr])
    rows[:, 3:] = rows[:, 3:][:, list(order)]
    p = tmp_path / "swap.txt"
    np.savetxt(p, rows, fmt="%.10g")
    extra = ["--acc-unit", "m/s^2", "--gyr-unit", "rad/s"] if unit == "rad/s" else []
    rc, out, err = _run([str(p), "--rate", "100", *extra], tmp_path / "c.json", capsys)
    names = ", ".join("xyz"[i] for i in order)
    m = re.search(rf"the gyro columns look swapped: taken in the order \({names}\) the gyro fit converges with an RMS "
                  r"gravity-direction misfit of ([\d.e-]+) deg and scales ([\d.e-]+), ([\d.e-]+), ([\d.e-]+); in the "
                  r"order given, ([\d.e+]+) deg", err)
    assert rc == 2 and m, err
    assert float(m.group(1)) < 0.2 < float(m.group(5))
    si = np.array([float(m.group(k)) for k in (2, 3, 4)]) / (1.0 if unit == "rad/s" else math.radians(1 / 65.5))
    np.testing.assert_allclose(si, 1.0, atol=0.02)
    assert "--gyr-unit" not in err and "deg/s" not in err


def test_a_t_column_in_ms_is_refused_naming_the_column_and_the_unit(tmp_path, capsys):
    h = simulate_hand_session(12, seed=42)
    p = tmp_path / "ms.csv"
    t_ms = 1000.0 * np.arange(len(h.acc)) / h.rate
    np.savetxt(p, np.column_stack([t_ms, h.acc, h.gyr]), delimiter=",", comments="", header=HEADER)
    out = tmp_path / "c.json"
    rc, _, err = _run([str(p), "--acc-unit", "m/s^2", "--gyr-unit", "rad/s"], out, capsys)
    assert rc == 2 and not out.exists()
    want = r"column `t`: median step 10 \(read as s: 0\.1 Hz.*the times look like ms \(then 100 Hz\)"
    assert re.search(want, err), err


@pytest.mark.parametrize("rate, gyro_fs", [(100.0, 500.0), (50.0, 250.0)])
def test_raw_counts_say_the_full_scale_they_imply_and_the_assumed_rate(tmp_path, capsys, rate, gyro_fs):
    # a 100 Hz session of a +-2 g / +-500 deg/s part, read without a t column at --rate `rate`
    h = simulate_hand_session(16, seed=43)
    p = tmp_path / "raw.txt"
    np.savetxt(p, _counts(h, G / 16384.0, math.radians(1 / 65.536)), fmt="%d")
    out_json = tmp_path / "c.json"
    rc, out, _ = _run([str(p), "--rate", f"{rate:g}"], out_json, capsys)
    assert rc == 0
    acc = re.search(r"accelerometer raw counts: full scale \+-([\d.]+) g over \+-32768 counts \(a 16-bit converter\)",
                    out)
    gyr = re.search(r"gyro raw counts: full scale \+-([\d.]+) deg/s over \+-32768 counts \(a 16-bit converter\).*at "
                    rf"the assumed --rate {rate:g} Hz \(no t column", out)
    assert acc and gyr, out
    # the truth's scale errors are under 1 %: the implied ranges within 1.5 % of the part's, times the rate's factor
    assert abs(float(acc.group(1)) / 2.0 - 1) < 0.015
    assert abs(float(gyr.group(1)) / gyro_fs - 1) < 0.015
    fs = json.loads(out_json.read_text())["calibration"]["settings"]["gyr_full_scale"]
    assert fs["bits"] == 16 and abs(fs["full_scale"] / gyro_fs - 1) < 0.015
