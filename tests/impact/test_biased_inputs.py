"""A regularised result as an input says that its std leave out its bias.

Before: ``casep impact`` on a ridge result (lambda 0.1) printed a downrange miss of 3747 +- 2.95 m, 95 std from
the true 3465 m, with no word (RMS of (estimate - truth) / std over the coefficients 1220). Now every use of a
result as an input (impact, fuse, a prior: :func:`casep.estimators.reading.read_input_result`) warns for
ridge and PCR, and for a bounded fit with a bound active; a bounded fit with none active is least squares.
"""

from __future__ import annotations

import pytest

from casep.cli import main


@pytest.fixture(scope="module")
def flight(tmp_path_factory):
    from casep.simulation.simulate import simulate_flight, write_simulation

    d = tmp_path_factory.mktemp("biased")
    write_simulation(simulate_flight("paper", seed=5, rate=5.0), d / "a.csv")
    return d


def _result(flight, capsys, name: str, *method: str) -> str:
    out = flight / f"{name}.json"
    assert main(["separate", str(flight / "a.csv"), *method, "--noise", "white", "--robust", "none",
                 "--json", str(out)]) in (0, 1)
    capsys.readouterr()
    return str(out)


@pytest.mark.parametrize("name, method, warned", [
    ("ridge", ["--method", "ridge", "--lambda", "0.1"], True),
    ("pcr", ["--method", "pcr", "--components", "10"], True),
    ("ols", [], False),
])
def test_impact_of_a_regularised_result_warns(flight, capsys, name, method, warned):
    res = _result(flight, capsys, name, *method)
    code = main(["impact", str(flight / "a.csv"), "--result", res])
    printed = capsys.readouterr()
    text = printed.out + printed.err
    assert code == 0, printed.err
    said = f"--result {res}: a result of method {name}, whose std (sampling) leave out the bias"
    assert (said in text) is warned, text
    if warned:
        assert "a miss std" in text and "ols, gls, or map" in text


def test_a_bounded_fit_with_no_bound_active_is_not_warned_about(flight, capsys, tmp_path):
    import json

    from casep.estimators.reading import read_input_result

    box = tmp_path / "box.json"
    box.write_text(json.dumps({"Kg0x": [-1e6, 1e6]}))  # far from the estimate: never active
    res = _result(flight, capsys, "bounded", "--method", "bounded", "--bounds", str(box))
    r, _ = read_input_result(res, option="--result")  # would warn (an error here) for an active bound
    assert r.method == "bounded" and r.std_kind == "sampling"


def test_a_bounded_fit_with_a_bound_active_is_warned_about(flight, capsys, tmp_path):
    import json

    from casep.estimators.reading import read_input_result
    from casep.exceptions import BiasedStdWarning

    box = tmp_path / "tight.json"
    box.write_text(json.dumps({"Kg0x": [0.0, 1e-6]}))  # a box the estimate leans on
    res = _result(flight, capsys, "bounded_active", "--method", "bounded", "--bounds", str(box))
    with pytest.warns(BiasedStdWarning, match="method bounded, whose std \\(conditional\\)"):
        r, _ = read_input_result(res, option="--result")
    assert r.std_kind == "conditional"
