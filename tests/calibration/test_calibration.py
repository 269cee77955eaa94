"""Ground calibration (casep.calibration): model lifecycle, exact recovery, std, bad segments, CLI."""

from __future__ import annotations

import json
import warnings

import casadi as ca
import numpy as np
import pandas as pd
import pytest
from scipy import stats

from casep import calibrate
from casep.calibration import CalibrationModel, load_calibration_model
from casep.calibration.calibrate import PositionMisfitWarning, RotationSignWarning
from casep.calibration.session import SegmentError, read_session, segments_from_labels
from casep.calibration.simulate import ferraris_design, simulate_session, tilted_design
from casep.cli import main
from casep.exceptions import IllConditionedWarning
from casep.model.error_model import ModelDefinitionError

# platform36's Table 1 magnitudes, with second-order terms large enough that double precision resolves
# 1e-9 of them in a 1 g reading (the paper's 3e-3 ug/g^2 moves a 1 g reading by 3e-9 of itself)
PLATFORM_TRUTH = dict(
    Kg0x=0.5, Kg1x=-0.1, Kg1xy=-0.01, Kg1xz=0.02, Kg2x=0.05, Kg0y=0.3, Kg1y=0.01, Kg1yz=0.02, Kg1yx=-0.01,
    Kg2y=0.05, Kg0z=-0.5, Kg1z=0.01, Kg1zx=-0.02, Kg1zy=0.02, Kg2z=0.05,
    Ka0x=-2, Ka1x=0.5, Ka1xy=50, Ka1xz=50, Ka2x=5, Ka2xy=5, Ka2xz=-5, Ka0y=-2, Ka1y=0.5, Ka1yz=50, Ka1yx=50,
    Ka2y=5, Ka2yz=5, Ka2yx=-5, Ka0z=1, Ka1z=0.5, Ka1zx=50, Ka1zy=50, Ka2z=5, Ka2zx=5, Ka2zy=-5,
    **{f"Sg_{i}{j}": (300.0 if i == j else 20.0 * (1 + 3 * "xyz".index(i) + "xyz".index(j)))
       for i in "xyz" for j in "xyz"})


@pytest.fixture(scope="module")
def ferraris():
    return load_calibration_model("ferraris")


@pytest.fixture(scope="module")
def platform_ground():
    return load_calibration_model("platform36_ground")


def ferraris_truth(model, seed=1):
    rng = np.random.default_rng(seed)
    truth = dict(zip(model.names, rng.normal(size=model.n_coefficients)))
    for i, a in enumerate("xyz"):
        truth[f"Ma_{a}{a}"] = 200.0 + 10 * i  # a.u. per m/s^2
        truth[f"Mg_{a}{a}"] = 16.0 + i  # a.u. per deg/s
    return truth


# ------------------------------------------------------------------ model lifecycle
def test_model_lifecycle_and_errors():
    m = CalibrationModel("toy", readings="si")
    c = m.declare(Ka0x="mg", Ka1x="mg/g")
    m.set_accel_reading(m.f + ca.vertcat(c.Ka0x + c.Ka1x * m.W[0], 0, 0))
    m.setup()
    assert m.names == ("Ka0x", "Ka1x") and m.slots == ("accel_reading",)
    with pytest.raises(RuntimeError, match="locked after setup"):
        m.declare(Ka0y="mg")
    # Jacobian per natural unit: d(reading_x)/dKa1x = mg * Wx
    J = m.jacobian("accel_reading", np.array([9.80665, 0, 0]), np.zeros(3))
    assert J[0, 1] == pytest.approx(1e-3 * 9.80665)
    bad = CalibrationModel("bad")
    c = bad.declare(a="mg", b="mg")
    bad.set_accel_reading(ca.vertcat(c.a * c.b, 0, 0))
    with pytest.raises(ModelDefinitionError, match="not linear in the coefficients"):
        bad.setup()
    sq = CalibrationModel("sq")
    c = sq.declare(s="rad/s")
    sq.set_gyro_reading(ca.vertcat(c.s * sq.omega[0] ** 2, 0, 0))
    with pytest.raises(ModelDefinitionError, match="not affine in model.omega"):
        sq.setup()
    both = CalibrationModel("both")
    c = both.declare(k="mg")
    both.set_accel_reading(ca.vertcat(c.k, 0, 0))
    both.set_gyro_reading(ca.vertcat(c.k, 0, 0))
    with pytest.raises(ModelDefinitionError, match="appear in both"):
        both.setup()
    missing = CalibrationModel("missing")
    with pytest.raises(ModelDefinitionError, match="Missing: error coefficients"):
        missing.setup()


