"""One-file flights with tracking gaps: a simulated paper-range flight keeps every telemetry sample
(casep.simulation.simulate), its rows without tracking are written with empty dv cells and read back
as not observed (casep.io.files), and separate's estimate on it agrees with the truth."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.stats import chi2

import casep
from casep.exceptions import IllConditionedWarning
from casep.io.flight import FlightDataError
from casep.simulation.scenarios import get_scenario
from casep.simulation.simulate import simulate_flight, write_simulation

GAPS = ((0.0, 8.0), (95.0, 6.0), (140.0, 1.5))  # the paper-range scenarios: tracking from 8 s, two dropouts


def _untracked(t):
    return np.logical_or.reduce([(t >= a) & (t < a + n) for a, n in GAPS])


def test_scenario_gaps_are_the_documented_ones():
    for name in ("paper-range-gm", "paper-range"):
        assert tuple(tuple(g) for g in get_scenario(name).noise.gaps) == GAPS


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_simulated_range_flight_keeps_the_telemetry_and_the_tracked_mask(tmp_path, suffix):
    sim = simulate_flight("paper-range-gm", seed=3, rate=10.0)
    fl = sim.flight
    # the whole telemetry: from lift-off at the trajectory's sample times, no row left out
    np.testing.assert_array_equal(fl.t, sim.trajectory.t)
    np.testing.assert_array_equal(fl.f, sim.trajectory.specific_force)
    assert fl.t[0] == 0.0 and np.ptp(np.diff(fl.t)) < 1e-9
    np.testing.assert_array_equal(fl.observed, ~_untracked(fl.t))
    assert np.isnan(fl.dv[~fl.observed]).all() and np.isfinite(fl.dv[fl.observed]).all()
    assert fl.meta["unobserved"] == int(_untracked(fl.t).sum()) == 80 + 60 + 15
    # dv = S_V D + n where tracked, S_V integrated from lift-off over every sample
    S = casep.build_sv(sim.model, fl.t, fl.f, signals=fl.signals)
    np.testing.assert_allclose(fl.dv[fl.observed], (S @ sim.truth + sim.noise)[fl.observed], atol=1e-12)
    for c in ("r_x", "v_y"):  # the tracked state: none without tracking
        assert np.isnan(fl.signals[c][~fl.observed]).all() and np.isfinite(fl.signals[c][fl.observed]).all()

    path, _ = write_simulation(sim, tmp_path / f"f{suffix}")
    back = casep.read_flight(path)
    np.testing.assert_array_equal(back.t, fl.t)
    np.testing.assert_array_equal(back.f, fl.f)
    np.testing.assert_array_equal(back.observed, fl.observed)
    np.testing.assert_array_equal(back.dv, fl.dv)  # NaN at the same places
    assert back.meta["unobserved"] == fl.meta["unobserved"]
    assert set(back.signals) == set(fl.signals)
    for c, v in fl.signals.items():
        np.testing.assert_array_equal(back.signals[c], v)
    if suffix == ".csv":
        lines = [x for x in path.read_text().splitlines() if not x.startswith("#")]
        first = lines[1].split(",")
        assert first[0] == "0" and first[4:7] == ["", "", ""]
        k = int(np.argmax(fl.observed))  # the first tracked row: t = 8 s
        assert fl.t[k] == 8.0 and all(lines[k + 1].split(",")[4:7])


def test_round_trip_of_a_flight_with_unobserved_rows(tmp_path):
    rng = np.random.default_rng(5)
    t = np.linspace(0.0, 3.0, 31)
    f = rng.normal(size=(31, 3))
    obs = ~((t > 0.45) & (t < 1.05)) & (t > 0.15)
    dv = np.where(obs[:, None], rng.normal(size=(31, 3)), 7.0)  # a value at an unobserved row is not data
    fl = casep.FlightData(t, f, dv, observed=obs, signals={"temp": np.where(obs, 20.0, np.nan)})
    for name in ("x.csv", "x.parquet"):
        casep.write_flight(fl, tmp_path / name)
        back = casep.read_flight(tmp_path / name)
        np.testing.assert_array_equal(back.t, t)
        np.testing.assert_array_equal(back.f, f)
        np.testing.assert_array_equal(back.observed, obs)
        np.testing.assert_array_equal(back.dv[obs], dv[obs])
        assert np.isnan(back.dv[~obs]).all()
        np.testing.assert_array_equal(back.signals["temp"], fl.signals["temp"])
    # every sample tracked: no empty cell, observed all True and no `unobserved` in meta
    full = casep.FlightData(t, f, np.where(obs[:, None], dv, 0.0))
    casep.write_flight(full, tmp_path / "full.csv")
    assert ",," not in (tmp_path / "full.csv").read_text()
    back = casep.read_flight(tmp_path / "full.csv")
    assert back.observed.all() and "unobserved" not in back.meta


def test_a_partly_empty_dv_row_is_refused_naming_the_row(tmp_path):
    head = "t,f_x,f_y,f_z,dv_x,dv_y,dv_z\n"
    rows = ["0,1,2,3,,,", "1,1,2,3,4,5,6", "2,1,2,3,4,5,6", "3,1,2,3,4,5,6"]
    ok = tmp_path / "ok.csv"
    ok.write_text(head + "\n".join(rows) + "\n")
    assert casep.read_flight(ok).observed.tolist() == [False, True, True, True]
    for bad_row, col, text in ((3, "dv_y", "2,1,2,3,4,,6"), (1, "dv_x", "0,1,2,3,,5,"), (4, "dv_z", "3,1,2,3,4,5,")):
        lines = list(rows)
        lines[bad_row - 1] = text
        p = tmp_path / f"bad{bad_row}.csv"
        p.write_text("# comment\n" + head + "\n".join(lines) + "\n")
        with pytest.raises(FlightDataError, match=rf"bad{bad_row}.csv: column `{col}`, row {bad_row} "
                                                  rf"\(line {bad_row + 2}\): empty value"):
            casep.read_flight(p)
    p = tmp_path / "nan.csv"  # a `nan` text is not an empty cell, even in all three
    p.write_text(head + "0,1,2,3,nan,nan,nan\n1,1,2,3,4,5,6\n")
    with pytest.raises(FlightDataError, match=r"column `dv_x`, row 1 \(line 2\): NaN value"):
        casep.read_flight(p)
    p = tmp_path / "none.csv"  # no tracking at all
    p.write_text(head + "0,1,2,3,,,\n1,1,2,3,,,\n")
    with pytest.raises(FlightDataError, match="no sample is observed"):
        casep.read_flight(p)


def test_a_partly_null_parquet_dv_row_is_refused(tmp_path):
    pa = pytest.importorskip("pyarrow")
    import pyarrow.parquet as pq

    cols = {"t": [0.0, 1.0, 2.0], "f_x": [1.0] * 3, "f_y": [1.0] * 3, "f_z": [1.0] * 3,
            "dv_x": [None, 1.0, 1.0], "dv_y": [None, None, 1.0], "dv_z": [None, 1.0, 1.0]}
    pq.write_table(pa.table({k: pa.array(v, type=pa.float64()) for k, v in cols.items()}), tmp_path / "p.parquet")
    with pytest.raises(FlightDataError, match=r"p.parquet: column `dv_y`, row 2: null value"):
        casep.read_flight(tmp_path / "p.parquet")
    cols["dv_y"][1] = 1.0
    pq.write_table(pa.table({k: pa.array(v, type=pa.float64()) for k, v in cols.items()}), tmp_path / "p.parquet")
    assert casep.read_flight(tmp_path / "p.parquet").observed.tolist() == [False, True, True]


def _chi2(flight, sim):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IllConditionedWarning)  # near-dependencies of platform36: reported, expected
        # a lateral scale factor this flight does not determine (Ka1z -104 +- 94 mg/g, declared 0.5) may land beyond
        # the 100 mg/g a linear model describes: withheld from the table, said; the fit's estimate is kept
        warnings.simplefilter("ignore", casep.exceptions.MagnitudeWarning)
        res = casep.separate(flight, sim.model)
    e = res.estimate - sim.truth  # natural units
    return float(e @ np.linalg.solve(res.covariance, e))


def test_separate_on_a_range_file_agrees_with_the_truth(tmp_path):
    """Five seeds of paper-range-gm at 10 Hz (Gauss-Markov noise tau 1 s, noise model 'auto'), each through
    the CSV file: the estimate minus the truth, weighted by the full covariance, sums to chi-square with
    5 x 36 dof (bound: its 0.999 quantile, 240). The flight without its untracked rows (starting at 8 s,
    trapezoid across the dropouts) fails that bound several times over: the test can tell them apart."""
    total, dropped = 0.0, 0.0
    for seed in range(1, 6):
        sim = simulate_flight("paper-range-gm", seed=seed, rate=10.0)
        path, _ = write_simulation(sim, tmp_path / f"s{seed}.csv")
        total += _chi2(casep.read_flight(path), sim)
        fl, k = sim.flight, sim.flight.observed
        if seed <= 2:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # the gaps warning of the flight checks
                dropped += _chi2(casep.FlightData(fl.t[k], fl.f[k], fl.dv[k]), sim)
    bound = chi2.ppf(0.999, 5 * 36)
    assert chi2.ppf(0.001, 5 * 36) < total < bound
    assert dropped > bound


def test_cli_simulate_then_separate_describes_the_gaps(tmp_path, capsys):
    """`casep simulate --scenario paper-range` then `casep separate`: the rows from lift-off are read, the two
    dropouts are printed as tracking gaps, and no warning of a gap integrated by the trapezoid rule is left."""
    import json

    from casep.cli import main

    out = tmp_path / "f.csv"
    assert main(["simulate", "--scenario", "paper-range", "--rate", "10", "--seed", "2", "-o", str(out)]) == 0
    assert main(["separate", str(out), "--json", str(tmp_path / "r.json")]) == 0
    text = capsys.readouterr()
    printed = text.out + text.err
    assert "tracking gaps: 2 longer than 3 sample periods: 6.1 s before line" in printed
    assert "(t = 101 s), 1.6 s before line" in printed and "(t = 141.5 s)" in printed
    assert "trapezoid" not in printed and "start after lift-off" not in printed
    res = json.loads((tmp_path / "r.json").read_text())
    assert res["n_samples"] == 1951 - 155  # the tracked rows; 155 rows without tracking (0-8, 95-101, 140-141.5 s)
    assert res["provenance"]["flights"][0]["exclusions"] == {"unobserved": 155}
