"""Result files from other tools, fuse consistency, CSV separators, impact on two-file and Earth-fixed
flights, and the edges of the audit (bad inputs refused with the culprit named, never a traceback)."""

from __future__ import annotations

import copy
import json
import sys

import numpy as np
import pytest

from casep.cli import main

SITE = ["28.5", "-80.6", "10", "90"]


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Two 10 Hz paper flights, their OLS result JSONs, a pitch-plane flight and an Earth-fixed pair."""
    d = tmp_path_factory.mktemp("rangeio")
    for name, seed in (("a", 1), ("b", 2)):
        assert main(["simulate", "--rate", "10", "--seed", str(seed), "-o", str(d / f"{name}.csv")]) == 0
        assert main(["separate", str(d / f"{name}.csv"), "--json", str(d / f"r{name}.json")]) == 0
    return d


def _load(p):
    return json.loads(p.read_text())


def _documented(res: dict) -> dict:
    """The documented form, as another tool would write it: model, coefficients list, covariance."""
    return {"model": res["model"],
            "coefficients": [{k: c[k] for k in ("name", "unit", "estimate", "std")} for c in res["coefficients"]],
            "covariance": res["covariance"]}


def _flat(res: dict) -> dict:
    """MATLAB-style flat arrays (jsonencode of a struct) with a `model` key."""
    return {"model": res["model"], "names": res["names"], "units": res["units"], "estimates": res["estimates"],
            "std": res["std"], "covariance": res["covariance"]}


def _write(path, data) -> str:
    path.write_text(json.dumps(data) if not isinstance(data, str) else data)
    return str(path)


def _run(capsys, *args) -> tuple[int, str, str]:
    status = main([str(a) for a in args])
    out = capsys.readouterr()
    return status, out.out, out.err


# --------------------------------------------------------------------------- the forms of a result file
def test_documented_form_as_prior_in_fuse_and_impact(files, tmp_path, capsys):
    """The documented form (hand-written by another tool) works as --prior, in fuse and in impact, and gives
    exactly what casep's own JSON gives."""
    doc = _write(tmp_path / "doc.json", _documented(_load(files / "ra.json")))
    outs = {}
    for name, prior in (("doc", doc), ("own", files / "ra.json")):
        s, _, err = _run(capsys, "separate", files / "b.csv", "--method", "map", "--prior", prior,
                         "--json", tmp_path / f"map_{name}.json")
        assert s == 0, err
        outs[name] = _load(tmp_path / f"map_{name}.json")["estimates"]
    assert outs["doc"] == outs["own"]
    s, out, err = _run(capsys, "fuse", doc, files / "rb.json")
    assert s == 0, err
    assert "2 results fused" in out
    s, out, err = _run(capsys, "impact", files / "a.csv", "--result", doc)
    assert s == 0, err
    assert "predicted miss" in out


def test_model_coefficients_covariance_without_method(files, tmp_path, capsys):
    """{model, coefficients, covariance} (no method, sigma, rank, ...) is read: was KeyError 'method'."""
    from casep.estimators.result import EstimateResult

    res = EstimateResult.from_json(_documented(_load(files / "ra.json")))
    own = EstimateResult.from_json(files / "ra.json")
    assert res.method == "external" and res.model == "platform36"
    np.testing.assert_array_equal(res.estimate, own.estimate)
    np.testing.assert_allclose(res.covariance, own.covariance, rtol=0, atol=0)


def test_flat_matlab_form_with_model_key_as_prior(files, tmp_path, capsys):
    """Flat arrays with a `model` key: was "unknown coefficient `model`"."""
    flat = _write(tmp_path / "flat.json", _flat(_load(files / "ra.json")))
    s, _, err = _run(capsys, "separate", files / "b.csv", "--method", "map", "--prior", flat)
    assert s == 0, err


def test_matlab_one_element_arrays_are_bare_values(tmp_path):
    from casep.io.result_json import parse_result_data

    rd = parse_result_data({"names": "Kg0x", "units": "deg/h", "estimates": 0.5, "std": 0.1, "covariance": 0.01})
    assert rd.names == ("Kg0x",) and rd.covariance.shape == (1, 1)


