"""The residual test for a tracking time offset (and a jerk term) of :func:`casep.checks.plausibility.check_fit`.

Tracking time tags late by dt give ``dv += a(t) dt``: a regressor outside the span of S_V, which
:func:`time_offset_test` finds in the residuals by an augmented regression (see its notes).

Across a telemetry gap (an INS navigated across lost IMU samples) the velocity error may jump: the
bridge leaves the velocity and the attitude known only to its bounds. Where the gap meets a change of
the acceleration (a burnout), that jump is a step in the residuals at the same time as a step in
``a(t)``, and would read as an offset: the test carries the jump as a nuisance
(:func:`gap_columns`).

At a step of the acceleration (a burnout within one sample) the first-order term fails: ``v(t - dt)``
ramps from ``a_before dt`` to ``a_after dt`` over the samples within ``dt`` after the step, while
``a(t) dt`` jumps at the first sample after it. Under Gauss-Markov noise, whose whitened rows are nearly
the velocity increments, the offset is read mostly off that step, and the ramp read as a jump biases it
(a 30 ms offset at a 50 Hz burnout read as 19.5 +- 1.6 ms). The test frees those samples
(:func:`step_rows`: one free velocity per axis each, the same as leaving them out before whitening): the
increment across them still carries the step's ``(a_after - a_before) dt``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from casep._kernels import cumulative_trapezoid
from casep.gravity import GRAVITY_LAUNCH, kinematic_acceleration
from casep.regression.linalg import reduce_qr_blocks

__all__ = ["TimeOffsetTest", "time_offset_test", "kinematic_acceleration", "GRAVITY_LAUNCH", "row_blocks",
           "is_problem", "shares_problem_test", "problem_time_offset_test", "gap_columns", "acceleration_steps",
           "step_rows", "STEP_RATIO", "STEP_WINDOW", "STEP_MAX_ROWS", "EFFECT_MIN"]

#: A sample-to-sample change of the acceleration beyond this many times the median of the changes within
#: :data:`STEP_WINDOW` samples of it is a step (:func:`acceleration_steps`).
STEP_RATIO = 10.0
STEP_WINDOW = 5
#: Samples freed after (or before) a step at most: an offset bound beyond this many samples is no step's.
STEP_MAX_ROWS = 25
#: m/s: RMS of a term's part outside span S_V below which it cannot matter against any tracking noise (keeps
#: noise-free data, where every effect is "significant", quiet); also the least ramp a step freed must leave.
EFFECT_MIN = 1e-3


@dataclass(frozen=True)
class TimeOffsetTest:
    """Augmented-regression test of the residuals for a tracking time offset and a jerk term.

    Attributes
    ----------
    offset, offset_std, offset_t : float
        Coefficient of ``a(t)`` (s; a tracking time offset dt_trk), its std and t-statistic.
    jerk, jerk_std, jerk_t : float
        Coefficient of ``da/dt`` (s^2), its std and t-statistic (NaN when not testable).
    offset_rms, jerk_rms : float
        RMS over the 3N rows of each term's part outside span S_V, m/s: its practical size.
    freed : int
        Samples at steps of the acceleration left out of the test (:func:`step_rows`).
    inflation : float
        Variance factor ``(1 + rho) / (1 - rho)`` for the residuals' lag-1 correlation; 1 when the rows were
        whitened for the fit's noise model.
    """

    offset: float
    offset_std: float
    offset_t: float
    jerk: float
    jerk_std: float
    jerk_t: float
    inflation: float
    offset_rms: float = 0.0
    jerk_rms: float = 0.0
    freed: int = 0


def row_blocks(S) -> tuple:
    """``(blocks(), n, nonzero)``: (row slice, S block (k, 3, n)) in time order, for an array or a Problem."""
    if is_problem(S):
        return (lambda: ((sl, S_b) for sl, S_b, _ in S.blocks())), S.n, S.red.scale > 0
    S = np.asarray(S, dtype=float)
    N = S.shape[0]

    def blocks(rows: int = 16384):
        for s in range(0, N, rows):
            yield slice(s, min(s + rows, N)), S[s:s + rows]

    return blocks, S.shape[-1], np.any(S.reshape(-1, S.shape[-1]) != 0.0, axis=0)


def is_problem(S) -> bool:
    """A :class:`casep.regression.problem.Problem` (by its interface: problem.py imports this module)."""
    return hasattr(S, "blocks") and hasattr(S, "red") and hasattr(S, "has_rows")


def gap_columns(t: np.ndarray, f: np.ndarray, gaps) -> np.ndarray:
    """The velocity error a telemetry gap may leave after it, as columns (N, 3, 6 per gap): a velocity jump
    ``dv_gap`` and an attitude jump ``phi_gap`` across the gap ``(a, b)``, on the rows after it::

        dv(t) = dv_gap + (integral_b^t f ds) x phi_gap,      t >= b

    (``dv_dot = f x phi`` of a constant attitude error; the integral by the trapezoid rule on the rows'
    own times, exact for the piecewise-linear specific force the rows sample). Columns 0-2: the unit
    jumps of ``dv_gap``; 3-5: those of ``phi_gap``. A gap with no row after it gives no columns.
    """
    t = np.asarray(t, dtype=float)
    f = np.asarray(f, dtype=float).reshape(-1, 3)
    cols = []
    for _, b in gaps:
        after = t >= b
        if not after.any():
            continue
        k = int(np.argmax(after))
        F = np.zeros((t.size, 3))  # integral_b^t f ds at the rows after the gap (from its first row)
        F[k:] = cumulative_trapezoid(f[k:], t[k:])
        C = np.zeros((t.size, 3, 6))
        C[after, :, :3] = np.eye(3)
        for j in range(3):
            C[after, :, 3 + j] = np.cross(F[after], np.eye(3)[j])
        cols.append(C)
    return np.concatenate(cols, axis=2) if cols else np.zeros((t.size, 3, 0))


def acceleration_steps(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The samples ``k`` at which the acceleration `a` (N, 3) steps between samples ``k - 1`` and ``k`` (a
    burnout), and the steps' sizes, m/s^2.

    The change ``da_k = a_k - a_(k-1)`` is a step where its norm exceeds :data:`STEP_RATIO` times the median of
    the norms of the changes within :data:`STEP_WINDOW` samples of it: a change within one sample that stands out of
    the changes around it (a smooth acceleration, however fast, or a kink changes as its neighbours do; a noisy
    specific force's median is its noise's). A step that an averaging accelerometer spreads over two samples
    gives two changes, each found. Its size is the norm of the change.
    """
    a = np.asarray(a, dtype=float).reshape(-1, 3)
    if a.shape[0] < 4:
        return np.zeros(0, dtype=int), np.zeros(0)
    s = np.linalg.norm(np.diff(a, axis=0), axis=1)  # s[k - 1] = |a_k - a_(k-1)|
    s[~np.isfinite(s)] = 0.0
    # the running median over 2 STEP_WINDOW + 1 changes, the ends repeated (NumPy: SciPy's import is not paid on
    # every separate for it)
    padded = np.pad(s, STEP_WINDOW, mode="edge")
    around = np.median(np.lib.stride_tricks.sliding_window_view(padded, 2 * STEP_WINDOW + 1), axis=1)
    big = np.flatnonzero(s > STEP_RATIO * around)
    return big + 1, s[big]


