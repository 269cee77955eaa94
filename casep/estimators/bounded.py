"""Box-bounded least squares with optional fixed coefficients (an exact active-set method; cvxpy + Clarabel
when it does not settle).

Notes
-----
In scaled coordinates ``z = c * D`` the problem is the n x n reduced one::

    min_z ||q - R z||^2     s.t.  c_j lo_j <= z_j <= c_j hi_j,   z_k = c_k v_k (fixed)

solved by a primal active-set method (:func:`_active_set`: least squares on the free coefficients,
a step to the first bound in the way, a bound released while its multiplier has the wrong sign), in
numpy on the n x n reduction: the 3N-row problem is never solved again. Should it not settle
(at most ``10 n`` steps) or its point fail the optimality test below, cvxpy with the Clarabel
interior-point solver solves it; on this ill-conditioned problem an interior point is accurate to
~1e-3 std only, so its solution is *polished*. Either point is polished the same way: least squares
is solved exactly (SVD) on the free coefficients with the active ones at their bounds, and the
polished point is kept when it is feasible and satisfies the KKT conditions below
(``diagnostics["polished"]``). Both solvers' points give the same active set, and so, polished,
the same numbers. A bound is *active* when the solution sits on it
(within ``1e-7 (1 + |bound|)`` in natural units, relative to the column scale). The
standard deviations of the free coefficients are conditional on the active set::

    Cov(D_F) = sigma^2 (S_F^T S_F)^-1,   sigma^2 = RSS / (m - |F|)

and null for coefficients on a bound or fixed (their value is set by the constraint).
Optimality (KKT): with gradient ``g = R^T (R z - q)``, ``g_j = 0`` for free coefficients,
``g_j >= 0`` at a lower and ``g_j <= 0`` at an upper bound.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Mapping, Sequence, Unpack

import numpy as np

from casep.estimators._base import MAX_PRIOR_VALUE, Prepared, finish, is_number
from casep.estimators._options import CoefficientTable, Labels, Method, Option
from casep.exceptions import CasepWarning

if TYPE_CHECKING:
    from casep.estimators.result import EstimateResult
    from casep.regression.problem import Problem

__all__ = ["solve_bounded", "parse_bounds", "shift_bounds", "BOUNDED", "BoundedExtras"]

#: Its option (``casep separate --bounds``), required.
BOUNDS = Option("bounds", "--bounds", None, (CoefficientTable("{name: [lo, hi] | value}"),),
                "box bounds and fixed values")


@dataclass(frozen=True)
class BoundedExtras:
    """Bounded: the bounds active at the solution, ``name -> "lower" | "upper" | "fixed"`` (the box, its
    input, is ``settings["bounds"]``, ``name -> [low, high]``)."""

    active_bounds: dict

    def describe(self, res: Any) -> list[str]:
        """Its part of the settings line."""
        n = len(res.names)
        kinds = list(self.active_bounds.values())
        box = res.settings.get("bounds") or {}
        return [f"bounds on {len(box)} of {n} coefficients; active set {kinds.count('lower')} at lower, "
                f"{kinds.count('upper')} at upper bound, {kinds.count('fixed')} fixed, {n - len(kinds)} free"]

    @staticmethod
    def old_form(settings: dict, diagnostics: dict, extras: dict | None) -> tuple[dict, dict, dict | None]:
        """A result file of an earlier casep: the active bounds also in ``diagnostics["active_bounds"]``
        (and the box also in ``extras["bounds"]``, which today's type leaves to ``settings``)."""
        diagnostics = dict(diagnostics)
        active = diagnostics.pop("active_bounds", None)
        if extras is None and active is not None:
            extras = {"active_bounds": active}
        return settings, diagnostics, extras

_ACTIVE_TOL = 1e-6  # relative, in scaled coordinates
#: A held bound is released while its multiplier has the wrong sign beyond this share of the KKT test's tolerance
#: (1e-14 of the gradient's scale: rounding), so the method stops at the optimum, not anywhere the test passes.
_RELEASE = 1e-6


def _at_bounds(z, lo, hi, fixed):
    """Masks of the non-fixed coordinates sitting on their lower / upper bound, and the tolerances."""
    tol_lo = _ACTIVE_TOL * (1.0 + np.abs(np.where(np.isfinite(lo), lo, 0.0)))
    tol_hi = _ACTIVE_TOL * (1.0 + np.abs(np.where(np.isfinite(hi), hi, 0.0)))
    on_lo = ~fixed & np.isfinite(lo) & (z - lo <= tol_lo)
    on_hi = ~fixed & np.isfinite(hi) & (hi - z <= tol_hi)
    return on_lo, on_hi, tol_lo, tol_hi


def _polish(R, q, z0, lo, hi, fixed, rcond):
    """Exact least squares on Clarabel's active set; kept if feasible and KKT holds.

    Returns the polished solution and True, or `z0` and False.
    """
    on_lo, on_hi, tol_lo, tol_hi = _at_bounds(z0, lo, hi, fixed)
    z = z0.copy()
    z[fixed] = lo[fixed]
    z[on_lo] = lo[on_lo]
    z[on_hi] = hi[on_hi]
    free = ~(fixed | on_lo | on_hi)
    _free_lstsq(R, q, z, free, rcond)
    g, gtol = _gradient(R, q, z)
    ok = (np.all(z[free] >= lo[free] - tol_lo[free]) and np.all(z[free] <= hi[free] + tol_hi[free])
          and np.all(g[on_lo] >= -gtol) and np.all(g[on_hi] <= gtol) and np.all(np.abs(g[free]) <= gtol))
    return (z, True) if ok else (z0, False)


def _free_lstsq(R, q, z, free, rcond) -> None:
    """``z[free]`` = the least-squares solution with the other coordinates held (SVD, rank by `rcond`)."""
    if free.any():
        rhs = q - R[:, ~free] @ z[~free]
        U, s, Vt = np.linalg.svd(R[:, free], full_matrices=False)
        r = int(np.sum(s > rcond * s[0])) if s.size and s[0] > 0 else 0
        z[free] = Vt[:r].T @ ((U[:, :r].T @ rhs) / s[:r])


def _gradient(R, q, z) -> tuple[np.ndarray, float]:
    """The gradient of ``0.5 ||R z - q||^2`` and the size below which a component of it counts as zero."""
    g = R.T @ (R @ z - q)
    # backward-stable scale of the gradient: ||R|| (||R z|| + ||q||) (relative to ||R^T q|| alone, an exact
    # least-squares point of an ill-conditioned R can fail by rounding, leaving the interior point's 1e-3 std)
    scale = float(np.linalg.norm(R, 2) * (np.linalg.norm(R @ z) + np.linalg.norm(q)))
    return g, 1e-8 * max(scale, 1e-300)


def _active_set(R, q, lo, hi, fixed, rcond) -> np.ndarray | None:
    """``min ||R z - q||`` within the box ``lo <= z <= hi`` (``fixed``: ``z = lo``) by a primal active-set method.

    From a feasible point (0 clipped to the box) with the coordinates on a bound held there: the least
    squares of the free ones (:func:`_free_lstsq`); if it leaves the box, a step towards it up to the first
    bound in the way, whose coordinate is then held; if not, the multiplier test, ``g_j >= 0`` held at a
    lower and ``g_j <= 0`` at an upper bound (``g`` the gradient, zero on the free ones), to rounding
    (:data:`_RELEASE`): the point is the optimum when it holds for all, else the worst is released.
    Returns None after ``10 n`` steps without settling (rank deficiency or degeneracy can make it cycle).
    """
    n = R.shape[1]
    z = np.clip(np.zeros(n), lo, hi)
    state = np.where(fixed, 2, np.where(z == lo, -1, np.where(z == hi, 1, 0)))  # 0 free, -1/1 lower/upper, 2 fixed
    for _ in range(10 * n + 1):
        free = state == 0
        target = z.copy()
        _free_lstsq(R, q, target, free, rcond)
        d = target - z
        with np.errstate(divide="ignore", invalid="ignore"):
            to_lo = np.where(free & (d < 0) & (target < lo), (lo - z) / d, np.inf)
            to_hi = np.where(free & (d > 0) & (target > hi), (hi - z) / d, np.inf)
        alpha = min(float(to_lo.min()), float(to_hi.min()))
        if alpha < 1.0:  # a bound in the way: step to it, hold it
            z = z + max(alpha, 0.0) * d
            hit_lo, hit_hi = to_lo <= alpha, to_hi <= alpha
            z[hit_lo], z[hit_hi] = lo[hit_lo], hi[hit_hi]
            state[hit_lo], state[hit_hi] = -1, 1
            continue
        z = target
        g, gtol = _gradient(R, q, z)
        wrong = np.where(state == -1, -g, np.where(state == 1, g, 0.0))  # a multiplier of the wrong sign
        j = int(np.argmax(wrong))
        if wrong[j] <= _RELEASE * gtol:
            return z
        state[j] = 0
    return None


def shift_bounds(bounds: Mapping, shift: Mapping[str, float]) -> dict:
    """`bounds` (``{name: [lo, hi] | value}``, natural units) moved by ``-shift[name]``, open sides kept: the box
    of a correction ``x = D - shift`` (a fit linearised at `shift`). Names without a shift keep theirs."""
    def moved(v: Any, d: float) -> Any:
        if is_number(v):
            return float(v) - d
        if isinstance(v, (list, tuple)) and len(v) == 2:
            return [e if e is None or not is_number(e) else float(e) - d for e in v]
        return v  # not a bound: parse_bounds says so

    return {k: moved(v, float(shift[k])) if k in shift else v for k, v in bounds.items()}


def parse_bounds(bounds: Mapping, names: Sequence[str], source: str = "`bounds`"):
    """Turn ``{name: [lo, hi] | value}`` into lo, hi arrays (natural units) and a fixed mask.

    ``null`` / None for either end means unbounded on that side; a single number, or
    ``lo == hi``, fixes the coefficient.
    """
    from casep.model.error_model import unknown_coefficient_message
    if not isinstance(bounds, Mapping):
        raise TypeError(f"{source} must be a mapping of coefficient name to [lo, hi], got {type(bounds).__name__}")
    n = len(names)
    lo, hi = np.full(n, -np.inf), np.full(n, np.inf)
    for name, spec in bounds.items():
        if name not in names:
            raise ValueError(unknown_coefficient_message(name, names, source))
        j = list(names).index(name)
        if is_number(spec):
            a = b = float(spec)
        elif isinstance(spec, (list, tuple)) and len(spec) == 2:
            for v in spec:  # strict: "1" or true is not a number
                if v is not None and not is_number(v):
                    raise ValueError(f"{source}: `{name}` must be [lo, hi] with numbers or null, got {spec!r} "
                                     f"({type(v).__name__} {v!r})")
            a = -np.inf if spec[0] is None else float(spec[0])
            b = np.inf if spec[1] is None else float(spec[1])
        else:
            raise ValueError(f"{source}: `{name}` must be [lo, hi] or a number, got {spec!r}")
        for side, v in (("lower", a), ("upper", b)):
            if np.isfinite(v) and abs(v) > MAX_PRIOR_VALUE:
                raise ValueError(f"{source}: `{name}` {side} bound {v:g} is beyond +-{MAX_PRIOR_VALUE:g} (natural "
                                 "units): the solver cannot scale it; give null (or -Infinity / Infinity) for an "
                                 "open side")
        if np.isnan(a) or np.isnan(b):
            raise ValueError(f"{source}: `{name}` has a NaN bound")
        # -Infinity below / Infinity above are open sides, like null; any other infinity is refused.
        if isinstance(spec, (int, float)) and not np.isfinite(a):
            raise ValueError(f"{source}: `{name}` fixed value must be finite, got {a:g}")
        for side, v, bad in (("lower", a, np.inf), ("upper", b, -np.inf)):
            if v == bad:
                raise ValueError(f"{source}: `{name}` {side} bound {v:g} leaves no finite value: bounds must be "
                                 "finite (null, or -Infinity below / Infinity above, for an open side)")
        if a > b:
            raise ValueError(f"{source}: `{name}` has lo > hi ({a:g} > {b:g})")
        lo[j], hi[j] = a, b
    return lo, hi, lo == hi


def _bound_text(v: float) -> str:
    return "null" if not np.isfinite(v) else f"{v:g}"


def solve_bounded(S: np.ndarray | Problem, y: np.ndarray | None = None, bounds: Mapping | None = None,
                  **labels: Unpack[Labels]) -> EstimateResult:
    """Least squares with per-coefficient bounds and fixed values.

    Parameters
    ----------
    S, y : array_like or Problem
        Regression (natural units) and velocity error, as :func:`casep.solve_ols`.
    bounds : mapping
        ``{name: [lo, hi]}`` in natural units (None for an open side), or ``{name: value}``
        to fix a coefficient. Names are those of `names`.
    **labels
        ``names``, ``units``, ``si_factors``, ``sigma``, ``rcond``, as :func:`casep.solve_ols`.

    Returns
    -------
    EstimateResult
        ``extras.active_bounds`` (:class:`BoundedExtras`): ``{name: "lower" | "upper" | "fixed"}``;
        ``diagnostics["active_set"]``: counts (at_lower, at_upper, fixed, free, undetermined);
        ``std_kind``: "conditional" when a bound is active or a value fixed (the std
        of the free coefficients are then conditional on the active set and understated), else
        "sampling". ``message`` states the counts and what the std mean.
    """
    return BOUNDED.call(S, y, bounds=bounds, **labels)


def _solve(pb: Prepared, *, method: Method, bounds: Mapping) -> EstimateResult:
    lo, hi, fixed = parse_bounds(bounds, pb.names)
    c = pb.red.scale
    zero = c == 0
    # A zero column has no scale: keep it in natural units (its z is D itself).
    cs = np.where(zero, 1.0, c)
    R = pb.red.R
    lo_s = lo * cs
    hi_s = hi * cs
    z_as = _active_set(R, pb.red.qty, lo_s, hi_s, fixed, pb.ra.rcond)
    zv, polished = (None, False) if z_as is None else _polish(R, pb.red.qty, z_as, lo_s, hi_s, fixed, pb.ra.rcond)
    if polished:
        solver, status = "active set", "optimal"
    else:
        zv, polished, status = _clarabel(pb, R, lo, hi, fixed, cs)
        solver = "cvxpy+clarabel"
    assert zv is not None
    return _result(pb, method, zv, polished, status, solver, lo, hi, fixed, c)


def _clarabel(pb: Prepared, R: np.ndarray, lo: np.ndarray, hi: np.ndarray, fixed: np.ndarray,
              cs: np.ndarray) -> tuple[np.ndarray, bool, str]:
    """cvxpy + Clarabel's solution, polished (:func:`_polish`), whether the polish held, and Clarabel's status."""
    import cvxpy as cp

    z = cp.Variable(pb.n)
    cons = []
    fin_lo = np.isfinite(lo) & ~fixed
    fin_hi = np.isfinite(hi) & ~fixed
    if fin_lo.any():
        cons.append(z[np.flatnonzero(fin_lo)] >= (lo * cs)[fin_lo])
    if fin_hi.any():
        cons.append(z[np.flatnonzero(fin_hi)] <= (hi * cs)[fin_hi])
    if fixed.any():
        cons.append(z[np.flatnonzero(fixed)] == (lo * cs)[fixed])
    prob = cp.Problem(cp.Minimize(cp.sum_squares(R @ z - pb.red.qty)), cons)
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="Solution may be inaccurate")  # handled below
        prob.solve(solver=cp.CLARABEL, tol_gap_abs=1e-10, tol_gap_rel=1e-10, tol_feas=1e-10)
    if prob.status not in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE):
        # A box is always feasible: "infeasible" here means bounds so far from the data, in the
        # scaled coordinates the solver works in (unit-norm columns), that it cannot resolve them.
        # Name the bounds farthest out; they are the input to fix.
        far = np.where(np.isfinite(lo) | np.isfinite(hi),
                       np.fmax(np.abs(np.where(np.isfinite(lo), lo * cs, 0.0)),
                               np.abs(np.where(np.isfinite(hi), hi * cs, 0.0))), 0.0)
        worst = [j for j in np.argsort(-far)[:3] if far[j] > 0]
        named = "; ".join(f"{pb.names[j]} [{_bound_text(lo[j])}, {_bound_text(hi[j])}] {pb.units[j]}" for j in worst)
        raise ValueError(f"bounded: the solver (cvxpy/Clarabel) reports the problem {prob.status}, although box bounds "
                         f"always admit a solution: bounds too far from anything the data allow, for it to resolve. "
                         f"Farthest out: {named}. Check their values and units (natural units)")
    zv, polished = _polish(R, pb.red.qty, np.asarray(z.value, dtype=float), lo * cs, hi * cs, fixed, pb.ra.rcond)
    if prob.status == cp.OPTIMAL_INACCURATE and not polished:
        warnings.warn("bounded: Clarabel reports an inaccurate solution and the active-set polish failed",
                      CasepWarning, stacklevel=3)
    return zv, polished, str(prob.status)