@pytest.mark.parametrize("edit, expect", [
    (lambda d: d["coefficients"][3].pop("std"), "missing field `coefficients[3].std`"),
    (lambda d: d.pop("coefficients"), "not a result: missing field `coefficients`"),
    (lambda d: d["coefficients"][2].update(estimate="0.5"),
     "`coefficients[2].estimate`: input should be a valid number"),
    (lambda d: d["coefficients"][2].update(std=True),
     "`coefficients[2].std`: input should be a valid number, got true"),
])
def test_missing_or_mistyped_field_named_with_the_file(files, tmp_path, capsys, edit, expect):
    d = _documented(_load(files / "ra.json"))
    edit(d)
    p = _write(tmp_path / "bad.json", d)
    for cmd in (["impact", files / "a.csv", "--result", p], ["fuse", p, files / "rb.json"],
                ["separate", files / "b.csv", "--method", "map", "--prior", p]):
        s, _, err = _run(capsys, *cmd)
        assert s == 2 and expect in err and "bad.json" in err, err
        assert "Traceback" not in err


def test_two_forms_disagreeing_is_an_error_naming_the_coefficient(files, tmp_path, capsys):
    """casep's JSON holds both forms: an edited `coefficients` list no longer passes silently (impact read
    the flat arrays and ignored it)."""
    d = _load(files / "ra.json")
    d["coefficients"][5]["estimate"] = 123.0
    p = _write(tmp_path / "edited.json", d)
    s, _, err = _run(capsys, "impact", files / "a.csv", "--result", p)
    assert s == 2
    assert f"the two forms disagree on `{d['names'][5]}`" in err and "estimates[5]" in err


def _cov_edit(kind):
    def edit(d):
        C = d["covariance"]
        if kind == "nan":
            C[1][2] = C[2][1] = float("nan")
        elif kind == "negative":
            C[4][4] = -abs(C[4][4])
        elif kind == "asymmetric":
            C[1][2] = C[2][1] * 1.5 + 1.0
        elif kind == "not psd":
            C[0][1] = C[1][0] = 3 * (C[0][0] * C[1][1]) ** 0.5  # correlation 3
        elif kind == "shape":
            d["covariance"] = [row[:-1] for row in C]
        elif kind == "std":
            d["coefficients"][7]["std"] *= 2
    return edit


@pytest.mark.parametrize("kind, expect", [
    ("nan", "`covariance[1][2]`"), ("negative", "`covariance[4][4]`"), ("asymmetric", "not symmetric"),
    ("not psd", "not positive semi-definite"), ("shape", "must be 36 x 36"), ("std", "std and the covariance disagree"),
])
def test_bad_covariance_refused_by_fuse_and_impact(files, tmp_path, capsys, kind, expect):
    d = _documented(_load(files / "ra.json"))
    _cov_edit(kind)(d)
    p = _write(tmp_path / "cov.json", json.dumps(d))  # NaN written as the NaN literal
    for cmd in (["impact", files / "a.csv", "--result", p], ["fuse", p, files / "rb.json"]):
        s, _, err = _run(capsys, *cmd)
        assert s == 2 and expect in err and "cov.json" in err, err


def test_singular_covariance_refused_by_fuse(files, tmp_path, capsys):
    d = _documented(_load(files / "ra.json"))
    C = np.array(d["covariance"])
    C[3, :] = C[:, 3] = 0.0  # a coefficient with zero variance: no inverse
    d["covariance"] = C.tolist()
    d["coefficients"][3]["std"] = 0.0
    p = _write(tmp_path / "sing.json", d)
    s, _, err = _run(capsys, "fuse", p, files / "rb.json")
    assert s == 2 and "singular" in err and "sing.json" in err


def test_units_must_be_the_models(files, tmp_path, capsys):
    d = _documented(_load(files / "ra.json"))
    d["coefficients"][0]["unit"] = "rad/s"
    p = _write(tmp_path / "unit.json", d)
    for cmd in (["impact", files / "a.csv", "--result", p], ["fuse", p, files / "rb.json"]):
        s, _, err = _run(capsys, *cmd)
        assert s == 2 and "`Kg0x` is in 'rad/s'" in err and "'deg/h'" in err, err


