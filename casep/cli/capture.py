"""casep's warnings during a command: recorded, then printed as ``warning:`` lines on stderr, after the report.

The report (the table, the summary) is stdout, so that it can be redirected or piped clean; the warnings go with
the errors. The ill-conditioning warning is not printed (the table says it); warnings that are not casep's are
passed on to Python's warning machinery as they were.
"""

from __future__ import annotations

import contextlib
import sys
import warnings
from typing import Iterator

from casep.exceptions import CasepWarning, IllConditionedWarning

__all__ = ["recorded", "report_lines", "print_warnings", "raised_so_far"]

#: The warning lists of the recorders now open, outermost first (:func:`raised_so_far` reads them).
_OPEN: list[list[warnings.WarningMessage]] = []


@contextlib.contextmanager
def recorded(passed_on: bool = True) -> Iterator[list[warnings.WarningMessage]]:
    """Record every warning of the block (casep's always, even if seen before).

    With `passed_on`, the recorded warnings are issued again when the block ends, for the
    enclosing recorder (:func:`casep.cli.main`'s) to print; the list stays available (the
    HTML report quotes them).
    """
    caught: list[warnings.WarningMessage] = []
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", CasepWarning)
            _OPEN.append(caught)
            try:
                yield caught
            finally:
                del _OPEN[next(i for i, c in enumerate(_OPEN) if c is caught)]
    finally:  # passed on when the block raises too: the enclosing recorder says them before the error
        if passed_on:
            for w in caught:
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)


def report_lines(caught: list[warnings.WarningMessage]) -> list[str]:
    """The messages of casep's warnings other than the ill-conditioning one."""
    return [str(w.message) for w in caught if issubclass(w.category, CasepWarning)
            and not issubclass(w.category, IllConditionedWarning)]


def print_warnings(caught: list[warnings.WarningMessage]) -> None:
    """Print casep's warnings as ``warning:`` lines on stderr; pass the others on."""
    for w in caught:
        if issubclass(w.category, CasepWarning) and not issubclass(w.category, IllConditionedWarning):
            print(f"warning: {w.message}", file=sys.stderr)
        elif not issubclass(w.category, CasepWarning):
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)


def raised_so_far() -> list[str]:
    """casep's warnings of the command so far (:func:`report_lines` of every open recorder, each once, in order):
    what a result file records of its run (``provenance["warnings"]``)."""
    lines: list[str] = []
    for caught in _OPEN:
        lines += [line for line in report_lines(caught) if line not in lines]
    return lines
