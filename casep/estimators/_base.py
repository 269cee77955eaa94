"""What every estimator shares: argument checks, the scaled QR reduction, and the result.

An estimator calls :func:`prepare` (validates ``S``, ``y``, labels and ``sigma``, reduces the
column-scaled system once and analyses its rank), solves in scaled coordinates, and hands
its natural-unit estimate and covariance to :func:`finish`, which computes the residuals
and the diagnostics and marks zero or exactly dependent coefficients as not identifiable
where the method leaves them undetermined.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from casep.checks.diagnostics import ILL_CONDITIONED, collinearity
from casep.estimators._lazydict import LazyDiagnostics
from casep.estimators._rules import SIGMA
from casep.estimators.result import EstimateResult
from casep.estimators.solution import Solution
from casep.exceptions import IllConditionedWarning, MagnitudeWarning
from casep.regression.linalg import (
    PARTNERS_NOTE,
    PartnerBound,
    RankAnalysis,
    ReducedSystem,
    condition_numbers,
    covariance_std,
    null_space,
    undetermined_nan,
    unidentifiable_reasons,
)
from casep.regression.problem import Problem as RegressionProblem
from casep.units import LINEAR_LIMITS

__all__ = ["Prepared", "prepare", "rows_of", "finish", "determined_up_to_partners", "check_positive", "inverse_scale"]



#: Largest |mean| and std of a prior, and the inverse of the smallest std, natural units: beyond any
#: instrument error in any unit, and the information 1/std^2 and its products stay finite.
MAX_PRIOR_VALUE = 1e30


def is_number(v) -> bool:
    """A real number that is not a bool (JSON ``true`` is not a number; nor is ``"0.1"``)."""
    import numbers

    return isinstance(v, numbers.Real) and not isinstance(v, (bool, np.bool_))


def check_positive(name: str, value: float | None, *, allow_none: bool = True, allow_zero: bool = False,
                   upper: float | None = None) -> float | None:
    """Validate a positive finite scalar, naming it in the error.

    ``sigma`` must also lie in the range its :data:`~casep.estimators._options.SIGMA` option declares;
    the message gives the range and why.
    """
    if value is None:
        if allow_none:
            return None
        raise ValueError(f"`{name}` is required")
    if name == SIGMA.name:
        return float(SIGMA.check(value))
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TypeError(f"`{name}` must be a number, got {type(value).__name__}")
    v = float(value)
    ok = np.isfinite(v) and (v >= 0 if allow_zero else v > 0) and (upper is None or v <= upper)
    if not ok:
        low = "[0" if allow_zero else "(0"
        want = f"in {low}, {upper:g}]" if upper is not None else (">= 0" if allow_zero else "> 0")
        raise ValueError(f"`{name}` must be finite and {want}, got {value}")
    return v


def inverse_scale(scale: np.ndarray) -> np.ndarray:
    """1 / scale, with 0 for zero columns."""
    safe = np.where(scale > 0, scale, 1.0)
    return np.where(scale > 0, 1.0 / safe, 0.0)


@dataclass(frozen=True)
class Prepared:
    """A validated :class:`casep.regression.problem.Problem` as a solver sees it: reduction, rank, sigma."""

    problem: RegressionProblem
    ra: RankAnalysis
    sigma: float | None  # given noise std, or None
    rcond_asked: float | None = None  # the rank threshold asked for (None: the default, ``ra.rcond`` the one used)

    @property
    def red(self) -> ReducedSystem:
        return self.problem.red

    @property
    def names(self) -> tuple[str, ...]:
        return self.problem.names

    @property
    def units(self) -> tuple[str, ...]:
        return self.problem.units

    @property
    def si_factors(self) -> np.ndarray:
        return self.problem.si_factors

    @property
    def shape(self) -> tuple:
        """Leading shape of y, e.g. (N, 3)."""
        return self.problem.y.shape if self.problem.y is not None else (self.m,)

    @property
    def S(self) -> np.ndarray:
        """(m, n) natural units: the whole S (materialised when the problem regenerates it)."""
        return self.problem.sv().reshape(-1, self.n)

    @property
    def y(self) -> np.ndarray:
        """(m,) observations."""
        return self.problem._need_rows().reshape(-1)

    #: Scalar rows (3 N) and coefficients of the problem.
    m = property(lambda self: self.red.m)
    n = property(lambda self: self.red.n)

    @property
    def inv_c(self) -> np.ndarray:
        return inverse_scale(self.red.scale)

    def residuals(self, x: np.ndarray) -> np.ndarray:
        """(m,) ``y - S x``, block by block."""
        return self.problem.residuals(x).reshape(-1)

    def ols_sigma(self) -> float:
        """Residual std of the least-squares fit, RSS / (m - rank)."""
        return float(np.sqrt(self.problem.ls_rss(self.ra.rcond) / (self.m - self.ra.rank)))


def rows_of(S: np.ndarray | RegressionProblem, y: np.ndarray | None, t: np.ndarray | None,
            names: Sequence[str] | None, units: Sequence[str] | None, si_factors: Sequence[float] | np.ndarray | None):
    """``(S, y, t, names, units, si_factors)`` as arrays, for the methods that need the rows whole.

    A Problem gives its S (materialised once, see :meth:`~casep.regression.problem.Problem.sv`),
    y, t and labels; arrays pass through.
    """
    if isinstance(S, RegressionProblem):
        if y is not None:
            raise ValueError("`y` must be omitted when `S` is a Problem (the problem holds it)")
        pb = S
        return pb.sv(), pb.y, (pb.t if t is None else t), pb.names, pb.units, pb.si_factors
    return S, y, t, names, units, si_factors


def prepare(S: np.ndarray | RegressionProblem, y: np.ndarray | None, names: Sequence[str] | None,
            units: Sequence[str] | None, si_factors: Sequence[float] | np.ndarray | None, sigma: float | None,
            rcond: float | None = None, model: str | None = None, t: np.ndarray | None = None) -> Prepared:
    """Validate arguments once: a :class:`~casep.regression.problem.Problem` as given (its reduction
    and rank analysis reused), or arrays ``S`` ``(N, 3, n)``/``(m, n)`` and ``y`` made into one."""
    sigma = check_positive("sigma", sigma)
    if isinstance(S, RegressionProblem):
        if y is not None:
            raise ValueError("`y` must be omitted when `S` is a Problem (the problem holds it)")
        pb = S
        if model is not None and pb.model not in (None, model):
            raise ValueError(f"`model` {model!r} differs from the Problem's {pb.model!r}")
        for label, given, have in (("names", names, pb.names), ("units", units, pb.units)):
            if given is not None and tuple(given) != have:
                raise ValueError(f"`{label}` differ from the Problem's")
    else:
        if y is None:
            raise ValueError("`y` is required with an array `S`")
        pb = RegressionProblem.from_arrays(S, y, t, names=names, units=units, si_factors=si_factors, model=model)
    ra = pb.rank(rcond)
    if pb.red.m <= ra.rank:
        raise ValueError(f"`S` has {pb.red.m} rows, not more than its rank {ra.rank}: "
                         "no degree of freedom for the noise")
    return Prepared(pb, ra, sigma, rcond)


def finish(
    pb: Prepared,
    method: Any,
    x: np.ndarray,
    cov: np.ndarray | None,
    sigma: float,
    *,
    settings: dict[str, Any],
    undetermined: np.ndarray | None = None,
    reasons: dict[str, str] | None = None,
    status: int | None = None,
    message: str | None = None,
    diagnostics: dict[str, Any] | None = None,
    history: np.ndarray | None = None,
    residuals: np.ndarray | None = None,
    history_std: np.ndarray | None = None,
    sigma_source: str | None = None,
    std_kind: str | None = None,
    extras: Any = None,
) -> EstimateResult:
    """Build the :class:`EstimateResult` of an estimator.

    Parameters
    ----------
    method : Method or str
        The method's declaration (:class:`~casep.estimators._options.Method`: its name, ``std_kind``,
        extras type and failure hint), or only a name (std "sampling", no hint).
    x : (n,) natural-unit estimate used for the residuals (every entry finite).
    cov : (n, n) natural-unit covariance, or None when the method defines none.
    undetermined : (n,) bool, optional
        Coefficients to report without an estimate (default: zero or exactly dependent
        columns, which the method leaves undetermined).
    reasons : dict, optional
        Extra ``name -> reason`` entries (merged over the rank-analysis reasons).
    sigma_source : str, optional
        Where `sigma` came from (default "given" when the caller gave it, else "estimated").
    std_kind : str, optional
        What the std mean (default: the method's declared ``std_kind``).
    extras : dataclass, optional
        The method's typed extras (an instance of its declared ``extras_type``).

    Notes
    -----
    Whatever the method, a result is marked failed (``success`` False) when it cannot be
    trusted on its face (:func:`_failure`): status -2 when an estimate or a residual is not
    finite or a std infinite; status -3 when its residual RMS exceeds ``MISFIT_FACTOR`` (3) times the
    least-squares residual std of the same data (the smallest misfit the model allows: the
    residual power is then 9 times the least one, far outside what noise explains with
    constant coefficients), as an RLS/RELS run with too strong forgetting or bounds or a prior
    the data contradict give, unless it is below ``MISFIT_FLOOR`` (2 %) of the RMS of ``y``:
    on (nearly) noise-free data the least-squares std is ~0 and a deliberately biased
    estimator (ridge, MAP, bounded) fitting dv to 1 % is not a failure.
    """
    declared = None if isinstance(method, str) else method
    name = method if declared is None else declared.name
    etype = getattr(declared, "extras_type", None)
    if extras is not None and etype is not None and not isinstance(extras, etype):
        raise TypeError(f"method {name}: extras must be {etype.__name__}, got {type(extras).__name__}")
    n = pb.n
    und = (~pb.ra.estimable) if undetermined is None else np.asarray(undetermined, dtype=bool)
    bounded_by: dict[str, str] = {}
    Pi = None
    if undetermined is None and und.any() and cov is not None and np.all(np.isfinite(x)) and np.all(np.isfinite(cov)):
        x, cov, und, bounded_by, Pi = determined_up_to_partners(pb, x, np.asarray(cov, dtype=float), und)
    res = pb.residuals(x) if residuals is None else np.asarray(residuals, dtype=float).reshape(-1)
    est = np.where(und, np.nan, x)
    solution = _solution(pb, x, cov) if und.any() and np.all(np.isfinite(x)) else None
    std = None
    if cov is not None:
        cov = undetermined_nan(np.array(cov, dtype=float), und)
        std = covariance_std(cov)  # NaN where undetermined
    all_reasons = {k: v for k, v in unidentifiable_reasons(pb.ra, pb.names).items() if und[pb.names.index(k)]}
    all_reasons.update(bounded_by)
    all_reasons.update(reasons or {})
    n_ok = int((~und).sum())
    if status is None:
        if n_ok == n:
            status, message = 1, message or f"all {n} coefficients estimated"
        elif n_ok:
            status = 2
            message = message or (f"{n - n_ok} of {n} coefficients not identifiable on this data "
                                  "(zero or exactly dependent columns); the other estimated")
        elif pb.ra.rank:  # every coefficient exactly dependent, but their combinations determined: a result
            status = 2
            message = message or (f"no coefficient is identifiable on its own on this data (zero or exactly "
                                  f"dependent columns); the data determine {pb.ra.rank} combinations of the {n}")
        else:
            status, message = STATUS_NONE_DETERMINED, message or ("no coefficient nor any combination of them is "
                                                                  "identifiable on this data (every column zero)")
    failure = _failure(pb, name, getattr(declared, "hint", ""), np.where(und, 0.0, x), std, res)
    if failure is not None:
        status, message = failure
    base = {**condition_numbers(pb.red, pb.ra), "sigma": float(sigma), "rank": pb.ra.rank,
            "unidentifiable": [pb.names[j] for j in np.flatnonzero(und)],
            "exact_groups": [[pb.names[j] for j in g] for g in pb.ra.exact_groups()]}
    # CRLB std, VIF and near-dependency groups: computed on first use (a Monte Carlo run reads none of them)
    red, ra, names, inv_c = pb.red, pb.ra, pb.names, pb.inv_c
    diag = LazyDiagnostics({**base, **(diagnostics or {})}, _COLLINEARITY_KEYS,
                           lambda: _collinearity_summary(red, ra, names, inv_c, float(sigma), ~und, Pi))
    note = _ill_conditioning_note(diag)
    if note:
        diag["warning"] = note
        warnings.warn(f"{name}: {note}", IllConditionedWarning, stacklevel=3)
    N = pb.shape[0] if len(pb.shape) == 2 else pb.m
    return EstimateResult(
        method=name, names=pb.names, units=pb.units, estimate=est, std=std, covariance=cov,
        reasons=all_reasons, residuals=res.reshape(pb.shape), sigma=float(sigma), rank=pb.ra.rank,
        status=status, message=message or "", success=status > 0, si_factors=pb.si_factors,
        settings=settings, diagnostics=diag, n_samples=N, history=history, history_std=history_std,
        model=pb.problem.model or "",  # set by the problem, not patched afterwards
        sigma_source=sigma_source or ("given" if pb.sigma is not None else "estimated"),
        std_kind=std_kind or str(getattr(declared, "std_kind", "sampling")), extras=extras, solution=solution,
    )


def determined_up_to_partners(pb: Prepared, x: np.ndarray, cov: np.ndarray, und: np.ndarray
                               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, str], np.ndarray | None]:
    """The exactly dependent coefficients the data determine in practice (:class:`~casep.regression.linalg.PartnerBound`
    with the problem's declared magnitudes): a dependency whose other members this flight barely excites (a
    misalignment times a lateral specific force that is only the instrument's own error) leaves a coefficient's
    combination equal to the coefficient up to a negligible share. Returns the solution of least size in units of
    the magnitudes, its covariance, the coefficients still without an estimate, a note per one now reported and
    the projection ``Pi``; `x`, `cov`, `und`, no notes and None when nothing changes."""
    mags = pb.problem.magnitudes
    pbnd = PartnerBound.of(pb.red, pb.ra, [declared_magnitude(mags, n) for n in pb.names]) if mags else None
    if pbnd is None:
        return x, cov, und, {}, None
    cov_w, now, notes = pbnd.reported(cov, und & ~pb.ra.zero, pb.names, pb.units)
    if not now.any():
        return x, cov, und, {}, None
    return pbnd.Pi @ x, cov_w, und & ~now, notes, pbnd.Pi


def _solution(pb: Prepared, x: np.ndarray, cov: np.ndarray | None) -> Solution:
    """The solver's `x` and `cov` with the null space of S_V in natural units (:mod:`casep.estimators.solution`).

    ``S = Z diag(c)``: a null vector ``v`` of the scaled ``Z`` is ``v / c`` in natural units; on a zero
    column (``c = 0``) any value is a null direction, kept as ``v``.
    """
    N = null_space(pb.red, pb.ra)
    C = None if cov is None or not np.all(np.isfinite(cov)) else np.array(cov, dtype=float)
    return Solution(np.array(x, dtype=float), C, N)


#: A residual RMS above this many least-squares residual std fails a result ...
MISFIT_FACTOR = 3.0
#: ... unless it is below this fraction of the RMS of the data.
MISFIT_FLOOR = 0.02


def _failure(pb: Prepared, method: str, hint_text: str, x: np.ndarray, std: np.ndarray | None,
             res: np.ndarray) -> tuple[int, str] | None:
    """``(status, message)`` of a result that cannot be trusted, or None (see :func:`finish`).

    `x`: the estimate, 0 where reported undetermined. A NaN std is a std the method does
    not define (a coefficient at a bound); an infinite one is a failure.
    """
    bad = [pb.names[j] for j in np.flatnonzero(~np.isfinite(x))]
    if std is not None:
        bad += [pb.names[j] for j in np.flatnonzero(np.isinf(std))]
    if bad or not np.all(np.isfinite(res)):
        what = f"non-finite estimate or std for {', '.join(dict.fromkeys(bad))}" if bad else "non-finite residuals"
        return -2, f"failed: {method} produced {what}; the result is not usable"
    rms = float(np.sqrt(np.mean(res**2)))
    rms_y = float(np.sqrt((pb.red.qty @ pb.red.qty + pb.red.rho2) / pb.m))  # ||y||^2 = ||Q^T y||^2 + rho^2
    ls = pb.ols_sigma()  # sqrt(min_D |y - S D|^2 / (m - rank)): the misfit the model allows
    if rms > MISFIT_FACTOR * ls and rms > MISFIT_FLOOR * rms_y:
        hint = f" ({hint_text})" if hint_text else ""
        unit = f" {pb.problem.row_unit}" if pb.problem.row_unit else " (whitened, dimensionless)"
        return -3, (f"failed: {method} residual RMS {rms:.3g}{unit} is {rms / ls:.3g} x the least-squares residual "
                    f"std {ls:.3g}{unit}: the estimate does not fit the data{hint}")
    return None


_COLLINEARITY_KEYS = ("crlb_std", "vif", "groups")


def _collinearity_summary(red: ReducedSystem, ra: RankAnalysis, names: Sequence[str], inv_c: np.ndarray,
                          sigma: float, reported: np.ndarray | None = None, Pi: np.ndarray | None = None
                          ) -> dict[str, Any]:
    """White-noise CRLB std (sigma^2 (S^T S)^-1), uncentred VIF and near-dependency groups; `reported`: the
    coefficients with an estimate (default: the estimable ones), `Pi` the projection onto the solution of least
    size in declared magnitudes when some exactly dependent ones are among them
    (:class:`~casep.regression.linalg.PartnerBound`: their bound is ``sqrt(diag(Pi C Pi^T))``)."""
    col = collinearity(red, ra)
    V, inv_s = ra.pinv_factors()
    W = (V * inv_s) * inv_c[:, None]  # natural units: sigma^2 W W^T = sigma^2 (S^T S)^+
    if Pi is not None:
        W = Pi @ W
    crlb = sigma * np.sqrt(np.sum(W**2, axis=1))  # sqrt(diag(sigma^2 (S^T S)^+)), or of Pi (S^T S)^+ Pi^T
    ok = ra.estimable if reported is None else np.asarray(reported, dtype=bool)

    def f(v: float) -> float | None:
        return float(v) if np.isfinite(v) else None

    return {
        "crlb_std": {n: (f(crlb[j]) if ok[j] else None) for j, n in enumerate(names)},
        "vif": {n: f(col["vif"][j]) for j, n in enumerate(names)},
        "groups": [[names[j] for j in g] for g in col["groups"]],
    }


def _ill_conditioning_note(diag: dict[str, Any]) -> str | None:
    """The warning of an ill-conditioned or rank-deficient regression (its groups read only then)."""
    ce = diag.get("condition_number_equilibrated")
    bad = ce is None or ce > ILL_CONDITIONED
    und = diag["unidentifiable"]
    if not bad and not und:
        return None
    parts = []
    exact = diag.get("exact_groups") or []
    if ce is None:
        if not exact:
            parts.append("exactly dependent columns")
    elif ce > ILL_CONDITIONED:
        parts.append(f"equilibrated condition number {ce:.3g} (> {ILL_CONDITIONED:g})")
    if exact:
        parts.append("exactly dependent (the data cannot separate these, only a combination of each group: fix or "
                     "drop one of each) " + "; ".join("[" + ", ".join(g) + "]" for g in exact))
    near = [g for g in diag["groups"] if not any(set(g) <= set(e) for e in exact)]
    if near:
        parts.append("near-dependencies " + "; ".join("[" + ", ".join(g) + "]" for g in near))
    if und:
        parts.append(f"{len(und)} unidentifiable: " + ", ".join(und))
    return "ill-conditioned regression: " + "; ".join(parts) + ". See `casep diagnose`."


# ------------------------------------------------------------------ judging a result against the set-up
#: An estimate this many times its declared magnitude (``declare(Kg0x=("deg/h", 0.5))``) is a warning ...
MAGNITUDE_WARN = 100.0
#: ... and this many times fails the result (status -5): no instrument is 1e4 times off its spec sheet;
#: a set-up, unit or model mistake is far likelier.
MAGNITUDE_FAIL = 1e4
#: Both judged on ``|estimate| - MAGNITUDE_Z std``: what the data say at least (5 std: two-sided
#: P = 6e-7 per coefficient, so that noise in a poorly determined coefficient is not flagged).
MAGNITUDE_Z = 5.0
#: :data:`casep.units.LINEAR_LIMITS`: magnitudes (SI) no coefficient of a linear error model can have.
#: An estimate fails against :data:`LINEAR_LIMITS` when beyond it by more than this many std
#: (``|x| - LINEAR_Z std >= limit``: its two-sided 95 % interval excludes the limit); within it the flight does not
#: determine the coefficient (said as such, :func:`check_magnitudes`), which is no evidence of a unit mistake.
LINEAR_Z = 2.0
#: The family-wise false-failure rate of the test against :data:`LINEAR_LIMITS` over the coefficients the data do
#: not resolve at the scale of the limit (std at or above it): a flight leaves tens of them with std 1e4-1e8 times
#: their magnitudes, and of 20 such estimates one is beyond 2 std of the limit in 60 % of correct flights; they
#: fail only beyond ``z = Phi^-1(1 - LINEAR_ALPHA / (2 n))`` std (Bonferroni over the ``n`` of them). A
#: coefficient whose std is below the limit keeps :data:`LINEAR_Z` (a platform flight that ignores the Earth's
#: rotation puts a g-sensitive drift at 22390 +- 570 deg/h: 3.1 std beyond the limit, and fails).
LINEAR_ALPHA = 0.01
#: Methods whose estimates of poorly determined coefficients the regularisation sets, not the data (and whose
#: std leave out that bias): beyond :data:`MAGNITUDE_FAIL` they get the warning, not a failure.
REGULARISED = ("ridge", "pcr", "bounded")
#: Status of a result whose data determine nothing: no coefficient and no combination of them identifiable (rank 0,
#: :func:`finish`; every coefficient exactly dependent but the fit of rank r > 0 determines r combinations: status 2,
#: a result), or no coefficient and no combination of them better than the declared magnitudes (check_magnitudes).
STATUS_NONE_DETERMINED = -1
#: Status of a result whose flight failed a set-up check (casep.checks.plausibility.setup_problems).
STATUS_SETUP = -4
#: Status of a result with estimates beyond :data:`MAGNITUDE_FAIL` times their declared magnitudes.
STATUS_MAGNITUDE = -5
#: Status of a result whose flight's tracking noise differs between stretches beyond what one noise level per axis
#: can weight (casep.checks.tracking_quality.noise_problem): the result says what the flight determines instead.
STATUS_TRACKING = -6
#: Status of a result whose iteration did not converge (or whose correction could not be applied):
#: casep.workflows.imu_separate.
STATUS_NOT_CONVERGED = -7
#: Status of a result whose residuals are a model error, not noise (casep.checks.plausibility.misfit_problem).
STATUS_MISFIT = -8
#: Status of a several-flight result whose flights disagree on the shared coefficients
#: (casep.workflows.flights.judge_consistency).
STATUS_DISAGREE = -9
#: Status of a result whose prior the data contradict (casep.estimators.rls.prior_conflict; a raw-IMU separation's
#: given heading and its std: casep.workflows.imu_separate.heading_conflict).
STATUS_PRIOR_CONFLICT = -10
#: Every failure status above, by name: one status, one meaning (tests/estimators/test_statuses.py).
FAILURE_STATUSES = {"none determined": STATUS_NONE_DETERMINED, "setup": STATUS_SETUP, "magnitude": STATUS_MAGNITUDE,
                    "tracking": STATUS_TRACKING,
                    "not converged": STATUS_NOT_CONVERGED, "misfit": STATUS_MISFIT, "disagree": STATUS_DISAGREE,
                    "prior conflict": STATUS_PRIOR_CONFLICT}


def failed(res: EstimateResult, status: int, message: str) -> EstimateResult:
    """`res` marked failed (``success`` False) with `status` and `message`; a failure already there is kept first."""
    import dataclasses

    if not res.success:
        return dataclasses.replace(res, message=f"{res.message}; {message}")
    return dataclasses.replace(res, status=status, success=False, message=message)


def _std_factor(res: EstimateResult) -> float:
    """How far too small the std are by the whiteness test of the result (its richer-noise-model factor), or 1."""
    wt = (res.diagnostics or {}).get("whiteness") or {}
    f = wt.get("std_factor_median") if isinstance(wt, dict) else None
    return float(f) if isinstance(f, (int, float)) and np.isfinite(f) and f > 1.0 else 1.0


def _beyond_linear(res: EstimateResult, regularised: bool) -> EstimateResult:
    """`res` failed (status -5) when an estimate's magnitude itself is beyond :data:`LINEAR_LIMITS` (named with
    its std and the limit); recorded in ``diagnostics["beyond_linear"]``.

    Beyond by more than :data:`LINEAR_Z` std for a coefficient whose std is below its limit; for the ``n`` whose
    std is at or above it (the data do not resolve them at the scale of the limit) by more than
    ``Phi^-1(1 - LINEAR_ALPHA / (2 n))`` std: one test over all of them at :data:`LINEAR_ALPHA`."""
    import dataclasses

    from casep._special import normal_sf
    from casep.checks.plausibility import misfit_advice
    from casep.units import si_factor

    std = res.std if res.std is not None else np.full(len(res.names), np.nan)
    # the coefficients the data do not resolve at the scale of their limit: one test over all of them
    loose = {n for n, u, sd in zip(res.names, res.units, std)
             if u in LINEAR_LIMITS and np.isfinite(sd) and sd * si_factor(u) >= LINEAR_LIMITS[u]}

    def significant(r: dict) -> bool:  # |x| - z std >= limit, z as its std is below its limit or not
        z = (abs(r["estimate"]) - r["limit"]) / r["std"] if r["std"] > 0 else np.inf
        if not z >= LINEAR_Z:  # a NaN std: judged on |x| alone
            return bool(np.isnan(z))
        return r["name"] not in loose or normal_sf(z) <= LINEAR_ALPHA / (2 * len(loose))

    beyond: list[dict[str, Any]] = [
        {"name": n, "estimate": float(x), "std": float(sd), "unit": u, "limit": LINEAR_LIMITS[u] / si_factor(u)}
        for n, u, x, sd in zip(res.names, res.units, res.estimate, std)
        if u in LINEAR_LIMITS and np.isfinite(x) and abs(x) * si_factor(u) >= LINEAR_LIMITS[u]]
    # beyond the limit significantly (significant()); short of that the data do not determine the coefficient
    # (its std is a large part of the limit): said by check_magnitudes as not determined, not a model mistake
    rows = [r for r in beyond if significant(r)]
    if not rows or regularised:
        return res
    rows.sort(key=lambda r: -abs(float(r["estimate"])) / float(r["limit"]))
    res = dataclasses.replace(res, diagnostics={**res.diagnostics, "beyond_linear": rows})
    listed = "; ".join(f"{r['name']} {r['estimate']:.4g} +- {r['std']:.2g} {r['unit']} (limit {r['limit']:.3g})"
                       for r in rows[:6]) + (f" and {len(rows) - 6} more" if len(rows) > 6 else "")
    return failed(res, STATUS_MAGNITUDE,
                  f"failed: {len(rows)} estimate(s) beyond what a linear error model can describe, by more than "
                  f"{LINEAR_Z:g} std ({listed}: a scale factor or misalignment of 0.1, a gyro bias of 0.1 rad/s): "
                  "the model does not describe these data: " + misfit_advice(res.model, res.names, res.units,
                                                                             res.estimate, res.std))


def declared_magnitude(scales: Mapping[str, float], name: str) -> float | None:
    """A coefficient's declared magnitude (natural units): by its name, else by its base name (a per-flight
    coefficient ``ba_x[2]`` has the magnitude of ``ba_x``); None when the model declares none."""
    return scales.get(name, scales.get(name.split("[")[0]))


def not_determined(names: Sequence[str], std: np.ndarray | None, scales: Mapping[str, float]) -> list[int]:
    """Indices of the coefficients the data do not determine: a finite std at or above the coefficient's declared
    magnitude (``std_j >= s_j``: the data say less about it than the model's prior idea of its size)."""
    sd = np.full(len(names), np.nan) if std is None else np.asarray(std, dtype=float)
    return [j for j, n in enumerate(names)
            if (s := declared_magnitude(scales, n)) and np.isfinite(sd[j]) and sd[j] >= s]


def _best_combination(res: EstimateResult, scales: Mapping[str, float]) -> float | None:
    """The std of the best-determined combination of the coefficients, each divided by its declared magnitude
    ``s``: ``sqrt(lambda_min(D^-1 P D^-1))``, ``D = diag(s)``, ``P`` the covariance (a unit vector of scaled
    coefficients; below 1 the data determine that combination better than the magnitudes say). None when a
    coefficient has no declared magnitude or the covariance is not finite (an exactly dependent group: its
    combination is determined, said in its note)."""
    s = np.array([declared_magnitude(scales, n) or np.nan for n in res.names], dtype=float)
    P = res.covariance
    if P is None or not np.all(np.isfinite(s)) or not np.all(np.isfinite(P)):
        return None
    lam = np.linalg.eigvalsh(P / np.outer(s, s))
    return float(np.sqrt(max(lam[0], 0.0)))


def _say_not_determined(res: EstimateResult, scales: Mapping[str, float], source: str) -> EstimateResult:
    """`res` with its coefficients the data do not determine (:func:`not_determined`) in ``reasons`` (the note
    column), ``diagnostics["not_determined"]`` and the message; a :class:`~casep.exceptions.MagnitudeWarning`
    naming those whose estimate is beyond :data:`LINEAR_LIMITS` (within :data:`LINEAR_Z` std of it: noise of
    an undetermined coefficient, not a unit mistake)."""
    import dataclasses

    from casep.units import si_factor

    # a coefficient with a note of its own keeps it, except an exactly dependent one with an estimate (the note
    # then says by how much its partners move it, in brackets after the std)
    idx = [j for j in not_determined(res.names, res.std, scales)
           if res.names[j] not in res.reasons or res.reasons[res.names[j]].startswith(PARTNERS_NOTE)]
    if not idx:
        return res
    std = np.asarray(res.std)  # not None: not_determined found a finite std
    names = [res.names[j] for j in idx]
    ratio = {res.names[j]: float(std[j] / declared_magnitude(scales, res.names[j])) for j in idx}
    reasons = {**res.reasons, **{n: f"not determined: std {ratio[n]:.3g} x declared magnitude"
                                 + (f" ({res.reasons[n]})" if n in res.reasons else "") for n in names}}
    listed = ", ".join(names[:8]) + (f" and {len(names) - 8} more" if len(names) > 8 else "")
    message = (f"{res.message}; {len(names)} of {len(res.names)} not determined by the data (std at or above their "
               f"declared magnitudes: {listed})")
    res = dataclasses.replace(res, reasons=reasons, message=message,
                              diagnostics={**res.diagnostics, "not_determined": names})
    best = _best_combination(res, scales) if len(idx) == len(res.names) else None
    if best is not None and best >= 1.0:
        res = failed(res, STATUS_NONE_DETERMINED, f"failed: the data determine none of the {len(idx)} coefficients "
                     "nor any combination of them better than the declared magnitudes (the best-determined "
                     f"combination, each coefficient divided by its magnitude, has std {best:.3g}): the estimates "
                     "say nothing about the instrument")
    failing = {r["name"] for r in res.diagnostics.get("beyond_linear") or ()}
    wild = [j for j in idx if res.units[j] in LINEAR_LIMITS and res.names[j] not in failing
            and abs(res.estimate[j]) * si_factor(res.units[j]) >= LINEAR_LIMITS[res.units[j]]]
    if wild:  # no estimate: the text, JSON, CSV and MAT give none (EstimateResult.withheld), the value stays here
        rows: list[dict[str, Any]] = [
            {"name": res.names[j], "value": float(res.estimate[j]), "std": float(std[j]), "unit": res.units[j],
             "limit": LINEAR_LIMITS[res.units[j]] / si_factor(res.units[j])} for j in wild]
        reasons = dict(res.reasons)
        for j in wild:
            reasons[res.names[j]] += (f"; its value {res.estimate[j]:.3g} is beyond what a linear error model can "
                                      f"describe (limit {LINEAR_LIMITS[res.units[j]] / si_factor(res.units[j]):.3g}): "
                                      "no estimate")
        res = dataclasses.replace(res, reasons=reasons,
                                  diagnostics={**res.diagnostics, "undetermined_beyond_linear": rows})
        where = f"{source}: " if source else ""
        listed = "; ".join(f"{res.names[j]} {res.estimate[j]:.4g} +- {std[j]:.2g} {res.units[j]} (limit "
                           f"{LINEAR_LIMITS[res.units[j]] / si_factor(res.units[j]):.3g})" for j in wild)
        warnings.warn(MagnitudeWarning(
            f"{where}not determined: {listed}: beyond what a linear error model can describe but not "
            f"significantly (within {LINEAR_Z:g} std of it, or within the test at {LINEAR_ALPHA:g} over the "
            "coefficients whose std exceed their limits); the flight does not determine these coefficients (their "
            "std are at or above the declared magnitudes): their estimates say nothing about the instrument"),
            stacklevel=3)
    return res


def check_magnitudes(res: EstimateResult, scales: dict[str, float], source: str = "", *,
                     regularised: bool = False) -> EstimateResult:
    """Estimates against the model's declared magnitudes: a :class:`~casep.exceptions.MagnitudeWarning` at
    :data:`MAGNITUDE_WARN` times, a failed result (status :data:`STATUS_MAGNITUDE`) at :data:`MAGNITUDE_FAIL`
    (a warning only, for a `regularised` method).

    Parameters
    ----------
    res : EstimateResult
    scales : dict
        Declared magnitude per coefficient, natural units (``ErrorModel.scales``); a several-flights
        name ``name[flight]`` uses ``name``'s.
    source : str, optional
        Flight name for the message.
    regularised : bool, optional
        The result's method sets poorly determined coefficients by its regularisation, not the data
        (its ``Method.regularised``: ridge, PCR, bounded): its std are the spread about its biased mean
        and omit the bias (ridge moves ``Ka2y`` of the paper flight to 89 +- 14 ug/g^2, truth 0.003,
        least-squares std 485), so each coefficient is judged with the larger of its std and its
        Cramer-Rao std (``diagnostics["crlb_std"]``: what the data know); beyond :data:`MAGNITUDE_FAIL`
        a warning.

    Returns
    -------
    EstimateResult
        `res`, or `res` failed; ``diagnostics["magnitudes"]`` lists the coefficients beyond
        :data:`MAGNITUDE_WARN` (name, estimate, unit, declared, ratio).
    """
    import dataclasses

    rows = []
    std = res.std if res.std is not None else np.zeros(len(res.names))
    if regularised:  # max(own std, Cramer-Rao std); NaN (a coefficient at a bound) stays: not judged
        crlb = res.diagnostics.get("crlb_std") or {}
        std = np.array([max(sd, crlb.get(n) or 0.0) if np.isfinite(sd) else sd for n, sd in zip(res.names, std)])
    factor = _std_factor(res)  # the whiteness test's measure of std too small: judged with std that large
    for name, unit, x, sd in zip(res.names, res.units, res.estimate, std):
        scale = declared_magnitude(scales, name)
        if not np.isfinite(sd):
            continue  # a std the method does not define (a coefficient at a bound): the bound is the user's
        # |x| - 5 std: what the data say at least, so that a poorly determined coefficient's noise is not flagged
        low = abs(x) - MAGNITUDE_Z * sd
        low_noise = abs(x) - MAGNITUDE_Z * factor * sd  # with the std the noise-model check measured
        if scale and np.isfinite(x) and low >= MAGNITUDE_WARN * scale:
            rows.append({"name": name, "estimate": float(x), "std": sd, "unit": unit, "declared": float(scale),
                         "ratio": float(abs(x) / scale), "ratio_low": float(low / scale),
                         "ratio_low_noise": float(low_noise / scale)})
    res = _beyond_linear(res, regularised)
    res = _say_not_determined(res, scales, source)
    if not rows:
        return res
    rows.sort(key=lambda r: -r["ratio"])
    listed = "; ".join(f"{r['name']} {r['estimate']:.4g} +- {r['std']:.2g} {r['unit']} = {r['ratio']:.3g} x "
                       f"{r['declared']:g}" for r in rows[:6]) + (f" and {len(rows) - 6} more" if len(rows) > 6 else "")
    where = f"{source}: " if source else ""
    res = dataclasses.replace(res, diagnostics={**res.diagnostics, "magnitudes": rows})
    worst = max(r["ratio_low"] for r in rows)
    cause = ("a set-up mistake (launch site, azimuth, time scales), a unit mistake or a missing model term is likelier "
             "than such instruments")
    if factor > 1.0 and max(r["ratio_low_noise"] for r in rows) < MAGNITUDE_WARN:
        # the residuals say the std are too small by `factor`: with std that large no estimate is beyond its magnitude
        cause = (f"the noise model is the likelier cause: the whitened residuals are still correlated and the std are "
                 f"about {factor:.2g} x too small (diagnostics.whiteness); with std {factor:.2g} x larger no estimate "
                 f"is {MAGNITUDE_WARN:g} x beyond its declared magnitude. Fit the noise (--noise auto or gmw)")
    text = (f"{len(rows)} estimate(s) at least {MAGNITUDE_WARN:g} x their declared magnitudes (by |estimate| - "
            f"{MAGNITUDE_Z:g} std; {listed}): {cause}")
    if worst >= MAGNITUDE_FAIL and not regularised:
        return failed(res, STATUS_MAGNITUDE, f"failed: {text} (beyond {MAGNITUDE_FAIL:g} x)")
    if not res.success:
        return res  # failed already, for its own reason (recorded in diagnostics["magnitudes"])
    warnings.warn(MagnitudeWarning(where + text), stacklevel=2)
    return res
