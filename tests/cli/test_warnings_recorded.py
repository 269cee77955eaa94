"""A result file records the warnings its run raised (``provenance["warnings"]``): the JSON found on a disk
months later says that the run warned about forces in g or times in ms, not only the terminal did."""

import json

import numpy as np
import pandas as pd

from casep.cli import main
from casep.units import G0


def test_separate_json_records_the_units_warnings(tmp_path, capsys):
    assert main(["simulate", "-o", str(tmp_path / "f.csv"), "--rate", "50", "--seed", "2"]) == 0
    df = pd.read_csv(tmp_path / "f.csv", comment="#")
    for a in "xyz":
        df[f"f_{a}"] /= G0  # forces in g
    df["t"] *= 1e3  # times in ms
    df.to_csv(tmp_path / "g.csv", index=False)
    status = main(["separate", str(tmp_path / "g.csv"), "--json", str(tmp_path / "r.json")])
    printed = capsys.readouterr().err
    res = json.loads((tmp_path / "r.json").read_text())
    recorded = res["provenance"]["warnings"]
    shown = [line.removeprefix("warning: ") for line in printed.splitlines()
             if line.startswith("warning: ") and "ill-conditioned" not in line]  # that one is the table's own
    assert any(" g)" in w and "specific force" in w for w in recorded), recorded
    assert any("median time step 20 s" in w and "Is t in ms" in w for w in recorded), recorded
    assert set(shown) <= set(recorded), (shown, recorded)  # every warning printed is in the file
    assert status in (0, 1) and np.isfinite(res["sigma"])


def test_a_quiet_run_records_no_warnings_and_foreign_formats_are_left_alone(tmp_path):
    assert main(["simulate", "-o", str(tmp_path / "f.csv"), "--rate", "50", "--seed", "3"]) == 0
    assert main(["separate", str(tmp_path / "f.csv"), "--json", str(tmp_path / "r.json")]) in (0, 1)
    assert json.loads((tmp_path / "r.json").read_text())["provenance"]["warnings"] == []


def test_the_warnings_a_command_raised_before_its_error_are_said_before_it(monkeypatch, capsys):
    """A command that warns (a screen's finding) and then stops on bad input: exit 2, and stderr says the warnings
    of the block (inside the command's own recorder too) before the error, not the error alone."""
    import warnings
    from types import SimpleNamespace

    from casep.cli import app
    from casep.cli.capture import recorded
    from casep.exceptions import TrackingQualityWarning

    def run(args):
        with recorded():
            warnings.warn("f.csv: tracking stale at t = 2..28 s (259 epochs)", TrackingQualityWarning, stacklevel=2)
            raise ValueError("f.csv: 7 samples observed are too few")

    real = app._command

    class Demo(SimpleNamespace):  # the demo command's parser, this run
        def __getattr__(self, key):
            return getattr(real("demo"), key)

    monkeypatch.setattr(app, "_command", lambda name: Demo(run=run) if name == "demo" else real(name))
    assert main(["demo"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert err == ["warning: f.csv: tracking stale at t = 2..28 s (259 epochs)",
                   "casep: error: f.csv: 7 samples observed are too few"], err
