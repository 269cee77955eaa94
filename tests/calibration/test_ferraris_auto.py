"""`--segments auto` with the Ferraris model: the six poses and three turns found without labels.

Checked on imucal's annotated session (against its own labels and the labelled calibration) and on
simulated continuous sessions (poses joined by flips, turns about the vertical) whose true intervals
and coefficients are known; the bad sessions (a pose twice, a missing pose or turn, a gyro whose
axes do not match the accelerometer's) end in a SegmentError naming the cause and the numbers.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from casep.calibration.calibrate import calibrate, calibrate_files
from casep.calibration.ferrarisauto import find_ferraris_segments
from casep.calibration.session import SegmentError, Session, segments_from_labels

DATA = Path(__file__).resolve().parents[1] / "data" / "imucal" / "annotated_session.csv"
G = 9.81
AXES = {"x_p": (1, 0, 0), "x_a": (-1, 0, 0), "y_p": (0, 1, 0), "y_a": (0, -1, 0), "z_p": (0, 0, 1),
        "z_a": (0, 0, -1)}


def _labelled():
    # --angle 360 as the guide runs this session: its turns are counter-clockwise, not imucal's default -360
    return calibrate_files(DATA, rate=204.8, label_column="part", gravity=G, angle_deg=360.0)


def test_annotated_session_auto_equals_labelled_within_std():
    """imucal's annotated session, `--segments auto --model ferraris --angle 360` (the default 0.5-s window)
    against its labels.

    Every segment found lies inside the labelled segment of its name, and every coefficient is within
    its std of the labelled calibration: max |auto - labelled| / std = 0.52 (Kga_zy; measured). Its
    segments were cut out of a longer recording, so a pose ends in a jump: the centred window sees it
    half a window ahead and each pose found starts and ends half a window (51 samples) inside its label.
    """
    lab = _labelled()
    auto = calibrate_files(DATA, rate=204.8, segments="auto", gravity=G, angle_deg=360.0)
    from casep.calibration.session import read_session

    ses = read_session(DATA, rate=204.8, label_column="part")
    truth = {s.name: (int(s.rows[0]), int(s.rows[-1])) for s in segments_from_labels(ses)}
    half = auto.segmentation.segmentation.window // 2
    for s in auto.segmentation.segments:
        a, b = truth[s.name]
        assert a <= s.rows[0] and s.rows[-1] <= b, (s.name, s.rows[0], s.rows[-1], a, b)
        assert len(s.rows) >= 0.8 * (b - a + 1), s.name
        if s.kind == "static" and a > 0:  # no more than half a window lost at a jump (plus one sample)
            assert s.rows[0] - a <= half + 1 and b - s.rows[-1] <= half + 1, (s.name, s.rows[0], s.rows[-1], a, b)
    z = np.abs(auto.result.estimate - lab.result.estimate) / lab.result.std
    assert np.all(np.isfinite(z))
    assert z.max() < 1.0, dict(zip(lab.names, z.round(2)))
    assert z.max() == pytest.approx(0.52, abs=0.05)  # the figure quoted above and in the guide
    d = auto.to_dict()["calibration"]["segmentation"]
    assert set(d["segments"]) == {"x_p", "x_a", "y_p", "y_a", "z_p", "z_a", "x_rot", "y_rot", "z_rot"}
    assert "segmentation (Ferraris, no labels)" in auto.text()


# --- simulated continuous sessions ------------------------------------------------------------------

MA = np.array([[208.0, 1.5, -2.3], [-1.6, 207.9, 4.9], [4.6, -2.3, 214.7]])  # counts per m/s^2
BA = np.array([-6.0, -48.0, -29.0])
MG = np.array([[955.0, 0.6, 12.5], [5.1, 926.0, -35.3], [-12.2, 34.0, 930.0]])  # counts per rad/s
BG = np.array([2.0, -4.5, -3.7])


def _pose(name: str) -> Rotation:
    """The orientation (body -> world) with the body axis of `name` along world up."""
    return Rotation.align_vectors([[0.0, 0.0, 1.0]], [AXES[name]])[0]


def _simulate(plan, *, rate=100.0, noise=(0.5, 0.5), seed=0, gyro_mix=None):
    """Readings of `plan`: ("hold", pose, s), ("move", pose, s) at a constant body rate, ("turn", axis, deg, s).

    Returns the Session (raw counts) and the true rows of each hold and turn by name.
    """
    rng = np.random.default_rng(seed)
    R = _pose(plan[0][1])
    f_b, w_b, where = [], [], {}
    for step in plan:
        kind = step[0]
        if kind == "hold":
            n = int(round(step[2] * rate))
            w = np.zeros(3)
            where.setdefault(step[1], []).append((len(f_b), len(f_b) + n))
        elif kind == "move":
            n = int(round(step[2] * rate))
            w = (R.inv() * _pose(step[1])).as_rotvec() * rate / n
        else:
            n = int(round(step[3] * rate))
            w = np.asarray(AXES[step[1]], float) * math.radians(step[2]) * rate / n
            where[step[1][0] + "_rot"] = [(len(f_b), len(f_b) + n)]
        for _ in range(n):
            f_b.append(R.inv().apply([0.0, 0.0, G]))
            w_b.append(w)
            R = R * Rotation.from_rotvec(w / rate)
    f_b, w_b = np.array(f_b), np.array(w_b)
    mg = MG if gyro_mix is None else gyro_mix @ MG
    acc = f_b @ MA.T + BA + noise[0] * rng.standard_normal(f_b.shape)
    gyr = w_b @ mg.T + BG + noise[1] * rng.standard_normal(w_b.shape)
    t = np.arange(len(acc)) / rate
    return Session(t=t, acc=acc, gyr=gyr, rate=rate, source="simulated"), where


def _plan(order=("x_p", "x_a", "y_p", "y_a", "z_p", "z_a"), turns=("x", "y", "z"), angle=-360.0):
    plan = [("hold", order[0], 6.0)]
    for name in order[1:]:
        plan += [("move", name, 1.0), ("hold", name, 3.0)]
    for ax in turns:
        plan += [("move", ax + "_p", 1.0), ("hold", ax + "_p", 2.0), ("turn", ax + "_p", angle, 4.0),
                 ("hold", ax + "_p", 2.0)]
    return plan


def test_simulated_session_segments_and_coefficients():
    """Every pose inside its hold, every turn covering its turn and inside the holds around it; the
    calibration of the segments found recovers the true M_a, b_a, M_g, b_g within 4 std."""
    ses, where = _simulate(_plan())
    found = find_ferraris_segments(ses)
    for s in found.segments:
        if s.kind == "static":
            a, b = where[s.name][0]
            assert a <= s.rows[0] and s.rows[-1] < b and len(s.rows) > 0.5 * (b - a), s.name
        else:
            a, b = where[s.name][0]
            assert s.rows[0] <= a and b <= s.rows[-1] + 1, (s.name, s.rows[0], s.rows[-1], a, b)
            assert b - a <= len(s.rows) <= b - a + 4.0 * ses.rate  # at most the two 2-s holds besides
            # the integrated gyro (bias of the poses removed): M_g times the turn, to its noise (0.1 count s)
            np.testing.assert_allclose(found.turns[s.name], MG @ (math.radians(-360.0) * s.axis), atol=1.0)
    cal = calibrate(ses, found.segments, "ferraris", "ols", gravity=G)
    true = {f"Ma_{a}{b}": MA[i, j] for i, a in enumerate("xyz") for j, b in enumerate("xyz")}
    true.update({f"ba_{a}": BA[i] for i, a in enumerate("xyz")})
    true.update({f"Mg_{a}{b}": MG[i, j] * math.pi / 180 for i, a in enumerate("xyz") for j, b in enumerate("xyz")})
    true.update({f"bg_{a}": BG[i] for i, a in enumerate("xyz")})
    z = {k: (cal.value(k) - v) / cal.std(k) for k, v in true.items()}
    assert max(abs(v) for v in z.values()) < 4.0, z


def test_two_poses_with_the_same_axis_is_an_error():
    with pytest.raises(SegmentError, match=r"two static poses with gravity along \+x: rows 0-\d+ and \d+"):
        find_ferraris_segments(_simulate(_plan(order=("x_p", "x_a", "x_p", "y_p", "y_a", "z_p", "z_a")))[0])


def test_a_missing_pose_or_turn_is_an_error():
    with pytest.raises(SegmentError, match=r"no static pose with gravity along -y \(found: \+x rows"):
        find_ferraris_segments(_simulate(_plan(order=("x_p", "x_a", "y_p", "z_p", "z_a")))[0])
    with pytest.raises(SegmentError, match=r"no turn about z found \(turns found about: x, y; a turn: a station's "
                                           r"integrated gyro of at least 0\.5 of the largest station's"):
        find_ferraris_segments(_simulate(_plan(turns=("x", "y")))[0])


def test_a_turn_about_no_single_axis_is_an_error():
    """A gyro whose axes are mixed (x and y readings 45 deg apart): the turn about x reads along (1, 1, 0)."""
    c = math.cos(math.radians(45))
    mix = np.array([[c, -c, 0.0], [c, c, 0.0], [0.0, 0.0, 1.0]])
    with pytest.raises(SegmentError, match=r"is about no single axis: its largest component, [xy], is 0\.7\d\d of "
                                           r"its norm \(one axis: at least 0\.866"):
        find_ferraris_segments(_simulate(_plan(), gyro_mix=mix)[0])


def test_a_turn_not_about_the_vertical_is_an_error():
    """Gyro columns x and y swapped (a wrong --gyr-columns): the turn in the +x pose reads about y."""
    swap = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    with pytest.raises(SegmentError, match=r"is about y with gravity along \+x: a Ferraris turn is about the "
                                           r"vertical axis"):
        find_ferraris_segments(_simulate(_plan(), gyro_mix=swap)[0])


# --- the figure and the command ---------------------------------------------------------------------


def test_segmentation_figure_draws_the_segmentation(tmp_path):
    """The figure is a PNG with content, and the intervals it drew are the segmentation's: the nine
    named segments, the detector's unused poses and its rejected runs (a Ferraris session), the
    detector's poses (a hand-turned one)."""
    from casep.calibration.handsim import simulate_hand_session
    from casep.calibration.segment import detect_static
    from casep.reporting.segmentation import plot_segmentation

    found = find_ferraris_segments(_simulate(_plan())[0])
    drawn = plot_segmentation(found, tmp_path / "ferraris.png")
    data = (tmp_path / "ferraris.png").read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000
    named = {s.name: (int(s.rows[0]), int(s.rows[-1]) + 1) for s in found.segments}
    assert {**drawn["poses"], **drawn["turns"]} == named and len(drawn["turns"]) == 3
    assert drawn["rejected"] == [(a, b) for a, b, _ in found.segmentation.rejected]
    inside = [p for p in found.segmentation.poses if p not in drawn["unused"]]
    assert all(any(a <= p[0] and p[1] <= b for a, b in named.values()) for p in inside)

    h = simulate_hand_session(12, seed=3)
    seg = detect_static(h.acc, h.gyr, h.rate)
    drawn = plot_segmentation(seg, tmp_path / "hand.png")
    assert (tmp_path / "hand.png").stat().st_size > 10_000
    assert list(drawn["poses"].values()) == [tuple(p) for p in seg.poses] and drawn["turns"] == {}
    assert drawn["rejected"] == [(a, b) for a, b, _ in seg.rejected]


