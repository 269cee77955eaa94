"""Flight file reading and writing (casep.io.files) and FlightData validation."""

from __future__ import annotations

import re

import numpy as np
import pytest

import casep
from casep.exceptions import CasepWarning, IllConditionedWarning
from casep.io.flight import FlightDataError

HEADER = "t,f_x,f_y,f_z,dv_x,dv_y,dv_z"


def _write(tmp_path, text, name="f.csv"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_round_trip_exact(tmp_path, rng):
    t = np.cumsum(rng.uniform(0.01, 0.02, 50))
    fl = casep.FlightData(t, rng.standard_normal((50, 3)) * 30, rng.standard_normal((50, 3)))
    p = tmp_path / "rt.csv"
    casep.write_flight(fl, p, comments=["made in a test"])
    back = casep.read_flight(p)
    for a in ("t", "f", "dv"):
        np.testing.assert_array_equal(getattr(back, a), getattr(fl, a))
    assert p.read_text().startswith("# made in a test\n" + HEADER)


def test_comments_blank_lines_extra_columns(tmp_path):
    p = _write(tmp_path, "# a comment\n\nt,f_x,f_y,f_z,dv_x,dv_y,dv_z,extra\n# mid\n"
                         "0,1,2,3,4,5,6,x\n\n1,1,2,3,4,5,7,y\n")
    fl = casep.read_flight(p)
    np.testing.assert_array_equal(fl.dv[:, 2], [6.0, 7.0])


def test_v_tel_v_trk_variant(tmp_path):
    p = _write(tmp_path, "t,f_x,f_y,f_z,v_tel_x,v_tel_y,v_tel_z,v_trk_x,v_trk_y,v_trk_z\n"
                         "0,1,2,3,10,20,30,9.5,20.25,31\n1,1,2,3,11,21,31,10,21,30\n")
    np.testing.assert_allclose(casep.read_flight(p).dv, [[0.5, -0.25, -1.0], [1.0, 0.0, 1.0]])


@pytest.mark.parametrize(
    "body, column, row, line, what",
    [
        (f"{HEADER}\n0,1,2,3,4,5,6\n1,1,abc,3,4,5,6\n", "f_y", 2, 3, "non-numeric value 'abc'"),
        (f"# c\n{HEADER}\n0,1,2,3,4,5,6\n\n1,1,2,3,4,,6\n", "dv_y", 2, 5, "empty value"),
        (f"{HEADER}\n0,1,2,3,4,5,6\n1,1,2,nan,4,5,6\n", "f_z", 2, 3, "NaN value"),
        (f"{HEADER}\n0,1,2,3,4,5,6\n1,1,2,3,inf,5,6\n", "dv_x", 2, 3, "infinite value"),
        (f"{HEADER}\n0,1,2,3,4,5,6\n2,1,2,3,4,5,6\n2,1,2,3,4,5,6\n", "t", 3, 4, "does not increase"),
        (f"{HEADER}\n0,1,2,3,4,5,6\n-1,1,2,3,4,5,6\n", "t", 2, 3, "does not increase"),
    ],
)
def test_bad_cells_name_column_and_row(tmp_path, body, column, row, line, what):
    p = _write(tmp_path, body)
    with pytest.raises(FlightDataError) as err:
        casep.read_flight(p)
    e = err.value
    assert (e.column, e.row, e.line) == (column, row, line)
    assert str(p) in str(e) and f"column `{column}`" in str(e) and f"row {row} (line {line})" in str(e)
    assert what in str(e)


@pytest.mark.parametrize(
    "header, missing",
    [("t,f_x,f_y,dv_x,dv_y,dv_z", "f_z"), ("t,f_x,f_y,f_z,dv_x,dv_y", "dv_z"),
     ("f_x,f_y,f_z,dv_x,dv_y,dv_z", "t"),
     ("t,f_x,f_y,f_z,v_tel_x,v_tel_y,v_tel_z,v_trk_x,v_trk_y", "v_trk_z")],
)
def test_missing_column_named(tmp_path, header, missing):
    n = header.count(",") + 1
    p = _write(tmp_path, header + "\n" + ",".join(["1"] * n) + "\n")
    with pytest.raises(FlightDataError, match=f"column `{missing}`, header \\(line 1\\): missing column"):
        casep.read_flight(p)


def test_empty_and_missing_files(tmp_path):
    with pytest.raises(FlightDataError, match="file does not exist"):
        casep.read_flight(tmp_path / "nope.csv")
    with pytest.raises(FlightDataError, match="no header row"):
        casep.read_flight(_write(tmp_path, ""))
    with pytest.raises(FlightDataError, match="header but no data rows"):
        casep.read_flight(_write(tmp_path, HEADER + "\n"))




def test_parquet_round_trip_and_bad_cell(tmp_path, rng):
    t = np.cumsum(rng.uniform(0.01, 0.02, 40))
    fl = casep.FlightData(t, rng.standard_normal((40, 3)), rng.standard_normal((40, 3)))
    p = tmp_path / "rt.parquet"
    casep.write_flight(fl, p)
    back = casep.read_flight(p)
    np.testing.assert_array_equal(back.dv, fl.dv)
    assert back.meta["format"] == "parquet"
    from casep.io.files import write_table

    cols = {"t": t, "f_x": t, "f_y": t, "f_z": t, "dv_x": t, "dv_y": t, "dv_z": t.copy()}
    cols["dv_z"][7] = np.nan
    write_table(tmp_path / "bad.parquet", cols)
    with pytest.raises(FlightDataError, match=r"column `dv_z`, row 8: NaN value"):
        casep.read_flight(tmp_path / "bad.parquet")


def test_apparent_velocity_to_force_analytic():
    # W(t) = a t^2 / 2 + b sin(w t): f = a t + b w cos(w t); non-uniform grid.
    t = np.cumsum(np.r_[0.0, 0.01 + 0.004 * np.sin(np.arange(1999))])
    a, b, w = np.array([3.0, 20.0, -1.0]), np.array([2.0, -1.0, 0.5]), 0.7
    W = np.outer(t**2 / 2, a) + np.outer(np.sin(w * t), b)
    f = np.outer(t, a) + np.outer(w * np.cos(w * t), b)
    err = np.abs(casep.apparent_velocity_to_force(t, W) - f).max()
    assert err < 1e-4 * np.abs(f).max()  # second order: ~ dt^2 |f''| / 6


def test_apparent_velocity_column_in_file(tmp_path):
    t = np.arange(0.0, 10.0, 0.1)
    W = np.column_stack([2.0 * t, 9.0 * t + 0.5 * t**2, -t])  # f = (2, 9 + t, -1)
    from casep.io.files import write_table

    write_table(tmp_path / "w.csv", {"t": t, "W_x": W[:, 0], "W_y": W[:, 1], "W_z": W[:, 2],
                                     "dv_x": t, "dv_y": t, "dv_z": t})
    fl = casep.read_flight(tmp_path / "w.csv")
    np.testing.assert_allclose(fl.f, np.column_stack([2.0 + 0 * t, 9.0 + t, -1.0 + 0 * t]), atol=1e-9)
    assert fl.meta["force"] == "W"


def _pair(tmp_path, t_tel, t_trk, v, dv, f=None):
    from casep.io.files import write_table

    f = np.ones((t_tel.size, 3)) if f is None else f
    tel = {"t": t_tel, "f_x": f[:, 0], "f_y": f[:, 1], "f_z": f[:, 2]}
    tel.update({f"v_tel_{a}": v(t_tel)[:, i] + dv[:, i] for i, a in enumerate("xyz")})
    write_table(tmp_path / "tel.csv", tel)
    write_table(tmp_path / "trk.csv", {"t": t_trk, **{f"v_trk_{a}": v(t_trk)[:, i] for i, a in enumerate("xyz")}})
    return tmp_path / "tel.csv", tmp_path / "trk.csv"


def test_two_rate_interpolation_against_analytic_velocity(tmp_path):
    # Boost-like velocity: v = (50 t^2 / 2 / 20, 40 t, 3 sin(0.2 t)) m/s sampled at 20 Hz,
    # telemetry at 100 Hz over a wider span; dv is a known ramp.
    def v(t):
        return np.column_stack([1.25 * t**2, 40.0 * t, 3.0 * np.sin(0.2 * t)])

    t_tel = np.arange(0.0, 60.0, 0.01)
    t_trk = np.arange(1.0, 50.0, 0.05)
    dv = np.column_stack([1e-3 * t_tel, -2e-3 * t_tel, 5e-4 * t_tel])
    tel, trk = _pair(tmp_path, t_tel, t_trk, v, dv)
    fl = casep.read_flight_pair(tel, trk, grid="telemetry")
    # Telemetry is kept from its first sample (S_V integrates from there) to the end of
    # tracking; dv is observed inside the tracking span only.
    keep = t_tel <= t_trk[-1]
    inside = keep & (t_tel >= 1.0)
    np.testing.assert_array_equal(fl.t, t_tel[keep])
    np.testing.assert_array_equal(fl.observed, inside[keep])
    assert np.isnan(fl.dv[~fl.observed]).all()
    np.testing.assert_allclose(fl.dv[fl.observed], dv[inside], atol=1e-9)  # cubic spline: exact for t^2, ~1e-10 for sin
    assert fl.meta["telemetry_dropped"] == int((~keep).sum()) and fl.meta["unobserved"] == 100
    assert fl.meta["observed_span_s"] == [1.0, 49.95] and fl.meta["span_s"] == [0.0, 49.95]
    lin = casep.read_flight_pair(tel, trk, interpolation="linear", grid="telemetry")
    # Linear interpolation of 1.25 t^2 errs by up to a dt^2 / 8 = 2.5 * 0.05^2 / 8.
    assert 1e-4 < np.abs(lin.dv[lin.observed, 0] - dv[inside, 0]).max() <= 2.5 * 0.05**2 / 8 + 1e-9
    # Default grid: the tracking times (on the telemetry grid here: no sample inserted), one row each.
    g = casep.read_flight_pair(tel, trk)
    np.testing.assert_array_equal(g.t, t_tel[keep])
    np.testing.assert_allclose(g.t[g.observed], t_trk, atol=1e-12)
    dv_trk = np.column_stack([1e-3 * t_trk, -2e-3 * t_trk, 5e-4 * t_trk])
    np.testing.assert_allclose(g.dv[g.observed], dv_trk, atol=1e-8)  # telemetry v interpolated: exact for t^2, ramp
    assert g.meta["grid"] == "tracking" and g.meta["inserted"] == 0 and g.meta["observed_span_s"] == [1.0, 49.95]


def test_tracking_grid_inserts_off_grid_tracking_times(tmp_path):
    """Tracking times 3 ms off the telemetry grid are inserted as rows of their own, f interpolated
    linearly (a linear f stays exact), dv formed there; outside the telemetry span they are dropped."""
    def v(t):
        return np.column_stack([1.25 * t**2, 40.0 * t, 3.0 * np.sin(0.2 * t)])

    t_tel = np.arange(0.0, 30.0, 0.01)
    t_trk = np.arange(0.003, 31.0, 0.1)  # last ones after telemetry ends
    f = np.column_stack([2.0 + 0.1 * t_tel, 9.8 + 0 * t_tel, -t_tel])
    dv = np.column_stack([1e-3 * t_tel, -2e-3 * t_tel, 5e-4 * t_tel])
    tel, trk = _pair(tmp_path, t_tel, t_trk, v, dv, f=f)
    g = casep.read_flight_pair(tel, trk)
    inside = t_trk <= t_tel[-1]
    assert g.meta["tracking_dropped"] == int((~inside).sum()) and g.meta["inserted"] == int(inside.sum())
    np.testing.assert_allclose(g.t[g.observed], t_trk[inside], atol=1e-12)
    assert g.t.size == t_tel.size + int(inside.sum())  # every telemetry sample, and each tracking time between
    tt = g.t
    np.testing.assert_allclose(g.f, np.column_stack([2.0 + 0.1 * tt, 9.8 + 0 * tt, -tt]), atol=1e-9)
    ti = t_trk[inside]
    np.testing.assert_allclose(g.dv[g.observed], np.column_stack([1e-3 * ti, -2e-3 * ti, 5e-4 * ti]), atol=1e-8)
    with pytest.raises(ValueError, match="`grid` must be one of tracking, telemetry"):
        casep.read_flight_pair(tel, trk, grid="both")


def test_two_rate_bad_inputs(tmp_path):
    t = np.arange(0.0, 5.0, 0.1)
    tel, trk = _pair(tmp_path, t, t + 100.0, lambda x: np.zeros((x.size, 3)), np.zeros((t.size, 3)))
    with pytest.raises(FlightDataError, match="share fewer than 2 telemetry samples"):
        casep.read_flight_pair(tel, trk)
    (tmp_path / "trk2.csv").write_text("t,v_trk_x,v_trk_y\n0,1,2\n")
    with pytest.raises(FlightDataError, match=r"trk2.csv: column `v_trk_z`, header \(line 1\): missing column"):
        casep.read_flight_pair(tel, tmp_path / "trk2.csv")
    (tmp_path / "trk3.csv").write_text("t,v_trk_x,v_trk_y,v_trk_z\n0,1,2,3\n1,1,2,3\n0.5,1,2,3\n")
    with pytest.raises(FlightDataError, match=r"trk3.csv: column `t`, row 3 \(line 4\): time 0.5 s does not increase"):
        casep.read_flight_pair(tel, tmp_path / "trk3.csv")
    with pytest.raises(ValueError, match="`interpolation` must be"):
        casep.read_flight_pair(tel, trk, interpolation="spline")


def test_writer_leaves_nothing_on_failure(tmp_path):
    fl = casep.FlightData([0.0, 1.0], np.zeros((2, 3)), np.zeros((2, 3)))
    with pytest.raises(TypeError):
        casep.write_flight("not a flight", tmp_path / "x.csv")
    from casep.io.files import write_table

    with pytest.raises(ValueError):
        write_table(tmp_path / "y.csv", {"t": [0.0, 1.0], "a": [1.0]})  # ragged: fails before writing
    casep.write_flight(fl, tmp_path / "ok.csv")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ok.csv"]


def _write_pair(d, tmp_path, **kw):
    tel, trk = tmp_path / "tel.csv", tmp_path / "trk.csv"
    d.write(tel, trk, **kw)
    return casep.read_flight_pair(tel, trk)


def test_tracking_from_10s_recovers_truth(tmp_path):
    """Defect: with tracking from 10 s, S_V was integrated from the first common sample and
    Kg0z came out 17.9 +- 0.9 deg/h (truth -0.5). S_V now starts at the first telemetry
    sample. Telemetry and tracking both at 20 Hz on the same times (no interpolation), so the
    noise is white and the OLS std honest: every coefficient within 4.5 std (36 normal
    z-scores exceed 4.5 with probability 2.4e-4)."""
    from casep.simulation.simulate import simulate_two_rate

    d = simulate_two_rate("paper", seed=2, telemetry_rate=20.0, tracking_rate=20.0, tracking_start=10.0)
    fl = _write_pair(d, tmp_path)
    assert fl.t[0] == 0.0 and fl.meta["observed_span_s"][0] == 10.0 and fl.meta["unobserved"] == 200
    with pytest.warns(IllConditionedWarning):
        res = casep.separate(fl, "platform36")
    assert res.n_samples == fl.n_observed == fl.n_samples - 200
    z = (res.estimate - d.truth) / res.std
    assert np.abs(z).max() < 4.5, dict(zip(d.model.names, np.round(z, 1)))
    j = d.model.names.index("Kg0z")
    assert abs(res.estimate[j] - (-0.5)) < 4.5 * res.std[j] < 8.0  # deg/h


def test_split_pair_noise_free_end_to_end(tmp_path):
    """End to end: telemetry at 100 Hz with apparent velocity W_* (f = dW/dt by second-order
    differences) and tracking at 20 Hz from 10 s, noise-free, through files, read_flight_pair
    (cubic spline) and separate(). The only errors left are the spline's and the
    differentiation's (and the trapezoid S_V on the differentiated f): measured, the largest
    estimate error is 5e-5 of the CRLB std for 0.1 m/s white noise at 100 Hz (residual RMS
    4e-5 m/s, from the spline at the thrust discontinuities). The tolerance, 1e-3 CRLB std,
    keeps a factor 20 over that and is still 300 times below what a noisy flight gives;
    linear interpolation (0.3 CRLB std) would fail it."""
    import dataclasses

    from conftest import noise_free_errors

    from casep.simulation.noise import NoiseModel
    from casep.simulation.scenarios import get_scenario
    from casep.simulation.simulate import simulate_two_rate

    quiet = dataclasses.replace(get_scenario("paper"), noise=NoiseModel("white", 0.0))
    d = simulate_two_rate(quiet, seed=0, telemetry_rate=100.0, tracking_rate=20.0, tracking_start=10.0)
    fl = _write_pair(d, tmp_path, apparent=True)
    # rows at the tracking times (every 5th telemetry sample from 10 s: the default tracking grid)
    assert fl.meta["force"] == "W" and not fl.observed[:1000].any() and fl.observed[1000::5].all()
    assert fl.observed.sum() == d.t_trk.size
    res, err = noise_free_errors(fl, d.model, d.truth)
    assert err.max() < 1e-3, dict(zip(d.model.names, err))
    assert res.sigma < 1e-3


@pytest.mark.parametrize("header, column", [
    ("t,f_x,f_y,f_z,dv_x,dv_y,dv_z,dv_x", "dv_x"),
    ("t,f_x,f_y,f_z,dv_x,dv_y,dv_z, t", "t"),
])
def test_repeated_column_refused(tmp_path, header, column):
    n = header.count(",") + 1
    p = _write(tmp_path, header + "\n" + "\n".join(",".join([str(k)] * n) for k in range(3)) + "\n")
    with pytest.raises(FlightDataError, match=f"column `{column}`, header \\(line 1\\): column name repeated"):
        casep.read_flight(p)


def test_repeated_column_refused_in_parquet(tmp_path):
    import pyarrow as pa
    import pyarrow.parquet as pq

    cols = ["t", "f_x", "f_y", "f_z", "dv_x", "dv_y", "dv_z", "dv_y"]
    pq.write_table(pa.Table.from_arrays([pa.array([0.0, 1.0, 2.0])] * len(cols), names=cols), tmp_path / "d.parquet")
    with pytest.raises(FlightDataError, match=r"column `dv_y`, header: column name repeated \(header positions 6, 8\)"):
        casep.read_flight(tmp_path / "d.parquet")


@pytest.mark.parametrize("value, column", [("1e308", "dv_z"), ("-1.7e308", "f_x"), ("1e31", "t")])
def test_huge_values_refused_naming_file_and_column(tmp_path, value, column):
    rows = [[str(k)] * 7 for k in range(4)]
    rows[2][HEADER.split(",").index(column)] = value
    p = _write(tmp_path, HEADER + "\n" + "\n".join(",".join(r) for r in rows) + "\n")
    with pytest.raises(FlightDataError, match=f"f.csv: column `{column}`, row 3 \\(line 4\\): value .* exceeds "
                                              "the magnitude limit 1e\\+30"):
        casep.read_flight(p)


def test_non_numeric_dtypes_refused(tmp_path):
    import pandas as pd

    n = 5
    base = {c: np.arange(n, dtype=float) for c in HEADER.split(",")}
    cases = [("t", pd.to_datetime(np.arange(n), unit="s"), "datetime64"), ("dv_y", np.arange(n) % 2 == 0, "bool"),
             ("f_z", [str(k) for k in range(n)], "")]
    for col, values, dtype in cases:
        frame = pd.DataFrame({**base, col: values})
        frame.to_parquet(tmp_path / "x.parquet")
        with pytest.raises(FlightDataError, match=f"x.parquet: column `{col}`, header: column has dtype {dtype}"):
            casep.read_flight(tmp_path / "x.parquet")
    p = _write(tmp_path, HEADER + "\n" + "".join(f"{k},1,2,3,True,False,True\n" for k in range(3)))
    with pytest.raises(FlightDataError, match="column `dv_x`, header \\(line 1\\): column has dtype bool"):
        casep.read_flight(p)


def test_directory_as_flight(tmp_path):
    with pytest.raises(FlightDataError, match="is a directory, not a flight file"):
        casep.read_flight(tmp_path)


def test_pair_cut_after_liftoff_warns_with_speed(tmp_path):
    from casep.io.files import write_table
    from casep.io.flight import LateStartWarning
    from casep.simulation.simulate import simulate_two_rate

    d = simulate_two_rate("paper", seed=5, telemetry_rate=20.0, tracking_rate=20.0)
    normal = _write_pair(d, tmp_path)
    assert normal.meta["start_speed_m_s"] == 0.0
    k = d.t_tel >= 20.0
    write_table(tmp_path / "tel.csv", {"t": d.t_tel[k], **{f"f_{a}": d.f[k, i] for i, a in enumerate("xyz")},
                                       **{f"v_tel_{a}": d.v_tel[k, i] for i, a in enumerate("xyz")}})
    cut = casep.read_flight_pair(tmp_path / "tel.csv", tmp_path / "trk.csv")
    with pytest.warns(CasepWarning) as rec:
        casep.separate(cut)
    late = [str(w.message) for w in rec if w.category is LateStartWarning]
    assert len(late) == 1 and re.search(r"telemetry speed at the first sample is 17\d\.?\d* m/s", late[0])


def test_cli_pair_with_late_tracking_counts_observed_samples(tmp_path, capsys):
    import json

    from casep.cli import main
    from casep.simulation.simulate import simulate_two_rate

    d = simulate_two_rate("paper", seed=6, telemetry_rate=10.0, tracking_rate=10.0, tracking_start=10.0)
    tel, trk = tmp_path / "tel.csv", tmp_path / "trk.csv"
    d.write(tel, trk, apparent=True)
    n_obs = int(np.sum(d.t_tel >= 10.0))
    assert main(["separate", str(tel), "--tracking", str(trk), "--json", str(tmp_path / "r.json")]) == 0
    assert json.loads((tmp_path / "r.json").read_text())["n_samples"] == n_obs
    assert main(["diagnose", str(tel), "--tracking", str(trk), "--tau", "1"]) == 0
    out, err = capsys.readouterr()
    assert f"model platform36, {n_obs} samples" in out
    assert "warning: " not in (out + err).replace("warning: ill-cond", "")


def test_two_rate_ols_coverage_is_honest_on_the_tracking_grid(rng):
    """Telemetry 20 Hz, tracking 5 Hz, white tracking noise 0.1 m/s, 150 seeded
    draws through pair_flight. On the tracking grid (default) the OLS 95 % intervals cover the truth
    93-97 % of the time and RMS z is about 1; on the telemetry grid (tracking interpolated) the std
    understate the error by about sqrt(20 / 5) = 2 (measured 0.64 coverage, RMS z 2.16)."""
    import dataclasses

    from casep.estimators.ols import ols_linear_map
    from casep.io.pair import pair_flight
    from casep.regression.problem import Problem
    from casep.simulation.noise import NoiseModel
    from casep.simulation.scenarios import get_scenario
    from casep.simulation.simulate import simulate_two_rate

    quiet = dataclasses.replace(get_scenario("paper"), noise=NoiseModel("white", 0.0))
    d = simulate_two_rate(quiet, seed=0, telemetry_rate=20.0, tracking_rate=5.0)
    out = {}
    for grid in ("tracking", "telemetry"):
        base = Problem.from_flight(pair_flight(d.t_tel, d.f, d.v_tel, d.t_trk, d.v_trk, grid=grid), d.model)
        S = base.sv().reshape(-1, d.model.n_coefficients)  # the observed rows
        lm = ols_linear_map(S)  # solve_ols as a linear map (tests/estimators/test_linear_maps.py): D = K y, Cov = s^2 C
        z = []
        for _ in range(150):
            fl = pair_flight(d.t_tel, d.f, d.v_tel, d.t_trk, d.v_trk + 0.1 * rng.standard_normal(d.v_trk.shape),
                             grid=grid)
            y = fl.dv[fl.observed].reshape(-1)
            est = lm.K @ y
            s2 = float(np.sum((y - S @ est) ** 2)) / lm.dof  # OLS sigma^2 = RSS / (m - rank)
            z.append((est - d.truth) / np.sqrt(np.diag(lm.cov) * s2))
        z = np.array(z)
        out[grid] = (np.mean(np.abs(z) < 1.959964), np.sqrt(np.mean(z**2)))
    assert 0.93 <= out["tracking"][0] <= 0.97 and 0.9 <= out["tracking"][1] <= 1.1, out
    assert out["telemetry"][0] < 0.8 and out["telemetry"][1] > 1.6, out
