"""Defects a fresh-eyes review of the range-data features found: a manifest's time_offset_ms = "auto",
fuse counting one flight's data twice, failed results used as inputs."""

from __future__ import annotations

import json
import warnings

import pytest

import casep
from casep.cli import main


def test_manifest_time_offset_auto_is_read(tmp_path):
    (tmp_path / "m.toml").write_text('[[flight]]\ntelemetry = "t.csv"\ntracking = "k.csv"\ntime_offset_ms = "auto"\n')
    for name in ("t.csv", "k.csv"):
        (tmp_path / name).write_text("t\n0\n")
    man = casep.read_manifest(tmp_path / "m.toml")
    assert man.flights[0].time_offset_ms == "auto"
    (tmp_path / "bad.toml").write_text('[[flight]]\ntelemetry = "t.csv"\ntracking = "k.csv"\ntime_offset_ms = inf\n')
    with pytest.raises(ValueError, match="time_offset_ms"):
        casep.read_manifest(tmp_path / "bad.toml")


@pytest.fixture(scope="module")
def two_results(tmp_path_factory):
    d = tmp_path_factory.mktemp("fuse")
    assert main(["simulate", "--scenario", "paper", "--rate", "5", "--seed", "2", "-o", str(d / "a.csv")]) == 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # conditioning: printed by the CLI
        assert main(["separate", str(d / "a.csv"), "--json", str(d / "r1.json")]) == 0
        assert main(["separate", str(d / "a.csv"), "--sigma", "0.1", "--json", str(d / "r2.json")]) == 0
    return d


def test_fuse_refuses_two_results_of_the_same_data(two_results, capsys):
    d = two_results
    assert main(["fuse", str(d / "r1.json"), str(d / "r2.json")]) == 2
    err = capsys.readouterr().err
    assert "both read the flight file" in err and "a.csv" in err and "counts its data twice" in err


def test_failed_results_are_no_input(two_results, capsys):
    d = two_results
    bad = json.loads((d / "r1.json").read_text())
    bad.update(success=False, status=-4, message="failed: set-up")
    (d / "failed.json").write_text(json.dumps(bad))
    assert main(["fuse", str(d / "failed.json"), str(d / "r2.json")]) == 2
    assert "failed.json: a failed result (status -4" in capsys.readouterr().err
    assert main(["separate", str(d / "a.csv"), "--method", "map", "--prior", str(d / "failed.json")]) == 2
    assert "--prior" in capsys.readouterr().err


def test_a_manifest_may_name_a_result_not_written_yet(tmp_path):
    """separate --manifest writes the result the manifest names: it need not exist before."""
    for name in ("t.csv", "k.csv"):
        (tmp_path / name).write_text("t\n0\n")
    (tmp_path / "m.toml").write_text('[[flight]]\ntelemetry = "t.csv"\ntracking = "k.csv"\nresult = "r.json"\n')
    man = casep.read_manifest(tmp_path / "m.toml")
    assert man.flights[0].result == tmp_path / "r.json" and not (tmp_path / "r.json").exists()


def test_fuse_json_has_provenance_and_a_fused_result_is_not_fused_again(two_results, capsys):
    d = two_results
    assert main(["simulate", "--scenario", "paper", "--rate", "5", "--seed", "3", "-o", str(d / "b.csv")]) == 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["separate", str(d / "b.csv"), "--json", str(d / "r3.json")]) == 0
        assert main(["fuse", str(d / "r1.json"), str(d / "r3.json"), "--json", str(d / "fz.json")]) == 0
    prov = json.loads((d / "fz.json").read_text())["provenance"]
    assert [i["role"] for i in prov["inputs"]] == ["result 1", "result 2"]
    assert prov["command_line"].startswith("casep fuse")
    capsys.readouterr()
    assert main(["fuse", str(d / "r1.json"), str(d / "fz.json")]) == 2
    assert "counts its data twice" in capsys.readouterr().err


def test_impact_manifest_reads_the_flights_tracking_and_frame(tmp_path):
    """impact --manifest equals impact with the same flight given on the command line (ECEF tracking)."""
    site = ["--launch-site", "28.5", "-80.6", "3", "90", "--launch-time", "0"]
    a, trk = str(tmp_path / "a.csv"), str(tmp_path / "a.tracking.csv")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["simulate", "--rotating-earth", *site[:5], "--tracking-frame", "ecef", "--rate", "5", "--seed",
                     "1", "-o", a]) == 0
        assert main(["separate", a, "--tracking", trk, "--tracking-frame", "ecef", *site, "--json",
                     str(tmp_path / "r.json")]) == 0
        assert main(["impact", a, "--tracking", trk, "--tracking-frame", "ecef", *site, "--result",
                     str(tmp_path / "r.json"), "--json", str(tmp_path / "i1.json")]) == 0
    (tmp_path / "m.toml").write_text(
        '[[flight]]\ntelemetry = "a.csv"\ntracking = "a.tracking.csv"\nframe = "ecef"\n'
        'site = { lat_deg = 28.5, lon_deg = -80.6, h_m = 3.0, azimuth_deg = 90.0 }\nlaunch_time_s = 0.0\n'
        'result = "r.json"\n')
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["impact", "--manifest", str(tmp_path / "m.toml"), "--json", str(tmp_path / "i2.json")]) == 0
    one, two = (json.loads((tmp_path / f"i{k}.json").read_text())["miss"] for k in (1, 2))
    assert one["downrange"] == pytest.approx(two["downrange"], rel=1e-12)
    assert one["std_crossrange"] == pytest.approx(two["std_crossrange"], rel=1e-12)
