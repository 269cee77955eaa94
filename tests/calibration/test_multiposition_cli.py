"""``casep calibrate --segments auto``: the command, its files (JSON, imu_tk's), its errors."""

from __future__ import annotations

import json
import re
import warnings
from pathlib import Path

import numpy as np
import pytest

from casep.calibration.handsim import simulate_hand_session
from casep.calibration.imutk import read_imu_tk
from casep.calibration.multiposition import acc_matrix, gyro_matrix
from casep.cli import main

DATA = Path(__file__).resolve().parents[1] / "data" / "mikoff_mpu9150"


def _independent_reader(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """imu_tk's format read by blocks separated by blank lines (not casep's reader)."""
    blocks = [b for b in path.read_text().strip().split("\n\n")]
    assert len(blocks) == 3
    T, K, B = (np.array([[float(v) for v in ln.split()] for ln in b.strip().splitlines()]) for b in blocks)
    assert T.shape == (3, 3) and K.shape == (3, 3) and B.shape == (3, 1)
    return T, K, B.ravel()


def test_cli_auto_on_the_mpu9150_session_writes_json_and_imu_tk(tmp_path, capsys):
    out, prefix = tmp_path / "cal.json", tmp_path / "imu0"
    rc = main(["calibrate", str(DATA / "imu0.log.gz"), "--rate", "100", "--segments", "auto", "--acc-unit", "m/s^2",
               "--gyr-unit", "rad/s", "--gravity", "9.81", "--json", str(out), "--imu-tk", str(prefix)])
    assert rc == 0
    text = capsys.readouterr().out
    assert "static poses" in text and "threshold" in text and "Ma_x." in text
    # the misalignment convention stated beside casep's own names (imu_tk's T_a upper triangular, T_g full)
    assert "imu_tk: a_cal = T_a K_a (a - b_a), T_a = [[1, -a_yz, a_zy], [0, 1, -a_zx], [0, 0, 1]]" in text
    assert "casep ferraris: y = M f + b, M_a = (T_a K_a)^-1" in text
    d = json.loads(out.read_text())
    assert d["model"] == "multiposition" and d["calibration"]["segmentation"]["poses"]
    # the drift each sensor's pose means show, in the report and the JSON
    assert "drift beyond white noise" in text
    drift = d["calibration"]["settings"]["drift"]
    assert set(drift) == {"accelerometer", "gyro"}
    assert all(0.0 <= v["share"] <= 1.0 and len(v["sigma_d"]) in (1, 3) and v["tau_s"] > 0 for v in drift.values())
    est = dict(zip(d["names"], d["estimates"]))
    xa = np.array([est[n] for n in ("a_yz", "a_zy", "a_zx", "sa_x", "sa_y", "sa_z", "ba_x", "ba_y", "ba_z")])
    xg = np.array([est[n] for n in ("g_yz", "g_zy", "g_xz", "g_zx", "g_xy", "g_yx", "sg_x", "sg_y", "sg_z")])
    for path, TK, b in ((Path(f"{prefix}_acc.calib"), acc_matrix(xa), xa[6:9]),
                        (Path(f"{prefix}_gyro.calib"), gyro_matrix(xg),
                         np.array([est["bg_x"], est["bg_y"], est["bg_z"]]))):
        for T, K, B in (read_imu_tk(path), _independent_reader(path)):
            np.testing.assert_allclose(T @ K, TK, rtol=1e-15, atol=1e-17)  # 17 digits: exact
            np.testing.assert_array_equal(B, b)
    # the accelerometer's T is upper triangular (imu_tk's convention)
    T, _, _ = read_imu_tk(Path(f"{prefix}_acc.calib"))
    assert T[1, 0] == T[2, 0] == T[2, 1] == 0.0


def test_cli_auto_from_latitude_and_raw_counts(tmp_path, capsys):
    # 16-bit counts, as a logger writes them: biases near mid-scale, 1/16384 g and 1/131 deg/s per count
    h = simulate_hand_session(16, seed=21, acc_noise=0.02, gyr_noise=0.002)
    ka, kg = 9.80665 / 16384.0, np.radians(1.0 / 131.0)
    rows = np.column_stack([np.round(h.acc / ka) + 32768, np.round(h.gyr / kg) + 32768])
    p = tmp_path / "raw.txt"
    np.savetxt(p, rows, fmt="%d")
    out = tmp_path / "cal.json"
    assert main(["calibrate", str(p), "--rate", "100", "--segments", "auto", "--latitude", "45", "--height", "100",
                 "--json", str(out)]) == 0
    d = json.loads(out.read_text())
    est, std = dict(zip(d["names"], d["estimates"])), dict(zip(d["names"], d["std"]))
    unit = dict(zip(d["names"], d["units"]))
    assert unit["sa_x"] == "m/s^2/a.u." and unit["ba_x"] == "a.u." and unit["sg_x"] == "rad/s/a.u."
    g45 = d["calibration"]["settings"]["gravity"]
    assert g45 == pytest.approx(9.80589, abs=1e-4)
    # the simulation's g is 9.80665: the scales absorb g/g45 - 1 = 7.8e-5; the rest within 4 std
    for i, a in enumerate("xyz"):
        assert abs(est[f"ba_{a}"] - (h.truth["acc"][6 + i] / ka + 32768)) < 4 * std[f"ba_{a}"] + 0.5
        ratio = est[f"sa_{a}"] / (h.truth["acc"][3 + i] * ka)
        assert abs(ratio * 9.80665 / g45 - 1) < 4 * std[f"sa_{a}"] / est[f"sa_{a}"]
        assert abs(est[f"sg_{a}"] / (h.truth["gyro"][6 + i] * kg) - 1) < 4 * std[f"sg_{a}"] / est[f"sg_{a}"]
        assert abs(est[f"bg_{a}"] - (h.truth["gyro_bias"][i] / kg + 32768)) < 4 * std[f"bg_{a}"] + 0.5
    # the biases in SI beside the counts: T K (b - 32768) = (T K)_true b (the simulation reads (T K)^-1 f + b, in SI)
    # within 4 std (the fitted scales carry g45 / 9.80665); the report prints them with mg and deg/s
    from casep.calibration.multiposition import acc_matrix, gyro_matrix

    settings = d["calibration"]["settings"]
    for key, TK, b, f in (("acc_full_scale", acc_matrix(h.truth["acc"]), h.truth["acc"][6:9], g45 / 9.80665),
                          ("gyr_full_scale", gyro_matrix(h.truth["gyro"]), h.truth["gyro_bias"], 1.0)):
        si = settings[key]["bias_si"]
        assert si["zero_counts"] == 32768.0 and si["unit"] in ("m/s^2", "rad/s")
        np.testing.assert_array_less(np.abs(np.array(si["estimate"]) - f * TK @ b), 4 * np.array(si["std"]))
    out_text = capsys.readouterr().out
    assert "accelerometer bias in SI, T K (b - 32768)" in out_text and " mg)" in out_text and " deg/s)" in out_text
    # a white-noise session: the drift share a pose-mean fit finds is printed with its likelihood ratio, and said
    # to be neither shown nor excluded exactly where the ratio is below the noise model's threshold
    from casep.noise.model import AUTO_LR

    lrs = [v["lr_stat"] for v in settings["drift"].values()]
    assert out_text.count("a drift neither shown nor excluded") == sum(lr <= AUTO_LR for lr in lrs) >= 1, lrs


def test_cli_auto_errors_exit_2_and_write_nothing(tmp_path, capsys):
    h = simulate_hand_session(6, seed=22)
    p = tmp_path / "few.txt"
    np.savetxt(p, np.column_stack([h.acc, h.gyr]))
    out = tmp_path / "cal.json"
    assert main(["calibrate", str(p), "--rate", "100", "--segments", "auto", "--acc-unit", "m/s^2",
                 "--gyr-unit", "rad/s", "--json", str(out)]) == 2
    assert "too few static poses: at most 6" in capsys.readouterr().err
    assert not out.exists()
    assert main(["calibrate", str(p), "--segments", "auto", "--json", str(out)]) == 2
    assert "--rate" in capsys.readouterr().err
    assert main(["calibrate", str(p), "--rate", "100", "--segments", "auto", "--gravity", "9.81", "--latitude", "45",
                 "--json", str(out)]) == 2
    assert "not both" in capsys.readouterr().err
    assert not out.exists()
    for flag, value in (("--window", "-1"), ("--min-static", "0"), ("--init", "nan")):
        with pytest.raises(SystemExit) as refused:  # argparse's refusal, exit 2
            main(["calibrate", str(p), "--rate", "100", "--segments", "auto", flag, value, "--json", str(out)])
        assert refused.value.code == 2
        err = capsys.readouterr().err
        assert flag in err and value in err, err
    assert main(["calibrate", str(p), "--rate", "100", "--segments", "auto", "--window", "1e9",
                 "--json", str(out)]) == 2
    assert "window (1e+09 s)" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize("extra, flag", [(["--method", "huber"], "--method"), (["--lambda", "0.1"], "--lambda"),
                                         (["--weighting", "samples"], "--weighting"), (["--sigma", "5"], "--sigma"),
                                         (["--angle", "360"], "--angle")])
def test_cli_auto_refuses_the_options_it_would_ignore(tmp_path, capsys, extra, flag):
    """Before: a hand-turned session with --method, an estimator option, --weighting or --sigma gave exit 0 and the
    estimates of a plain run (a --bounds box was broken by the result): the options were ignored silently."""
    h = simulate_hand_session(12, seed=23)
    p = tmp_path / "s.txt"
    np.savetxt(p, np.column_stack([h.acc, h.gyr]))
    out = tmp_path / "cal.json"
    assert main(["calibrate", str(p), "--rate", "100", "--segments", "auto", "--acc-unit", "m/s^2",
                 "--gyr-unit", "rad/s", "--json", str(out), *extra]) == 2
    err = capsys.readouterr().err
    assert f"{flag}: not used by model multiposition" in err and "--model ferraris" in err
    assert not out.exists()


def _refused(argv: list[str], out: Path, capsys) -> str:
    """Run the command, assert exit 2, nothing written and no StaticMotionWarning; return its error message."""
    from casep.calibration.segment import StaticMotionWarning

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert main(argv + ["--json", str(out)]) == 2
    # the unit (or rate) is checked first: the poses' noise read 57 x too large is not blamed on motion
    assert not [w for w in caught if issubclass(w.category, StaticMotionWarning)], [str(w.message) for w in caught]
    assert not out.exists()
    return capsys.readouterr().err


@pytest.mark.parametrize("factor, declared, says", [
    (180.0 / np.pi, "rad/s", r"the fitted gyro scales are 0\.017\d+, 0\.017\d+, 0\.017\d+ \(read as rad/s at 100 Hz\): "
     r"the readings turn 5[67]\.\d+ x the rotation .*: the readings look like deg/s: --gyr-unit deg/s \(read as rad/s "
     r"they are 57\.3 x the truth\)"),
    (1.0, "deg/s", r"the fitted gyro scales are 5[67]\.\d+, 5[67]\.\d+, 5[67]\.\d+ \(read as deg/s at 100 Hz\): the "
     r"readings turn 0\.017\d+ x .*look like rad/s: --gyr-unit rad/s \(read as deg/s they are 1/57\.3 x the truth\)"),
])
def test_cli_auto_refuses_a_gyro_declared_in_the_wrong_unit(tmp_path, capsys, factor, declared, says):
    # the labelled path's rule (casep.calibration.checks.gyro_scale_hint) on the fitted scales: exit 2
    h = simulate_hand_session(16, seed=23)
    p = tmp_path / "gyro.txt"
    np.savetxt(p, np.column_stack([h.acc, h.gyr * factor]))
    err = _refused(["calibrate", str(p), "--rate", "100", "--segments", "auto", "--acc-unit", "m/s^2",
                    "--gyr-unit", declared], tmp_path / "c.json", capsys)
    assert re.search(says, err), err


def test_cli_auto_refuses_an_accelerometer_declared_in_the_wrong_unit(tmp_path, capsys):
    # g declared m/s^2: the fitted scales are ~9.8; the labelled path's rule (checks.acc_scale_hint) names g
    h = simulate_hand_session(16, seed=23)
    p = tmp_path / "acc.txt"
    np.savetxt(p, np.column_stack([h.acc / 9.80665, h.gyr]))
    err = _refused(["calibrate", str(p), "--rate", "100", "--segments", "auto", "--acc-unit", "m/s^2",
                    "--gyr-unit", "rad/s"], tmp_path / "c.json", capsys)
    assert re.search(r"the fitted accelerometer scales are 9\.[6-9]\d*, 9\.[6-9]\d*, 9\.[6-9]\d* \(read as m/s\^2\): "
                     r"the readings are 0\.10\d* x the specific force \(more than 10% off 1\): the readings look like "
                     r"g: --acc-unit g", err), err


def test_cli_auto_refuses_a_wrong_rate_without_a_time_column(tmp_path, capsys):
    # the real 100 Hz session declared 50 Hz: every motion integral doubles, the fitted gyro scales halve
    err = _refused(["calibrate", str(DATA / "imu0.log.gz"), "--rate", "50", "--segments", "auto", "--acc-unit",
                    "m/s^2", "--gyr-unit", "rad/s", "--gravity", "9.81"], tmp_path / "c.json", capsys)
    assert re.search(r"the fitted gyro scales are 0\.(49|50)\d+, 0\.(49|50)\d+, 0\.(49|50)\d+ \(read as rad/s at 50 "
                     r"Hz\): the readings turn 2\.0\d+ x .*with no `t` column .* --rate 50 Hz is probably wrong "
                     r"\(about 100 Hz would give 1\)", err), err
    # with a time column the rate is not blamed (the times say it)
    h = simulate_hand_session(16, seed=23)
    p = tmp_path / "t.csv"
    t = np.arange(len(h.acc)) / h.rate
    np.savetxt(p, np.column_stack([t, h.acc, 2.0 * h.gyr]), delimiter=",", comments="",
               header="t,acc_x,acc_y,acc_z,gyr_x,gyr_y,gyr_z")
    err = _refused(["calibrate", str(p), "--segments", "auto", "--acc-unit", "m/s^2", "--gyr-unit", "rad/s"],
                   tmp_path / "d.json", capsys)
    assert re.search(r"the readings turn (1\.99|2\.0)\d* x", err) and "--rate" not in err, err
    assert "the readings are not a gyro's in rad/s, or the sensor is broken" in err, err


def test_a_gyro_that_clips_in_the_turns_is_a_warning_and_no_success(tmp_path, capsys):
    # raw counts of a +-250 deg/s gyro (131 counts per deg/s, signed): the fastest turns exceed it
    h = simulate_hand_session(16, seed=24, motion_s=(0.8, 1.0), angle_deg=(140.0, 170.0))
    kg = np.radians(1.0 / 131.0)
    g = np.clip(np.round(h.gyr / kg), -32768, 32767)
    assert np.any(g == 32767) or np.any(g == -32768)
    p = tmp_path / "clip.txt"
    np.savetxt(p, np.column_stack([h.acc, g]), fmt="%.10g")
    out = tmp_path / "c.json"
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        rc = main(["calibrate", str(p), "--rate", "100", "--segments", "auto", "--acc-unit", "m/s^2",
                   "--json", str(out)])
    # the calibration's warnings are casep's: printed as `warning:` lines on stderr, not Python warnings
    assert not caught, [f"{w.category.__name__}: {w.message}" for w in caught]
    std = capsys.readouterr()
    sat = [ln for ln in std.err.splitlines() if ln.startswith("warning: ") and "the sensor saturates" in ln]
    assert len(sat) == 1 and re.search(r"gyro [xyz]: \d+ samples at its (maximum 32767|minimum -32768)", sat[0]), sat
    assert "SaturationWarning" not in std.err and "handturned.py" not in std.err
    assert rc == 1 and json.loads(out.read_text())["success"] is False
    assert "saturates" in std.err


def test_imu_tk_files_as_a_prior_of_the_ferraris_model(tmp_path, capsys):
    # imucal's labelled session calibrated by casep (ferraris), written as imu_tk's files, read back as a prior
    imucal = Path(__file__).resolve().parents[1] / "data" / "imucal" / "annotated_session.csv"
    base = ["calibrate", str(imucal), "--rate", "204.8", "--label-column", "part", "--gravity", "9.81"]
    first = tmp_path / "first.json"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # imucal's session turns the other way (RotationSignWarning): not this test
        assert main([*base, "--json", str(first)]) == 0
    est = dict(zip(*(json.loads(first.read_text())[k] for k in ("names", "estimates"))))
    from casep.calibration.imutk import format_imu_tk, from_imu_tk

    prefix = tmp_path / "lab"
    for sensor, M, b, unit in (("acc", "Ma", "ba", 1.0), ("gyro", "Mg", "bg", np.pi / 180.0)):
        Mv = np.array([[est[f"{M}_{i}{j}"] for j in "xyz"] for i in "xyz"]) / unit  # reading per SI unit
        TK = np.linalg.inv(Mv)
        k = np.diag(TK)
        Path(f"{prefix}_{sensor}.calib").write_text(format_imu_tk(TK / k[None, :], np.diag(k),
                                                                  [est[f"{b}_{a}"] for a in "xyz"]))
    back = from_imu_tk(f"{prefix}_acc.calib", f"{prefix}_gyro.calib")
    for n, v in back.items():
        assert v == pytest.approx(est[n], rel=1e-12, abs=1e-12), n
    out = tmp_path / "post.json"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main([*base, "--method", "map", "--prior", f"{prefix}_acc.calib", "--prior-rel-std", "0.01",
                     "--json", str(out)]) == 0
    post = json.loads(out.read_text())
    assert post["method"] == "map"
    sd0 = dict(zip(*(json.loads(first.read_text())[k] for k in ("names", "std"))))
    sd1 = dict(zip(post["names"], post["std"]))
    assert sd1["ba_y"] < sd0["ba_y"] and sd1["Mg_zz"] < sd0["Mg_zz"]  # both files' information added
    assert main([*base, "--method", "map", "--prior", f"{prefix}_acc.calib", "--json", str(out)]) == 2
    assert "imu_tk calibration, which states no std" in capsys.readouterr().err


def test_the_calibration_warnings_are_casep_warnings():
    # casep.cli.main prints CasepWarning subclasses as `warning:` lines; any other class would surface as a raw
    # Python warning (`.../handturned.py:NNN: StaticMotionWarning: ...`)
    from casep.calibration.ferrarisauto import TurnBoundaryWarning
    from casep.calibration.handturned import FitWarning, SaturationWarning
    from casep.calibration.segment import PoseSpreadWarning, StaticMotionWarning
    from casep.exceptions import CasepWarning

    for cls in (TurnBoundaryWarning, FitWarning, SaturationWarning, PoseSpreadWarning, StaticMotionWarning):
        assert issubclass(cls, CasepWarning), cls


def test_cli_drift_prior_enters_the_bias_std_and_is_checked(tmp_path, capsys):
    # the MPU-9150 session with a gyro drift prior of 36 deg/h (1.75e-4 rad/s), tau 300 s: the gyro bias std is the
    # prior's (larger than the session's own: a drift that slow is mostly a bias the session cannot tell)
    out = tmp_path / "cal.json"
    args = ["calibrate", str(DATA / "imu0.log.gz"), "--rate", "100", "--segments", "auto", "--acc-unit", "m/s^2",
            "--gyr-unit", "rad/s", "--gravity", "9.81", "--json", str(out)]
    assert main(args + ["--gyr-drift", "36,300", "--acc-drift", "0.5,300"]) == 0
    text = capsys.readouterr().out
    d = json.loads(out.read_text())
    dr = d["calibration"]["settings"]["drift"]
    assert dr["gyro"]["prior"]["sigma_d"][0] == pytest.approx(np.radians(36 / 3600), rel=1e-3)
    assert dr["gyro"]["prior"]["tau_s"] == 300.0 and dr["accelerometer"]["prior"]["tau_s"] == 300.0
    std = dict(zip(d["names"], d["std"]))
    # the bias's std at least the common part of a drift that slow over the session, sigma_d exp(-T / (2 tau))
    assert std["bg_x"] > np.radians(36 / 3600) * np.exp(-0.5), std["bg_x"]
    assert "gyro bias std with the drift prior (std 0.000175" in text
    for bad, why in (("36", "give STD,TAU"), ("36,-5", "a positive std")):
        assert main(args + ["--gyr-drift", bad]) == 2
        assert why in capsys.readouterr().err