def step_rows(t: np.ndarray, steps: tuple[np.ndarray, np.ndarray], offset: float, offset_std: float) -> np.ndarray:
    """The samples whose tracking, `offset` +- 2 `offset_std` (s) late, straddles a step of :func:`acceleration_steps`
    (``(samples, sizes)``) that matters: whose size times that bound exceeds :data:`EFFECT_MIN`.

    With tracking ``dt`` late, ``v_trk(t_j) = v(t_j - dt)`` mixes the accelerations before and after a step
    between ``t_(k-1)`` and ``t_k`` for ``t_k <= t_j < t_k + dt``: the samples ``k .. k + m - 1``,
    ``m = ceil(D / h)`` for the bound ``D = |offset| + 2 offset_std`` and the sample period ``h``, at most
    :data:`STEP_MAX_ROWS`; early tracking (``dt < 0``) the ``m`` before ``k``. One sample more on each side:
    where in its interval the step fell, and a specific force that averages over the interval, are unknown.
    """
    t = np.asarray(t, dtype=float)
    bound = abs(offset) + 2.0 * offset_std
    at = steps[0][steps[1] * bound > EFFECT_MIN] if np.isfinite(bound) else steps[0]
    if not at.size or t.size < 2:
        return np.zeros(0, dtype=int)
    h = float(np.median(np.diff(t)))
    m = int(min(np.ceil(bound / h), STEP_MAX_ROWS)) if np.isfinite(bound) and h > 0 else STEP_MAX_ROWS
    lo, hi = (-1, m) if offset >= 0 else (-m - 1, 0)
    rows = np.unique((at[:, None] + np.arange(lo, hi + 1)[None, :]).ravel())
    return rows[(rows >= 0) & (rows < t.size)]


