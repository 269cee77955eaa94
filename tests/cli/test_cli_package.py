"""The command-line package casep.cli: one module per command, each small; the API's errors exit 2."""

import importlib
from pathlib import Path

import pytest

import casep.cli
from casep.cli import build_parser, main
from casep.cli.app import COMMANDS

CLI = Path(casep.cli.__file__).parent


def test_every_command_is_one_module_with_add_parser_and_run():
    sub = next(a for a in build_parser()._actions if a.dest == "command")
    assert list(sub.choices) == list(COMMANDS)
    for name in COMMANDS:
        module = importlib.import_module(f"casep.cli.{name}")
        assert callable(module.add_parser) and callable(module.run), name


def test_modules_are_small():
    sizes = {p.name: len(p.read_text().splitlines()) for p in CLI.glob("*.py")}
    assert max(sizes.values()) <= 150, sizes


@pytest.mark.parametrize("argv, message", [
    (["design", "--knots", "1"], "option --knots (`knots`) must be an int >= 2, got 1"),  # the API's check
])
def test_the_api_check_is_the_message(argv, message, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err == f"casep: error: {message}\n"


def test_workers_is_a_count_of_processes(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["montecarlo", "--workers", "0"])
    assert exc.value.code == 2
    assert "option --workers (`workers`) must be >= 1, got 0" in capsys.readouterr().err


@pytest.mark.parametrize("argv, message", [  # every command's option errors in the one form
    (["simulate", "--rate", "-3", "-o", "x.csv"], "option --rate (`rate`) must be finite and > 0, got -3"),
    (["montecarlo", "--runs", "-2"], "option --runs (`runs`) must be >= 0, got -2"),
])
def test_option_errors_of_every_command_have_one_form(argv, message, capsys):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2 and message in capsys.readouterr().err