def test_cli_ferraris_auto_writes_json_and_figure(tmp_path, capsys):
    from casep.cli import main

    out, figs = tmp_path / "cal.json", tmp_path / "figs"
    rc = main(["calibrate", str(DATA), "--rate", "204.8", "--segments", "auto", "--model", "ferraris",
               "--angle", "360", "--gravity", "9.81", "--json", str(out), "--figures", str(figs)])
    assert rc == 0
    cap = capsys.readouterr()
    text = cap.out
    assert "warning" not in (cap.out + cap.err).lower()
    assert "segmentation (Ferraris, no labels)" in text and "x_rot" in text
    assert (figs / "segmentation.png").stat().st_size > 10_000
    import json

    d = json.loads(out.read_text())
    assert d["model"] == "ferraris" and set(d["calibration"]["segmentation"]["segments"]) >= {"x_p", "z_rot"}


def test_cli_ferraris_auto_error_exits_2_and_writes_nothing(tmp_path, capsys):
    """Two poses along +x: exit 2, the message with the rows, no file."""
    import pandas as pd

    from casep.cli import main

    ses, _ = _simulate(_plan(order=("x_p", "x_a", "x_p", "y_p", "y_a", "z_p", "z_a")))
    path = tmp_path / "s.csv"
    pd.DataFrame({"t": ses.t, **{f"acc_{a}": ses.acc[:, i] for i, a in enumerate("xyz")},
                  **{f"gyr_{a}": ses.gyr[:, i] for i, a in enumerate("xyz")}}).to_csv(path, index=False)
    out, figs = tmp_path / "cal.json", tmp_path / "figs"
    rc = main(["calibrate", str(path), "--segments", "auto", "--model", "ferraris", "--json", str(out),
               "--figures", str(figs)])
    assert rc == 2
    assert "two static poses with gravity along +x" in capsys.readouterr().err
    assert not out.exists() and not (figs / "segmentation.png").exists()


