"""Output safety (casep.io._atomic and the CLI): links, FIFOs, descriptors, modes, inputs, early checks."""

from __future__ import annotations

import json
import os
import stat
import threading
from pathlib import Path

import numpy as np
import pytest

import casep
from casep.cli import main
from casep.io._atomic import atomic_open, check_output, check_output_dir, check_outputs
from casep.simulation.synthetic import excitation_force, inject_errors


@pytest.fixture(scope="module")
def flight_csv(tmp_path_factory, platform36, truth36):
    t = np.arange(0.0, 120.0, 0.1)
    f = excitation_force(t, duration=120.0)
    p = tmp_path_factory.mktemp("io") / "flight.csv"
    casep.write_flight(casep.FlightData(t, f, inject_errors(platform36, t, f, truth36)), p)
    return p


# --- atomic_open -------------------------------------------------------------------------------

def test_symlink_is_written_through(tmp_path):
    target = tmp_path / "real.json"
    target.write_text("old\n")
    link = tmp_path / "link.json"
    link.symlink_to(target)
    with atomic_open(link) as fh:
        fh.write("new\n")
    assert link.is_symlink() and os.readlink(link) == str(target)
    assert target.read_text() == "new\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link.json", "real.json"]


def test_dangling_symlink_creates_its_target(tmp_path):
    link = tmp_path / "link.json"
    link.symlink_to(tmp_path / "later.json")
    with atomic_open(link) as fh:
        fh.write("x\n")
    assert link.is_symlink() and (tmp_path / "later.json").read_text() == "x\n"


def test_fifo_is_written_directly(tmp_path):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    got: list[bytes] = []

    def reader():
        with open(fifo, "rb") as fh:
            got.append(fh.read())

    th = threading.Thread(target=reader, daemon=True)
    th.start()
    with atomic_open(fifo) as fh:
        fh.write('{"a": 1}\n')
    th.join(timeout=10)
    assert not th.is_alive() and got == [b'{"a": 1}\n']
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)  # still a FIFO, not replaced by a regular file
    assert sorted(p.name for p in tmp_path.iterdir()) == ["pipe"]


def test_own_descriptor_is_written_through_not_replaced(tmp_path):
    """/dev/stdout-like paths (/proc/self/fd/N, /dev/fd/N) write into the descriptor itself."""
    r, w = os.pipe()
    try:
        for path in (f"/proc/self/fd/{w}", f"/dev/fd/{w}"):
            with atomic_open(path) as fh:
                fh.write("line\n")
        os.close(w)
        w = -1
        with os.fdopen(r, "rb") as fh:
            r = -1
            assert fh.read() == b"line\nline\n"
    finally:
        for fd in (r, w):
            if fd >= 0:
                os.close(fd)


@pytest.mark.skipif(os.geteuid() != 0, reason="making a device node needs root")
def test_character_device_stays(tmp_path):
    # A private null device (never the system's /dev/null: a faulty writer would replace it).
    dev = tmp_path / "null"
    os.mknod(dev, 0o666 | stat.S_IFCHR, os.makedev(1, 3))
    with atomic_open(dev) as fh:
        fh.write("discarded\n")
    assert stat.S_ISCHR(os.lstat(dev).st_mode)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["null"]


def test_existing_mode_is_kept(tmp_path):
    p = tmp_path / "secret.json"
    p.write_text("old\n")
    p.chmod(0o600)
    with atomic_open(p) as fh:
        fh.write("new\n")
    assert stat.S_IMODE(p.stat().st_mode) == 0o600 and p.read_text() == "new\n"


def test_new_file_gets_umask_mode(tmp_path):
    old = os.umask(0o027)
    try:
        with atomic_open(tmp_path / "n.json") as fh:
            fh.write("x")
    finally:
        os.umask(old)
    assert stat.S_IMODE((tmp_path / "n.json").stat().st_mode) == 0o640


def test_error_leaves_target_and_no_temporary(tmp_path):
    p = tmp_path / "keep.json"
    p.write_text("old\n")
    with pytest.raises(RuntimeError):
        with atomic_open(p) as fh:
            fh.write("half")
            raise RuntimeError("boom")
    assert p.read_text() == "old\n" and [q.name for q in tmp_path.iterdir()] == ["keep.json"]


# --- check_output ------------------------------------------------------------------------------

def test_check_output_refuses_input_also_through_a_link(tmp_path):
    inp = tmp_path / "flight.csv"
    inp.write_text("t\n")
    link = tmp_path / "alias.json"
    link.symlink_to(inp)
    for out in (inp, link, tmp_path / "." / "flight.csv"):
        with pytest.raises(ValueError, match=f"--json {out} is the input file {inp}"):
            check_output(out, "--json", inputs=[None, inp])


def test_check_output_missing_folder_and_folder_target(tmp_path):
    with pytest.raises(ValueError, match=f"--json {tmp_path}/no/r.json: folder {tmp_path}/no does not exist"):
        check_output(tmp_path / "no" / "r.json", "--json")
    with pytest.raises(ValueError, match="is a folder"):
        check_output(tmp_path, "--csv")
    assert check_output("/dev/null", "--json") == Path("/dev/null")


