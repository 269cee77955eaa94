"""A manifest's ``[fit]`` table is a fit request (casep.FitSpec), built and checked when the manifest is read.

The third edge of a request (after the API's keywords and the command line's arguments): the same
FitSpec as the keywords, the same one-form errors naming the option and here the manifest and its
table, and with ``casep separate --manifest`` the request of the manifest, a fit option on the command
line too refused whatever its value (a value equal to the default is given too).
"""

from __future__ import annotations

import json
import textwrap

import numpy as np
import pytest

import casep
from casep.cli import main
from casep.estimators.spec import FitSpec


@pytest.fixture(scope="module")
def two(tmp_path_factory):
    from casep.simulation.simulate import simulate_flight

    folder = tmp_path_factory.mktemp("manifest_fit")
    for seed, name in ((0, "paper"), (1, "paper-pitch")):
        casep.write_flight(simulate_flight(name, seed=seed, rate=10.0).flight, folder / f"{name}.csv")
    flights = '[[flight]]\ntelemetry = "paper.csv"\n\n[[flight]]\ntelemetry = "paper-pitch.csv"\n'
    (folder / "plain.toml").write_text(flights)
    (folder / "fit.toml").write_text(flights + textwrap.dedent("""
        [fit]
        method = "ridge"
        options = { lam = 0.1 }
        noise = "white"
        robust = "none"
        """))
    return folder


def test_manifest_fit_table_is_the_keywords_fitspec(two):
    man = casep.read_manifest(two / "fit.toml")
    assert man.spec() == FitSpec.build("ridge", options={"lam": 0.1}, noise="white", robust="none")
    assert casep.read_manifest(two / "plain.toml").spec() is None


def test_manifest_fit_fits_as_the_command_line(two, capsys):
    by_man, by_line = two / "man.json", two / "line.json"
    assert main(["separate", "--manifest", str(two / "fit.toml"), "--json", str(by_man)]) == 0
    assert main(["separate", "--manifest", str(two / "plain.toml"), "--method", "ridge", "--lambda", "0.1",
                 "--noise", "white", "--robust", "none", "--json", str(by_line)]) == 0
    capsys.readouterr()
    m, c = json.loads(by_man.read_text()), json.loads(by_line.read_text())
    assert m["method"] == "ridge" and m["settings"]["lambda"] == 0.1 == c["settings"]["lambda"]
    np.testing.assert_allclose(np.array(m["estimates"], dtype=float), np.array(c["estimates"], dtype=float),
                               rtol=1e-12, atol=0.0)
    assert m["provenance"]["manifest"]["fit"]["method"] == "ridge"


@pytest.mark.parametrize("flags", [["--method", "ols"], ["--noise", "auto"], ["--lambda", "0.1"], ["--rob", "auto"]])
def test_a_fit_option_on_the_command_line_too_is_refused(two, capsys, flags):
    """The default value (``--noise auto``) and an abbreviation (``--rob``) count as given."""
    assert main(["separate", "--manifest", str(two / "fit.toml"), *flags]) == 2
    err = capsys.readouterr().err
    flag = {"--rob": "--robust"}.get(flags[0], flags[0])
    assert "holds the fit request (its [fit] table): leave out " + flag in err


@pytest.mark.parametrize("table, message", [
    ('method = "ridge"\noptions = { lam = -1.0 }', "option --lambda (`lam`) of method `ridge` must be"),
    ('method = "ols"\noptions = { p0 = 1.0 }', "option --p0 (`p0`) is not taken by method `ols`"),
    ('method = "rls"\np0 = 1.0\noptions = { p0 = 1.0 }', "option --p0 (`p0`) given both as a keyword and in `options`"),
    ('noise = "pink"', "noise"),
])
def test_a_bad_fit_table_is_refused_when_read(two, table, message):
    path = two / "bad.toml"
    path.write_text((two / "plain.toml").read_text() + "\n[fit]\n" + table + "\n")
    with pytest.raises(ValueError) as e:
        casep.read_manifest(path)
    assert str(e.value).startswith(f"manifest {path}: table [fit]: ") and message in str(e.value)


@pytest.mark.parametrize("flags, flag", [(["--tracking-frame", "launch"], "--tracking-frame"),
                                         (["--grid", "tracking"], "--grid"), (["--time-shift", "0"], "--time-shift")])
def test_a_set_up_option_at_its_default_with_a_manifest_is_given(two, capsys, flags, flag):
    """The manifest holds each flight's set-up: a single-flight option is refused even at its default value."""
    assert main(["separate", "--manifest", str(two / "plain.toml"), *flags]) == 2
    assert f"leave out {flag} (they describe one flight" in capsys.readouterr().err
