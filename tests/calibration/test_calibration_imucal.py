"""casep calibrate on real IMU data (imucal's example sessions, tests/data/imucal), imucal as the oracle."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from casep import calibrate
from casep.calibration import load_calibration_model
from casep.calibration.calibrate import RotationSignWarning
from casep.calibration.imucal import from_imucal, imucal_prior, to_imucal
from casep.calibration.session import read_segments, read_session, segments_from_labels
from casep.cli import main

imucal = pytest.importorskip("imucal")  # the test extra installs it (pyproject)

DATA = Path(__file__).resolve().parents[1] / "data" / "imucal"
ANNOTATED = DATA / "annotated_session.csv"
SNAPSHOT = DATA / "example_cal.json"
RATE = 204.8  # Hz, imucal's example
G_IMUCAL = 9.81  # imucal's FerrarisCalibration(grav=9.81)


def _imucal_annotated():
    """imucal run on the annotated session as its README does (the oracle)."""
    from imucal import FerrarisCalibration, ferraris_regions_from_df

    df = pd.read_csv(ANNOTATED).set_index("part")
    regions = ferraris_regions_from_df(df)
    return FerrarisCalibration().compute(regions, sampling_rate_hz=RATE, from_acc_unit="a.u.", from_gyr_unit="a.u.")


@pytest.fixture(scope="module")
def real():
    ses = read_session(ANNOTATED, rate=RATE, label_column="part")
    segs = segments_from_labels(ses)  # imucal's expected angle, -360 deg
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        cal = calibrate(ses, segs, "ferraris", gravity=G_IMUCAL)
    return ses, segs, cal, caught


def _kr(cal):
    d = to_imucal(cal)
    return {k: np.asarray(v) for k, v in d.items() if k in ("K_a", "R_a", "b_a", "K_g", "R_g", "K_ga", "b_g")}


def test_imucal_oracle_reproduces_its_snapshot():
    snap = json.loads(SNAPSHOT.read_text())
    ours = json.loads(_imucal_annotated().to_json())
    for k in ("K_a", "R_a", "b_a", "K_g", "R_g", "K_ga", "b_g"):
        np.testing.assert_allclose(ours[k], snap[k], rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("reference", ["snapshot", "imucal"])
def test_ferraris_equals_imucal_on_the_real_session(real, reference):
    """K and R within 1e-3 relative (measured: 2e-7 for the accelerometer, 9e-6 for the gyro), K_ga and the
    biases within their std (measured b_a 0.21, 0.50, 0.80 std; b_g 0.04, 0.02, 0.00 std)."""
    _, _, cal, _ = real
    ref = (json.loads(SNAPSHOT.read_text()) if reference == "snapshot" else json.loads(_imucal_annotated().to_json()))
    ref = {k: np.asarray(ref[k]) for k in ("K_a", "R_a", "b_a", "K_g", "R_g", "K_ga", "b_g")}
    ours = _kr(cal)
    for k in ("K_a", "K_g"):
        rel = np.abs(np.diag(ours[k]) - np.diag(ref[k])) / np.diag(ref[k])
        assert np.max(rel) < 1e-3, (k, rel)
    for k in ("R_a", "R_g"):  # entries of unit-norm rows: absolute = relative to the row
        assert np.max(np.abs(ours[k] - ref[k])) < 1e-3, (k, ours[k] - ref[k])
    sd = {n: cal.std(n) for n in cal.names}
    for i, a in enumerate("xyz"):
        assert abs(ours["b_a"][i] - ref["b_a"][i]) < sd[f"ba_{a}"]
        assert abs(ours["b_g"][i] - ref["b_g"][i]) < sd[f"bg_{a}"]
        for j, b in enumerate("xyz"):
            assert abs(ours["K_ga"][i, j] - ref["K_ga"][i, j]) < sd[f"Kga_{a}{b}"]


def test_every_coefficient_has_a_std_and_the_misfit_is_reported(real):
    _, _, cal, caught = real
    assert np.all(np.isfinite(cal.result.std)) and np.all(cal.result.std > 0)  # imucal reports none
    # the six position means misfit the model far above the sample noise: said per segment
    acc = {s["name"]: s["misfit"]["accelerometer"] for s in cal.segments if s["kind"] == "static"}
    assert all(m["ratio"] > 5 for m in acc.values())  # measured 6.9 .. 70
    assert cal.sensors["accelerometer"].sigma == pytest.approx(1.0, abs=1e-6)  # rows whitened, tilt estimated
    # imucal's data turn the other way than its default expected angle (its R_g is -I): casep says so
    rot = [str(w.message) for w in caught if issubclass(w.category, RotationSignWarning)]
    assert len(rot) == 3 and "segment `x_rot`" in rot[0] and "+6016.1 a.u. s" in rot[0]


def test_measured_weightings_on_the_real_session(real):
    """Per-sample least squares vs the six means of equal weight: K_a R_a differ by 7e-4 relative, b_a by
    1 %; both differ from Ferraris' b_a (two positions per axis) by 7-32 %, the position misfit. The equal-weight
    means reproduce imucal's K_a R_a exactly (the same equations); the default (position-error model) keeps
    Ferraris' bias (tilts do not move the on-axis readings) and states a std 30 times smaller."""
    ses, segs, cal, _ = real
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RotationSignWarning)
        smp = calibrate(ses, segs, "ferraris", gravity=G_IMUCAL, weighting="samples")
        seg = calibrate(ses, segs, "ferraris", gravity=G_IMUCAL, weighting="segments")
    np.testing.assert_allclose(_kr(seg)["K_a"], json.loads(SNAPSHOT.read_text())["K_a"], rtol=1e-12)
    m = load_calibration_model("ferraris")
    Ma = [m.index(f"Ma_{a}{b}") for a in "xyz" for b in "xyz"]
    ba = [m.index(f"ba_{a}") for a in "xyz"]
    dM = np.max(np.abs(smp.result.estimate[Ma] - seg.result.estimate[Ma])) / np.max(np.abs(seg.result.estimate[Ma]))
    assert 5e-4 < dM < 9e-4
    snap = np.asarray(json.loads(SNAPSHOT.read_text())["b_a"])
    for other in (smp, seg):
        rel_f = np.abs(other.result.estimate[ba] - snap) / np.abs(snap)
        assert np.max(rel_f) > 0.15 and np.min(rel_f) > 0.05
    # per-sample std from the sample noise alone: tens of times smaller than the equal-weight std; and
    # 12-61 std away from Ferraris' bias, which the position-error model finds within 1 std
    assert np.all(smp.result.std[ba] * 10 < seg.result.std[ba])
    assert np.all(np.abs(smp.result.estimate[ba] - snap) > 10 * smp.result.std[ba])
    assert np.all(np.abs(cal.result.estimate[ba] - snap) < cal.result.std[ba])
    assert cal.sensors["accelerometer"].diagnostics["position_error_deg"] == pytest.approx(0.42, abs=0.05)


