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
from casep.estimators.registry import OPTIONS, Interval
from casep.simulation.synthetic import excitation_force, inject_errors

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "data" / "example_flight.csv"
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
    from casep.simulation.simulate import simulate_two_rate

    d = simulate_two_rate("paper", seed=2, telemetry_rate=20.0, tracking_rate=5.0)
    d.write(tmp_path / "tel.csv", tmp_path / "trk.parquet")
    out = tmp_path / "r.json"
    assert main(["separate", str(tmp_path / "tel.csv"), "--tracking", str(tmp_path / "trk.parquet"),
                 "--json", str(out)]) == 0
    data = json.loads(out.read_text())
    assert data["n_samples"] == d.t_trk.size  # one row per tracking sample (the default tracking grid)
    assert main(["separate", str(tmp_path / "tel.csv"), "--tracking", str(tmp_path / "trk.parquet"),
                 "--grid", "telemetry", "--json", str(out)]) == 0
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
    """Every method writes its JSON. `good_csv` is noise-free: RLS and RELS fail there by the prior-data conflict test
    (their prior N(0, sigma^2 p0) shrinks with sigma estimated from residuals the prior biases: Ka0x 9 std off), an
    exit 1 whose result file still records what was found."""
    out = tmp_path / "r.json"
    code = main(["separate", str(good_csv), "--method", method, "--json", str(out), *extra])
    assert code == (1 if method in ("rls", "rels") else 0)
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


def _one_form(expect: str) -> str:
    """``argument --lambda: must be ...`` in the one form of a refused option: ``option --lambda (`lam`) must ...``."""
    flag, rest = expect.removeprefix("argument ").split(": ", 1)
    name = next(o.name for o in OPTIONS.values() if o.flag == flag)
    return f"error: option {flag} (`{name}`) {rest}"


@pytest.mark.parametrize("args, expect", [  # the argparse type is the registry's rule (Option.parse)
    (["--method", "rls", "--forgetting", "1.5"], "argument --forgetting: must be float in [0.5, 1], got '1.5'"),
    (["--method", "rls", "--p0", "-1"], "argument --p0: must be float in (0, 1e+30], got '-1'"),
    (["--method", "ridge", "--lambda", "aic"], "argument --lambda: must be gcv | lcurve | float > 0, got 'aic'"),
    (["--method", "rels", "--noise-order", "-2"], "argument --noise-order: must be int >= 1, got '-2'"),
    (["--method", "rels", "--noise-order", "1.5"], "argument --noise-order: must be int >= 1, got '1.5'"),
    (["--method", "pcr", "--components", "0"], "argument --components: must be int >= 1, got '0'"),
    (["--method", "gls", "--tau", "soon"], "argument --tau: must be auto | float in (0, 10000] s, got 'soon'"),
])
def test_bad_option_values_exit_2(good_csv, capsys, args, expect):
    with pytest.raises(SystemExit) as e:
        main(["separate", str(good_csv), *args])
    assert e.value.code == 2 and _one_form(expect) in capsys.readouterr().err


def test_missing_required_option_files(good_csv, capsys):
    assert main(["separate", str(good_csv), "--method", "bounded"]) == 2
    assert "option --bounds (`bounds`) is required" in capsys.readouterr().err
    with pytest.raises(SystemExit) as e:  # refused by the registry's rule as the argparse type
        main(["separate", str(good_csv), "--method", "rels", "--noise-order", "0"])
    assert e.value.code == 2
    assert "error: option --noise-order (`noise_order`) must be int >= 1, got '0'" in capsys.readouterr().err


# --- option values are finite and in a plausible range -----------------------

_RANGE_CASES = [  # (option, value, command, extra args)
    ("sigma", "1e300", "separate", []),
    ("sigma", "2000", "separate", []),
    ("sigma", "inf", "separate", []),
    ("sigma", "nan", "separate", []),
    ("sigma", "1e300", "diagnose", []),
    ("tau", "1e300", "separate", ["--method", "gls"]),
    ("tau", "2e4", "diagnose", []),
    ("weight", "1e300", "separate", ["--method", "rls"]),
    ("weight", "1e-13", "separate", ["--method", "rls"]),
    ("weight", "inf", "separate", ["--method", "rls"]),
    ("p0", "1e50", "separate", ["--method", "rls"]),
    ("p0", "1e31", "separate", ["--method", "rels"]),
    ("p0", "inf", "separate", ["--method", "rls"]),
    ("p0", "0", "separate", ["--method", "rls"]),
]


