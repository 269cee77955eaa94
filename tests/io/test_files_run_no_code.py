"""Opening a result, prior, truth or manifest never runs code; a model file runs only when the user names it.

Every case uses a model file that leaves a marker file when it runs (a platform36 copy under another
name). A result, prior, truth file or manifest that names it is refused by `fuse`, `impact`,
`separate --prior`, `montecarlo --truth`, `design --prior` and the report without the marker
appearing, with a message that says which option to give; named by the user with the SHA-256 the
result records, the file runs and the command works; with another SHA-256 the command fails naming
both files and both hashes, before the file runs.
"""

from __future__ import annotations

import hashlib
import json
import shutil

import pytest

from casep.cli import main

EVIL = '''"""A model that leaves a marker file when it runs."""
import pathlib

from casep.model.loader import build_model

pathlib.Path(__file__).with_name("MARKER").write_text("ran")


def build():
    m = build_model("platform36")
    m.name = "evil"
    return m
'''


def _run(capsys, *argv) -> tuple[int, str, str]:
    status = main([str(a) for a in argv])
    cap = capsys.readouterr()
    return status, cap.out, cap.err


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """A 5 Hz paper flight, the marker model, a result of it (written with the model named), a failed
    copy and a result of platform36."""
    import warnings

    import casep
    from casep.simulation.simulate import simulate_flight, write_simulation

    d = tmp_path_factory.mktemp("nocode")
    write_simulation(simulate_flight("paper", seed=3, rate=5.0), d / "flight.csv")
    write_simulation(simulate_flight("paper", seed=4, rate=5.0), d / "flight2.csv")  # the prior's next flight
    (d / "evil.py").write_text(EVIL)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the separation's own warnings are not the point here
        res = casep.separate(d / "flight.csv", d / "evil.py", sigma=0.1, noise="white", robust="none")
    assert res.model == "evil" and res.model_sha256 == hashlib.sha256((d / "evil.py").read_bytes()).hexdigest()
    d_res = res.to_dict()
    prov = {"inputs": [{"role": "flight", "file": str(d / "flight.csv"),
                        "sha256": hashlib.sha256((d / "flight.csv").read_bytes()).hexdigest()}]}
    (d / "r.json").write_text(json.dumps({**d_res, "provenance": prov}))
    (d / "r2.json").write_text(json.dumps(d_res))
    (d / "MARKER").unlink()
    return d


@pytest.fixture
def clean(files):
    """The folder with no marker, and a check that none appears unless the test names the model."""
    (files / "MARKER").unlink(missing_ok=True)
    yield files
    (files / "MARKER").unlink(missing_ok=True)


def _refused(status: int, err: str, files) -> None:
    assert status == 2, err
    assert "not shipped with casep" in err and f"--model {files / 'evil.py'}" in err, err
    assert not (files / "MARKER").exists()


def _mismatch(status: int, err: str, files, changed) -> None:
    recorded = hashlib.sha256(EVIL.encode()).hexdigest()
    assert status == 2, err
    assert recorded in err and hashlib.sha256(changed.read_bytes()).hexdigest() in err, err
    assert str(files / "evil.py") in err and str(changed) in err, err
    assert not (files / "MARKER").exists()  # refused before it runs


@pytest.fixture
def changed(clean):
    """A copy of the marker model with one more comment: another SHA-256."""
    p = clean / "sub" / "evil.py"
    p.parent.mkdir(exist_ok=True)
    p.write_text(EVIL + "# edited\n")
    return p


# ----------------------------------------------------------------------------- impact
def test_impact_runs_no_code_of_a_result(clean, capsys):
    s, _, err = _run(capsys, "impact", clean / "flight.csv", "--result", clean / "r.json")
    _refused(s, err, clean)


def test_impact_with_the_model_named_and_its_sha256_works(clean, capsys):
    s, out, err = _run(capsys, "impact", clean / "flight.csv", "--result", clean / "r.json", "--model",
                       clean / "evil.py")
    assert s == 0 and "predicted miss" in out and "model evil" in out, err
    assert (clean / "MARKER").exists()  # the user named it: it ran


def test_impact_with_another_sha256_names_both(changed, capsys):
    s, _, err = _run(capsys, "impact", changed.parent.parent / "flight.csv", "--result",
                     changed.parent.parent / "r.json", "--model", changed)
    _mismatch(s, err, changed.parent.parent, changed)


