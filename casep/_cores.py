"""The number of cores this process may use: one rule for every default that counts cores."""

from __future__ import annotations

import os

__all__ = ["usable_cores"]


def usable_cores() -> int:
    """The cores this process may run on: its CPU affinity where the platform tells it
    (``os.sched_getaffinity``: a container or ``taskset`` may allow fewer than the machine has), else the
    machine's CPU count; at least 1."""
    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return os.cpu_count() or 1