@pytest.mark.parametrize("option, value, command, extra", _RANGE_CASES)
def test_out_of_range_option_exit_2_one_line(good_csv, capsys, option, value, command, extra):
    with pytest.raises(SystemExit) as e:
        main([command, str(good_csv), *extra, f"--{option}", value])
    err = capsys.readouterr().err
    assert e.value.code == 2 and err.count("\n") == 1
    if option == "sigma":  # a common option: the solvers' check and message
        assert f"error: option --{option} (`{option}`) must be" in err
    else:  # a method option: the registry's rule (diagnose --tau: its number rule only)
        rule = " | ".join(str(r) for r in OPTIONS[option].rules if command == "separate" or isinstance(r, Interval))
        assert f"error: option --{option} (`{option}`) must be {rule}, got '{value}'" in err


@pytest.mark.parametrize("option, value", sorted({(o, v) for o, v, _, _ in _RANGE_CASES if o != "tau"}))
def test_out_of_range_option_api_same_message(paper_problem, platform36, capsys, good_csv, option, value):
    """The solvers and the CLI refuse the same values: sigma with the same message (one check),
    the registry's options (p0, weight) by its rule, whose interval is the solvers' range
    (test_registry_rules_are_the_solvers_ranges)."""
    S, y, _ = paper_problem
    kw = {"p0": 1.0} if option == "p0" else {}  # the others need a valid p0 of their own: default
    with pytest.raises(ValueError) as e:
        casep.solve_rls(S, y, **{**kw, option: float(value)}, names=platform36.names)
    api = str(e.value)
    assert api.startswith(f"option --{option} (`{option}`) must be")
    with pytest.raises(SystemExit):
        main(["separate", str(good_csv), "--method", "rls", f"--{option}", value])
    err = capsys.readouterr().err
    assert (api if option == "sigma" else f"must be {OPTIONS[option].rule}, got '{value}'") in err


@pytest.mark.parametrize("option", ["p0", "weight", "tau", "forgetting"])
def test_registry_rules_are_the_solvers_ranges(option):
    """One range per option: the registry's Interval (CLI) is the range the solvers check."""
    from casep.estimators.registry import option_ranges

    OPTION_RANGES = option_ranges()

    lo, hi, low_inclusive, _ = OPTION_RANGES[option]
    (rule,) = [r for r in OPTIONS[option].rules if isinstance(r, Interval)]
    assert (rule.low, rule.high) == (lo, hi)
    assert rule.closed == ("both" if low_inclusive else "right")


@pytest.mark.parametrize("value", ["1e12", "1e300", "0", "-1"])
def test_gls_tau_range_api_same_message(paper_problem, platform36, capsys, good_csv, value):
    """solve_gls(tau=...) shares the range table with `--tau` (1e12 gave sigma ~2e5, 1e300 a
    misleading "`y` is not finite")."""
    S, y, _ = paper_problem
    t = np.arange(S.shape[0]) * 0.05
    with pytest.raises(ValueError) as e:
        casep.solve_gls(S, y, t, tau=float(value), names=platform36.names)
    with pytest.raises(SystemExit):
        main(["separate", str(good_csv), "--method", "gls", "--tau", value])
    assert str(e.value).startswith("option --tau (`tau`) must be")  # see test_registry_rules_are_the_solvers_ranges
    assert f"error: option --tau (`tau`) must be {OPTIONS['tau'].rule}, got '{value}'" in capsys.readouterr().err


@pytest.mark.parametrize("option, value", [("sigma", 1e3), ("weight", 1e-12), ("weight", 1e12), ("p0", 1e30)])
def test_option_range_ends_are_accepted(paper_problem, platform36, option, value):
    S, y, truth = paper_problem
    res = casep.solve_rls(S, y, **{option: value}, names=platform36.names)
    assert np.all(np.isfinite(res.estimate))


def test_p0_at_its_bound_is_still_least_squares(paper_problem, platform36):
    """p0 = 1e30 (the upper end) must still agree with OLS: the bound sits below where RLS breaks."""
    S, y, _ = paper_problem
    ols = casep.solve_ols(S, y, names=platform36.names)
    rls = casep.solve_rls(S, y, p0=1e30, names=platform36.names)
    assert np.max(np.abs(rls.estimate - ols.estimate) / ols.std) < 1e-3
    np.testing.assert_allclose(rls.std, ols.std, rtol=1e-6)


_BOUNDED = ("separate", "--method", "bounded", "--bounds")
_SCALES = ("diagnose", "--scales")
_MAP = ("separate", "--method", "map", "--prior")


