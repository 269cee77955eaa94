"""A strapdown telemetry navigated at a wrong heading, then separated against its tracking: the heading is named
first (:mod:`casep.workflows.telemetry_heading`), not "a noise as slow as the record ... likelier a model error".

The flight: ``casep simulate --scenario strapdown-boost --rate 10 --seed 11`` (rotating Earth, geodetic tracking, the
raw IMU with a 10 s pad; body x up, body y's true heading 200.067 deg), navigated by ``casep navigate`` with body y's
heading given 10 deg off (210.067) and at the truth, each separated under ``strapdown15_axial`` (about 3 s of CPU a
separation).
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from casep.cli import main
from casep.estimators.registry import STATUS_PRIOR_CONFLICT

SITE = ["--launch-site", "32.4", "-106.5", "1200", "20", "--launch-time", "0"]
TRUE_HEADING = 200.067


@pytest.fixture(scope="module")
def boost(tmp_path_factory):
    d = tmp_path_factory.mktemp("telemetry_heading")
    assert main(["simulate", "--scenario", "strapdown-boost", "--rate", "10", "--seed", "11", "-o", str(d / "b.csv"),
                 "--imu-output", str(d / "imu.csv"), "--imu-pad", "10", "--rotating-earth", *SITE[:5],
                 "--tracking-frame", "geodetic", "--tracking-output", str(d / "trk.csv")]) == 0
    return d


def _separated(boost, heading: float, capsys) -> tuple[int, dict, str]:
    tel = boost / f"tel_{heading:g}.csv"
    assert main(["navigate", str(boost / "imu.csv"), *SITE, "--align", "-10", "-1", "--heading", f"{heading:g}",
                 "--heading-axis", "y", "-o", str(tel)]) == 0
    out = boost / f"sep_{heading:g}.json"
    rc = main(["separate", str(tel), "--tracking", str(boost / "trk.csv"), "--tracking-frame", "geodetic", *SITE,
               "--model", "strapdown15_axial", "--json", str(out)])
    return rc, json.loads(out.read_text()), capsys.readouterr().out


def test_a_telemetry_navigated_10_deg_off_names_the_heading_first(boost, capsys):
    """The turn located within 3 of its std of the -10 deg navigated in (right-handed about the launch frame's up),
    the result failed with status -10, its message opening with the turn and the heading the data point to, the
    misfit it leaves after it."""
    rc, res, printed = _separated(boost, TRUE_HEADING + 10.0, capsys)
    test = res["diagnostics"]["heading"]["test"]
    assert rc == 1 and res["status"] == STATUS_PRIOR_CONFLICT, res["message"]
    assert test["conflict"] and test["explains"] and test["located"] and test["turned"] == "telemetry", test
    assert abs(test["turn_deg"] + 10.0) < 3 * test["std_deg"] and test["std_deg"] < 1.0, test
    assert abs(test["suggested_heading_deg"] - TRUE_HEADING) < 3 * test["std_deg"], test
    first, *rest = res["message"].split("\n")
    assert "the telemetry and the tracking are turned about the vertical against each other" in first, first
    assert f"navigate again with --heading {test['suggested_heading_deg']:.4g}" in first, first
    assert "may lack terms" not in first and "as slow as the record" not in first, first
    assert rest and rest[0].startswith("with the turn named above (the heading, or the frames), the other "
                                                "findings may be its consequences")
    assert math.isfinite(test["z"]) and test["z"] > test["limit_z"]


def test_a_telemetry_navigated_at_the_true_heading_is_not_turned(boost, capsys):
    """At the true heading no turn is named (the test runs only on a failed result; where it ran, no conflict)."""
    rc, res, _ = _separated(boost, TRUE_HEADING, capsys)
    test = (res["diagnostics"].get("heading") or {}).get("test") or {}
    assert res["status"] != STATUS_PRIOR_CONFLICT and not test.get("conflict"), res["message"]
    if test:
        assert abs(test["turn_deg"]) < 3 * test["std_deg"] or not np.isfinite(test["std_deg"]), test
