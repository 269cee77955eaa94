"""The command line (casep.cli): output, JSON and exit status 2 on bad input."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import casep
from casep.cli import main
from casep.synthetic import excitation_force, inject_errors

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "data" / "example_flight.csv"
HEADER = "t,f_x,f_y,f_z,dv_x,dv_y,dv_z"


@pytest.fixture(scope="module")
def good_csv(tmp_path_factory, platform36, truth36):
    t = np.arange(0.0, 120.0, 0.1)
    f = excitation_force(t, duration=120.0)
    dv = inject_errors(platform36, t, f, truth36)
    p = tmp_path_factory.mktemp("cli") / "clean.csv"
    casep.write_flight(casep.FlightData(t, f, dv), p)
    return p


def test_separate_writes_spec_json(good_csv, tmp_path, capsys, truth36):
    out = tmp_path / "r.json"
    assert main(["separate", str(good_csv), "--method", "ols", "--model", "platform36", "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert "Kg0x" in text and "deg/h" in text and "condition number" in text
    data = json.loads(out.read_text())
    assert data["model"] == "platform36" and data["method"] == "ols" and data["n_samples"] == 1200
    assert data["denoise"] is None and set(data["residual_rms"]) == {"x", "y", "z"}
    names = [c["name"] for c in data["coefficients"]]
    assert names == list(casep.load_model("platform36").names)
    est = np.array([c["estimate"] for c in data["coefficients"]])
    np.testing.assert_allclose(est, truth36, rtol=1e-5)  # noise-free file, 17-digit CSV
    assert all(c["std"] is not None for c in data["coefficients"])
    assert data["diagnostics"]["condition_number_equilibrated"] > 1e3


def test_pitch_plane_json_has_null_with_reason(tmp_path, platform36, truth36):
    t = np.arange(0.0, 60.0, 0.1)
    f = excitation_force(t, duration=60.0, cross_range=False)
    p = tmp_path / "pitch.csv"
    casep.write_flight(casep.FlightData(t, f, inject_errors(platform36, t, f, truth36)), p)
    out = tmp_path / "r.json"
    assert main(["separate", str(p), "--json", str(out)]) == 0
    rows = {c["name"]: c for c in json.loads(out.read_text())["coefficients"]}
    assert rows["Kg1xz"]["estimate"] is None and rows["Kg1xz"]["std"] is None
    assert "zero column" in rows["Kg1xz"]["reason"]
    assert rows["Ka0x"]["estimate"] is not None


@pytest.mark.parametrize(
    "body, expect",
    [
        ("t,f_x,f_y,dv_x,dv_y,dv_z\n0,1,2,4,5,6\n", "column `f_z`"),
        (f"{HEADER}\n0,1,2,3,4,5,6\n1,1,2,3,4,5,x\n", "column `dv_z`, row 2 (line 3): non-numeric"),
        (f"{HEADER}\n0,1,2,3,4,5,6\n1,1,2,3,4,nan,6\n", "column `dv_y`, row 2 (line 3): NaN"),
        (f"{HEADER}\n0,1,2,3,4,5,6\n1,1,-inf,3,4,5,6\n", "column `f_y`, row 2 (line 3): infinite"),
        (f"{HEADER}\n0,1,2,3,4,5,6\n0,1,2,3,4,5,6\n", "column `t`, row 2 (line 3): time 0 s does not increase"),
        (f"{HEADER}\n" + "".join(f"{k},1,2,3,4,5,6\n" for k in range(5)), "column `t`, row 5: 5 samples are too few"),
    ],
)
def test_bad_input_exit_2_one_line_no_output(tmp_path, capsys, body, expect):
    p = tmp_path / "bad.csv"
    p.write_text(body)
    out = tmp_path / "r.json"
    assert main(["separate", str(p), "--json", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("casep: error: ") and str(p) in err
    assert expect in err
    assert not out.exists() and list(tmp_path.iterdir()) == [p]


def test_bad_usage_exit_2(capsys):
    with pytest.raises(SystemExit) as e:
        main(["separate", str(EXAMPLE), "--method", "nope"])
    assert e.value.code == 2
    assert main(["separate", str(EXAMPLE), "--model", "nope"]) == 2
    assert "unknown model `nope`" in capsys.readouterr().err


def test_console_entry_point_on_example(tmp_path):
    out = tmp_path / "r.json"
    proc = subprocess.run([sys.executable, "-m", "casep", "separate", str(EXAMPLE), "--json", str(out)],
                          capture_output=True, text=True, check=False)
    assert proc.returncode == 0, proc.stderr
    data = json.loads(out.read_text())
    assert data["n_samples"] == 1801
    # The example carries 0.1 m/s white noise: the estimated sigma and residual RMS show it.
    assert 0.09 < data["sigma"] < 0.11
    assert all(0.09 < v < 0.11 for v in data["residual_rms"].values())


def test_models_command(capsys):
    assert main(["models"]) == 0
    out = capsys.readouterr().out
    assert "platform36" in out and "39 coefficients" in out


def test_separate_two_files(tmp_path, capsys):
    from casep.simulate import simulate_two_rate

    d = simulate_two_rate("paper", seed=2, telemetry_rate=20.0, tracking_rate=5.0)
    d.write(tmp_path / "tel.csv", tmp_path / "trk.parquet")
    out = tmp_path / "r.json"
    assert main(["separate", str(tmp_path / "tel.csv"), "--tracking", str(tmp_path / "trk.parquet"),
                 "--json", str(out)]) == 0
    data = json.loads(out.read_text())
    assert data["n_samples"] == int(np.sum((d.t_tel >= d.t_trk[0]) & (d.t_tel <= d.t_trk[-1])))


@pytest.mark.parametrize("method, extra", [
    ("rls", ["--p0", "1e6", "--weight", "1", "--forgetting", "1"]),
    ("rels", ["--noise-order", "2"]),
    ("ridge", ["--lambda", "gcv"]),
    ("ridge", ["--lambda", "1e-3"]),
    ("pcr", ["--components", "20"]),
])
def test_every_method_writes_json(good_csv, tmp_path, method, extra):
    out = tmp_path / "r.json"
    assert main(["separate", str(good_csv), "--method", method, "--json", str(out), *extra]) == 0
    data = json.loads(out.read_text())
    assert data["method"] == method and len(data["coefficients"]) == 36


def test_bounded_and_map_from_files(good_csv, tmp_path, truth36):
    names = casep.load_model("platform36").names
    bfile, pfile = tmp_path / "b.json", tmp_path / "p.json"
    bfile.write_text(json.dumps({n: [v - 1.0, v + 1.0] for n, v in zip(names, truth36)} | {"Kg0x": 0.5}))
    pfile.write_text(json.dumps({n: {"mean": v, "std": 0.1 * abs(v)} for n, v in zip(names, truth36)}))
    out = tmp_path / "r.json"
    assert main(["separate", str(good_csv), "--method", "bounded", "--bounds", str(bfile), "--json", str(out)]) == 0
    rows = {c["name"]: c for c in json.loads(out.read_text())["coefficients"]}
    assert rows["Kg0x"]["estimate"] == 0.5 and rows["Kg0x"]["std"] is None
    assert main(["separate", str(good_csv), "--method", "map", "--prior", str(pfile), "--json", str(out)]) == 0
    data = json.loads(out.read_text())
    est = np.array([c["estimate"] for c in data["coefficients"]])
    np.testing.assert_allclose(est, truth36, rtol=1e-4)  # noise-free data, prior centred on the truth


@pytest.mark.parametrize("content, args, expect", [
    ('{"Kzz": [0, 1]}', ["--method", "bounded", "--bounds"], "unknown coefficient `Kzz`"),
    ('{"Kg0x": [2, 1]}', ["--method", "bounded", "--bounds"], "`Kg0x` has lo > hi"),
    ('{"Kg0x": {"mean": 0, "std": -1}}', ["--method", "map", "--prior"], "`Kg0x` std must be > 0"),
    ('{"Kg0x": ', ["--method", "map", "--prior"], "not valid JSON"),
    ('[1, 2]', ["--method", "map", "--prior"], "must hold a JSON object"),
])
def test_bad_option_files_exit_2(good_csv, tmp_path, capsys, content, args, expect):
    f = tmp_path / "opt.json"
    f.write_text(content)
    out = tmp_path / "r.json"
    assert main(["separate", str(good_csv), *args, str(f), "--json", str(out)]) == 2
    err = capsys.readouterr().err
    assert expect in err and str(f) in err and err.count("\n") == 1
    assert not out.exists()


@pytest.mark.parametrize("args, expect", [
    (["--method", "rls", "--forgetting", "1.5"], "must be in (0, 1]"),
    (["--method", "rls", "--p0", "-1"], "must be finite and > 0"),
    (["--method", "ridge", "--lambda", "aic"], "not a number"),
    (["--method", "rels", "--noise-order", "-2"], "must be >= 0"),
])
def test_bad_option_values_exit_2(good_csv, capsys, args, expect):
    with pytest.raises(SystemExit) as e:
        main(["separate", str(good_csv), *args])
    assert e.value.code == 2 and expect in capsys.readouterr().err


def test_missing_required_option_files(good_csv, capsys):
    assert main(["separate", str(good_csv), "--method", "bounded"]) == 2
    assert "`bounds` is required" in capsys.readouterr().err
    assert main(["separate", str(good_csv), "--method", "rels", "--noise-order", "0"]) == 2
    assert "--noise-order must be >= 1 for rels" in capsys.readouterr().err