@pytest.mark.skipif(os.geteuid() == 0, reason="root may write anywhere")
def test_check_output_unwritable_folder(tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        with pytest.raises(ValueError, match="not writable"):
            check_output(ro / "r.json", "--json")
    finally:
        ro.chmod(0o700)


def test_check_output_dir(tmp_path):
    assert check_output_dir(tmp_path / "a" / "b", "--figures") == tmp_path / "a" / "b"
    assert not (tmp_path / "a").exists()  # checked, not created
    (tmp_path / "file").write_text("")
    with pytest.raises(ValueError, match="exists and is not a folder"):
        check_output_dir(tmp_path / "file", "--figures")


def test_check_outputs_refuses_two_options_on_one_file(tmp_path):
    with pytest.raises(ValueError, match="--json and --csv both name"):
        check_outputs({"--json": tmp_path / "r", "--mat": None, "--csv": tmp_path / "r"})
    check_outputs({"--json": "/dev/null", "--csv": "/dev/null"})  # a device may take both


# --- CLI ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("option", ["--json", "--mat", "--csv"])
def test_separate_refuses_output_onto_flight(flight_csv, tmp_path, capsys, option):
    before = flight_csv.read_bytes()
    assert main(["separate", str(flight_csv), option, str(flight_csv)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{option} {flight_csv} is the input file {flight_csv}" in err
    assert flight_csv.read_bytes() == before


def test_separate_refuses_output_onto_tracking_file(tmp_path, capsys):
    from casep.simulation.simulate import simulate_two_rate

    d = simulate_two_rate("paper", seed=2, telemetry_rate=20.0, tracking_rate=5.0)
    tel, trk = tmp_path / "tel.csv", tmp_path / "trk.csv"
    d.write(tel, trk)
    before = trk.read_bytes()
    assert main(["separate", str(tel), "--tracking", str(trk), "--json", str(trk)]) == 2
    assert f"--json {trk} is the input file {trk}" in capsys.readouterr().err
    assert trk.read_bytes() == before


def test_separate_refuses_output_onto_bounds_file(flight_csv, tmp_path, capsys):
    b = tmp_path / "b.json"
    b.write_text(json.dumps({"Kg0x": [-1, 1]}))
    assert main(["separate", str(flight_csv), "--method", "bounded", "--bounds", str(b), "--csv", str(b)]) == 2
    assert "is the input file" in capsys.readouterr().err


def _forbid(monkeypatch, target: str):
    def fail(*a, **k):
        raise AssertionError(f"{target} ran although the output check should have stopped the command")

    monkeypatch.setattr(target, fail)


@pytest.mark.parametrize("argv, forbidden", [
    (["separate", "{flight}", "--json", "{missing}/r.json"], "casep.workflows.separate.separate"),
    (["separate", "{flight}", "--mat", "{missing}/r.mat"], "casep.workflows.separate.separate"),
    (["separate", "{flight}", "--csv", "{missing}/r.csv"], "casep.workflows.separate.separate"),
    (["diagnose", "{flight}", "--json", "{missing}/d.json"], "casep.checks.diagnostics.diagnose_noise"),
    (["simulate", "-o", "{missing}/f.csv"], "casep.simulation.simulate.simulate_flight"),
    (["montecarlo", "--runs", "2", "--json", "{missing}/mc.json"], "casep.montecarlo.run_montecarlo"),
    (["montecarlo", "--runs", "2", "--csv", "{missing}/mc.csv"], "casep.montecarlo.run_montecarlo"),
    (["montecarlo", "--runs", "2", "--figure", "{missing}/mc.png"], "casep.montecarlo.run_montecarlo"),
])
def test_missing_output_folder_exit_2_before_any_work(flight_csv, tmp_path, capsys, monkeypatch, argv, forbidden):
    _forbid(monkeypatch, forbidden)
    missing = tmp_path / "nowhere"
    args = [a.format(flight=flight_csv, missing=missing) for a in argv]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.startswith("casep: error: ") and err.count("\n") == 1
    assert f"folder {missing} does not exist" in err
    assert list(tmp_path.iterdir()) == []


def test_diagnose_figures_under_a_file_exit_2_before_any_work(flight_csv, tmp_path, capsys, monkeypatch):
    _forbid(monkeypatch, "casep.checks.diagnostics.diagnose")
    (tmp_path / "file").write_text("")
    assert main(["diagnose", str(flight_csv), "--figures", str(tmp_path / "file")]) == 2
    assert "exists and is not a folder" in capsys.readouterr().err


def test_separate_json_to_symlink_and_mode_kept(flight_csv, tmp_path, capsys):
    real = tmp_path / "real.json"
    real.write_text("{}")
    real.chmod(0o600)
    link = tmp_path / "link.json"
    link.symlink_to(real)
    assert main(["separate", str(flight_csv), "--json", str(link)]) == 0
    assert link.is_symlink() and stat.S_IMODE(real.stat().st_mode) == 0o600
    assert len(json.loads(real.read_text())["estimates"]) == 36