def test_platform_ground_model_carries_the_flight_names_and_units(platform_ground):
    import casep

    flight = casep.load_model("platform36")
    shared = [n for n in platform_ground.names if n in flight.names]
    assert shared == list(flight.names)  # all 36, same order
    for n in shared:
        assert platform_ground.units[platform_ground.index(n)] == flight.units[flight.index(n)]
        assert platform_ground.si_factors[platform_ground.index(n)] == flight.si_factors[flight.index(n)]
    # the ground accelerometer error equals the flight model's Delta at the same specific force
    f = np.array([3.1, -8.2, 4.4])
    D = np.random.default_rng(3).normal(size=platform_ground.n_coefficients)
    Df = np.array([D[platform_ground.index(n)] for n in flight.names])
    ground = platform_ground.known("accel_reading", f, np.zeros(3)) + platform_ground.jacobian(
        "accel_reading", f, np.zeros(3)) @ D - f
    flight_delta = np.array(flight.functions["Delta"](f, Df)).ravel()
    np.testing.assert_allclose(ground, flight_delta, rtol=1e-13, atol=1e-15)
    # a flight model cannot be used by calibrate, nor a calibration model by separate
    with pytest.raises(ModelDefinitionError, match="not casep.calibration.CalibrationModel"):
        load_calibration_model(casep.model.loader.find_model_file("platform36"))


# ------------------------------------------------------------------ exact recovery
def test_noise_free_ferraris_session_recovered_exactly(ferraris):
    truth = ferraris_truth(ferraris)
    ses, segs = simulate_session(ferraris, truth, ferraris_design(50, 60), rate=100.0)
    cal = calibrate(ses, segs, ferraris)
    D = np.array([truth[n] for n in ferraris.names])
    rel = np.abs(cal.result.estimate - D) / np.abs(D)
    assert np.max(rel) < 1e-9, dict(zip(ferraris.names, rel))
    assert cal.result.success


def test_calibration_follows_the_result_protocol(ferraris):
    from casep.results import Result

    truth = ferraris_truth(ferraris)
    ses, segs = simulate_session(ferraris, truth, ferraris_design(50, 60), rate=100.0)
    cal = calibrate(ses, segs, ferraris)
    assert isinstance(cal, Result)
    text = cal.text()
    with pytest.warns(DeprecationWarning, match="report"):
        assert text == cal.report()  # the old name, an alias for one release
    assert text.splitlines()[0].split()[:4] == ["coefficient", "unit", "estimate", "std"]
    d = json.loads(json.dumps(cal.to_dict()))  # plain data
    assert d["calibration"]["model"] == "ferraris" and len(d["calibration"]["segments"]) == len(segs)
    with pytest.raises(AttributeError):  # a frozen record of what was computed
        cal.settings = {}


def test_calibration_model_files_load_as_flight_model_files(tmp_path):
    bad = tmp_path / "bad_ground.py"
    bad.write_text("import casep.calibration\n\ndef build():\n    m = casep.calibration.CalibrationModel('b')\n"
                   "    c = m.declare(Ka0x='mg')\n    return m.undefined\n")
    with pytest.raises(ModelDefinitionError, match=rf"model file {bad}, line 6, in build\(\): AttributeError"):
        load_calibration_model(bad)
    with pytest.raises(ValueError, match=r"unknown calibration model `ferrari`. Use one of: .*ferraris"):
        load_calibration_model("ferrari")
    # the shared declaration machinery: the same "did you mean" as a flight model
    with pytest.raises(KeyError, match=r"model `ferraris`: unknown coefficient `BA_x` \(did you mean `ba_x`\?\)"):
        load_calibration_model("ferraris").index("BA_x")


def test_noise_free_platform_session_recovered_exactly_and_six_positions_say_what_they_miss(platform_ground):
    ses, segs = simulate_session(platform_ground, PLATFORM_TRUTH, ferraris_design(20, 60) + tilted_design(20),
                                 rate=100.0)
    cal = calibrate(ses, segs, platform_ground)
    D = np.array([PLATFORM_TRUTH[n] for n in platform_ground.names])
    rel = np.abs(cal.result.estimate - D) / np.abs(D)
    assert np.max(rel) < 1e-9, dict(zip(platform_ground.names, rel))
    # the six axis positions alone cannot separate the cross-quadratic accelerometer terms: said as for flights
    ses, segs = simulate_session(platform_ground, PLATFORM_TRUTH, ferraris_design(20, 60), rate=100.0)
    with pytest.warns(IllConditionedWarning, match="6 unidentifiable: Ka2xy, Ka2xz, Ka2yz, Ka2yx, Ka2zx, Ka2zy"):
        cal = calibrate(ses, segs, platform_ground)
    assert cal.result.status == 2 and np.isnan(cal.value("Ka2xy")) and "Ka2xy" in cal.result.reasons
    assert abs(cal.value("Ka1x") - 0.5) < 1e-9


