"""The ``casep`` parser and :func:`main`: one module per command (``add_parser``, ``run``), dispatched here.

Exit status: 0 success, 2 bad usage or bad input (one line on stderr: argparse's, or the API's ``ValueError``/
``TypeError``/``OSError`` message, here in one place), 1 anything else, including
a result that is not successful (``success`` false: table and JSON still written); 141 (quietly, like any Unix
tool ended by SIGPIPE) when the reader of stdout closes early (``casep models | head -1``).
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import importlib
import os
import sys
from typing import Any, Callable, NoReturn, Sequence

from casep._version import __version__
from casep.cli.blas import blas_threads_limited
from casep.cli.capture import print_warnings, recorded
from casep.cli.ending import freeze_at_exit
from casep.exceptions import refused_option

__all__ = ["main", "build_parser", "COMMANDS", "EXIT_BROKEN_PIPE"]

#: The commands in the order ``casep --help`` lists them; each is the module ``casep.cli.<name>``.
COMMANDS = ("separate", "simulate", "diagnose", "noise", "demo", "montecarlo", "fuse", "methods", "models", "impact",
            "design", "calibrate", "navigate")

#: Exit status when the reader of stdout goes away (``casep ... | head``): 128 + SIGPIPE, what the
#: shell reports for any Unix tool ended by the broken pipe, so ``set -o pipefail`` sees the same.
EXIT_BROKEN_PIPE = 141

class Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line (exit 2) and that refuses a one-value option given twice."""

    def error(self, message: str) -> NoReturn:  # one line, exit 2, main's form; "option --sigma (`sigma`) ..."
        self.exit(2, f"casep: error: {refused_option(message)}\n")

    def _check_value(self, action: argparse.Action, value: Any) -> None:  # the one form of a refused option
        if action.choices is not None and action.option_strings and value not in action.choices:
            from casep.cli.types import choice_refusal  # (casep --help imports no registry)
            raise argparse.ArgumentError(action, choice_refusal(action, value))
        super()._check_value(action, value)

    def parse_known_args(self, args: Any = None, namespace: Any = None) -> Any:
        given = self._given(sys.argv[1:] if args is None else list(args))
        ns, rest = super().parse_known_args(args, namespace)
        # the options given on the command line, by destination (a value equal to the default is given too)
        ns.given = frozenset(getattr(ns, "given", frozenset())) | {a.dest for a, _ in given}
        return ns, rest

    def _action(self, token: str) -> argparse.Action | None:
        """This parser's option that `token` names (an unambiguous prefix too, as argparse reads it), or None."""
        if not token.startswith("-"):
            return None
        name = token.split("=", 1)[0]
        action = self._option_string_actions.get(name)
        if action is None and self.allow_abbrev and name.startswith("--"):
            hits = {id(a): a for s, a in self._option_string_actions.items() if s.startswith(name)}
            action = next(iter(hits.values())) if len(hits) == 1 else None
        return action

    def _given(self, argv: list[str]) -> list[tuple[argparse.Action, str]]:
        """This parser's options in `argv` (a subcommand's parser reads its own); one given twice is refused."""
        out = []
        for token in argv:
            if token == "--":
                break
            action = self._action(token)
            if action is not None:
                out.append((action, token))
        self._refuse_repeated(out)
        return out

    def _refuse_repeated(self, given: list[tuple[argparse.Action, str]]) -> None:
        """An option that takes one value (``--launch-site``, ``--model``) given twice is an error: argparse
        would keep the last silently. Options that collect (``--tracking``, once per flight) may repeat."""
        seen: dict[int, str] = {}
        collect = (argparse._AppendAction, argparse._CountAction, argparse._HelpAction, argparse._VersionAction)
        for action, token in given:
            if isinstance(action, collect):
                continue
            if id(action) in seen:
                self.error(f"{token.split('=', 1)[0]} given twice: it takes one value (argparse would keep the last "
                           "silently); flights with their own set-up go in a manifest (--manifest FLIGHTS.toml)")
            seen[id(action)] = token


def _command(name: str) -> Any:
    return importlib.import_module(f"casep.cli.{name}")


def build_parser() -> argparse.ArgumentParser:
    """The ``casep`` argument parser, with every command and option.

    Returns
    -------
    argparse.ArgumentParser
        A new parser; the documentation's command-line reference is generated from it.
    """
    p = Parser(prog="casep", description="Guidance instrumentation error separation.")
    p.add_argument("--version", action="version", version=f"casep {__version__}")
    sub = p.add_subparsers(dest="command", required=True, parser_class=Parser)
    for name in COMMANDS:
        _command(name).add_parser(sub)
    return p


def _quiet_on_broken_pipe(run: Callable[..., int]) -> Callable[..., int]:
    """Wrap `run` so a closed stdout ends it quietly with :data:`EXIT_BROKEN_PIPE` (the Python recipe, "Note on
    SIGPIPE": flush inside the guard, then point stdout at /dev/null so the interpreter's final flush is silent),
    and the objects alive at exit out of its last garbage collections (:func:`casep.cli.ending.freeze_at_exit`)."""
    @functools.wraps(run)
    def guarded(argv: Sequence[str] | None = None) -> int:
        freeze_at_exit()
        try:
            status = run(argv)
            sys.stdout.flush()
            return status
        except BrokenPipeError:
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
            os.close(devnull)
            return EXIT_BROKEN_PIPE

    return guarded


@_quiet_on_broken_pipe
def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status."""
    args = build_parser().parse_args(argv)
    args.argv = ["casep", *(sys.argv[1:] if argv is None else argv)]  # the command line, for the provenance
    from casep.io._atomic import output_group

    # outputs all or none (not montecarlo: its --out keeps each finished part); the warnings said before an error too
    group, caught = contextlib.nullcontext() if args.command == "montecarlo" else output_group(), []
    try:
        with blas_threads_limited(), recorded(passed_on=False) as caught, group:
            status = int(_command(args.command).run(args))
    except BrokenPipeError:
        raise  # the reader left: quiet exit, see _quiet_on_broken_pipe
    except (ValueError, TypeError, OSError) as exc:  # FlightDataError, ModelDefinitionError among them
        print_warnings(caught)
        print(f"casep: error: {exc}", file=sys.stderr)
        return 2
    print_warnings(caught)  # casep's warnings on stderr, after the report (ill-conditioning: in the table)
    return status
