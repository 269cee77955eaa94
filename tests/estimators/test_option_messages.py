"""Every option of a fit request is refused in one message form, in the API and on the command line:
``option --FLAG (`keyword`)[ of method `m`] must be RULE, got VALUE``."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

import casep
from casep.cli import main
from casep.estimators.spec import FitSpec

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "data" / "example_flight.csv"
FORM = re.compile(r"option (--[a-z-]+) \(`(\w+)`\)( of method `\w+`)? must be .+, got .+")

# (keyword, its command-line flag, bad value in the API, the same on the command line, other arguments)
CASES = [
    ("method", "--method", "lsq", "lsq", {}),
    ("sigma", "--sigma", -1.0, "-1", {}),
    ("noise", "--noise", "pink", "pink", {}),
    ("tau", "--tau", -1.0, "-1", {}),
    ("robust", "--robust", "tukey", "tukey", {}),
    ("std", "--std", "sandwich", "sandwich", {}),
    ("exclude_outliers", "--exclude-outliers", 2.0, "2", {}),
    ("outliers", "--outliers", 2.0, "2", {}),
    ("denoise", "--denoise", "fourier", "fourier", {}),
    ("lam", "--lambda", "aic", "aic", {"method": "ridge"}),
    ("max_condition_index", "--max-condition-index", -1.0, "-1", {"method": "pcr"}),
]


def _assert_form(message: str, name: str, flag: str) -> None:
    m = FORM.fullmatch(message.strip())
    assert m is not None, message
    assert (m.group(1), m.group(2)) == (flag, name), message


@pytest.mark.parametrize(("name", "flag", "value", "text", "other"), CASES, ids=[c[0] for c in CASES])
def test_api_refusal_names_flag_and_keyword(name, flag, value, text, other):
    kw = {**other, name: value}
    method = kw.pop("method", "ols")
    with pytest.raises(ValueError) as e:
        FitSpec.build(method, **kw)
    _assert_form(str(e.value), name, flag)


CLI_CASES = [c for c in CASES if c[0] != "max_condition_index"]  # a solver keyword of the API only


@pytest.mark.parametrize(("name", "flag", "value", "text", "other"), CLI_CASES, ids=[c[0] for c in CLI_CASES])
def test_cli_refusal_in_the_same_form(name, flag, value, text, other, capsys):
    args = ["separate", str(EXAMPLE)] + [a for k, v in other.items() for a in (f"--{k}", v)] + [flag, text]
    try:
        code = main(args)
    except SystemExit as exc:  # argparse's refusal
        code = exc.code
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    _assert_form(err[0].split(": error: ", 1)[1], name, flag)


def test_cli_and_api_say_the_same(capsys):
    """The same refusal, word for word, whether the request comes from keywords or arguments."""
    with pytest.raises(ValueError) as e:
        FitSpec.build("ols", sigma=-1.0)
    with pytest.raises(SystemExit) as ex:
        main(["separate", str(EXAMPLE), "--sigma", "-1"])
    assert ex.value.code == 2
    assert capsys.readouterr().err.strip().endswith(str(e.value))


AXIS_FORM = re.compile(r"option --tau \(`tau`\) for axis (\w+) must be .+, got (.+)")


@pytest.mark.parametrize(("tau", "axis", "got"), [((1.0, -2.0, 1.0), "y", "-2.0"), ([1, 2, "a"], "z", "'a'"),
                                                  ({"x": 1.0, "y": 2.0, "z": 0.0}, "z", "0.0")],
                         ids=["tuple", "list", "mapping"])
def test_a_bad_tau_of_one_axis_is_named_by_its_axis(tau, axis, got):
    """Per-axis tau (the noise model's: a tuple, a list or a mapping by axis) refused naming the axis and its value."""
    with pytest.raises(ValueError) as e:
        FitSpec.build("ols", tau=tau)
    m = AXIS_FORM.fullmatch(str(e.value))
    assert m is not None and m.groups() == (axis, got), str(e.value)


def test_a_bad_tau_of_one_axis_on_the_command_line(capsys):
    """``--tau 1,-2,1``: three values for the noise model, the one of axis y refused in the API's words."""
    with pytest.raises(ValueError) as e:
        FitSpec.build("ols", tau=(1.0, -2.0, 1.0))
    assert main(["separate", str(EXAMPLE), "--tau", "1,-2,1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].endswith(str(e.value)), err


def test_tau_has_one_owner_wherever_it_is_given():
    """One rule: GLS owns tau (its option), every other method's tau is the noise model's, as a keyword or in
    `options`; given both ways it is refused whatever the values."""
    for where in ({"tau": 2.0}, {"options": {"tau": 2.0}}):
        gls, ols = FitSpec.build("gls", **where), FitSpec.build("ols", **where)
        assert (gls.options.get("tau"), gls.noise.tau) == (2.0, None)
        assert (ols.options.get("tau"), ols.noise.tau, ols.noise.kind) == (None, 2.0, "gm")
    assert FitSpec.build("ols", options={"tau": "auto"}).noise.tau is None
    assert FitSpec.build("ols", tau=(1.0, 2.0, 3.0)).noise.tau == (1.0, 2.0, 3.0)
    for method in ("ols", "gls"):
        with pytest.raises(ValueError, match="given both"):
            FitSpec(method, {"tau": 2.0}, noise=casep.NoiseSpec(tau=2.0))