# ------------------------------------------------------------------ std: seeded simulation of the test
@pytest.mark.montecarlo
def test_std_covers_the_position_error_and_per_sample_std_does_not(ferraris):
    """Positions tilted by 1 deg rms: the std of the position-error model hold for every coefficient (t with
    6 dof: 95 % intervals cover ~0.95); equal weight of the means overstates the std of the diagonal scale
    factors (the tilt does not move the on-axis reading); per-sample least squares states a std from the
    sample noise, many times too small for the biases."""
    truth = ferraris_truth(ferraris, seed=4)
    D = np.array([truth[n] for n in ferraris.names])
    q = stats.t.ppf(0.975, 6)  # 18 accelerometer rows - 12 coefficients
    u = {"positions": [], "segments": [], "samples": []}
    for seed in range(36):
        ses, segs = simulate_session(ferraris, truth, ferraris_design(100, 100), rate=100.0, noise=(3.0, 1.0),
                                     position_error_deg=1.0, seed=seed)
        for w in u if seed < 8 else ("positions",):  # the others: 8 sessions show them
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", PositionMisfitWarning)
                cal = calibrate(ses, segs, ferraris, weighting=w)
            u[w].append((cal.result.estimate - D) / cal.result.std)
    pos, seg, smp = np.array(u["positions"]), np.array(u["segments"]), np.array(u["samples"])
    b = [ferraris.index(f"ba_{a}") for a in "xyz"]
    diag = [ferraris.index(f"Ma_{a}{a}") for a in "xyz"]
    for grp in ("Ma_", "ba_", "Mg_", "Kga_", "bg_"):
        j = [ferraris.index(n) for n in ferraris.names if n.startswith(grp)]
        assert np.mean(np.abs(pos[:, j]) < q) > 0.88, grp  # >= 108 draws: binomial sd 0.021 around 0.95
        assert 0.7 < np.sqrt(np.mean(pos[:, j] ** 2)) < 1.6, grp  # t_6: 1.22 expected
    assert 0.7 < np.sqrt(np.mean(pos[:, diag] ** 2)) < 1.6
    assert np.sqrt(np.mean(seg[:, diag] ** 2)) < 0.3  # equal weight: std of the scale factors overstated
    assert np.sqrt(np.mean(smp[:, b] ** 2)) > 5.0  # per-sample std: far too small


# ------------------------------------------------------------------ bad segments
def _write_labelled(tmp_path, ses, segs, name="s.csv", relabel=None):
    lab = np.full(ses.n_samples, "", dtype=object)
    for s in segs:
        lab[s.rows] = (relabel or {}).get(s.name, s.name)
    df = pd.DataFrame({"samples": np.arange(ses.n_samples), "part": lab,
                       **{f"acc_{a}": ses.acc[:, i] for i, a in enumerate("xyz")},
                       **{f"gyr_{a}": ses.gyr[:, i] for i, a in enumerate("xyz")}})
    path = tmp_path / name
    df.to_csv(path, index=False)
    return path


@pytest.fixture(scope="module")
def noisy_session(ferraris):
    return simulate_session(ferraris, ferraris_truth(ferraris), ferraris_design(100, 100), rate=100.0,
                            noise=(3.0, 1.0), position_error_deg=0.3, seed=7)


def test_missing_segment_exit_2_naming_it(tmp_path, noisy_session, capsys):
    ses, segs = noisy_session
    path = _write_labelled(tmp_path, ses, [s for s in segs if s.name != "y_rot"])
    out = tmp_path / "c.json"
    assert main(["calibrate", str(path), "--rate", "100", "--label-column", "part", "--json", str(out)]) == 2
    assert "Missing: y_rot" in capsys.readouterr().err and not out.exists()


def test_mislabelled_positions_exit_2_naming_the_segment(tmp_path, noisy_session, capsys):
    ses, segs = noisy_session
    path = _write_labelled(tmp_path, ses, segs, relabel={"x_p": "y_p", "y_p": "x_p"})
    out = tmp_path / "c.json"
    assert main(["calibrate", str(path), "--rate", "100", "--label-column", "part", "--json", str(out)]) == 2
    err = capsys.readouterr().err
    assert "segment `y_p`" in err and "looks like gravity along +x" in err and "mislabelled" in err
    assert not out.exists()
    path = _write_labelled(tmp_path, ses, segs, relabel={"z_p": "z_a", "z_a": "z_p"})
    assert main(["calibrate", str(path), "--rate", "100", "--label-column", "part", "--json", str(out)]) == 2
    assert "looks like gravity along +z" in capsys.readouterr().err