def _result(pb: Prepared, method: Method, zv: np.ndarray, polished: bool, status: str, solver: str,
            lo: np.ndarray, hi: np.ndarray, fixed: np.ndarray, c: np.ndarray) -> EstimateResult:
    """The estimate, its conditional covariance and the active set, from the scaled solution `zv`."""
    zero = c == 0
    cs = np.where(zero, 1.0, c)
    lo_s, hi_s = lo * cs, hi * cs
    R = pb.red.R
    x = zv / cs
    x = np.where(fixed, lo, x)
    at_lo, at_hi, _, _ = _at_bounds(zv, lo_s, hi_s, fixed)
    x = np.where(at_lo, lo, np.where(at_hi, hi, x))
    active = {pb.names[j]: ("fixed" if fixed[j] else "lower" if at_lo[j] else "upper")
              for j in np.flatnonzero(fixed | at_lo | at_hi)}
    free = ~(fixed | at_lo | at_hi) & ~zero
    # Conditional covariance of the free coefficients: sigma^2 (Z_F^T Z_F)^-1, via the SVD of R_F.
    RF = R[:, free]
    Uf, sf, Vtf = np.linalg.svd(RF, full_matrices=False)
    keep = sf > pb.ra.rcond * (sf[0] if sf.size else 1.0)
    resid = pb.residuals(x)
    rss = float(resid @ resid)
    nfree = int(keep.sum())
    sig = float(np.sqrt(rss / max(pb.m - nfree, 1))) if pb.sigma is None else pb.sigma
    W = Vtf[keep].T / sf[keep]
    cov = np.full((pb.n, pb.n), np.nan)
    inv = 1.0 / c[free]
    cov[np.ix_(free, free)] = sig**2 * (W @ W.T) * np.outer(inv, inv)
    # Flat directions among the free coefficients stay undetermined; constrained ones are set.
    null_rows = np.linalg.norm(Vtf[~keep].T, axis=1) > 1e-8 if (~keep).any() else np.zeros(free.sum(), bool)
    undetermined = zero & ~(fixed | at_lo | at_hi)
    undetermined[np.flatnonzero(free)[null_rows]] = True
    reasons = {name: ("fixed to its given value" if kind == "fixed" else f"at its {kind} bound: std undefined")
               for name, kind in active.items()}
    std_mask = fixed | at_lo | at_hi
    cov[std_mask, :] = np.nan
    cov[:, std_mask] = np.nan
    box = {k: [float(a) if np.isfinite(a) else None, float(b) if np.isfinite(b) else None]
           for k, a, b in zip(pb.names, lo, hi) if np.isfinite(a) or np.isfinite(b)}
    counts = {"at_lower": int((at_lo & ~fixed).sum()), "at_upper": int((at_hi & ~at_lo & ~fixed).sum()),
              "fixed": int(fixed.sum()),
              "free": int(pb.n - std_mask.sum()), "undetermined": int(undetermined.sum())}
    return finish(pb, method, x, cov, sig, undetermined=undetermined, reasons=reasons,
                  message=_active_set_message(counts, pb.n),
                  settings={"bounds": box, "solver": solver,
                            "sigma": "estimated" if pb.sigma is None else pb.sigma},
                  diagnostics={"active_set": counts, "solver_status": status, "polished": polished},
                  std_kind="conditional" if std_mask.any() else "sampling",
                  extras=BoundedExtras(dict(active)))


def _active_set_message(counts: dict[str, int], n: int) -> str:
    """How many coefficients sit on a bound / are fixed / are free, and what the std mean."""
    at = counts["at_lower"] + counts["at_upper"]
    msg = (f"{at} of {n} coefficients at a bound ({counts['at_lower']} lower, {counts['at_upper']} upper), "
           f"{counts['fixed']} fixed, {counts['free']} free")
    if counts["undetermined"]:
        msg += f" ({counts['undetermined']} of them not identifiable on this data)"
    if at + counts["fixed"]:
        return msg + ("; coefficients at a bound or fixed have no std; the std of the free ones are conditional "
                      "on this active set (understated: the uncertainty of which bounds are active is ignored)")
    return msg + "; no bound active: the unconstrained least-squares estimate and its std"


#: Box-bounded least squares (std conditional on the active set).
BOUNDED = Method("bounded", "box-bounded least squares (active set, exact)", _solve, "solve_bounded",
                 (BOUNDS,), required=("bounds",), std_kind="conditional", extras_type=BoundedExtras,
                 regularised=True, hint="bounds the data contradict?")
