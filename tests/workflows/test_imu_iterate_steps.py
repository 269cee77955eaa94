"""The step control of the iterated IMU separation (:mod:`casep.workflows.imu_separate`): the secant step's metric
and the descent test of a white pass, against closed-form maps and sums; the flight they were found on (the shipped
MEMS example under ``strapdown33``) is ``test_imu_separate_strapdown33.py``."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from casep.workflows.imu_separate import WORSE, _Run, _secant_step


def _whiten(q: np.ndarray, sig: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """``W = diag(1 / sig) q^T / scale``: :attr:`Step.metric` of the combinations ``q`` (columns) of std ``sig``."""
    return q.T / sig[:, None] / scale


def test_the_secant_step_finds_a_contracting_maps_fixed_point_when_no_coefficient_has_a_std_of_its_own():
    """Four coefficients in two exactly dependent pairs (``a + b``, ``c - d`` determined; no coefficient has a std):
    a pass's correction is ``d(D) = (1 - rho) P (D* - D)`` along one determined combination (``P`` its projector),
    the passes contracting by ``rho = 0.64``. The secant step through two passes lands on ``D*`` along it (closed
    form: the root of a linear map's secant is its fixed point). With the coefficients' own std (NaN) as the metric
    the step was the plain one, and the passes contracted by 0.64 each."""
    scale = np.array([1.0, 1.0, 60.0, 60.0])
    q = np.array([[1.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, -1.0]]).T / np.sqrt(2.0)  # on D / scale
    sig = np.array([0.5, 3.0])
    W = _whiten(q, sig, scale)
    g = scale * q[:, 0]  # the contracting direction, natural units
    P = np.outer(g, g) / (g @ g)
    rho, target = 0.64, np.array([7.0, -2.0, 300.0, 120.0])

    def d_of(D):
        return (1.0 - rho) * P @ (target - D)

    D0 = np.zeros(4)
    D1 = D0 + d_of(D0)
    step = _secant_step(D1, d_of(D1), W, (D0, d_of(D0)))
    assert np.allclose(P @ (D1 + step), P @ target, rtol=0, atol=1e-9 * np.abs(target).max())
    assert np.abs(P @ (D1 + d_of(D1) - target)).max() > 0.3 * np.abs(P @ (D0 - target)).max()  # the plain step
    nan_std = np.full(4, np.nan)
    own = np.eye(4)[np.isfinite(nan_std)]  # what the coefficients' own std give: no row, the plain step
    assert np.array_equal(_secant_step(D1, d_of(D1), own, (D0, d_of(D0))), d_of(D1))
    assert np.array_equal(_secant_step(D1, d_of(D1), W, None), d_of(D1))  # no pass before: the plain step


def _fake_run(rows_after: np.ndarray, data_scale: float = 100.0) -> _Run:
    """A run whose pass at any D has the rows `rows_after` (its solve replaced: the decision alone is tested)."""
    run = object.__new__(_Run)
    run.nav, run.imu_k, run.model_k, run.q_aligned, run.C_tb = "nav", "imu", "model", "q", "C"
    run.data_scale = data_scale

    def solve(D, spec):
        run.nav = "moved"  # what a pass leaves on the run, restored when its step is rejected
        return ("res", "nav", "flight", "model", SimpleNamespace(y=rows_after))
    run.solve = solve
    return run


@pytest.mark.parametrize(("after_rms", "bound", "kept"), [
    (0.9, 300.0, True),  # descends
    (1.2, 300.0, False),  # rises above the bound: a white pass's step is rejected ...
    (1.2, 500.0, True),  # ... unless below a pass before's sum (the non-monotone bound)
    (1.2, None, True),  # ... and the tenfold rule of a pass solved as requested keeps it
    (10.5, None, False),
])
def test_a_white_pass_step_must_keep_the_rows_sum_of_squares_within_its_bound(after_rms, bound, kept):
    """Rows of RMS 1 m/s before the step (300 of them: sum 300 m^2/s^2), `after_rms` after: with a bound (a white
    pass) the step is kept when their sum of squares is within it; without, when their RMS is within WORSE times."""
    before = SimpleNamespace(y=np.ones((100, 3)))
    run = _fake_run(np.full((100, 3), after_rms))
    out = run.trial(np.zeros(2), None, before, bound)
    assert isinstance(out, tuple) == kept, out
    if not kept:
        assert run.nav == "nav"  # the last pass's state restored
        assert ("does not descend" in out) == (bound is not None), out
    assert WORSE == 10.0


def test_rows_at_the_rounding_level_are_kept_whatever_their_rise():
    """A noise-free record's rows at 1e-11 of its data rising to 1e-10: rounding, not a step outside the model."""
    before = SimpleNamespace(y=np.full((100, 3), 1e-11))
    out = _fake_run(np.full((100, 3), 1e-10), data_scale=10.0).trial(np.zeros(2), None, before, 0.0)
    assert isinstance(out, tuple)


def _pad_at_rest(directory):
    """16 s at rest on the pad (45 N, 100 m), a quiet IMU at 5 Hz (white noise 1e-3 m/s^2, 1e-5 rad/s), geodetic
    tracking at rest at 1 Hz (white noise 0.02 m/s): (imu, tracking, site)."""
    from casep.frames import LaunchSite
    from casep.gravity import normal_gravity
    from casep.io.files import write_table
    from casep.navigation import ImuData

    T, lat, wE = 16.0, np.radians(45.0), 7.292115e-5
    rng = np.random.default_rng(0)
    t = np.arange(0, T, 0.2)
    f = np.tile([0, 0, normal_gravity(45.0, 100.0)], (t.size, 1)) + rng.normal(0, 1e-3, (t.size, 3))
    w = np.tile([0, wE * np.cos(lat), wE * np.sin(lat)], (t.size, 1)) + rng.normal(0, 1e-5, (t.size, 3))
    tt = np.arange(0, T, 1.0)
    v = rng.normal(0, 0.02, (tt.size, 3))
    trk = directory / "trk.csv"
    write_table(trk, {"t": tt, "lat": np.full(tt.size, 45.0), "lon": np.full(tt.size, 10.0),
                      "h": np.full(tt.size, 100.0), "v_east": v[:, 0], "v_north": v[:, 1], "v_up": v[:, 2]})
    return ImuData(t, w, f), trk, LaunchSite(45.0, 10.0, 100.0, 90.0, T / 2)


@pytest.mark.parametrize("refused", ["halvings", "halvings + 1"])
def test_a_white_pass_step_that_does_not_descend_is_halved_then_narrowed(tmp_path, monkeypatch, refused):
    """A pad record at rest under ``strapdown12`` whose first white pass's step the test makes not descend (its
    first `refused` trials, :data:`HALVINGS` or one more, said not to descend): the same step is tried at 1, 1/2, ...
    of its size. Refused HALVINGS times, the step of ``1 / 2^HALVINGS`` is taken (``damped``) and the passes go on
    to convergence; refused once more, the halving stops there and the pass steps again without its widest
    combinations (``rejected``, the descent's reason), never a smaller fraction."""
    import warnings

    from casep.workflows.imu_separate import _NO_DESCENT, HALVINGS, separate_imu

    refused_n = HALVINGS + (refused == "halvings + 1")
    imu, trk, site = _pad_at_rest(tmp_path)
    judged, trial = [], _Run.trial

    def refusing(self, D, spec, before, bound=None):
        if bound is None:  # not a white pass's judged step
            return trial(self, D, spec, before, bound)
        judged.append(np.array(D, dtype=float))
        if len(judged) <= refused_n:
            return f"{_NO_DESCENT}: said by the test"
        return trial(self, D, spec, before, bound)

    monkeypatch.setattr(_Run, "trial", refusing)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # what the pad leaves undetermined: said by the result
        out = separate_imu(imu, trk, site, (0.0, 8.0), "strapdown12", heading_deg=90.0, tracking_frame="geodetic")
    first = out.result.diagnostics["iterations"]["passes"][0]
    step = judged[0]  # the first pass's full step from D = 0
    assert np.linalg.norm(step) > 0
    for k in range(HALVINGS + 1):  # the same step at 1, 1/2, ..., 1/2^HALVINGS
        np.testing.assert_allclose(judged[k], step * 0.5**k, rtol=1e-12, atol=0)
    if refused_n == HALVINGS:
        assert first.get("damped") == 0.5**HALVINGS and "rejected" not in first, first
        assert out.success and out.result.diagnostics["iterations"]["converged"], out.message
    else:
        assert "damped" not in first and len(first["rejected"]) == 1, first
        assert first["rejected"][0]["why"] == f"{_NO_DESCENT}: said by the test"
        assert not any(np.allclose(D, step * 0.5 ** (HALVINGS + 1)) for D in judged[HALVINGS + 1:])  # not halved again