def test_a_turn_without_rest_after_it_is_a_warning():
    """The flip to the next pose starts right at the end of the turn about x: its integral may hold the
    start of the flip, which the station (gravity within 30 deg of +x) still contains."""
    from casep.calibration.ferrarisauto import TurnBoundaryWarning

    plan = _plan()
    i = next(k for k, s in enumerate(plan) if s[0] == "turn")
    del plan[i + 1]  # the 2-s hold after the turn about x
    with pytest.warns(TurnBoundaryWarning, match=r"the turn about x \(rows \d+-\d+\) has no rest at its end"):
        found = find_ferraris_segments(_simulate(plan)[0])
    assert [s.name for s in found.segments][-3:] == ["x_rot", "y_rot", "z_rot"]


def test_turns_in_physical_units_are_judged_by_the_expected_angle():
    """A gyro in rad/s: the turns are 2 pi rad = 360 deg, found; declared deg/s, they are 6.3 deg,
    less than half the expected 360 deg: no turn (the error names the threshold)."""
    ses, _ = _simulate(_plan(), noise=(0.0005, 0.0005))
    si = Session(t=ses.t, acc=(ses.acc - BA) @ np.linalg.inv(MA).T, gyr=(ses.gyr - BG) @ np.linalg.inv(MG).T,
                 rate=ses.rate, source="si", acc_unit="m/s^2", gyr_unit="rad/s")
    found = find_ferraris_segments(si)
    np.testing.assert_allclose(found.turns["z_rot"], [0.0, 0.0, -2 * math.pi], atol=1e-3)
    wrong = Session(t=si.t, acc=si.acc, gyr=si.gyr, rate=si.rate, source="si", acc_unit="m/s^2", gyr_unit="deg/s")
    with pytest.raises(SegmentError, match=r"no turn about x, y, z found \(turns found about: none; a turn: a "
                                           r"station's integrated gyro of at least 0\.5 of the expected 360 deg; the "
                                           r"largest station's is 0\.0175 of it, 6\.28\d deg\)"):
        find_ferraris_segments(wrong)