# --------------------------------------------------------------------------- strict JSON inputs
@pytest.mark.parametrize("option, text, expect", [
    ("--prior", '{"Kg0x": {"mean": 0, "std": 1}, "Kg0x": {"mean": 5, "std": 1}}', "key `Kg0x` appears twice"),
    ("--prior", "[" * 100000 + "]" * 100000, "nested too deeply"),
    ("--prior", '{"Kg0x": {"mean": 0, "std": true}}', "`Kg0x` std must be a number, got True"),
    ("--prior", '{"Kg0x": {"mean": 1e308, "std": 1}}', "`Kg0x` mean must be finite and within +-1e+30"),
    ("--bounds", '{"Kg0x": ["1", "2"]}', "`Kg0x` must be [lo, hi] with numbers or null"),
    ("--bounds", '{"Kg0x": 1e308}', "`Kg0x` lower bound 1e+308 is beyond +-1e+30"),
])
def test_strict_option_files(files, tmp_path, capsys, option, text, expect):
    p = _write(tmp_path / "opt.json", text)
    method = "map" if option == "--prior" else "bounded"
    s, _, err = _run(capsys, "separate", files / "a.csv", "--method", method, option, p)
    assert s == 2 and expect in err and "opt.json" in err, err


# --------------------------------------------------------------------------- fuse
def test_fuse_consistency_equals_the_two_result_closed_form(files, capsys):
    """K = 2: sum_k (D_k - D)^T C_k^-1 (D_k - D) = (D_1 - D_2)^T (C_1 + C_2)^-1 (D_1 - D_2)."""
    from casep.estimators.result import EstimateResult
    from casep.workflows.fusion import fuse

    a, b = (EstimateResult.from_json(files / f"r{k}.json") for k in "ab")
    res = fuse([a, b])
    d = a.estimate - b.estimate
    chi2 = float(d @ np.linalg.solve(a.covariance + b.covariance, d))
    ov = res.diagnostics["consistency"]["overall"]
    assert ov["dof"] == 36
    assert ov["chi2"] == pytest.approx(chi2, rel=1e-6)
    assert res.success and 0.01 < ov["p_value"]
    s, out, err = _run(capsys, "fuse", files / "ra.json", files / "rb.json")
    assert s == 0 and "sigma -" in out and "nan" not in out and "chi2" in out and "warning" not in out + err


def _shifted(res: dict, t: float) -> dict:
    """`res` moved along its first Cholesky direction so that fusing it with `res` gives chi2 = t^2."""
    C = np.array(res["covariance"])
    L = np.linalg.cholesky(C)
    out = copy.deepcopy(res)
    x = np.array(res["estimates"]) + np.sqrt(2.0) * t * L[:, 0]  # (2C)^-1 form: chi2 = t^2
    for c, v in zip(out["coefficients"], x):
        c["estimate"] = float(v)
    out["estimates"] = [float(v) for v in x]
    out.pop("provenance", None)  # another flight's result: not estimated from `res`'s input files
    return out


def test_fuse_warns_with_the_numbers_between_the_thresholds(files, tmp_path, capsys):
    """chi2 = 70 on 36 dof: p 6e-4, a warning naming chi2, dof and p; still a success."""
    ra = _load(files / "ra.json")
    p = _write(tmp_path / "shift.json", _shifted(ra, np.sqrt(70.0)))
    s, out, err = _run(capsys, "fuse", files / "ra.json", p)
    assert s == 0
    assert "warning: the fused results disagree: chi2 70 on 36 dof, p 0.000" in err


def test_fuse_results_1000_std_apart_is_a_failed_result(files, tmp_path, capsys):
    ra = _load(files / "ra.json")
    p = _write(tmp_path / "far.json", _shifted(ra, 1000.0))
    s, out, err = _run(capsys, "fuse", files / "ra.json", p, "--json", tmp_path / "fused.json")
    assert s == 1 and "result not successful" in err and "disagree: chi2 1e+06" in err
    assert _load(tmp_path / "fused.json")["success"] is False


@pytest.mark.parametrize("edit, expect", [
    (lambda d: d["coefficients"][0].update(estimate=1e308), "beyond the magnitude limit"),
    (lambda d: d["coefficients"][1].update(unit="mg"), "`Kg1x` is in 'mg'"),
])
def test_fuse_refuses_absurd_values_and_changed_units(files, tmp_path, capsys, edit, expect):
    d = _documented(_load(files / "rb.json"))
    edit(d)
    s, _, err = _run(capsys, "fuse", files / "ra.json", _write(tmp_path / "x.json", d))
    assert s == 2 and expect in err


def test_joint_outputs_are_dimensionless(files, capsys):
    s, out, _ = _run(capsys, "separate", files / "a.csv", files / "b.csv")
    assert s == 0
    assert "sigma 1 (whitened, dimensionless)" in out and "residual RMS (whitened, dimensionless)" in out
    assert "sigma 1 m/s" not in out