@pytest.mark.parametrize("command, content, expect", [
    (_BOUNDED, '{"Kg0x": Infinity}', "`Kg0x` fixed value must be finite, got inf"),
    (_BOUNDED, '{"Kg0x": [Infinity, null]}', "`Kg0x` lower bound inf leaves no finite value"),
    (_BOUNDED, '{"Kg0x": [null, -Infinity]}', "`Kg0x` upper bound -inf leaves no finite value"),
    (_BOUNDED, '{"Kg0x": [NaN, 1]}', "`Kg0x` has a NaN bound"),
    (_BOUNDED, '{"KaOy": [0, 1]}', "unknown coefficient `KaOy` (did you mean `Ka0y`?)"),
    (_SCALES, '{"Kg0x": Infinity}', "`Kg0x` must be a finite number > 0, got inf"),
    (_SCALES, '{"Kg0x": NaN}', "`Kg0x` must be a finite number > 0, got nan"),
    (_SCALES, '{"Kg0x": 0}', "`Kg0x` must be a finite number > 0, got 0"),
    (_SCALES, '{"KaOy": 1}', "unknown coefficient `KaOy` (did you mean `Ka0y`?)"),
    (_MAP, '{"KaOy": {"mean": 0, "std": 1}}', "unknown coefficient `KaOy` (did you mean `Ka0y`?)"),
    (_MAP, '{"Kg0x": {"mean": Infinity, "std": 1}}', "`Kg0x` mean must be finite"),
    (_MAP, '{"Kg0x": {"mean": 0, "std": NaN}}', "`Kg0x` std must be > 0"),
])
def test_bad_coefficient_file_values_exit_2(good_csv, tmp_path, capsys, command, content, expect):
    """--bounds, --scales and --prior: non-finite values and misspelt names, one line, exit 2."""
    f = tmp_path / "values.json"
    f.write_text(content)
    cmd, *opts = command
    assert main([cmd, str(good_csv), *opts, str(f)]) == 2
    err = capsys.readouterr().err
    assert expect in err and f"{opts[-1]} {f}" in err and err.count("\n") == 1


def test_infinite_bound_on_its_own_side_is_open(platform36):
    lo, hi, fixed = casep.estimators.bounded.parse_bounds({"Kg0x": [-np.inf, np.inf], "Kg0y": [None, 2.0]},
                                                          platform36.names)
    j, k = platform36.index("Kg0x"), platform36.index("Kg0y")
    assert lo[j] == -np.inf and hi[j] == np.inf and lo[k] == -np.inf and hi[k] == 2.0 and not fixed.any()


# --- model files -----------------------------------------------------

def test_broken_model_file_exit_2_one_line(good_csv, tmp_path, capsys):
    path = tmp_path / "x.py"
    path.write_text("import casep\n\ndef build():\n    m = casep.build_model('platform36')\n    return ca.vertcat(1)\n")
    assert main(["separate", str(good_csv), "--model", str(path)]) == 2
    err = capsys.readouterr().err  # the file named before it runs, then the error in one line
    assert err == (f"casep: running model file {path}\n"
                   f"casep: error: model file {path}, line 5, in build(): NameError: name 'ca' is not defined\n")


def test_sys_exit_in_build_is_an_error_not_success(good_csv, tmp_path, capsys):
    path = tmp_path / "quits.py"
    path.write_text("import sys\n\ndef build():\n    sys.exit(0)\n")
    out = tmp_path / "r.json"
    assert main(["separate", str(good_csv), "--model", str(path), "--json", str(out)]) == 2
    assert f"model file {path}, line 4, in build(): SystemExit(0)" in capsys.readouterr().err
    assert not out.exists()


def test_models_lists_the_others_and_reports_the_broken_one(tmp_path, monkeypatch, capsys):
    (tmp_path / "aaa_broken.py").write_text("def build(:\n")
    (tmp_path / "mine.py").write_text("import casep\n\ndef build():\n    m = casep.build_model('platform36')\n"
                                      "    m.name = 'mine'\n    return m\n")
    monkeypatch.setenv("CASEP_MODEL_PATH", str(tmp_path))
    assert main(["models"]) == 0
    out, err = capsys.readouterr()
    assert "platform36" in out and "platform39_misalignment" in out and "mine " in out
    assert (f"warning: model `aaa_broken` not listed: model file {tmp_path / 'aaa_broken.py'}, line 1: "
            "SyntaxError:") in err and "warning:" not in out  # the list on stdout, clean; the warnings on stderr


def test_models_exit_2_when_none_loads(tmp_path, monkeypatch, capsys):
    (tmp_path / "bad.py").write_text("raise ImportError('gone')\n")
    monkeypatch.setenv("CASEP_MODEL_PATH", str(tmp_path))
    monkeypatch.setattr("casep.model.loader.available_models", lambda: ["bad"])  # the CLI imports it lazily
    assert main(["models"]) == 2
    cap = capsys.readouterr()
    assert "none of the 1 model files loads" in cap.err
    assert "model file" in cap.err and "line 1: ImportError: gone" in cap.err


# --- a reader that closes early ends casep quietly --------------------------

