"""The usable core count (casep._cores): the CPU affinity, used by every default that counts cores."""

from __future__ import annotations

import os

import pytest

from casep._cores import usable_cores

affinity = pytest.mark.skipif(not hasattr(os, "sched_setaffinity"), reason="no CPU affinity on this platform")


@affinity
def test_usable_cores_follow_the_affinity_and_monte_carlo_uses_them():
    from casep.montecarlo.inputs import check_options

    allowed = os.sched_getaffinity(0)
    assert usable_cores() == len(allowed)
    one = min(allowed)
    os.sched_setaffinity(0, {one})  # as a container or `taskset -c 0` would
    try:
        assert usable_cores() == 1
        assert check_options(2, 0, ["ols"], None, "white", None, None)[3] == 1  # default workers
        assert check_options(2, 0, ["ols"], 3, "white", None, None)[3] == 3  # asked: as asked
    finally:
        os.sched_setaffinity(0, allowed)
    assert usable_cores() == len(allowed)


def test_without_affinity_the_cpu_count(monkeypatch):
    import casep._cores as cores

    monkeypatch.delattr(cores.os, "sched_getaffinity")
    monkeypatch.setattr(cores.os, "cpu_count", lambda: None)  # unknown: one core
    assert usable_cores() == 1
    monkeypatch.setattr(cores.os, "cpu_count", lambda: 5)
    assert usable_cores() == 5