# --------------------------------------------------------------------------- edges that were tracebacks
@pytest.mark.parametrize("args, expect", [
    (["simulate", "--rate", "1e308", "-o", "x.csv"], "must be in (0, 10000] Hz"),
    (["separate", "{a}", "--method", "rels", "--forgetting", "1e-300"], "must be float in [0.5, 1]"),
    (["impact", "{a}", "--result", "{ra}", "--top", "0"], "must be >= 1"),
])
def test_edge_values_refused_at_the_edge(files, tmp_path, capsys, args, expect):
    args = [a.format(a=files / "a.csv", ra=files / "ra.json") for a in args]
    with pytest.raises(SystemExit) as e:
        main(args)
    assert e.value.code == 2 and expect in capsys.readouterr().err


def test_forgetting_range_in_the_api(files):
    import casep
    from casep.io.files import read_flight

    with pytest.raises(ValueError, match=r"forgetting.*\[0.5, 1\]"):
        casep.separate(read_flight(files / "a.csv"), "platform36", "rls", forgetting=1e-300)


def test_bounds_the_data_contradict_fail_naming_the_coefficient(files, tmp_path, capsys):
    """A box far from anything the data allow: solved exactly (the coefficient on its bound), then failed by
    the residual check, exit 1, the coefficient at its bound in the table."""
    p = _write(tmp_path / "far.json", '{"Kg0x": [1e10, 1e11]}')
    s, out, err = _run(capsys, "separate", files / "a.csv", "--method", "bounded", "--bounds", p)
    assert s == 1 and "bounds the data contradict?" in err and "Traceback" not in err
    assert any(ln.startswith("Kg0x") and "at its lower bound" in ln for ln in out.splitlines())


def test_diagnose_prints_dash_not_nan(tmp_path, capsys):
    f = tmp_path / "pitch.csv"
    assert main(["simulate", "--scenario", "paper-pitch", "--rate", "5", "-o", str(f)]) == 0
    s, out, _ = _run(capsys, "diagnose", f)
    assert s == 0 and "unidentifiable (zero column" in out and "nan" not in out


def test_non_finite_s_column_names_the_coefficient():
    import casep

    S = np.random.default_rng(0).normal(size=(50, 3))
    S[7, 2] = np.inf
    with pytest.raises(ValueError, match=r"row 7, column 2 \(c\)"):
        casep.solve_ols(S, np.zeros(50), names=["a", "b", "c"])


# --------------------------------------------------------------------------- outputs all or none
def test_full_disk_names_the_file_and_leaves_no_other_output(files, tmp_path, capsys):
    """/dev/full: ENOSPC on write. The error names it; the JSON written before it is not left behind."""
    j = tmp_path / "first.json"
    s, _, err = _run(capsys, "separate", files / "a.csv", "--json", j, "--csv", "/dev/full")
    assert s == 2 and "cannot write /dev/full: No space left on device" in err
    assert not j.exists() and not list(tmp_path.glob(".first.json.*"))


def test_output_group_renames_all_or_none(tmp_path):
    from casep.io._atomic import atomic_open, output_group

    with pytest.raises(RuntimeError), output_group():
        with atomic_open(tmp_path / "a.txt") as fh:
            fh.write("a")
        raise RuntimeError("second output failed")
    assert list(tmp_path.iterdir()) == []
    with output_group():
        with atomic_open(tmp_path / "a.txt") as fh:
            fh.write("a")
        assert not (tmp_path / "a.txt").exists()  # not before the group ends
    assert (tmp_path / "a.txt").read_text() == "a"


# --------------------------------------------------------------------------- model files
def test_model_file_that_loops_forever_is_stopped(files, tmp_path, capsys, monkeypatch):
    m = tmp_path / "loop.py"
    m.write_text("import casep\n\n\ndef build():\n    while True:\n        pass\n")
    monkeypatch.setenv("CASEP_MODEL_TIMEOUT", "0.5")
    s, _, err = _run(capsys, "separate", files / "a.csv", "--model", m)
    assert s == 2 and "loop.py, line 5, in build(): still running after 0.5 s" in err


