"""Failure statuses: one status, one meaning, all defined beside :func:`casep.estimators.registry.failed`."""

from casep.estimators import _base as registry  # where every status is defined


def test_every_failure_status_is_distinct_and_negative():
    values = list(registry.FAILURE_STATUSES.values())
    assert len(set(values)) == len(values), registry.FAILURE_STATUSES
    assert all(v < 0 for v in values)
    named = {k: v for k, v in vars(registry).items() if k.startswith("STATUS_")}
    assert sorted(named.values()) == sorted(values), named  # every STATUS_ name is in the table
