"""The robust filter judges each stretch of the tracking (casep.noise.robust.stretches: split at its pauses, the
outlier check's split) by its own noise level, and weights its rows by it: a 30 x noisier stretch after a
reacquisition keeps its good epochs; a real spike in it is still rejected."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from casep.estimators.solve import fit
from casep.estimators.spec import FitSpec
from casep.regression.problem import Problem
from casep.regression.rows import prepare_rows

QUIET, NOISY = 0.02, 0.6  # m/s: the noise before and after the pause
SPIKE = 106  # epoch of the spike, the 7th after the pause


def _flight(seed: int) -> tuple[Problem, np.ndarray, np.ndarray]:
    """100 epochs at 5 Hz (0.02 m/s white noise), a 5 s pause, 14 epochs at 5 Hz (0.6 m/s), a bias and a drift; a
    spike of 15 x 0.6 m/s on y at epoch SPIKE. Returns the problem, the truth and each epoch's noise std."""
    rng = np.random.default_rng(seed)
    t = np.concatenate([np.arange(100) * 0.2, 25.0 + np.arange(14) * 0.2])
    S = np.zeros((t.size, 3, 2))
    S[:, :, 0] = 1.0
    S[:, :, 1] = (t / 30.0)[:, None]
    x = np.array([0.5, -0.3])
    sig = np.where(np.arange(t.size) < 100, QUIET, NOISY)
    y = S @ x + sig[:, None] * rng.standard_normal((t.size, 3))
    y[SPIKE, 1] += 15 * NOISY
    return Problem.from_arrays(S, y, t, names=("a", "b")), x, sig


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_noisy_stretch_after_a_pause_keeps_its_good_epochs(seed):
    """Before: one scale for the whole flight (the quiet stretch's) rejected 13 of the 14 epochs after the pause."""
    pb, _, sig = _flight(seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the robust fit's own notes
        rows = prepare_rows(pb, "white", robust="huber")
        res = fit(pb, FitSpec.build("ols", noise="white", robust="huber"))
    assert list(np.flatnonzero(~rows.keep)) == [SPIKE]
    # independent: least squares with each epoch weighted by its true noise, the spike left out; the robust fit
    # within half its std of it, and its std within 20 % of that fit's (the noisy stretch weighted by its own noise)
    keep = np.arange(pb.t.size) != SPIKE
    A = (pb.sv()[keep] / sig[keep, None, None]).reshape(-1, 2)
    b = (pb.y[keep] / sig[keep, None]).reshape(-1)
    ref = np.linalg.lstsq(A, b, rcond=None)[0]
    ref_std = np.sqrt(np.diag(np.linalg.inv(A.T @ A)))
    assert np.all(np.abs(res.estimate - ref) < 0.5 * ref_std), (res.estimate, ref, ref_std)
    np.testing.assert_allclose(res.std, ref_std, rtol=0.2)


def test_one_stretch_is_the_whole_flights_scale():
    """Without a pause the scale is the whole flight's, as before: no per-stretch weights."""
    from casep.noise.model import NoiseModel
    from casep.noise.robust import robust_filter

    rng = np.random.default_rng(4)
    t = np.arange(200) * 0.1
    e = 0.1 * rng.standard_normal((t.size, 3))
    e[50, 0] += 2.0
    rw = robust_filter(e, t, NoiseModel.white())
    assert rw.precision is None and list(rw.rejected) == [50]
    assert rw.row_weights is rw.weights