def test_result_of_a_model_file_needs_it_named_with_its_sha256(files, tmp_path, capsys):
    """A result records its model file and SHA-256; reading it back runs that file only when it is named
    (--model), and only when its SHA-256 is the recorded one; a file moved keeps its hash."""
    import hashlib

    import casep.model.loader as loader

    text = (loader.model_dirs()[-1] / "platform36.py").read_text().replace('ErrorModel("platform36"',
                                                                            'ErrorModel("mine"')
    m = tmp_path / "mine.py"
    m.write_text(text)
    r = tmp_path / "r.json"
    assert main(["separate", str(files / "a.csv"), "--model", str(m), "--json", str(r)]) == 0
    assert _load(r)["model_file"] == str(m.resolve())
    assert _load(r)["model_sha256"] == hashlib.sha256(m.read_bytes()).hexdigest()
    capsys.readouterr()
    s, _, err = _run(capsys, "impact", files / "a.csv", "--result", r)
    assert s == 2 and "not shipped with casep" in err and f"give --model {m.resolve()}" in err
    s, out, err = _run(capsys, "impact", files / "a.csv", "--result", r, "--model", m)
    assert s == 0 and "model mine" in out, err
    m.rename(tmp_path / "moved.py")
    s, out, err = _run(capsys, "impact", files / "a.csv", "--result", r, "--model", tmp_path / "moved.py")
    assert s == 0 and "model mine" in out, err


def test_models_verbose_shows_magnitudes_and_docstring(capsys):
    s, out, _ = _run(capsys, "models", "-v")
    assert s == 0
    assert "magnitude" in out and "    | platform36: the paper's 36-coefficient" in out
    assert [ln for ln in out.splitlines() if ln.split()[:1] == ["Kg0x"]][0].split()[2] == "0.5"


# --------------------------------------------------------------------------- CSV from other tools
def test_semicolon_and_tab_separated_csv_read_like_comma(files, tmp_path):
    """European Excel (semicolon) and MATLAB writetable with 'Delimiter','tab' read exactly as the comma file."""
    import pandas as pd

    from casep.io.files import read_flight

    df = pd.read_csv(files / "a.csv", comment="#")
    ref = read_flight(files / "a.csv")
    for sep, name in ((";", "semi.csv"), ("\t", "tab.csv")):
        df.to_csv(tmp_path / name, sep=sep, index=False, float_format="%.17g")
        fl = read_flight(tmp_path / name)
        np.testing.assert_array_equal(fl.dv, ref.dv)
        np.testing.assert_array_equal(fl.f, ref.f)


def test_decimal_comma_gets_a_hint_not_a_guess(files, tmp_path):
    import pandas as pd

    from casep.io.files import read_flight
    from casep.io.flight import FlightDataError

    pd.read_csv(files / "a.csv", comment="#").to_csv(tmp_path / "euro.csv", sep=";", decimal=",", index=False)
    with pytest.raises(FlightDataError, match="a decimal comma\\? the columns are semicolon-separated"):
        read_flight(tmp_path / "euro.csv")


def test_matlab_writetable_with_bom(files, tmp_path):
    """Excel's "CSV UTF-8" starts with a byte-order mark; the first column is still `t`."""
    from casep.io.files import read_flight

    text = (files / "a.csv").read_text()
    (tmp_path / "bom.csv").write_text("\ufeff" + "\n".join(ln for ln in text.splitlines() if not ln.startswith("#")))
    assert read_flight(tmp_path / "bom.csv").n_samples == read_flight(files / "a.csv").n_samples


# --------------------------------------------------------------------------- Earth-fixed impact and noise
@pytest.fixture(scope="module")
def earth(tmp_path_factory):
    d = tmp_path_factory.mktemp("earth")
    assert main(["simulate", "--rate", "10", "--rotating-earth", "--launch-site", *SITE, "-o", str(d / "one.csv")]) == 0
    assert main(["simulate", "--rate", "10", "--rotating-earth", "--launch-site", *SITE, "--tracking-frame", "ecef",
                 "--tracking-rate", "10", "-o", str(d / "tel.csv")]) == 0
    assert main(["separate", str(d / "one.csv"), "--json", str(d / "one.json")]) == 0
    return d


def test_impact_two_file_earth_fixed(earth, capsys):
    """impact reads telemetry + ECEF tracking with the frame options; the burnout state comes from the tracking
    (launch-inertial), equal to the one-file flight's r_* within the tracking noise."""
    from casep.io.files import read_flight, read_flight_pair

    frames = ["--tracking", earth / "tel.tracking.csv", "--tracking-frame", "ecef", "--launch-site", *SITE,
              "--launch-time", "0"]
    s, _, err = _run(capsys, "separate", earth / "tel.csv", *frames, "--json", earth / "r.json")
    assert s == 0, err
    s, out, err = _run(capsys, "impact", earth / "tel.csv", *frames, "--result", earth / "r.json")
    assert s == 0 and "predicted miss" in out, err
    from casep.frames import LaunchSite

    pair = read_flight_pair(earth / "tel.csv", earth / "tel.tracking.csv", tracking_frame="ecef",
                            site=LaunchSite(*map(float, SITE), 0.0))
    one = read_flight(earth / "one.csv")
    r_pair = np.array([pair.signals[f"r_{a}"][-1] for a in "xyz"])
    r_one = np.array([one.signals[f"r_{a}"][-1] for a in "xyz"])
    assert pair.t[-1] == one.t[-1]
    assert np.max(np.abs(r_pair - r_one)) < 1.0  # m
    s, out, err = _run(capsys, "noise", earth / "tel.csv", *frames)
    assert s == 0 and "Allan deviation" in out, err


