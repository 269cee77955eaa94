"""FlightData validation (casep.io.flight) and the sample-count and all-zero dv checks (casep.checks.plausibility)."""

from __future__ import annotations

import numpy as np
import pytest

import casep
from casep.checks.plausibility import check_enough_samples, min_samples
from casep.io.flight import FlightDataError


def test_flightdata_validates_arrays():
    with pytest.raises(FlightDataError, match=r"column `f_y`, row 2: value nan is not finite"):
        casep.FlightData([0.0, 1.0], [[0, 0, 0], [0, np.nan, 0]], np.zeros((2, 3)))
    with pytest.raises(FlightDataError, match="`dv` must have shape"):
        casep.FlightData([0.0, 1.0], np.zeros((2, 3)), np.zeros((3, 3)))
    fl = casep.FlightData([0.0, 1.0], np.zeros((2, 3)), np.zeros((2, 3)))
    with pytest.raises(ValueError):
        fl.t[0] = 5.0  # read-only


def test_enough_samples_rule():
    assert min_samples(36) == 14 and min_samples(39) == 15
    fl = casep.FlightData(np.arange(13.0), np.zeros((13, 3)), np.zeros((13, 3)), source="s.csv")
    with pytest.raises(FlightDataError, match="s.csv: column `t`, row 13: 13 samples are too few for model `m`"):
        check_enough_samples(fl, 36, "m")
    check_enough_samples(casep.FlightData(np.arange(14.0), np.zeros((14, 3)), np.zeros((14, 3))), 36, "m")


def test_too_few_samples_after_the_tracking_screen_says_what_it_left_out():
    """A flight whose tracking the screen mostly left out (a receiver repeating its last fix, then lagged 1 Hz
    steps the physics check rejects): the error says how many epochs of how many and where, not only the count."""
    from casep.checks.tracking_quality import TrackingScreen

    screen = TrackingScreen(stale=[(2.1, 27.9, 259), (28.1, 29.9, 19), (30.1, 30.9, 9), (31.1, 31.9, 9)],
                            rejected=[(0.0, 2.0, 21)], epochs=320, kept=3).to_dict()
    obs = np.zeros(320, bool)
    obs[[22, 50, 80]] = True
    fl = casep.FlightData(np.arange(320.0) / 10, np.zeros((320, 3)), np.zeros((320, 3)), source="s.csv",
                          observed=obs, meta={"tracking_screen": screen})
    with pytest.raises(FlightDataError) as err:
        check_enough_samples(fl, 33, "strapdown33")
    msg = str(err.value)
    assert "3 samples observed (tracking covers 3 of 320) are too few" in msg
    assert "the tracking screen left out 317 of its 320 epochs" in msg
    assert "stale (repeated fixes) 296 in 4 spans: t = 2.1..27.9 s (259)" in msg and "and 1 more" in msg
    assert "rejected by the physics check 21 in 1 span: t = 0..2 s (21)" in msg


def test_observed_mask_selects_regression_rows(tmp_path):
    t = np.arange(10.0)
    dv = np.ones((10, 3))
    dv[:4] = np.nan  # not observed: may be NaN
    obs = t >= 4
    fl = casep.FlightData(t, np.ones((10, 3)), dv, observed=obs)
    assert (fl.n_samples, fl.n_observed) == (10, 6)
    S = np.arange(10 * 3 * 2, dtype=float).reshape(10, 3, 2)
    S2, dv2, t2 = fl.observed_rows(S)
    np.testing.assert_array_equal(S2, S[4:])
    np.testing.assert_array_equal(t2, t[4:])
    assert np.isfinite(dv2).all() and np.shares_memory(S2, S)  # contiguous: a view, no copy
    with pytest.raises(FlightDataError, match=r"column `dv_x`, row 4: value nan is not finite"):
        casep.FlightData(t, np.ones((10, 3)), dv, observed=t >= 3)
    with pytest.raises(FlightDataError, match="`observed` must be a boolean array of shape"):
        casep.FlightData(t, np.ones((10, 3)), dv, observed=obs.astype(int))
    with pytest.raises(FlightDataError, match="no sample is observed"):
        casep.FlightData(t, np.ones((10, 3)), dv, observed=np.zeros(10, bool))
    with pytest.raises(FlightDataError, match=r"6 samples observed \(tracking covers 6 of 10\) are too few"):
        check_enough_samples(fl, 36, "m")
    # the one-file formats hold the samples without tracking: their three dv cells empty (CSV) or null (Parquet)
    for name in ("x.csv", "x.parquet"):
        casep.write_flight(fl, tmp_path / name)
        back = casep.read_flight(tmp_path / name)
        np.testing.assert_array_equal(back.observed, obs)
        np.testing.assert_array_equal(back.dv[obs], dv[obs])
        assert np.isnan(back.dv[~obs]).all() and back.meta["unobserved"] == 4
    assert (tmp_path / "x.csv").read_text().splitlines()[1] == "0,1,1,1,,,"