def test_broken_pipe_is_quiet():
    """`casep models -v | head -0`: the read end is closed before casep writes a byte."""
    proc = subprocess.Popen([sys.executable, "-m", "casep", "models", "-v"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)
    proc.stdout.close()
    err = proc.stderr.read()
    proc.stderr.close()
    assert proc.wait(timeout=120) == 141  # 128 + SIGPIPE, as the shell reports for any Unix tool
    assert err == b""


# --- the CLI reads the registry, imports lazily ------------------------------------------

def test_separate_help_has_one_group_per_method_set_from_the_registry(capsys):
    """Every registry option is in `separate --help`, once, in the group of the methods that take
    it (shared RLS/RELS options in "rls / rels options"), with its rule and default."""
    from casep.estimators.registry import METHODS

    with pytest.raises(SystemExit) as e:
        main(["separate", "--help"])
    assert e.value.code == 0
    out = capsys.readouterr().out
    for name, opt in OPTIONS.items():
        takers = " / ".join(m for m, meth in METHODS.items() if name in meth.options)
        group = out[out.index(f"\n{takers} options:\n"):]
        group = group[: group.find("\n\n") if "\n\n" in group else None]
        assert f"  {opt.flag} " in group, (name, takers)
        assert out.count(f"  {opt.flag} ") == 1
    flat = " ".join(out.split())  # help lines are wrapped
    assert "rls / rels options:" in out and "float in [0.5, 1] (default 1)" in flat
    assert ("--bounds FILE box bounds and fixed values; JSON file {name: [lo, hi] | value} "
            "(needed by --method bounded)") in flat


def test_montecarlo_takes_prior_and_bounds_from_the_registry(capsys):
    with pytest.raises(SystemExit):
        main(["montecarlo", "--help"])
    flat = " ".join(capsys.readouterr().out.split())
    assert f"--prior FILE {OPTIONS['prior'].help}; {OPTIONS['prior'].rule} (default: the demo" in flat
    assert f"--bounds FILE {OPTIONS['bounds'].help}; {OPTIONS['bounds'].rule} (default: the demo" in flat


def test_cli_imports_lazily():
    """`import casep.cli` (what `casep --help` costs) loads neither CasADi, numba, SciPy, pandas,
    matplotlib, PyWavelets, cvxpy nor a workflow; a command imports them when it runs. (The
    estimator modules are imported by the registry, which builds the method options of the
    parser: they import numpy only.)"""
    code = ("import sys, casep.cli; heavy = ('casadi', 'numba', 'scipy', 'pandas', 'matplotlib', 'pywt', "
            "'cvxpy', 'casep.workflows.separate', 'casep.model.sv'); "
            "print(','.join(m for m in heavy if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == ""


@pytest.mark.parametrize("package", ["casep", "casep.io", "casep.estimators", "casep.regression", "casep.noise",
                                     "casep.checks", "casep.model", "casep.simulation", "casep.radar"])
def test_lazy_public_names_resolve(package):
    """Every name in a lazily resolved package's __all__ is importable (the tables of casep._lazy)."""
    import importlib

    mod = importlib.import_module(package)
    for name in mod.__all__:
        assert getattr(mod, name) is not None, name
    assert set(mod.__all__) <= set(dir(mod))
    with pytest.raises(AttributeError, match="no attribute 'not_a_name'"):
        _ = mod.not_a_name


def test_parser_and_command_refusals_have_one_form(capsys):
    """A refusal of the command's parser (a bad option value) and of the command (a missing file) both read
    ``casep: error: ...``, one line, exit 2."""
    from casep.cli.app import main

    with pytest.raises(SystemExit) as e:
        main(["separate", "missing.csv", "--tau", "-2"])
    parser = capsys.readouterr().err
    assert e.value.code == 2 and parser.startswith("casep: error: ") and parser.count("\n") == 1, parser
    assert main(["separate", "missing.csv"]) == 2
    command = capsys.readouterr().err
    assert command.startswith("casep: error: ") and command.count("\n") == 1, command


def test_separate_on_the_example_flight_does_not_import_scipy():
    """`casep separate` on the example flight runs on NumPy, CasADi and pandas: SciPy's import (about 0.15 s, a
    sixth of the command) is paid only by the paths that need it (the burnout-step median was one)."""
    flight = Path(__file__).resolve().parents[2] / "examples" / "data" / "example_flight.csv"
    code = ("import sys, io, contextlib; from casep.cli import main\n"
            "with contextlib.redirect_stdout(io.StringIO()): status = main(['separate', sys.argv[1]])\n"
            "print(status, 'scipy' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code, str(flight)], capture_output=True, text=True, check=True).stdout
    assert out.split()[-2:] == ["0", "False"], out