def test_impact_launch_frame_pair_says_what_is_missing(earth, tmp_path, capsys):
    import pandas as pd

    trk = pd.DataFrame({"t": np.arange(0, 195.05, 0.1)})
    tel = pd.read_csv(earth / "one.csv", comment="#")
    for a in "xyz":
        trk[f"v_trk_{a}"] = np.interp(trk.t, tel.t, tel[f"v_{a}"])
    tel = tel.rename(columns={f"v_{a}": f"v_tel_{a}" for a in "xyz"}).drop(
        columns=[c for c in tel.columns if c.startswith(("dv_", "r_"))])
    tel.to_csv(tmp_path / "tel.csv", index=False)
    trk.to_csv(tmp_path / "trk.csv", index=False)
    # the files are one.csv rewritten (other bytes): a result without provenance, which impact cannot check
    res = {k: v for k, v in json.loads((earth / "one.json").read_text()).items() if k != "provenance"}
    (tmp_path / "one.json").write_text(json.dumps(res))
    s, _, err = _run(capsys, "impact", tmp_path / "tel.csv", "--tracking", tmp_path / "trk.csv", "--result",
                     tmp_path / "one.json")
    assert s == 2 and "missing columns r_x, r_y, r_z" in err and "--tracking-frame ecef|geodetic" in err


if __name__ == "__main__":  # pragma: no cover
    sys.exit(pytest.main([__file__, "-n", "0", "-q"]))


def test_api_separate_takes_a_result_file_as_prior(files, tmp_path):
    """The API reads a result file given as `prior` with the same reader (was: parsed as a prior mapping)."""
    import warnings

    import casep
    from casep.io.files import read_flight

    doc = _write(tmp_path / "doc.json", _documented(_load(files / "ra.json")))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", casep.CasepWarning)
        res = casep.separate(read_flight(files / "b.csv"), "platform36", "map", prior=doc)
    assert res.success and "correlation" in res.settings["prior"]


def test_json_writer_names_a_non_finite_value(tmp_path):
    from casep.io.result_files import write_json_atomic

    with pytest.raises(ValueError, match=r"non-finite value \(inf\) at `settings.prior.Kg0x.mean`"):
        write_json_atomic({"settings": {"prior": {"Kg0x": {"mean": float("inf")}}}}, tmp_path / "x.json")
    assert not (tmp_path / "x.json").exists()


def test_bounded_result_is_read_by_impact(files, tmp_path, capsys):
    """A bounded result's coefficients at a bound have an estimate, no std and null covariance rows: legal."""
    b = _write(tmp_path / "box.json", '{"Kg0x": [-0.1, 0.1], "Ka0x": 0.0}')
    r = tmp_path / "rb.json"
    assert main(["separate", str(files / "a.csv"), "--method", "bounded", "--bounds", b, "--json", str(r)]) == 0
    capsys.readouterr()
    s, out, err = _run(capsys, "impact", files / "a.csv", "--result", r)
    assert s == 0 and "predicted miss" in out, err


def test_truth_from_prior_std_1e308_refused_before_the_runs(tmp_path, capsys):
    p = _write(tmp_path / "tp.json", '{"Kg0x": {"mean": 0, "std": 1e308}}')
    s, _, err = _run(capsys, "montecarlo", "--runs", "1", "--workers", "1", "--truth-from-prior", p)
    assert s == 2 and "`Kg0x` std must be > 0, within [1e-30, 1e+30]" in err


def test_other_separator_gets_a_hint(tmp_path):
    from casep.io.files import read_flight
    from casep.io.flight import FlightDataError

    (tmp_path / "sp.csv").write_text("t f_x f_y f_z dv_x dv_y dv_z\n0 1 2 3 4 5 6\n")
    with pytest.raises(FlightDataError, match="the header looks space-separated"):
        read_flight(tmp_path / "sp.csv")
