"""Failure statuses: one status, one meaning, all defined beside :func:`casep.estimators.registry.failed`."""

import numpy as np

from casep.estimators import _base as registry  # where every status is defined


def test_every_failure_status_is_distinct_and_negative():
    values = list(registry.FAILURE_STATUSES.values())
    assert len(set(values)) == len(values), registry.FAILURE_STATUSES
    assert all(v < 0 for v in values)
    named = {k: v for k, v in vars(registry).items() if k.startswith("STATUS_")}
    assert sorted(named.values()) == sorted(values), named  # every STATUS_ name is in the table


def test_status_follows_what_the_data_determine_not_each_coefficient_alone(rng):
    """Every column exactly dependent on another (c0 = c1, c2 = -2 c3): no coefficient is identifiable on its
    own, but the fit determines 2 combinations (c0 + c1 and c2 - 2 c3), to their least-squares values: a result
    (status 2), not "nothing identifiable". Only zero columns (rank 0) determine nothing: status -1."""
    import casep

    a, b = rng.normal(size=(2, 200))
    S = np.column_stack([a, a, b, -2.0 * b])
    x = np.array([1.0, 2.0, -0.5, 0.25])
    y = S @ x + 1e-3 * rng.normal(size=200)
    res = casep.solve_ols(S, y)
    assert res.success and res.status == 2 and res.rank == 2, res.message
    assert np.all(np.isnan(res.estimate)) and "the data determine 2 combinations" in res.message
    fitted = res.fitted_coefficients()  # the combinations, independently: the fit of [a, b] alone
    ref = np.linalg.lstsq(np.column_stack([a, b]), y, rcond=None)[0]
    np.testing.assert_allclose([fitted[0] + fitted[1], fitted[2] - 2.0 * fitted[3]], ref, rtol=0, atol=1e-10)
    zero = casep.solve_ols(np.zeros((200, 2)), y)
    assert not zero.success and zero.status == registry.STATUS_NONE_DETERMINED, zero.message
