"""The end of a casep process (casep.cli.ending): the objects alive at exit are out of the last collections."""

from __future__ import annotations

import subprocess
import sys


def test_objects_alive_at_exit_are_frozen_once():
    # gc.freeze counted; an atexit function registered first runs last: it sees what happened at exit
    code = ("import atexit, gc\n"
            "calls, freeze = [], gc.freeze\n"
            "gc.freeze = lambda: (calls.append(1), freeze())[1]\n"
            "atexit.register(lambda: print('at exit', len(calls), gc.get_freeze_count() > 0))\n"
            "from casep.cli.ending import freeze_at_exit\n"
            "freeze_at_exit(); freeze_at_exit()\n"
            "print('before exit', len(calls), gc.get_freeze_count() > 0)\n")
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True).stdout.split("\n")
    assert out[:2] == ["before exit 0 False", "at exit 1 True"]
