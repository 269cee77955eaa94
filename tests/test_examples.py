"""Every example runs (reduced size) and says what it should.

An example runs as ``python examples/NAME.py ARGS`` would run it, in a forked child of the test process
(:func:`conftest.run_forked`: its own argv, folder on ``sys.path[0]``, working directory, Python's default
warning filters, exit status), without the 1.2-1.5 s of CPU of a new interpreter importing casep, NumPy, SciPy
and CasADi again; the Dask Monte Carlo study in a new interpreter (:func:`_example`).
"""

from __future__ import annotations

import runpy
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import run_forked

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _example(name: str, args: list[str], cwd: Path, *, new_interpreter: bool = False) -> tuple[int, str, str]:
    """``python examples/NAME ARGS`` in `cwd`: ``(exit status, stdout, stderr)``; forked, or with
    `new_interpreter` in a new one (an example that starts a Dask cluster: a fork of a test process that has
    used Dask inherits its threads' locks in whatever state they were, and can hang)."""
    script = str(EXAMPLES / name)
    if new_interpreter:
        done = subprocess.run([sys.executable, script, *args], cwd=cwd, capture_output=True, text=True, timeout=600)
        return done.returncode, done.stdout, done.stderr
    return run_forked(lambda: runpy.run_path(script, run_name="__main__"), [script, *args], cwd,
                      path0=str(EXAMPLES), timeout=600)


def _run(name: str, tmp_path: Path, *extra: str, new_interpreter: bool = False) -> str:
    code, out, err = _example(name, ["--quick", *extra], tmp_path, new_interpreter=new_interpreter)
    assert code == 0, err[-2000:]
    return out


def test_reproduce_table1(tmp_path):
    out = _run("reproduce_table1.py", tmp_path, "--out", str(tmp_path))
    assert "CRLB std" in out and "wavelet+RELS" in out and (tmp_path / "report.md").exists()


def test_add_error_term(tmp_path):
    out = _run("add_error_term.py", tmp_path, "--out", str(tmp_path))
    assert "Kg3x: true 0.05, estimate" in out and (tmp_path / "platform37_gsens.py").exists()


def test_collinearity_ridge_qp(tmp_path):
    out = _run("collinearity_ridge_qp.py", tmp_path)
    assert "near-dependencies" in out and "closed form vs cvxpy/Clarabel" in out
    diff = float(out.split("max rel. diff ")[1].split()[0])
    assert diff < 1e-5


# examples/two_rate_workflow.py --quick runs once, in tests/model/test_model_signals.py
# (test_two_rate_example_dt_trk_removes_the_ka0y_bias), which asserts what it printed and wrote.


@pytest.mark.montecarlo
def test_monte_carlo_study(tmp_path):
    out = _run("monte_carlo_study.py", tmp_path, "--out", str(tmp_path), new_interpreter=True)  # a Dask cluster
    assert "median efficiency" in out and (tmp_path / "mc.csv").exists() and (tmp_path / "mc.png").exists()


def test_make_example_flight_is_reproducible(tmp_path):
    fresh = tmp_path / "example_flight.csv"
    code, _, err = _example("make_example_flight.py", ["--out", str(fresh)], tmp_path)
    assert code == 0, err
    # Same header and comments exactly; the numbers to 1e-9 relative (+ 1e-9 absolute, in m/s^2
    # and m/s): the trajectory integration and libm differ in the last digits between CPUs, so
    # the bytes are equal on one machine but need not be on another (docs/guide/simulation.md, "Reproducibility").
    ref = EXAMPLES / "data" / "example_flight.csv"
    new_lines, ref_lines = fresh.read_text().splitlines(), ref.read_text().splitlines()
    header = [k for k, line in enumerate(ref_lines) if not line.startswith("#")][0]
    assert new_lines[: header + 1] == ref_lines[: header + 1]
    np.testing.assert_allclose(np.loadtxt(new_lines[header + 1:], delimiter=","),
                               np.loadtxt(ref_lines[header + 1:], delimiter=","), rtol=1e-9, atol=1e-9)


def test_several_flights_example(tmp_path):
    out = _run("several_flights.py", tmp_path)
    rows = [line for line in out.splitlines() if line.startswith("| paper")]
    counts = [[int(c) for c in line.strip("|").split("|")[1:]] for line in rows]
    assert len(rows) == 9 and all(1 <= a <= b <= 36 for a, b in counts)  # a prior never determines less
    assert counts[-1][0] > counts[0][0]  # four flights determine more than one



def test_make_example_imu_is_reproducible(tmp_path):
    fresh = tmp_path / "example_imu.csv"
    code, _, err = _example("make_example_imu.py", ["--out", str(fresh)], tmp_path)
    assert code == 0, err
    ref = (EXAMPLES / "data" / "imu" / "example_imu.csv").read_text().splitlines()
    new = fresh.read_text().splitlines()
    assert new[:2] == ref[:2]
    np.testing.assert_allclose(np.loadtxt(new[2:], delimiter=","), np.loadtxt(ref[2:], delimiter=","),
                               rtol=1e-9, atol=1e-9)


def test_the_mems_example_has_no_step_between_samples():
    """Lift-off (10 s) and burnout (30 s) fall on samples, which the example writes as the mean of their two sides
    (:func:`casep.navigation.imu.split_steps`), so its record leaves no step's place in an interval unknown (its truth
    is casep's navigation of the record). Kept as sampled they were two steps (9.95 and 29.95 s) whose consider std
    widened the example's std up to 14.9 times. The axial force at lift-off is the mean of the pad's and the boost's
    samples beside it: ``fb_x`` errs by ``ba_x + sa_x fb_x`` alone, affine in it."""
    from casep.navigation.imu import sample_steps

    lines = (EXAMPLES / "data" / "imu" / "mems_imu.csv").read_text().splitlines()
    assert lines[1] == "t,w_x,w_y,w_z,fb_x,fb_y,fb_z"
    a = np.loadtxt(lines[2:], delimiter=",")
    assert sample_steps(a[:, 0], a[:, 1:4], a[:, 4:7]).k.size == 0
    for t_step in (10.0, 30.0):
        k = int(np.flatnonzero(np.isclose(a[:, 0], t_step))[0])
        assert abs(a[k + 1, 4] - a[k - 1, 4]) > 10.0  # a step of several m/s^2 ...
        np.testing.assert_allclose(a[k, 4], 0.5 * (a[k - 1, 4] + a[k + 1, 4]), rtol=1e-12)  # ... split at its sample


def test_make_example_mems_is_reproducible(tmp_path):
    code, _, err = _example("make_example_mems.py", ["--out-dir", str(tmp_path)], tmp_path)
    assert code == 0, err
    for name in ("mems_imu.csv", "mems_tracking.csv"):
        ref = (EXAMPLES / "data" / "imu" / name).read_text().splitlines()
        new = (tmp_path / name).read_text().splitlines()
        head = sum(line.startswith("#") for line in ref) + 1
        assert new[:head] == ref[:head]
        np.testing.assert_allclose(np.loadtxt(new[head:], delimiter=","), np.loadtxt(ref[head:], delimiter=","),
                                   rtol=1e-9, atol=1e-9)