def test_rotation_of_the_wrong_sign_warns_with_the_numbers(ferraris):
    truth = ferraris_truth(ferraris)
    design = ferraris_design(100, 100)
    design[-2]["angle_deg"] = +360.0  # y turned the other way; the session says -360 (imucal's default)
    ses, segs = simulate_session(ferraris, truth, design, rate=100.0, noise=(3.0, 1.0), seed=2)
    segs = [s if s.name != "y_rot" else type(s)(s.name, s.kind, s.rows, s.gravity, s.axis, -360.0) for s in segs]
    with pytest.warns(RotationSignWarning, match=r"segment `y_rot` .*integrates to \+.* a\.u\. s, the opposite sign "
                                                 r"of the expected angle -360 deg.*-17(\.\d+)? a\.u\. per deg/s"):
        cal = calibrate(ses, segs, ferraris)
    assert cal.value("Mg_yy") == pytest.approx(-17.0, rel=1e-3)  # the sign flip shows in the scale


def test_segment_file_errors(tmp_path, noisy_session):
    from casep.calibration.session import read_segments

    ses, segs = noisy_session
    p = tmp_path / "seg.json"
    p.write_text(json.dumps({"x_p": {"start": 0, "end": 100}, "x_a": {"start": 50, "end": 150}}))
    with pytest.raises(SegmentError, match="overlap"):
        read_segments(p, ses)
    p.write_text(json.dumps([{"name": "tilt", "start": 0, "end": 100}]))
    with pytest.raises(SegmentError, match="segment `tilt`: Missing: `kind`"):
        read_segments(p, ses)
    p.write_text(json.dumps([{"name": "r", "start": 0, "end": 100, "kind": "rotation", "axis": [1, 0, 0],
                              "gravity": [0, 0, 1], "angle_deg": 360}]))
    with pytest.raises(SegmentError, match="not along gravity"):
        read_segments(p, ses)
    p.write_text(json.dumps({"x_p": {"start": 0, "end": 10 ** 6}}))
    with pytest.raises(SegmentError, match="not inside the session"):
        read_segments(p, ses)


def test_label_in_two_runs_is_refused(tmp_path, noisy_session):
    ses, segs = noisy_session
    path = _write_labelled(tmp_path, ses, segs, relabel={"y_a": "x_p"})
    s = read_session(path, rate=100.0, label_column="part")
    with pytest.raises(SegmentError, match="label `x_p` occurs in 2 separate runs"):
        segments_from_labels(s)


def test_session_column_errors(tmp_path, noisy_session):
    ses, segs = noisy_session
    path = _write_labelled(tmp_path, ses, segs)
    with pytest.raises(ValueError, match="no `t` column and no sample rate"):
        read_session(path)
    df = pd.read_csv(path)
    df["gyr_y"] = df["gyr_y"].astype(object)
    df.loc[17, "gyr_y"] = "x"
    df.to_csv(path, index=False)
    with pytest.raises(ValueError, match="column `gyr_y`, row 19: not a number"):
        read_session(path, rate=100.0)
    with pytest.raises(ValueError, match="Missing column"):
        read_session(path, rate=100.0, acc_columns=("ax", "ay", "az"))


# ------------------------------------------------------------------ CLI and estimators
def test_cli_writes_json_and_imucal_and_methods_apply(tmp_path, noisy_session, ferraris, capsys):
    ses, segs = noisy_session
    path = _write_labelled(tmp_path, ses, segs)
    out, imu = tmp_path / "c.json", tmp_path / "imucal.json"
    assert main(["calibrate", str(path), "--rate", "100", "--label-column", "part", "--json", str(out),
                 "--imucal", str(imu)]) == 0
    text = capsys.readouterr().out
    assert "misfit per segment" in text and "accelerometer: sigma" in text
    d = json.loads(out.read_text())
    assert d["model"] == "ferraris" and d["calibration"]["settings"]["weighting"] == "positions"
    assert len(d["covariance"]) == ferraris.n_coefficients and json.loads(imu.read_text())["cal_type"] == "Ferraris"
    # huber (robust) and ridge run on the same rows; a time-series method is refused
    for method in ("huber", "ridge"):
        out2 = tmp_path / f"{method}.json"
        assert main(["calibrate", str(path), "--rate", "100", "--label-column", "part", "--method", method,
                     "--json", str(out2)]) == 0
        assert json.loads(out2.read_text())["method"] == method
    with pytest.raises(SystemExit):  # not among the choices
        main(["calibrate", str(path), "--rate", "100", "--label-column", "part", "--method", "gls", "--json", str(out)])
    # a flight model's option for a method that does not take it
    assert main(["calibrate", str(path), "--rate", "100", "--label-column", "part", "--lambda", "3",
                 "--json", str(out)]) == 2
    assert "--lambda" in capsys.readouterr().err