def test_imucal_export_loads_in_imucal_and_calibrates_like_casep(real, tmp_path):
    _, _, cal, _ = real
    from imucal import CalibrationInfo

    path = tmp_path / "cal.json"
    path.write_text(json.dumps(to_imucal(cal)))
    info = CalibrationInfo.from_json_file(path)
    Ma = np.array([[cal.value(f"Ma_{a}{b}") for b in "xyz"] for a in "xyz"])
    np.testing.assert_allclose(info.K_a @ info.R_a, Ma, rtol=1e-14)
    # imucal applies it: a raw reading made by casep's model comes back as the specific force
    f = np.array([[1.0, -2.0, 9.0]])
    ba = np.array([cal.value(f"ba_{a}") for a in "xyz"])
    acc, _ = info.calibrate((Ma @ f.T).T + ba, np.zeros((1, 3)), "a.u.", "a.u.")
    np.testing.assert_allclose(acc, f, rtol=1e-12, atol=1e-12)
    # and back: the same coefficients
    back = from_imucal(path)
    for n in cal.names:
        assert back[n] == pytest.approx(cal.value(n), rel=1e-13, abs=1e-15)


def test_imucal_calibration_as_a_prior(real):
    ses, segs, cal, _ = real
    prior = imucal_prior(SNAPSHOT, 0.01)
    assert set(prior) == set(cal.names)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RotationSignWarning)
        post = calibrate(ses, segs, "ferraris", "map", gravity=G_IMUCAL, options={"prior": prior})
    j = cal.names.index("ba_y")
    assert post.result.std[j] < cal.result.std[j]  # the prior's information added
    assert post.result.method == "map" and post.result.success


