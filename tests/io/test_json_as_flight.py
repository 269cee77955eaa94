"""A JSON file given where a flight table is read: refused saying what it is and which command or option takes it."""

from __future__ import annotations

import json

import pytest

from casep.cli import main

RESULT = {"model": "platform36", "method": "ols", "names": ["Ka0x"], "estimates": [1.0], "std": [0.1],
          "coefficients": [{"name": "Ka0x", "unit": "mg", "estimate": 1.0, "std": 0.1}]}


@pytest.mark.parametrize(("content", "said"), [
    (RESULT, ("a result JSON (model platform36, method ols)", "casep fuse", "--result", "--prior")),
    ({"Ka0x": {"mean": 0.0, "std": 1.0}}, ("a JSON file, not flight data", "--bounds or --prior")),
    ({"name": "S1", "lat": 28.5, "lon": -80.6, "h": 3.0}, ("a radar station JSON", "--radar STATION.json")),
], ids=["result", "prior", "station"])
@pytest.mark.parametrize("where", ["flight", "tracking"])
def test_json_given_as_a_flight_says_what_it_is(tmp_path, capsys, content, said, where):
    path = tmp_path / "given.json"
    path.write_text(json.dumps(content, indent=1))
    flight = tmp_path / "any.csv"
    flight.write_text("t,f_x\n0,1\n")
    args = ["separate", str(path)] if where == "flight" else ["separate", str(flight), "--tracking", str(path)]
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"casep: error: {path}: ") and err.count("\n") == 0, err
    assert "CSV" not in err.split("not flight data")[0] and all(s in err for s in said), err