def test_imucal_example_session_continuous_recording():
    """imucal's other session (m/s^2, deg/s, 102.4 Hz), a continuous recording with a section list.

    With --init 3 (a bump at 3.3 s ends its initial rest) the nine segments are found, each turn
    containing the listed one, each pose overlapping the listed one. The poses found calibrate the
    same as the listed ones: with the listed turns, max |auto - listed| / std = 0.84 (measured). The
    turns found differ: they run from rest to rest, while the list ends `x_rot` with the gyro still at
    1 deg/s and the sensor settles for 0.3 s more (0.3-1.6 deg/s): 0.05 deg about x, 1.4e-4 of the
    turn, 3.3 std of Mg_xx (measured: the full auto calibration is within 3.3 std of the listed one).
    """
    from casep.calibration.session import read_segments, read_session

    path = DATA.parent / "example_ferraris_session.csv"
    ses = read_session(path, rate=102.4, acc_unit="m/s^2", gyr_unit="deg/s")
    listed = read_segments(DATA.parent / "example_ferraris_session_list.json", ses)
    found = find_ferraris_segments(ses, init_s=3.0)
    for f, s in zip(found.segments, listed):
        assert f.name == s.name
        if f.kind == "rotation":
            assert f.rows[0] <= s.rows[0] and s.rows[-1] <= f.rows[-1], f.name
        else:
            both = np.intersect1d(f.rows, s.rows).size
            assert both >= 0.9 * len(s.rows), (f.name, both, len(s.rows))
    ref = calibrate(ses, listed, "ferraris", "ols", gravity=G)
    mixed = calibrate(ses, found.segments[:6] + listed[6:], "ferraris", "ols", gravity=G)
    z = np.abs(mixed.result.estimate - ref.result.estimate) / ref.result.std
    assert z.max() < 1.0, dict(zip(ref.names, z.round(2)))
    turn = ses.gyr - ses.gyr[:280].mean(axis=0)
    end = listed[6].rows[-1] + 1
    tail = turn[end:found.segments[6].rows[-1] + 1, 0].sum() / ses.rate  # deg, after the listed end
    assert np.linalg.norm(turn[end - 1]) > 0.5 and 0.02 < abs(tail) < 0.1  # at rest: ~0.1 deg/s


def test_cli_hand_turned_session_writes_the_figure(tmp_path, capsys):
    """--figures with model multiposition: the detector's poses drawn into DIR/segmentation.png."""
    from casep.calibration.handsim import simulate_hand_session
    from casep.cli import main

    h = simulate_hand_session(14, seed=5)
    p = tmp_path / "hand.txt"
    np.savetxt(p, np.column_stack([h.acc, h.gyr]))
    figs = tmp_path / "figs"
    assert main(["calibrate", str(p), "--rate", "100", "--segments", "auto", "--acc-unit", "m/s^2", "--gyr-unit",
                 "rad/s", "--json", str(tmp_path / "cal.json"), "--figures", str(figs)]) == 0
    assert (figs / "segmentation.png").stat().st_size > 10_000
    assert f"figure: {figs / 'segmentation.png'}" in capsys.readouterr().out