def row_columns(n: int, rows: np.ndarray) -> np.ndarray:
    """One free velocity per axis at each of `rows` (sample indices), as columns (n, 3, 3 len(rows)): the same
    as leaving those samples out before whitening."""
    C = np.zeros((n, 3, 3 * len(rows)))
    for i, k in enumerate(rows):
        C[k, :, 3 * i:3 * i + 3] = np.eye(3)
    return C


def shares_problem_test(S, dv: np.ndarray) -> bool:
    """Whether the residuals are those of S's own Problem (so its one time-offset test applies)."""
    return is_problem(S) and S.y is not None and (dv is S.y or np.array_equal(dv, S.y))


def problem_time_offset_test(problem, t: np.ndarray, f: np.ndarray, noise=None):
    """:func:`time_offset_test`, once per Problem and noise model: by Frisch-Waugh-Lovell it depends on the
    residuals only through their part off span S, which is dv's whatever the estimate, so every method solved
    on one Problem (``casep demo``) with one noise model shares one test."""
    cache = problem.__dict__.setdefault("_time_offset_tests", {})
    key = None if noise is None else repr(noise)
    if key not in cache:
        cache[key] = time_offset_test(problem, problem.y, t, f, noise=noise)  # r -> dv: same projection
    return cache[key]


def time_offset_test(S: np.ndarray, r: np.ndarray, t: np.ndarray, f: np.ndarray,
                     keep: np.ndarray | None = None, gaps=None, noise=None) -> TimeOffsetTest | None:
    """Test residuals for a tracking time offset: ``r = S d + G g + a(t) dt + (da/dt) c + e``.

    Tracking time tags late by dt give ``v_trk(t) = v(t - dt) ~ v(t) - a(t) dt``, so
    ``dv += a(t) dt``, not integrated: a regressor outside the span of S_V. The test adds
    the columns ``a(t)`` and ``da/dt`` (stacked over the three axes, one shared coefficient
    each, as a model term would be) to S and reads their coefficients off the last 2 x 2
    block of the QR factor of ``[S | a | j] / c`` (:func:`casep.regression.linalg.reduce_qr`):
    ``R22 beta = q2``, ``Cov(beta) = s^2 kappa (R22^T R22)^-1`` with
    ``s^2 = RSS / (m - p)`` and ``kappa = max_axis (1 + rho) / (1 - rho)`` (rho = lag-1
    autocorrelation of the augmented residuals, clipped to [0, 0.999]): the long-run
    variance of AR(1) noise against a smooth regressor, so correlated noise does not
    read as a signal. By Frisch-Waugh-Lovell the test does not depend on the estimate
    that produced `r` (any D_hat leaves the same projection off span S).

    With the fit's `noise` model (Gauss-Markov, or Gauss-Markov plus white: what the fit whitened its rows
    for) the augmented rows are whitened for it as the fit's are (:func:`casep.noise.model.whiten_blocks`)
    and ``kappa = 1``: the lag-1 factor describes AR(1) noise only, and for Gauss-Markov plus white noise,
    whose lag-1 correlation the white part lowers while the long-run variance keeps the Gauss-Markov
    part's, it is several times too small (the strapdown-boost scenario at 50 Hz, tau 1 s, 0.1 + 0.05 m/s:
    kappa ~8 against a long-run factor ~80; RMS t 3.3 over 30 flights, ``|t| > 5`` in 4 of 30).

    ``G``: the velocity and attitude jumps the telemetry's gaps may leave (:func:`gap_columns`),
    nuisance columns between S and ``[a | j]``: a jump at a burnout inside a gap is not an offset,
    and an offset is still seen wherever ``a(t)`` changes away from the gaps (lift-off).

    At a step of the acceleration (:func:`acceleration_steps`) the samples whose tracking straddles it at the
    offset found (:func:`step_rows`) are freed, one free velocity per axis each, and the test run again until
    they settle: the first-order term does not hold there (see the module notes).

    `S` may be a :class:`~casep.regression.problem.Problem`: its rows are then regenerated block
    by block (twice), never held whole.

    Cost: one QR of the 3N x (n + 2) matrix, about one OLS solve (0.04 s against 0.03 s on
    the paper flight at 100 Hz, 19 501 samples), small beside building S_V and reading the
    file, and negligible beside GLS, RLS or the bounded QP.

    Parameters
    ----------
    S : (N, 3, n) array_like
        Regression matrix of the fit.
    r : (N, 3) array_like
        Residuals ``dv - S D_hat``, m/s.
    t, f : array_like
        Times (s) and specific force (N, 3), m/s^2.
    keep : (N,) bool array_like, optional
        The samples the fit kept (a robust fit's glitches and excluded outliers left out): only
        they enter the test, so that a glitch the fit removed is not read as an offset.
        ``da/dt`` is still taken on every sample's times.
    gaps : sequence of (start, end), optional
        The telemetry's gaps, s (default: a Problem's :attr:`~casep.regression.problem.Problem.gaps`,
        else none).
    noise : NoiseModel, optional
        The noise model the fit whitened its rows for; None or white: the lag-1 factor.

    Returns
    -------
    TimeOffsetTest or None
        None when ``a`` is constant or indistinguishable from S_V (no test possible).
    """
    t = np.asarray(t, dtype=float)
    test = _augmented_test(S, r, t, f, keep, gaps, noise, np.zeros(0, dtype=int))
    steps = acceleration_steps(kinematic_acceleration(t, np.asarray(f, dtype=float).reshape(-1, 3)))
    free = np.zeros(0, dtype=int)
    for _ in range(4):  # the freed samples follow the offset found, which follows them: a few passes settle
        if test is None or not steps[0].size:
            break
        rows = step_rows(t, steps, test.offset, test.offset_std)
        if np.array_equal(rows, free):
            break
        free = rows
        test = _augmented_test(S, r, t, f, keep, gaps, noise, free)
    return test


