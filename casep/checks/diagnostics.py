"""Collinearity and identifiability: what a flight can and cannot tell.

Notes
-----
All quantities use the column-equilibrated regression ``Z = S diag(c)^-1`` (unit-norm
columns, *never centred*: the model has no intercept), reduced by QR, ``R = U diag(s) V^T``;
zero columns are left out (they are unidentifiable by definition).

- Condition number of S in natural units and of Z; singular values ``s``; condition
  indices ``eta_k = s_0 / s_k``.
- Belsley-Kuh-Welsch variance-decomposition proportions:
  ``phi_jk = V_jk^2 / s_k^2``, ``pi_kj = phi_jk / sum_k phi_jk`` (share of Var(z_j) due to
  dimension k; each coefficient's proportions sum to 1). Where singular values tie, the
  basis of the tied subspace is made canonical (pivoted QR) so the proportions are defined.
- Uncentred VIF: ``VIF_j = [(Z^T Z)^-1]_jj = sum_k V_jk^2 / s_k^2`` (1 for orthogonal columns).
- Near-dependency groups: for each dimension with ``eta_k > 30``, the coefficients with
  ``pi_kj > 0.5`` (two or more).
- Cramer-Rao bound for white noise of std sigma: ``Cov >= sigma^2 (S^T S)^-1``. For
  first-order Gauss-Markov noise (stationary std sigma, correlation time tau) the bound is the
  GLS covariance ``(S^T Sigma^-1 S)^-1``, computed by whitening each axis in time:
  ``w_0 = e_0 / sigma``, ``w_k = (e_k - a_k e_{k-1}) / (sigma sqrt(1 - a_k^2))``,
  ``a_k = exp(-(t_k - t_{k-1}) / tau)``. With a Gaussian prior of std tau_j the Bayesian bound
  is ``(Fisher + diag(1 / tau_j^2))^-1``.
- Identifiability: *unidentifiable* (zero or exactly dependent column), *weak* (CRLB std
  larger than the coefficient's scale: its prior std, a given scale, or by default its
  Table 1 magnitude), else *identifiable*.
- A flight's rows (:func:`diagnose_noise`): the bound under the noise model ``casep separate``
  fits by default (:func:`casep.regression.rows.prepare_rows`, noise ``auto``: white, Gauss-Markov
  or Gauss-Markov plus white per axis by likelihood-ratio tests), from the rows whitened for it:
  least squares there is the GLS estimate, so the bound is the GLS covariance
  ``sigma^2 (S_w^T S_w)^-1`` with ``sigma`` the whitened residuals' std.
- Estimable combinations: the best-determined directions ``v_k`` of the scaled problem,
  written as ``sum_j w_j D_j`` with ``w_j = v_kj c_j`` normalised so the largest ``|w_j|`` is 1;
  std ``sigma / (s_k max_j |v_kj c_j|)``.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field, replace
from typing import Any, ClassVar, Mapping, Sequence

import numpy as np

from casep.noise.model import whiten_series
from casep.regression.linalg import (
    PartnerBound,
    RankAnalysis,
    ReducedSystem,
    analyze_rank,
    condition_numbers,
    least_squares_rss,
    reduce_qr,
    undetermined_nan,
    unidentifiable_reasons,
)
from casep.regression.problem import Problem, rounding_level
from casep.results import Completed, deprecated_alias

__all__ = ["Diagnostics", "diagnose", "diagnose_noise", "crlb_covariance", "collinearity", "ar1_whiten",
           "ILL_CONDITIONED", "GROUP_INDEX", "GROUP_PROPORTION"]

#: Equilibrated condition number above which estimators warn.
ILL_CONDITIONED = 1e3
GROUP_INDEX = 30.0
GROUP_PROPORTION = 0.5


def _canonical_ties(s: np.ndarray, Vt: np.ndarray, rel: float = 1e-9) -> np.ndarray:
    """Make the basis of tied singular values canonical (as axis-aligned as possible).

    Within a cluster of equal singular values the SVD basis is arbitrary, and so would be the
    variance proportions. Pivoted QR of the cluster's rows rotates them to an echelon form
    in the coordinates: for orthogonal columns (one cluster) the proportions become the
    identity, as Belsley et al. intend.
    """
    Vt = Vt.copy()
    k = 0
    while k < s.size:
        m = k + 1
        while m < s.size and abs(s[m] - s[k]) <= rel * max(s[0], 1e-300):
            m += 1
        if m - k > 1:
            from scipy.linalg import qr  # here: most spectra have no ties, and its import is 0.3 s

            Q, _, _ = qr(Vt[k:m], mode="economic", pivoting=True)  # B^T P = Q R, B^T = rows k..m-1
            Vt[k:m] = Q.T @ Vt[k:m]  # new rows R P^T: echelon in the coordinates
        k = m
    return Vt


def collinearity(red: ReducedSystem, ra: RankAnalysis) -> dict[str, Any]:
    """BKW proportions, condition indices, uncentred VIF and groups (indices into the columns).

    Returns keys ``s`` (singular values of the non-zero columns), ``eta`` (condition indices,
    inf for a zero singular value), ``proportions`` (dims x n, NaN on zero columns), ``vif``
    (n, inf for dependent, NaN for zero columns), ``groups`` (lists of column indices).
    """
    n = red.n
    keep = np.flatnonzero(~ra.zero)
    out = {"s": np.zeros(0), "eta": np.zeros(0), "proportions": np.full((0, n), np.nan),
           "vif": np.full(n, np.nan), "groups": []}
    if keep.size == 0:
        return out
    _, s, Vt = np.linalg.svd(red.R[:, keep])
    Vt = _canonical_ties(s, Vt)
    live = np.arange(s.size) < ra.rank  # the rank analysis' rule: its zero singular values are these
    safe = np.where(live, s, 1.0)
    eta = np.where(live, s[0] / safe, np.inf)
    phi = np.where(live[:, None], Vt**2 / safe[:, None] ** 2, 0.0)  # phi_jk = V_jk^2 / s_k^2, as (k, j)
    # A zero singular value gives infinite variance to the columns that load on it (its members as the rank
    # analysis names them: a dependency at the rounding level leaks ~1e-7 into every column)
    inf_load = ~live[:, None] & (np.abs(Vt) > 1e-8) & ra.dependent[keep][None, :]
    tot = phi.sum(axis=0)
    dependent = inf_load.any(axis=0)
    tot = np.where(dependent, np.inf, tot)
    prop = np.where(dependent, inf_load / np.maximum(inf_load.sum(axis=0), 1), phi / np.where(tot > 0, tot, 1.0))
    # Columns in an exact dependency load on a zero singular value: infinite VIF, proportion 1 there.
    dims = len(s)
    P = np.full((dims, n), np.nan)
    P[:, keep] = prop
    vif = np.full(n, np.nan)
    vif[keep] = tot  # (Z^T Z)^-1_jj = sum_k V_jk^2 / s_k^2
    groups: list[list[int]] = []
    for k in range(dims):
        if eta[k] > GROUP_INDEX:
            members = [int(keep[j]) for j in np.flatnonzero(prop[k] > GROUP_PROPORTION)]
            if len(members) >= 2 and members not in groups:
                groups.append(members)
    out.update(s=s, eta=eta, proportions=P, vif=vif, groups=groups)
    return out


def ar1_whiten(S: np.ndarray, t: np.ndarray, sigma: float, tau: float, share: float = 0.0) -> np.ndarray:
    """Whiten (N, 3, n) regressors for first-order Gauss-Markov noise of stationary std `sigma` (see module
    notes; with a white share `share` of the variance, Gauss-Markov plus white): the whitening of
    :func:`casep.noise.model.whiten_series` on each axis, divided by `sigma`."""
    t = np.asarray(t, dtype=float)
    if t.shape != (S.shape[0],):
        raise ValueError(f"`t` must have {S.shape[0]} samples, got shape {t.shape}")
    if not np.isfinite(tau) or tau <= 0:
        raise ValueError(f"`tau` must be finite and > 0 s, got {tau}")
    W = np.empty(S.shape)
    for j in range(S.shape[1]):
        W[:, j, :] = whiten_series(S[:, j, :], t, tau, share)[0]  # u_k = (e_k - a_k e_(k-1)) / sqrt(1 - a_k^2)
    W /= sigma
    return W


def crlb_covariance(S: np.ndarray, sigma: float, *, t: np.ndarray | None = None, tau: float | None = None,
                    prior_std: np.ndarray | None = None, rcond: float | None = None,
                    prior_information: np.ndarray | None = None, mask: bool = True) -> np.ndarray:
    """Cramer-Rao bound covariance in natural units (NaN rows for unidentifiable coefficients; with `mask`
    False the pseudo-inverse's, whose rows are exact for determined combinations only).

    Parameters
    ----------
    S : (N, 3, n) array_like
        Regression in natural units.
    sigma : float
        Noise std (white), or stationary std of the Gauss-Markov noise, m/s.
    t, tau : optional
        Sample times and correlation time for the Gauss-Markov bound.
    prior_std : (n,) array_like, optional
        Prior std per coefficient (inf for none): the Bayesian bound.
    prior_information : (k, n) array_like, optional
        A correlated prior's square-root information rows ``W`` (``W^T W = Cov^-1``, natural
        units; :func:`casep.estimators.map.prior_information`), used instead of `prior_std`.
    """
    S = np.asarray(S, dtype=float)
    if not np.isfinite(sigma) or sigma <= 0:
        raise ValueError(f"`sigma` must be finite and > 0, got {sigma}")
    if tau is not None:
        if t is None:
            raise ValueError("`t` is required with `tau` (Gauss-Markov bound)")
        F = ar1_whiten(S, t, sigma, tau).reshape(-1, S.shape[-1])
    else:
        F = S.reshape(-1, S.shape[-1]) / sigma
    return _crlb_from_reduction(reduce_qr(F, np.zeros(F.shape[0])), 1.0, prior_std, rcond, prior_information, mask)


def _crlb_from_reduction(red: ReducedSystem, sigma: float, prior_std: np.ndarray | None,
                         rcond: float | None, prior_information: np.ndarray | None = None,
                         mask: bool = True) -> np.ndarray:
    """The bound from the reduction of S (``F = S / sigma`` has the same R, column norms c / sigma)."""
    n = red.n
    c = np.where(red.scale > 0, red.scale, 1.0) / sigma
    A = red.R
    if prior_information is not None:
        Wp = np.asarray(prior_information, dtype=float)
        if Wp.ndim != 2 or Wp.shape[1] != n or not np.all(np.isfinite(Wp)):
            raise ValueError(f"`prior_information` must be finite (k, {n}) rows")
        A = np.vstack([A, Wp / c])  # W D = W diag(1/c) (c D): prior rows in scaled coordinates
    elif prior_std is not None:
        ps = np.asarray(prior_std, dtype=float)
        if ps.shape != (n,) or np.any(ps <= 0) or np.any(np.isnan(ps)):
            raise ValueError(f"`prior_std` must be {n} values > 0 (inf for none)")
        has = np.isfinite(ps)
        A = np.vstack([A, np.diag(1.0 / (c * ps))[has]])  # prior rows in scaled coordinates
    _, s, Vt = np.linalg.svd(A, full_matrices=False)
    tol = (max(red.m, n) * np.finfo(float).eps if rcond is None else rcond) * s[0]
    r = int(np.sum(s > tol))
    W = Vt[:r].T / s[:r]
    cov = (W @ W.T) / np.outer(c, c)
    if not mask:
        return cov
    null = Vt[r:].T
    return undetermined_nan(cov, np.linalg.norm(null, axis=1) > 1e-8 if null.size else np.zeros(n, bool))


def _combination(v: np.ndarray, c: np.ndarray, names: Sequence[str], top: int = 5) -> tuple[dict[str, float], float]:
    w = v * c
    big = np.max(np.abs(w))
    w = w / big
    order = np.argsort(-np.abs(w))[:top]
    return {names[j]: float(round(w[j], 4)) for j in order if abs(w[j]) >= 1e-3}, float(big)


def _others_at_scale(v: np.ndarray, c: np.ndarray, names: Sequence[str], scales: Mapping[str, float]
                     ) -> float | None:
    """The size of a combination's terms beside its leading one at their scales, in the leading coefficient's units:
    ``sqrt(sum_j (w_j s_j)^2)`` over every other term (``w = v c / max|v c|`` the weights per unit of each
    coefficient, as :func:`_combination`'s; ``s_j`` the :func:`_scales` yardstick, prior std or declared
    magnitude). What the combination leaves of the leading coefficient beside its std when the others are known only
    to their scales; None when a term has no scale."""
    w = v * c
    w = w / np.max(np.abs(w))
    lead = int(np.argmax(np.abs(w)))
    total = 0.0
    for j, nm in enumerate(names):
        if j == lead or w[j] == 0.0:
            continue
        if nm not in scales:
            return None
        total += (w[j] * scales[nm]) ** 2
    return float(math.sqrt(total))


@dataclass(frozen=True)
class Diagnostics(Completed):
    """What the flight determines, per coefficient and per combination (see module notes)."""

    what: ClassVar[str] = "diagnostics of the regression (conditioning, Cramer-Rao bounds, identifiability)"

    names: tuple[str, ...]
    units: tuple[str, ...]
    condition_number: float | None
    condition_number_equilibrated: float | None
    singular_values: np.ndarray
    condition_indices: np.ndarray
    proportions: np.ndarray
    vif: np.ndarray
    sigma: float
    sigma_source: str
    noise: dict
    crlb_covariance: np.ndarray
    identifiability: dict[str, str]
    reasons: dict[str, str]
    groups: list[list[str]]
    combinations: list[dict]
    scales: dict[str, float] = field(default_factory=dict)

    @property
    def crlb_std(self) -> np.ndarray:
        """Cramer-Rao std per coefficient, natural units (NaN where unidentifiable)."""
        return np.sqrt(np.diag(self.crlb_covariance))

    @property
    def correlation(self) -> np.ndarray:
        """Correlation matrix of the estimates at the bound."""
        sd = self.crlb_std
        with np.errstate(invalid="ignore", divide="ignore"):
            return self.crlb_covariance / np.outer(sd, sd)

    @property
    def unidentifiable(self) -> list[str]:
        return [n for n in self.names if self.identifiability[n] == "unidentifiable"]

    def to_dict(self) -> dict[str, Any]:
        """The ``diagnostics`` JSON of ``docs/reference/file-formats.md`` (plus details)."""
        def f(v):
            return float(v) if v is not None and np.isfinite(v) else None

        return {
            "condition_number": self.condition_number,
            "condition_number_equilibrated": self.condition_number_equilibrated,
            "sigma": float(self.sigma),
            "sigma_source": self.sigma_source,
            "noise": self.noise,
            "crlb_std": {n: f(s) for n, s in zip(self.names, self.crlb_std)},
            "vif": {n: f(v) for n, v in zip(self.names, self.vif)},
            "unidentifiable": self.unidentifiable,
            "groups": self.groups,
            "identifiability": dict(self.identifiability),
            "reasons": dict(self.reasons),
            "singular_values": [float(v) for v in self.singular_values],
            "condition_indices": [f(v) for v in self.condition_indices],
            "estimable_combinations": self.combinations,
            "correlation": [[f(v) for v in row] for row in self.correlation],
            "scales": self.scales,
        }

    report = deprecated_alias("text", "report")

    def text(self) -> str:
        """Readable terminal report (what ``casep diagnose`` prints)."""
        cn = self.condition_number
        ce = self.condition_number_equilibrated
        lines = [f"condition number: {cn:.3g} (natural units), {ce:.3g} (columns equilibrated)"
                 if cn and ce else "condition number: infinite (exactly dependent columns)",
                 f"noise: {self.noise.get('model', 'white')}, sigma {self.sigma:.4g} m/s ({self.sigma_source})",
                 *([f"  {self.noise['line']}"] if "line" in self.noise else []), "",
                 f"{'coefficient':<12} {'unit':<10} {'CRLB std':>12} {'scale':>10} {'VIF':>10}  verdict"]
        for j, (n, u) in enumerate(zip(self.names, self.units)):
            sd = self.crlb_std[j]
            sc = self.scales.get(n)
            lines.append(f"{n:<12} {u:<10} {_cell(sd, 12, '.4g')} {(f'{sc:.3g}' if sc else '-'):>10} "
                         f"{_cell(self.vif[j], 10, '.3g')}  {self.identifiability[n]}"
                         + (f" ({self.reasons[n]})" if n in self.reasons else ""))
        counts = {k: sum(v == k for v in self.identifiability.values())
                  for k in ("identifiable", "weak", "unidentifiable")}
        lines += ["", f"identifiable {counts['identifiable']}, weak {counts['weak']}, "
                      f"unidentifiable {counts['unidentifiable']} of {len(self.names)} (each coefficient on its own: "
                      "unidentifiable means exactly dependent on others, so the data determine only combinations of "
                      "it, which may still be known well: see the combinations below)"]
        if self.groups:
            lines.append(f"near-dependencies (condition index > {GROUP_INDEX:g}, proportion > {GROUP_PROPORTION}):")
            lines += ["  " + ", ".join(g) for g in self.groups]
        # the order is the equilibrated problem's singular values, largest first (condition index from 1): the
        # std are in the leading coefficient's units, so they are not comparable from line to line
        lines.append("best-determined combinations, best first by condition index (columns equilibrated); "
                     "std in the units of the leading coefficient, not comparable between lines; one led by a "
                     "coefficient determines that coefficient only to the other terms' size as well: 'others' is "
                     "their root sum square at their scales (weight times scale), which the std does not hold:")
        for cmb in self.combinations:
            terms = " ".join((f"{'-' if w < 0 else ''}{abs(w):.3g} {n}" if k == 0 else  # "-1 ba_x", not a bullet
                              f"{'+' if w >= 0 else '-'} {abs(w):.3g} {n}")
                             for k, (n, w) in enumerate(cmb["combination"].items()))
            lead = next(iter(cmb["combination"]), None)
            unit = self.units[self.names.index(lead)] if lead in self.names else ""
            others = cmb.get("others_at_scale")
            lines.append(f"  {terms}   std {cmb['std']:.3g}{' ' + unit if unit else ''}   "
                         + (f"others {others:.3g}{' ' + unit if unit else ''}   " if others is not None else "")
                         + f"condition index {cmb['condition_index']:.3g}")
        return "\n".join(lines)


def _cell(v: float, width: int, fmt: str) -> str:
    """A table cell: the number, or ``-`` where it does not exist (an unidentifiable coefficient's bound)."""
    return f"{v:>{width}{fmt}}" if v is not None and np.isfinite(v) else "-".rjust(width)


def _scales(names: Sequence[str], prior_std: np.ndarray | None, scales: Mapping | None) -> dict[str, float]:
    """The yardstick of the "weak" verdict: prior std where given, else `scales` (a model's
    declared typical magnitudes, :attr:`casep.ErrorModel.scales`, or the user's)."""
    out: dict[str, float] = {}
    for j, n in enumerate(names):
        if prior_std is not None and np.isfinite(prior_std[j]):
            out[n] = float(prior_std[j])
        elif scales is not None and n in scales:
            out[n] = float(scales[n])
    return out


def _bound(S: Any, red: ReducedSystem, ra: RankAnalysis, sigma: float, t: np.ndarray | None, tau: float | None,
           prior_std: np.ndarray | None, rcond: float | None, prior_information: np.ndarray | None,
           mask: bool) -> np.ndarray:
    """:func:`diagnose`'s bound (white: from the reduction already made; Gauss-Markov: :func:`crlb_covariance`),
    as the fit's: a column at the rounding level (the rank analysis' ``rounding``) is a zero column."""
    rounding = ra.rounding if ra.rounding is not None and ra.rounding.any() else None
    if tau is None:
        red_b = red if rounding is None else replace(red, R=np.where(rounding, 0.0, red.R))
        return _crlb_from_reduction(red_b, sigma, prior_std, rcond, prior_information, mask)
    S_b = S.sv() if isinstance(S, Problem) else np.asarray(S, dtype=float)
    return crlb_covariance(S_b if rounding is None else np.where(rounding, 0.0, S_b), sigma, t=t, tau=tau,
                           prior_std=prior_std, rcond=rcond, prior_information=prior_information, mask=mask)


def _partner_bound(bound: Any, pbnd: PartnerBound | None, ra: RankAnalysis, names: Sequence[str],
                   units: Sequence[str]) -> tuple[np.ndarray, dict[str, str]]:
    """The bound's covariance (``bound(mask)``: NaN rows for the unidentifiable when `mask`) and, with `pbnd`, that
    of the solution of least size in declared magnitudes for the exactly dependent coefficients it determines in
    practice, with their notes (:class:`~casep.regression.linalg.PartnerBound`)."""
    if pbnd is None:
        return bound(True), {}
    cov, now, notes = pbnd.reported(bound(False), ra.dependent, names, units)
    return undetermined_nan(cov, ~ra.estimable & ~now), notes


def diagnose(
    S: np.ndarray | Problem,
    y: np.ndarray | None = None,
    *,
    names: Sequence[str] | None = None,
    units: Sequence[str] | None = None,
    sigma: float | None = None,
    t: np.ndarray | None = None,
    tau: float | None = None,
    prior_std: np.ndarray | None = None,
    scales: Mapping | None = None,
    n_combinations: int = 6,
    rcond: float | None = None,
    prior_information: np.ndarray | None = None,
) -> Diagnostics:
    """Collinearity and identifiability diagnostics of a regression ``y = S D + e``.

    Parameters
    ----------
    S : (N, 3, n) array_like, or Problem
        Regression in natural units, or a :class:`~casep.regression.problem.Problem` (then `y` is
        omitted: the problem holds it).
    y : (N, 3) array_like, optional
        Velocity error; used to estimate sigma when `sigma` is not given.
    sigma : float, optional
        Noise std, m/s.
    t, tau : optional
        Sample times and correlation time: Gauss-Markov CRLB instead of white.
    prior_std : (n,) array_like, optional
        Prior std per coefficient (inf: none): Bayesian bound, and the scale for "weak".
    scales : mapping, optional
        ``name -> typical magnitude`` for the "weak" verdict, e.g. a model's declared
        :attr:`casep.ErrorModel.scales` (default none: only the prior std, where given, makes a
        coefficient "weak").
    prior_information : (k, n) array_like, optional
        A correlated prior's square-root information rows (see :func:`crlb_covariance`): the
        Bayesian bound uses them instead of `prior_std` (which stays the "weak" yardstick).
    """
    if isinstance(S, Problem):  # its reduction and rank analysis, reused
        if y is not None:
            raise ValueError("`y` must be omitted when `S` is a Problem (the problem holds it)")
        pb = S
        n, y, red, ra = pb.n, pb.y, pb.red, pb.rank(rcond)
        names = pb.names if names is None else tuple(names)
        units = pb.units if units is None else tuple(units)
        t = pb.t if t is None and tau is not None else t
        yy = y
    else:
        S = np.asarray(S, dtype=float)
        if S.ndim != 3 or S.shape[1] != 3:
            raise ValueError(f"`S` must be (N, 3, n), got shape {S.shape}")
        n = S.shape[-1]
        names = tuple(f"c{j}" for j in range(n)) if names is None else tuple(names)
        units = ("",) * n if units is None else tuple(units)
        yy = np.zeros(S.shape[:2]) if y is None else np.asarray(y, dtype=float)
        red = reduce_qr(S, yy)
        # the declared magnitudes (`scales`), as a Problem's rank analysis takes them: a column at the rounding level
        # relative to them counts as zero (casep.regression.linalg.rounding_columns)
        mags = None if not scales else [None if scales.get(nm) is None else float(scales[nm]) for nm in names]
        ra = analyze_rank(red, rcond, magnitudes=mags, rounding_level=rounding_level)
    if len(names) != n or len(units) != n:
        raise ValueError(f"`names` and `units` must have {n} entries")
    if sigma is None:
        if y is None:
            raise ValueError("`sigma` or `y` is required (the bound scales with the noise std)")
        sigma = float(np.sqrt(least_squares_rss(red, ra) / (red.m - ra.rank)))
        if not sigma > 0:  # all-zero y (flights: casep.checks.plausibility.check_dv_not_zero) or an exact fit
            raise ValueError("`y` is " + ("0 everywhere" if not np.any(yy) else "fitted exactly (residuals 0)")
                             + ": sigma cannot be estimated from it; give `sigma`")
        source = "estimated from least-squares residuals"
    else:
        if not np.isfinite(sigma) or sigma <= 0:
            raise ValueError(f"`sigma` must be finite and > 0, got {sigma}")
        source = "given"
    col = collinearity(red, ra)
    sc = _scales(names, None if prior_std is None else np.asarray(prior_std, float), scales)
    # exactly dependent coefficients whose partners this flight barely excites: their bound is that of the solution
    # of least size in declared magnitudes, as separate reports them (PartnerBound); not under a prior, which
    # determines every coefficient itself
    pbnd = PartnerBound.of(red, ra, [sc.get(n) for n in names]) \
        if prior_std is None and prior_information is None else None

    bound = functools.partial(_bound, S, red, ra, sigma, t, tau, prior_std, rcond, prior_information)
    cov, partner_notes = _partner_bound(bound, pbnd, ra, names, units)
    reasons = unidentifiable_reasons(ra, names)
    sd = np.sqrt(np.diag(cov))
    verdict: dict[str, str] = {}
    for j, nm in enumerate(names):
        if not np.isfinite(sd[j]):
            verdict[nm] = "unidentifiable"
        elif nm in sc and sd[j] > sc[nm]:
            verdict[nm] = "weak"
            reasons[nm] = f"CRLB std {sd[j]:.3g} > scale {sc[nm]:.3g}"
        else:
            verdict[nm] = "identifiable"
            reasons.pop(nm, None)
        if nm in partner_notes:
            reasons[nm] = f"{reasons[nm]}; {partner_notes[nm]}" if verdict[nm] == "weak" else partner_notes[nm]
    keep = np.flatnonzero(~ra.zero)
    combos = []
    if keep.size:
        _, s, Vt = np.linalg.svd(red.R[:, keep])
        c = red.scale[keep]
        for k in range(min(n_combinations, int(np.sum(s > ra.rcond * s[0])))):
            kept = [names[j] for j in keep]
            w, big = _combination(Vt[k], c, kept)
            combos.append({"combination": w, "std": float(sigma / (s[k] * big)),
                           "others_at_scale": _others_at_scale(Vt[k], c, kept, sc),
                           "condition_index": float(s[0] / s[k])})
    cn = condition_numbers(red, ra)
    noise = {"model": "white"} if tau is None else {"model": "ar1", "tau": float(tau)}
    if prior_std is not None:
        noise["prior"] = "Bayesian bound with the given prior std"
    return Diagnostics(
        names=names, units=units, condition_number=cn["condition_number"],
        condition_number_equilibrated=cn["condition_number_equilibrated"], singular_values=col["s"],
        condition_indices=col["eta"], proportions=col["proportions"], vif=col["vif"], sigma=float(sigma),
        sigma_source=source, noise=noise, crlb_covariance=cov, identifiability=verdict, reasons=reasons,
        groups=[[names[j] for j in g] for g in col["groups"]], combinations=combos, scales=sc,
    )


def diagnose_noise(problem: Problem, noise: str = "auto", **kw: Any) -> Diagnostics:
    """:func:`diagnose` under the noise model of a problem's rows that ``casep separate`` fits (module notes).

    Parameters
    ----------
    problem : Problem
        Raw rows ``(N, 3)`` with their times (not whitened).
    noise : {"auto", "gm", "gmw", "white"}
        The noise kind, chosen and fitted by :func:`casep.regression.rows.prepare_rows` (the rule
        of ``casep separate``; no robust weights: the bound of clean rows).
    **kw
        Passed to :func:`diagnose` (not `sigma` or `tau`: they fix the noise model themselves).

    Returns
    -------
    Diagnostics
        Its ``noise`` holds the fitted model (:meth:`casep.noise.model.NoiseModel.to_dict`) and
        its one-line description under ``"line"``.
    """
    from casep.regression.rows import prepare_rows

    if "sigma" in kw or "tau" in kw:
        raise ValueError("`sigma` and `tau` fix the noise model: call `diagnose` with them")
    rows = prepare_rows(problem, noise, robust=None)
    nm = rows.noise
    diag = diagnose(rows.solved, **kw)  # the whitened rows: least squares there is GLS
    kinds = {"white": "white", "gm": "gauss-markov", "gmw": "gauss-markov+white"}
    model = " / ".join(dict.fromkeys(kinds[k] for k in nm.axis_kinds()))  # each kind once, x first
    described = {"model": model + (" (axis scales)" if nm.scale != (1.0, 1.0, 1.0) else ""), **nm.to_dict(),
                 "line": nm.line()}
    if "prior" in diag.noise:
        described["prior"] = diag.noise["prior"]
    source = diag.sigma_source if nm.is_white else "stationary std of x, from the residuals of the whitened rows"
    return replace(diag, noise=described, sigma_source=source)