def test_map_with_a_previous_calibration_as_prior(tmp_path, noisy_session, ferraris):
    """A ground result is a prior of the next calibration: the posterior is between them, std smaller."""
    ses, segs = noisy_session
    first = calibrate(ses, segs, ferraris)
    ses2, segs2 = simulate_session(ferraris, ferraris_truth(ferraris), ferraris_design(100, 100), rate=100.0,
                                   noise=(3.0, 1.0), position_error_deg=0.3, seed=8)
    from casep.calibration.calibrate import _table_file

    path = tmp_path / "first.json"
    path.write_text(json.dumps(first.to_dict()))
    prior = _table_file(path, "prior", None)
    post = calibrate(ses2, segs2, ferraris, "map", options={"prior": prior})
    alone = calibrate(ses2, segs2, ferraris)
    j = ferraris.index("ba_x")
    assert post.result.std[j] < min(first.result.std[j], alone.result.std[j])


def test_parquet_session_with_time_column_and_segment_list(tmp_path, noisy_session, ferraris):
    """A Parquet session with `t` (rate from its step) and a JSON segment list give the label-column result."""
    ses, segs = noisy_session
    df = pd.DataFrame({"t": ses.t, **{f"acc_{a}": ses.acc[:, i] for i, a in enumerate("xyz")},
                       **{f"gyr_{a}": ses.gyr[:, i] for i, a in enumerate("xyz")}})
    df.to_parquet(tmp_path / "s.parquet")
    (tmp_path / "seg.json").write_text(json.dumps({s.name: {"start": int(s.rows[0]), "end": int(s.rows[-1]) + 1}
                                                   for s in segs}))
    out = tmp_path / "c.json"
    assert main(["calibrate", str(tmp_path / "s.parquet"), "--segments", str(tmp_path / "seg.json"),
                 "--json", str(out)]) == 0
    ref = calibrate(ses, segs, ferraris)
    np.testing.assert_allclose(json.loads(out.read_text())["estimates"], ref.result.estimate, rtol=1e-9)


def test_earth_rate_given_per_segment_is_modelled(platform_ground):
    """Static segments with the Earth's rate (15 deg/h, projected on the sensor axes) stated: the gyro biases in
    deg/h are recovered exactly; left out, it would be in them (Kg0 off by the projection)."""
    earth = 15.041 / 3600.0  # deg/s
    design = []
    for k, d in enumerate(ferraris_design(20, 60)[:6] + tilted_design(20)):
        g = (np.asarray(d["gravity"], dtype=float) if "gravity" in d
             else np.eye(3)["xyz".index(d["name"][0])] * (1.0 if d["name"][2] == "p" else -1.0))
        g /= np.linalg.norm(g)
        # the Earth's rate at 50 deg latitude: vertical part along gravity, horizontal part across it
        h = np.cross(g, [0.0, 0.0, 1.0] if abs(g[2]) < 0.9 else [1.0, 0.0, 0.0])
        h /= np.linalg.norm(h)
        w = earth * (np.sin(np.radians(50)) * g + np.cos(np.radians(50)) * h)
        design.append({"name": f"s{k}", "kind": "static", "gravity": g.tolist(), "omega_dps": w.tolist(),
                       "samples": 20})
    design += ferraris_design(20, 60)[6:]
    ses, segs = simulate_session(platform_ground, PLATFORM_TRUTH, design, rate=100.0)
    cal = calibrate(ses, segs, platform_ground)
    for n in ("Kg0x", "Kg0y", "Kg0z", "Kg1x", "Sg_xx"):
        assert cal.value(n) == pytest.approx(PLATFORM_TRUTH[n], rel=1e-9)
    blind = [type(s)(s.name, s.kind, s.rows, s.gravity, s.axis, s.angle_deg) for s in segs]  # omega_dps 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PositionMisfitWarning)
        off = calibrate(ses, blind, platform_ground)
    assert max(abs(off.value(n) - PLATFORM_TRUTH[n]) for n in ("Kg0x", "Kg0y", "Kg0z", "Kg1x", "Kg1y")) > 1.0