def _augmented_test(S, r, t: np.ndarray, f, keep, gaps, noise, free: np.ndarray) -> TimeOffsetTest | None:
    """:func:`time_offset_test` with the samples `free` freed (:func:`row_columns`)."""
    blocks, n, nonzero = row_blocks(S)
    t = np.asarray(t, dtype=float)
    N = t.size
    X = np.empty((N, 3, 2))  # [a | da/dt] per sample and axis (built in place: long flights)
    X[:, :, 0] = f  # a = f + g (kinematic_acceleration), in place
    X[:, :, 0] += GRAVITY_LAUNCH
    for i in range(3):
        X[:, i, 1] = np.gradient(X[:, i, 0], t) if N >= 2 else 0.0
    usable = np.array([np.any(X[:, :, j] != 0.0) for j in range(2)])
    if not usable[0]:
        return None
    if not usable.all():
        X = X[:, :, usable]
    k = X.shape[2]
    gaps = getattr(S, "gaps", ()) if gaps is None else gaps
    if gaps:
        X = np.concatenate([gap_columns(t, f, gaps), X], axis=2)  # the nuisance before the tested columns
    if free.size:
        X = np.concatenate([row_columns(N, free), X], axis=2)
    p = int(nonzero.sum()) + X.shape[2]
    kept = np.ones(N, dtype=bool) if keep is None else np.asarray(keep, dtype=bool)
    M = int(kept.sum())  # samples in the test
    if 3 * M <= p + 2:
        return None
    y = np.asarray(r, dtype=float).reshape(N, 3)
    whiten = noise is not None and any(tau is not None for tau in noise.tau)  # white: nothing to whiten

    def raw_rows():  # (slice, [S (non-zero columns: zero ones would leave arbitrary Householder vectors) | a | j], y)
        for sl, S_b in blocks():
            yield sl, np.concatenate([S_b[:, :, nonzero], X[sl]], axis=2), y[sl]

    def augmented():  # the rows of the test, whitened for the fit's noise model (in time order, then kept)
        from casep.noise.model import whiten_blocks

        for sl, A_b, y_b in (whiten_blocks(raw_rows(), t, noise) if whiten else raw_rows()):
            use = kept[sl]
            yield A_b[use].reshape(-1, p), y_b[use].reshape(-1)

    red = reduce_qr_blocks(augmented(), p)
    R22, q2 = red.R[-k:, -k:], red.qty[-k:]
    if np.min(np.abs(np.diag(R22))) < 1e-6:  # ||x_perp|| / ||x|| (unit-norm columns): no separation
        return None
    coef_all = np.linalg.lstsq(red.R, red.qty, rcond=None)[0]  # augmented fit, scaled coordinates
    coef = coef_all / np.where(red.scale > 0, red.scale, 1.0)
    # Lag-1 autocorrelation per axis of the augmented residuals, accumulated block by block
    num, den, last = np.zeros(3), np.zeros(3), None
    for A_b, y_b in augmented():
        e = (y_b - A_b @ coef).reshape(-1, 3)
        den += np.einsum("ki,ki->i", e, e)
        num += np.einsum("ki,ki->i", e[1:], e[:-1]) + (last * e[0] if last is not None else 0.0)
        last = e[-1].copy()
    from casep.noise.whiteness import ar1_long_run_factor

    kappa = 1.0 if whiten else float(np.max(ar1_long_run_factor(num, den)))
    s2 = red.rho2 / (3 * M - p)
    beta = np.linalg.solve(R22, q2) / red.scale[-k:]  # natural units
    Rinv = np.linalg.inv(R22)
    std = np.sqrt(s2 * kappa * np.sum(Rinv**2, axis=1)) / red.scale[-k:]  # diag (R22^T R22)^-1
    effect = np.abs(beta) * red.scale[-k:] / np.sqrt(np.sum(Rinv**2, axis=1) * 3 * M)  # |b| ||x_perp|| / sqrt(m)
    jerk = (float(beta[1]), float(std[1]), float(beta[1] / std[1])) if k == 2 else (np.nan, np.nan, np.nan)
    return TimeOffsetTest(offset=float(beta[0]), offset_std=float(std[0]), offset_t=float(beta[0] / std[0]),
                          jerk=jerk[0], jerk_std=jerk[1], jerk_t=jerk[2], inflation=kappa,
                          offset_rms=float(effect[0]), jerk_rms=float(effect[1]) if k == 2 else 0.0,
                          freed=int(free.size))