def test_impact_manifest_result_runs_no_code(clean, capsys):
    (clean / "m.toml").write_text('[[flight]]\ntelemetry = "flight.csv"\nresult = "r.json"\n')
    s, _, err = _run(capsys, "impact", "--manifest", clean / "m.toml")
    _refused(s, err, clean)


# ----------------------------------------------------------------------------- fuse
def test_fuse_runs_no_code_and_works_with_the_model_named(clean, capsys):
    s, _, err = _run(capsys, "fuse", clean / "r.json", clean / "r2.json")
    _refused(s, err, clean)
    # the same result twice: refused as one data set counted twice, after the model check passed
    s, _, err = _run(capsys, "fuse", clean / "r.json", clean / "r2.json", "--model", clean / "evil.py")
    assert s == 2 and "count" in err and "not shipped" not in err, err


def test_fuse_with_another_sha256_names_both(changed, capsys):
    d = changed.parent.parent
    s, _, err = _run(capsys, "fuse", d / "r.json", d / "r2.json", "--model", changed)
    _mismatch(s, err, d, changed)


# ----------------------------------------------------------------------------- separate --prior
def test_separate_prior_runs_no_code(clean, capsys):
    """The default --model (platform36, shipped) is not the result's: refused by name, nothing run."""
    s, _, err = _run(capsys, "separate", clean / "flight.csv", "--method", "map", "--prior", clean / "r.json")
    assert s == 2 and "of model `evil`, not of model `platform36`" in err, err
    assert not (clean / "MARKER").exists()


def test_separate_prior_with_the_model_named_works_and_checks_sha256(clean, changed, capsys):
    s, out, err = _run(capsys, "separate", clean / "flight.csv", "--method", "map", "--prior", clean / "r.json",
                       "--model", changed)
    _mismatch(s, err, clean, changed)
    s, out, err = _run(capsys, "separate", clean / "flight2.csv", "--method", "map", "--prior", clean / "r.json",
                       "--model", clean / "evil.py", "--noise", "white", "--robust", "none")
    assert s == 0 and "map" in out, err
    assert (clean / "MARKER").exists()  # the user named it: it ran


# ----------------------------------------------------------------------------- montecarlo --truth, design --prior
@pytest.fixture
def truth(clean):
    side = json.loads((clean / "flight.truth.json").read_text())
    p = clean / "truth_evil.json"
    p.write_text(json.dumps({**side, "model": "evil"}))
    return p


def test_montecarlo_truth_runs_no_code(clean, truth, capsys):
    s, _, err = _run(capsys, "montecarlo", "--flight", clean / "flight.csv", "--truth", truth, "--runs", "2",
                     "--workers", "1", "--no-progress", "--methods", "ols")
    assert s == 2 and "not shipped with casep" in err and "give --model path/to/evil.py" in err, err
    assert not (clean / "MARKER").exists()
    s, out, err = _run(capsys, "montecarlo", "--flight", clean / "flight.csv", "--truth", truth, "--runs", "2",
                       "--workers", "1", "--no-progress", "--methods", "ols", "--model", clean / "evil.py")
    assert s == 0 and "2 runs" in out, err
    assert (clean / "MARKER").exists()


def test_montecarlo_prior_with_another_sha256_names_both(changed, capsys):
    d = changed.parent.parent
    s, _, err = _run(capsys, "montecarlo", "--prior", d / "r.json", "--runs", "2", "--workers", "1",
                     "--no-progress", "--methods", "map")
    _refused(s, err, d)
    s, _, err = _run(capsys, "montecarlo", "--prior", d / "r.json", "--runs", "2", "--workers", "1",
                     "--no-progress", "--methods", "map", "--model", changed)
    _mismatch(s, err, d, changed)


def test_design_prior_runs_no_code(clean, changed, capsys):
    s, _, err = _run(capsys, "design", "--prior", clean / "r.json", "--knots", "3", "--starts", "1")
    _refused(s, err, clean)
    s, _, err = _run(capsys, "design", "--prior", clean / "r.json", "--knots", "3", "--starts", "1", "--model",
                     changed)
    _mismatch(s, err, clean, changed)


def test_design_truth_with_the_model_named_works(clean, truth, capsys):
    s, _, err = _run(capsys, "design", "--flight", clean / "flight.csv", "--truth", truth, "--knots", "3",
                     "--starts", "1")
    assert s == 2 and "give --model path/to/evil.py" in err and not (clean / "MARKER").exists(), err
    s, out, err = _run(capsys, "design", "--flight", clean / "flight.csv", "--truth", truth, "--prior",
                       clean / "r.json", "--knots", "3", "--starts", "1", "--model", clean / "evil.py")
    assert s == 0 and "IPOPT" in out, err
    assert (clean / "MARKER").exists()


