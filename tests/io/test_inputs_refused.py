"""Inputs that casep refuses, each with exit 2 and a message naming what it refuses and why.

A failed result is no input of `impact` (as of `fuse` and `--prior`: one rule,
:func:`casep.estimators.reading.check_usable`); a result estimated on another flight (its provenance
records the SHA-256 of its data files) is no input of `impact` for this flight; a result without a
covariance gives no miss std; a flight file with NUL bytes; `montecarlo --runs 0`; a prior entry
without `std`; a model file that hangs is named on stderr before it runs.
"""

from __future__ import annotations

import json

import pytest
from test_files_run_no_code import _run

from casep.cli import main


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Two 5 Hz paper flights and `casep separate --json` of the first (with its provenance)."""
    from casep.simulation.simulate import simulate_flight, write_simulation

    d = tmp_path_factory.mktemp("refused")
    write_simulation(simulate_flight("paper", seed=3, rate=5.0), d / "a.csv")
    write_simulation(simulate_flight("paper", seed=4, rate=5.0), d / "b.csv")
    assert main(["separate", str(d / "a.csv"), "--json", str(d / "a.json"), "--noise", "white",
                 "--robust", "none"]) == 0
    return d


def _edited(files, name: str, **change) -> str:
    d = json.loads((files / "a.json").read_text())
    for k, v in change.items():
        if v is None:
            d.pop(k, None)
        else:
            d[k] = v
    (files / name).write_text(json.dumps(d))
    return str(files / name)


# ----------------------------------------------------------------------------- usable results
@pytest.mark.parametrize("command", ["impact", "fuse", "prior"])
def test_a_failed_result_is_no_input(files, capsys, command):
    bad = _edited(files, "failed.json", success=False, status=-1, message="Gauss-Newton did not converge")
    argv = {"impact": ["impact", files / "a.csv", "--result", bad],
            "fuse": ["fuse", bad, files / "a.json"],
            "prior": ["separate", files / "b.csv", "--method", "map", "--prior", bad]}[command]
    s, out, err = _run(capsys, *argv)
    assert s == 2 and out == "", (out, err)
    assert "failed.json: a failed result (status -1: Gauss-Newton did not converge)" in err
    assert "not usable as an input" in err


def test_impact_refuses_a_result_of_another_flight_naming_both(files, capsys):
    import hashlib

    s, out, err = _run(capsys, "impact", files / "b.csv", "--result", files / "a.json")
    assert s == 2 and out == "", err
    sha = {n: hashlib.sha256((files / n).read_bytes()).hexdigest() for n in ("a.csv", "b.csv")}
    assert "estimated on other data" in err and str(files / "b.csv") in err and str(files / "a.csv") in err, err
    assert sha["a.csv"] in err and sha["b.csv"] in err
    s, out, err = _run(capsys, "impact", files / "a.csv", "--result", files / "a.json")  # its own flight: fine
    assert s == 0 and "predicted miss" in out, err


def test_impact_given_a_result_as_its_flight_says_so_with_the_usage(files, capsys):
    """`casep impact a.json`: the file is a result, and the command to give names its flight (from its provenance)."""
    s, out, err = _run(capsys, "impact", files / "a.json")
    assert s == 2 and out == "", err
    assert f"{files / 'a.json'} is a result JSON, not a flight file" in err, err
    assert f"Use: casep impact {files / 'a.csv'} --result {files / 'a.json'}" in err, err


def test_impact_warns_when_the_flight_is_read_from_no_file(files):
    import casep
    from casep.exceptions import CasepWarning

    fl = casep.read_flight(files / "a.csv")
    mem = casep.FlightData(fl.t, fl.f, fl.dv, signals=fl.signals, source="<memory>")
    with pytest.warns(CasepWarning, match="cannot check that it is that flight"):
        casep.impact_analysis(mem, files / "a.json")


@pytest.mark.parametrize("std", [True, False])
def test_impact_refuses_a_result_without_covariance(files, capsys, std):
    d = json.loads((files / "a.json").read_text())
    d.pop("covariance")
    if not std:
        d = {"model": d["model"], "coefficients": [{**c, "std": None} for c in d["coefficients"]]}
    (files / "nocov.json").write_text(json.dumps(d))
    s, out, err = _run(capsys, "impact", files / "a.csv", "--result", files / "nocov.json")
    assert s == 2 and out == "", err
    assert "nocov.json has no `covariance`" in err and "G Cov G^T" in err


# ----------------------------------------------------------------------------- audit cases
@pytest.mark.parametrize("where", ["inside", "end of line", "tail"])
def test_a_flight_file_with_nul_bytes_is_refused_naming_file_and_row(files, tmp_path, capsys, where):
    lines = (files / "a.csv").read_bytes().split(b"\n")
    first = next(k for k, ln in enumerate(lines) if ln and not ln.startswith(b"#")) + 1  # first data line (0-based)
    k = first + 9  # data row 10
    if where == "inside":
        lines[k] = lines[k][:4] + b"\0" + lines[k][4:]
    elif where == "end of line":
        lines[k] += b"\0"
    p = tmp_path / "nul.csv"
    data = b"\n".join(lines) + (b"\0" * 512 if where == "tail" else b"")
    p.write_bytes(data)
    s, out, err = _run(capsys, "separate", p)
    assert s == 2 and out == "", err
    assert f"{p}:" in err and "NUL byte" in err, err
    if where != "tail":
        assert f"row 10 (line {k + 1})" in err, err
    else:
        line = data[: data.index(b"\0")].count(b"\n") + 1
        assert f"line {line})" in err, err


def test_montecarlo_runs_0_names_the_option_and_the_rule(capsys):
    with pytest.raises(SystemExit) as e:
        main(["montecarlo", "--runs", "0"])
    assert e.value.code == 2
    assert "option --runs (`runs`) must be >= 1, got 0" in capsys.readouterr().err


def test_a_prior_entry_without_std_names_the_entry_and_the_field(files, tmp_path, capsys):
    p = tmp_path / "p.json"
    p.write_text(json.dumps({"Kg0x": {"mean": 0.1}}))
    s, out, err = _run(capsys, "separate", files / "a.csv", "--method", "map", "--prior", p)
    assert s == 2 and out == "", err
    assert f"--prior {p}: entry `Kg0x`: missing field `std` (found: mean)" in err
    p.write_text(json.dumps([{"Kg0x": {"mean": 0.1, "std": 1}}]))
    s, _, err = _run(capsys, "separate", files / "a.csv", "--method", "map", "--prior", p)
    assert s == 2 and "must hold a JSON object keyed by coefficient name" in err and "got an array" in err


@pytest.mark.parametrize("field", ["unit", "sigma"])
def test_a_prior_entry_with_an_unknown_field_is_refused(files, tmp_path, capsys, field):
    """Before: `unit` or `sigma` in an entry were ignored (the value taken in deg/h whatever the unit said)."""
    p = tmp_path / "p.json"
    p.write_text(json.dumps({"Kg0x": {"mean": 0.0, "std": 1.0, field: "rad/s" if field == "unit" else 2.0}}))
    s, out, err = _run(capsys, "separate", files / "a.csv", "--method", "map", "--prior", p)
    assert s == 2 and out == "", err
    assert f"--prior {p}: entry `Kg0x`: unknown field(s) `{field}`" in err and "natural unit" in err


def test_a_prior_estimated_on_the_same_flight_is_refused(files, capsys):
    """Before: exit 0, every std sqrt 2 too small (the flight counted twice); fuse refused the same pair."""
    import hashlib

    s, out, err = _run(capsys, "separate", files / "a.csv", "--method", "map", "--prior", files / "a.json")
    assert s == 2 and out == "", err
    digest = hashlib.sha256((files / "a.csv").read_bytes()).hexdigest()
    assert "was estimated on this flight's own data" in err and digest in err and "sqrt 2" in err
    s, _, err = _run(capsys, "separate", files / "b.csv", "--method", "map", "--prior", files / "a.json")
    assert s == 0, err  # another flight's result is a prior


def test_a_model_file_is_named_on_stderr_before_it_runs(files, tmp_path, capsys, monkeypatch):
    m = tmp_path / "hangs.py"
    m.write_text("import casep\n\n\ndef build():\n    while True:\n        pass\n")
    monkeypatch.setenv("CASEP_MODEL_TIMEOUT", "0.3")
    s, _, err = _run(capsys, "separate", files / "a.csv", "--model", m)
    assert s == 2
    first, second = err.splitlines()[:2]
    assert first == f"casep: running model file {m}"
    assert "still running after 0.3 s" in second