def test_values_beyond_magnitude_limit_refused():
    f = np.ones((3, 3))
    f[2, 1] = 1e200
    with pytest.raises(FlightDataError, match=r"column `f_y`, row 3: value 1e\+200 exceeds the magnitude limit 1e\+30"):
        casep.FlightData([0.0, 1.0, 2.0], f, np.ones((3, 3)))


def test_all_zero_dv_one_rule_for_separate_and_diagnose(tmp_path, capsys):
    """separate() used to return sigma 0 and std 0, diagnose a message about `sigma`."""
    from casep.cli import main
    from casep.simulation.simulate import simulate_flight

    fl = simulate_flight("paper", seed=1, rate=10.0).flight
    zero = casep.FlightData(fl.t, fl.f, np.zeros_like(fl.dv), source="zero.csv")
    rule = r"zero.csv: the velocity error \(columns dv_x, dv_y, dv_z\) is exactly 0 at all \d+ observed samples"
    with pytest.raises(FlightDataError, match=rule):
        casep.separate(zero)
    p = tmp_path / "zero.csv"
    casep.write_flight(zero, p)
    for cmd in ("separate", "diagnose"):
        assert main([cmd, str(p)]) == 2
        assert "is exactly 0 at all" in capsys.readouterr().err
    from casep.checks.diagnostics import diagnose

    with pytest.raises(ValueError, match="`y` is 0 everywhere: sigma cannot be estimated"):
        diagnose(np.ones((20, 3, 2)), np.zeros((20, 3)))


def test_one_file_v_trk_rows_left_empty_are_untracked_as_empty_dv_rows(tmp_path):
    """A one-file v_tel/v_trk flight (an INS log with its GNSS fixes every fifth row): a row whose three v_trk
    cells are empty is a sample without tracking, as one whose three dv cells are; one or two empty of three is
    refused, naming the row and column. Its repeated tracking rows are counted among the tracked rows only."""
    rng = np.random.default_rng(4)
    n = 20
    t = 0.02 * np.arange(n)
    f = rng.normal(size=(n, 3))
    v_tel = rng.normal(size=(n, 3))
    v_trk = v_tel - 0.1 * rng.normal(size=(n, 3))
    obs = np.arange(n) % 5 == 0
    v_trk[~obs] = np.nan
    v_trk[10] = v_trk[5]  # a receiver repeating its fix, five rows on

    def write(rows):
        head = "t,f_x,f_y,f_z,v_tel_x,v_tel_y,v_tel_z,v_trk_x,v_trk_y,v_trk_z"
        cells = [",".join("" if np.isnan(v) else repr(float(v)) for v in r) for r in rows]
        p = tmp_path / "ins.csv"
        p.write_text("\n".join([head, *cells]) + "\n")
        return p

    back = casep.read_flight(write(np.column_stack([t, f, v_tel, v_trk])))
    np.testing.assert_array_equal(back.observed, obs)
    np.testing.assert_allclose(back.dv[obs], (v_tel - v_trk)[obs], rtol=0, atol=1e-12)
    assert np.isnan(back.dv[~obs]).all() and back.meta["unobserved"] == n - 4
    assert list(back.meta["tracking_repeats"]) == [10]
    part = v_trk.copy()
    part[2, 0] = 1.0  # row 3 of data: v_trk_x given, v_trk_y and v_trk_z empty
    with pytest.raises(FlightDataError, match=r"column `v_trk_y`, row 3 \(line 4\): empty value"):
        casep.read_flight(write(np.column_stack([t, f, v_tel, part])))