# ----------------------------------------------------------------------------- the report, the API
def test_report_and_api_run_no_code(clean, tmp_path):
    import casep
    from casep.impact.miss import impact_analysis
    from casep.reporting.report import write_report

    res = casep.EstimateResult.from_json(clean / "r.json")  # no model given: none loaded
    fl = casep.read_flight(clean / "flight.csv")
    page = write_report(res, tmp_path / "r.html", flight=fl).read_text()
    assert "not shipped with casep" in page
    with pytest.raises(ValueError, match="not shipped with casep"):
        impact_analysis(fl, res)
    with pytest.raises(ValueError, match="of model `evil`, not of model `platform36`"):
        casep.separate(fl, "platform36", method="map", prior=str(clean / "r.json"))
    assert not (clean / "MARKER").exists()


def test_a_model_path_recorded_as_the_name_is_not_run(clean, capsys):
    """An older or hand-written result whose `model` is the file's path: still only by --model."""
    d = json.loads((clean / "r2.json").read_text())
    d["model"] = str(clean / "evil.py")
    d.pop("model_file", None)
    (clean / "path.json").write_text(json.dumps(d))
    s, _, err = _run(capsys, "impact", clean / "flight.csv", "--result", clean / "path.json")
    _refused(s, err, clean)


def test_a_shipped_model_is_found_by_name(clean, capsys, tmp_path):
    """A result of platform36 needs no --model; a copy of platform36.py elsewhere named with --model is
    another file only if its bytes differ."""
    import casep.model.loader as loader

    assert main(["separate", str(clean / "flight.csv"), "--json", str(tmp_path / "p.json"), "--noise", "white",
                 "--robust", "none"]) == 0
    d = json.loads((tmp_path / "p.json").read_text())
    src = loader.shipped_model_file("platform36")
    assert d["model"] == "platform36" and "model_file" not in d
    assert d["model_sha256"] == hashlib.sha256(src.read_bytes()).hexdigest()
    capsys.readouterr()
    s, out, err = _run(capsys, "impact", clean / "flight.csv", "--result", tmp_path / "p.json")
    assert s == 0 and "casep: running model file" not in err, err
    copy = tmp_path / "platform36.py"
    shutil.copy(src, copy)
    s, out, err = _run(capsys, "impact", clean / "flight.csv", "--result", tmp_path / "p.json", "--model", copy)
    assert s == 0 and f"casep: running model file {copy}" in err, err


def test_a_time_offset_model_is_read_as_its_base_file(clean):
    """`NAME+dt_trk` (a model with the tracking time offset added): a shipped base by its name; a user's base
    file only when named, with its SHA-256."""
    from casep.model.loader import load_recorded_model, model_record, with_time_offset

    shipped = with_time_offset("platform36")
    rec = model_record(shipped)
    assert rec["model_file"] is None
    back = load_recorded_model(shipped.name, sha256=rec["model_sha256"], where="r.json")
    assert back.name == "platform36+dt_trk" and back.names == shipped.names
    mine = with_time_offset(clean / "evil.py")
    (clean / "MARKER").unlink()
    rec = model_record(mine)
    assert rec["model_file"] == str((clean / "evil.py").resolve())
    with pytest.raises(ValueError, match=r"`evil\+dt_trk` .* not shipped with casep"):
        load_recorded_model(mine.name, sha256=rec["model_sha256"], model_file=rec["model_file"], where="r.json")
    assert not (clean / "MARKER").exists()
    back = load_recorded_model(mine.name, sha256=rec["model_sha256"], model_file=rec["model_file"], where="r.json",
                               given=clean / "evil.py")
    assert back.name == "evil+dt_trk" and back.names == mine.names


def test_a_shipped_model_changed_since_is_a_warning_naming_both_hashes():
    from casep.exceptions import CasepWarning
    from casep.model.loader import load_recorded_model, shipped_model_file

    now = hashlib.sha256(shipped_model_file("platform36").read_bytes()).hexdigest()
    with pytest.warns(CasepWarning, match=f"sha256 {'0' * 64}, but .*platform36.py has sha256 {now}"):
        load_recorded_model("platform36", sha256="0" * 64, where="r.json")
