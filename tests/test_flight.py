"""Flight CSV reading and writing (casep.flight)."""

from __future__ import annotations

import numpy as np
import pytest

import casep
from casep.flight import FlightDataError

HEADER = "t,f_x,f_y,f_z,dv_x,dv_y,dv_z"


def _write(tmp_path, text, name="f.csv"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_round_trip_exact(tmp_path, rng):
    t = np.cumsum(rng.uniform(0.01, 0.02, 50))
    fl = casep.FlightData(t, rng.standard_normal((50, 3)) * 30, rng.standard_normal((50, 3)))
    p = tmp_path / "rt.csv"
    casep.write_flight_csv(fl, p, comments=["made in a test"])
    back = casep.read_flight(p)
    for a in ("t", "f", "dv"):
        np.testing.assert_array_equal(getattr(back, a), getattr(fl, a))
    assert p.read_text().startswith("# made in a test\n" + HEADER)


def test_comments_blank_lines_extra_columns(tmp_path):
    p = _write(tmp_path, "# a comment\n\nt,f_x,f_y,f_z,dv_x,dv_y,dv_z,extra\n# mid\n0,1,2,3,4,5,6,x\n\n1,1,2,3,4,5,7,y\n")
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


def test_flightdata_validates_arrays():
    with pytest.raises(FlightDataError, match=r"column `f_y`, row 2: value nan is not finite"):
        casep.FlightData([0.0, 1.0], [[0, 0, 0], [0, np.nan, 0]], np.zeros((2, 3)))
    with pytest.raises(FlightDataError, match="`dv` must have shape"):
        casep.FlightData([0.0, 1.0], np.zeros((2, 3)), np.zeros((3, 3)))
    fl = casep.FlightData([0.0, 1.0], np.zeros((2, 3)), np.zeros((2, 3)))
    with pytest.raises(ValueError):
        fl.t[0] = 5.0  # read-only