def test_second_session_with_section_list_against_imucal(tmp_path, capsys):
    """example_ferraris_session.csv (m/s^2, deg/s, 102.4 Hz: its turns integrate to -360 deg at that rate)
    and its section list: casep calibrate (CLI, --angle default -360) against imucal run on the same."""
    from imucal import FerrarisCalibration, ferraris_regions_from_section_list

    session, seglist = DATA / "example_ferraris_session.csv", DATA / "example_ferraris_session_list.json"
    out, imu = tmp_path / "c.json", tmp_path / "i.json"
    assert main(["calibrate", str(session), "--rate", "102.4", "--segments", str(seglist), "--gravity", "9.81",
                 "--acc-unit", "m/s^2", "--gyr-unit", "deg/s", "--json", str(out), "--imucal", str(imu)]) == 0
    assert "warning:" not in "".join(capsys.readouterr())  # turns of the expected sign
    data = pd.read_csv(session)
    sl = pd.read_json(seglist).T
    ref = json.loads(FerrarisCalibration().compute(ferraris_regions_from_section_list(data, sl), 102.4,
                                                   "m/s^2", "deg/s").to_json())
    ours = json.loads(imu.read_text())
    assert ours["from_acc_unit"] == "m/s^2" and ours["from_gyr_unit"] == "deg/s"
    for k in ("K_a", "K_g"):
        assert np.max(np.abs(np.diag(ours[k]) - np.diag(ref[k])) / np.diag(ref[k])) < 1e-3
    for k in ("R_a", "R_g"):
        assert np.max(np.abs(np.asarray(ours[k]) - np.asarray(ref[k]))) < 1e-3
    cal = json.loads(out.read_text())
    sd = dict(zip(cal["names"], cal["std"]))
    for i, a in enumerate("xyz"):
        assert abs(ours["b_g"][i] - ref["b_g"][i]) < 2.0 * sd[f"bg_{a}"]


def test_platform_model_on_real_si_session_is_a_flight_prior(tmp_path):
    """The same real session through platform36_ground: platform36's names and units, six positions leave
    the cross-quadratic terms undetermined (said so), the result is a prior of the flight model."""
    import casep
    from casep.calibration.consistency import ground_prior
    from casep.exceptions import IllConditionedWarning

    ses = read_session(DATA / "example_ferraris_session.csv", rate=102.4, acc_unit="m/s^2", gyr_unit="deg/s")
    segs = read_segments(DATA / "example_ferraris_session_list.json", ses)
    with pytest.warns(IllConditionedWarning, match="unidentifiable"):
        cal = calibrate(ses, segs, "platform36_ground", gravity=9.81)
    assert np.isnan(cal.value("Ka2xy")) and np.isfinite(cal.value("Ka1x"))
    prior = ground_prior(cal, "platform36")
    flight = casep.load_model("platform36")
    assert "Sg_xx" not in prior and "Ka2xy" not in prior and "Kg0x" in prior
    for n, v in prior.items():
        if n != "correlation":
            assert v["mean"] == cal.value(n) and v["std"] == pytest.approx(cal.std(n), rel=1e-15)
            assert flight.units[flight.index(n)] == cal.result.units[cal.names.index(n)]


def test_robust_and_recursive_estimators_on_the_real_session(real):
    """Huber (scale: the least-squares sigma, MAD is biased low at 6 dof) and RLS agree with OLS; time-series
    noise models (GLS, RELS) are refused on segment rows."""
    ses, segs, cal, _ = real
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RotationSignWarning)
        hub = calibrate(ses, segs, "ferraris", "huber", gravity=G_IMUCAL)
        rls = calibrate(ses, segs, "ferraris", "rls", gravity=G_IMUCAL)
    np.testing.assert_allclose(hub.result.std, cal.result.std, rtol=0.2)
    assert np.all(np.abs(rls.result.estimate - cal.result.estimate) < 1e-3 * cal.result.std)
    for method in ("gls", "rels"):
        with pytest.raises(ValueError, match="no time order"):
            calibrate(ses, segs, "ferraris", method, gravity=G_IMUCAL)
