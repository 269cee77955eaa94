"""Maximum a posteriori (MAP) estimate with a Gaussian prior per coefficient (or a correlated one).

Notes
-----
Prior ``D_j ~ N(mu_j, tau_j^2)`` (natural units, e.g. from ground calibration; a coefficient
without a prior, or with ``tau = inf``, is flat), noise ``N(0, sigma^2)`` (given, or the
least-squares residual std). The posterior is Gaussian with::

    Cov^-1 = S^T S / sigma^2 + diag(1 / tau^2)
    mean   = Cov (S^T y / sigma^2 + diag(1 / tau^2) mu)

computed without normal equations as the least-squares solution of the stacked system
(scaled coordinates ``z = c D``, reduced ``(R, q)``)::

    [ R / sigma          ] z = [ q / sigma       ]
    [ diag(1/(c_j tau_j)) ]     [ mu_j / tau_j   ]      (rows for coefficients with a prior)

by SVD; the posterior covariance is ``V diag(1/s^2) V^T`` of that stacked matrix.
Coefficients that neither the data nor a prior determine (zero or dependent columns with a
flat prior) are reported without an estimate.

A correlated prior (a group ``G`` of coefficients with std ``tau_G`` and correlation matrix
``Rho = L L^T``, for instance the posterior of earlier flights, :func:`prior_from_result`) enters
the same way, by square-root information rows ``W = L^-1 diag(1 / tau_G)`` with
``W^T W = Cov_G^-1``::

    [ W diag(1 / c_G) ] z_G = [ W mu_G ]

so the posterior of flights 1..k used as the prior of flight k+1 gives the joint estimate of all
k+1 flights (the Gaussian likelihoods multiply).

Prior mapping: ``{name: {"mean": m, "std": s}, ..., "correlation": {"names": [...], "matrix":
[[...]]}}``; the optional ``correlation`` entry names coefficients that all have a mean and std.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Mapping, Sequence, Unpack

import numpy as np

from casep.estimators._base import MAX_PRIOR_VALUE, Prepared, finish, is_number
from casep.estimators._options import SIGMA, CoefficientTable, Labels, Method, Option

if TYPE_CHECKING:
    from casep.estimators.ols import LinearMap
    from casep.estimators.result import EstimateResult
    from casep.regression.problem import Problem

__all__ = ["solve_map", "parse_prior", "prior_information", "prior_from_result", "per_flight_names", "shift_prior",
           "result_model", "MAP", "MAPExtras"]

#: Its option (``casep separate --prior``), required.
PRIOR = Option("prior", "--prior", None, (CoefficientTable("{name: {mean, std}}"),),
               "Gaussian prior per coefficient, or a result file (its estimate and covariance; "
               "docs/guide/result-files.md)")


@dataclass(frozen=True)
class MAPExtras:
    """MAP finds nothing beyond its estimate: its input, the Gaussian prior ``name -> {"mean", "std"}``
    (coefficients not listed: flat), is ``settings["prior"]``; this type gives the settings line."""

    def describe(self, res: Any) -> list[str]:
        """Its part of the settings line (the prior of ``res.settings``)."""
        given = res.settings.get("prior") or {}
        prior = {k: v for k, v in given.items() if k != CORRELATION}
        corr = given.get(CORRELATION)
        out = [f"Gaussian prior on {len(prior)} of {len(res.names)} coefficients (others flat)"
               + (f", correlated over {len(corr['names'])}" if corr else "")]
        if 0 < len(prior) <= 4:
            out.append(", ".join(f"{k} {v['mean']:.4g} +- {v['std']:.4g}" for k, v in prior.items()))
        return out

#: The key of a prior mapping that holds a correlation block (not a coefficient name).
CORRELATION = "correlation"


def parse_prior(prior: Mapping, names: Sequence[str], source: str = "`prior`") -> tuple[np.ndarray, np.ndarray]:
    """``{name: {"mean": m, "std": s}}`` to mean and (marginal) std arrays (std inf where absent).

    A ``"correlation"`` entry is checked too (see :func:`prior_information`, which uses it).
    """
    mu, tau, _ = _parse(prior, names, source)
    return mu, tau


def _parse(prior: Mapping, names: Sequence[str], source: str):
    from casep.model.error_model import unknown_coefficient_message

    if not isinstance(prior, Mapping):
        raise TypeError(f"{source} must be a mapping of coefficient name to {{'mean', 'std'}}")
    n = len(names)
    mu, tau = np.zeros(n), np.full(n, np.inf)
    corr = None
    for name, spec in prior.items():
        if name == CORRELATION and name not in names:
            corr = spec
            continue
        if name not in names:
            raise ValueError(unknown_coefficient_message(name, names, source))
        if not isinstance(spec, Mapping):
            raise ValueError(f"{source}: entry `{name}` must be {{\"mean\": m, \"std\": s}} (natural units), got "
                             f"{spec!r}")
        lacking = [k for k in ("mean", "std") if k not in spec]
        if lacking:
            raise ValueError(f"{source}: entry `{name}`: missing field {' and '.join(f'`{k}`' for k in lacking)} "
                             f"(found: {', '.join(map(str, spec)) or 'none'}); each entry is "
                             "{\"mean\": m, \"std\": s} in natural units")
        unknown = [str(k) for k in spec if k not in ("mean", "std")]
        if unknown:  # a "unit" or "sigma" would be ignored: the value taken in the natural unit, the std lost
            raise ValueError(f"{source}: entry `{name}`: unknown field(s) {', '.join(f'`{k}`' for k in unknown)}; "
                             "each entry is {\"mean\": m, \"std\": s} in the coefficient's natural unit (as "
                             "`casep models` lists it)")
        for key in ("mean", "std"):  # strict: true or "0.1" is not a number
            if not is_number(spec[key]):
                raise ValueError(f"{source}: `{name}` {key} must be a number, got {spec[key]!r} "
                                 f"({type(spec[key]).__name__})")
        m_, s_ = float(spec["mean"]), float(spec["std"])
        if not np.isfinite(m_) or abs(m_) > MAX_PRIOR_VALUE:
            raise ValueError(f"{source}: `{name}` mean must be finite and within +-{MAX_PRIOR_VALUE:g} (natural "
                             f"units), got {m_:g}")
        if np.isnan(s_) or s_ <= 0 or (np.isfinite(s_) and not 1.0 / MAX_PRIOR_VALUE <= s_ <= MAX_PRIOR_VALUE):
            raise ValueError(f"{source}: `{name}` std must be > 0, within [{1.0 / MAX_PRIOR_VALUE:g}, "
                             f"{MAX_PRIOR_VALUE:g}] (natural units; Infinity, or leaving the coefficient out, for no "
                             f"prior), got {s_:g}")
        j = list(names).index(name)
        mu[j], tau[j] = m_, s_
    if corr is None:
        return mu, tau, None
    where = f"{source}: `{CORRELATION}`"
    if not isinstance(corr, Mapping) or "names" not in corr or "matrix" not in corr:
        raise ValueError(f"{where} must be {{\"names\": [...], \"matrix\": [[...]]}}")
    group = list(corr["names"])
    for g in group:
        if g not in names:
            raise ValueError(unknown_coefficient_message(g, names, where))
        if not np.isfinite(tau[list(names).index(g)]):
            raise ValueError(f"{where} names `{g}`, which has no finite mean and std in the prior")
    if len(set(group)) < len(group):
        raise ValueError(f"{where}: `names` repeat a coefficient")
    try:
        rho = np.array(corr["matrix"], dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{where}: `matrix` must be a square array of numbers") from None
    k = len(group)
    if rho.shape != (k, k) or not np.all(np.isfinite(rho)):
        raise ValueError(f"{where}: `matrix` must be {k} x {k} finite numbers, got shape {rho.shape}")
    if np.max(np.abs(rho - rho.T), initial=0.0) > 1e-9 or np.max(np.abs(np.diag(rho) - 1.0), initial=0.0) > 1e-9:
        raise ValueError(f"{where}: `matrix` must be symmetric with a unit diagonal (a correlation matrix)")
    try:
        L = np.linalg.cholesky((rho + rho.T) / 2)  # Rho = L L^T
    except np.linalg.LinAlgError:
        raise ValueError(f"{where}: `matrix` is not positive definite (smallest eigenvalue "
                         f"{np.linalg.eigvalsh((rho + rho.T) / 2)[0]:.3g})") from None
    return mu, tau, ([list(names).index(g) for g in group], L)


def prior_information(prior: Mapping, names: Sequence[str], source: str = "`prior`"
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Square-root information of a Gaussian prior, natural units.

    Returns
    -------
    (W, b, mu, tau)
        Rows ``W`` (k, n) and right-hand side ``b = W mu`` (k,) with ``W^T W = Cov^-1`` on the
        coefficients the prior covers (zero columns elsewhere: flat); the mean and marginal std.
        Independent coefficients give ``e_j / tau_j``; a correlation group ``G`` gives
        ``L^-1 diag(1 / tau_G)`` with ``Rho = L L^T``.
    """
    from scipy.linalg import solve_triangular

    mu, tau, corr = _parse(prior, names, source)
    n = len(names)
    grouped = np.zeros(n, bool)
    blocks = []
    if corr is not None:
        idx, L = corr
        grouped[idx] = True
        Wg = np.zeros((len(idx), n))
        Wg[:, idx] = solve_triangular(L, np.diag(1.0 / tau[idx]), lower=True)  # L^-1 diag(1/tau_G)
        blocks.append(Wg)
    single = np.flatnonzero(np.isfinite(tau) & ~grouped)
    Ws = np.zeros((single.size, n))
    Ws[np.arange(single.size), single] = 1.0 / tau[single]  # e_j / tau_j
    W = np.vstack([Ws, *blocks])
    return W, W @ mu, mu, tau


def shift_prior(prior: Mapping, shift: Mapping[str, float]) -> dict:
    """`prior` (``{name: {"mean", "std"}, "correlation": ...}``, natural units) with each listed mean moved by
    ``-shift[name]``, its std and correlations kept: the prior of a correction ``x = D - shift`` (a fit
    linearised at `shift`). Names without a shift keep their mean."""
    return {k: ({**v, "mean": float(v["mean"]) - float(shift[k])} if k != CORRELATION and k in shift
                and isinstance(v, Mapping) and is_number(v.get("mean")) else v) for k, v in prior.items()}


def per_flight_names(result, model=None) -> set[str]:
    """The coefficients of a result that belong to one flight (the model's ``per_flight=True`` ones,
    a several-flights result's ``name[file]`` and a radar result's station terms ``S1.range_bias``):
    they are not shared with another flight.

    `model` (ErrorModel or name) defaults to the result's own (:func:`result_model`); a result whose model cannot
    be found is an error (guessing would silently treat a flight's own time offset as shared).
    """
    model = result_model(result, model)
    own = {n for n, pf in zip(model.names, model.per_flight) if pf}
    stations = set((result.diagnostics or {}).get("tracking_terms") or ())  # a radar result's station errors
    return own | stations | {n for n in result.names if "[" in n}


def result_model(result, model=None):
    """The model of `result`, set up: `model` (ErrorModel or name) when given, with the result's flight's own tracking
    offset when the result's model is that model plus it (``name+dt_trk``); else the shipped model the result names
    (:func:`casep.model.loader.load_recorded_model`: never a file on the result's word)."""
    from casep.model.loader import TIME_OFFSET_SUFFIX, load_model, load_recorded_model, with_time_offset

    if model is None:  # a shipped model by its name; any other only when named (never run on a result's word)
        if not result.model:
            raise ValueError("the result names no model: give `model` to tell its per-flight coefficients")
        return load_recorded_model(result.model, sha256=result.model_sha256, model_file=result.model_file,
                                   where=f"the result of model `{result.model}`", option="`model` (--model)")
    model = load_model(model)
    if result.model and result.model == model.name + TIME_OFFSET_SUFFIX:
        model = with_time_offset(model)  # the model given, with the result's flight's own tracking offset
    return model


def prior_from_result(result, names: Sequence[str] | None = None, model=None) -> dict:
    """The Gaussian posterior of a result (estimate and covariance) as a prior mapping.

    Parameters
    ----------
    result : EstimateResult
        With a covariance (e.g. OLS or MAP); coefficients without an estimate are left flat, and so
        are per-flight coefficients (the model's ``per_flight=True`` ones, e.g. ``dt_trk``, and a
        several-flights result's ``name[file]``: another flight does not share them; marginalising
        them is taking the covariance block of the others).
    names : sequence of str, optional
        Keep only these coefficients (marginalising: the covariance block).
    model : ErrorModel or str, optional
        The result's model, to tell its per-flight coefficients (default: loaded by the result's
        model name).

    Returns
    -------
    dict
        ``{name: {"mean", "std"}, ..., "correlation": {"names", "matrix"}}`` in natural units, for
        :func:`solve_map` (``prior=``) or as a ``--prior`` JSON file.
    """
    if result.covariance is None:
        raise ValueError(f"the {result.method} result has no covariance: it cannot be used as a prior")
    own = per_flight_names(result, model)
    keep = [j for j, n in enumerate(result.names) if n not in own and (names is None or n in names)
            and np.isfinite(result.estimate[j]) and np.isfinite(result.covariance[j, j])
            and result.covariance[j, j] > 0]
    C = result.covariance[np.ix_(keep, keep)]
    sd = np.sqrt(np.diag(C))
    rho = C / np.outer(sd, sd)
    out: dict = {result.names[j]: {"mean": float(result.estimate[j]), "std": float(s)} for j, s in zip(keep, sd)}
    out[CORRELATION] = {"names": [result.names[j] for j in keep], "matrix": rho.tolist()}
    return out


def solve_map(S: np.ndarray | Problem, y: np.ndarray | None = None, prior: Mapping | None = None,
              **labels: Unpack[Labels]) -> EstimateResult:
    """Posterior mean and covariance of ``D`` under a Gaussian prior.

    Parameters
    ----------
    S : (N, 3, n) or (m, n) array_like, or Problem
        Regression matrix in natural units (a Problem holds `y`), as :func:`casep.solve_ols`.
    y : (N, 3) or (m,) array_like
        Velocity error, m/s.
    prior : mapping
        ``{name: {"mean": m, "std": s}}`` in natural units; absent names are flat.
    **labels
        ``names``, ``units``, ``si_factors``, ``rcond`` as :func:`casep.solve_ols`; ``sigma``: noise
        std, m/s (default: the least-squares residual std).

    Returns
    -------
    EstimateResult
    """
    return MAP.call(S, y, prior=prior, **labels)


def _solve(pb: Prepared, *, method: Method, prior: Mapping) -> EstimateResult:
    prior_arg = prior
    Wp, bp, mu, tau = prior_information(prior, pb.names)
    sig = pb.ols_sigma() if pb.sigma is None else pb.sigma
    c = pb.red.scale
    cs = np.where(c > 0, c, 1.0)  # zero columns: z_j = D_j
    P = Wp / cs  # prior rows in z = c D: W diag(1/c) z = W mu
    A = np.vstack([pb.red.R / sig, P])
    b = np.concatenate([pb.red.qty / sig, bp])
    Ua, s, Vt = np.linalg.svd(A, full_matrices=False)
    r = int(np.sum(s > pb.ra.rcond * s[0]))
    z = Vt[:r].T @ ((Ua[:, :r].T @ b) / s[:r])
    W = Vt[:r].T / s[:r]
    cov = (W @ W.T) / np.outer(cs, cs)  # posterior covariance, natural units
    null = Vt[r:].T
    undetermined = np.linalg.norm(null, axis=1) > 1e-8 if null.size else np.zeros(pb.n, bool)
    prior = {n: {"mean": float(m), "std": float(t)} for n, m, t in zip(pb.names, mu, tau) if np.isfinite(t)}
    if CORRELATION in prior_arg and CORRELATION not in pb.names:
        prior[CORRELATION] = prior_arg[CORRELATION]
    return finish(pb, method, z / cs, cov, sig, undetermined=undetermined, extras=MAPExtras(),
                  settings={"prior": prior, "sigma": "estimated" if pb.sigma is None else pb.sigma})


# ------------------------------------------------------------------ linear map (batched Monte Carlo)
__all__ += ["map_linear_map"]


def map_linear_map(S: np.ndarray, prior: Mapping, sigma: float, *, names: Sequence[str] | None = None,
                   rcond: float | None = None) -> LinearMap:
    """The linear map of :func:`solve_map` with a given noise std: ``D = K y + b``.

    The posterior mean is the least-squares solution of the stacked system of the module
    Notes, ``z = A^+ [Q^T y / sigma; mu / tau]``, so ``K = diag(1/c) A^+[:, :n] Q^T / sigma``
    and ``b = diag(1/c) A^+[:, n:] (mu / tau)``.

    Parameters
    ----------
    S : (N, 3, n) or (m, n) array_like
        Regression matrix in natural units.
    prior : mapping
        ``{name: {"mean": m, "std": s}}`` in natural units (see :func:`parse_prior`).
    sigma : float
        Noise std, m/s (the map is linear in ``y`` only for a given sigma).
    names : sequence of str, optional
        Coefficient names the prior refers to (default ``c0, c1, ...``).
    rcond : float, optional
        Rank threshold, as :func:`solve_map`.

    Returns
    -------
    casep.estimators.ols.LinearMap
        The posterior covariance at `sigma`, ``dof`` None.
    """
    from casep.estimators.ols import LinearMap, scaled_factors

    sigma = SIGMA.check(sigma)
    if sigma is None:
        raise ValueError("`sigma` is required: the map is linear in y only for a given sigma")
    pb, Q, U, s, Vt = scaled_factors(S, rcond)
    names = pb.names if names is None else tuple(names)
    Wp, bp, _, _ = prior_information(prior, names)
    cs = np.where(pb.red.scale > 0, pb.red.scale, 1.0)
    A = np.vstack([((U * s) @ Vt) / sigma, Wp / cs])  # [R / sigma; prior rows W diag(1/c)]
    Ua, sa, Vta = np.linalg.svd(A, full_matrices=False)
    r = int(np.sum(sa > pb.ra.rcond * sa[0]))
    W = Vta[:r].T / sa[:r]
    Ainv = W @ Ua[:, :r].T  # A^+
    K = (Ainv[:, :pb.n] @ Q.T) / (sigma * cs[:, None])
    b = (Ainv[:, pb.n:] @ bp) / cs
    cov = (W @ W.T) / np.outer(cs, cs)  # posterior covariance, natural units
    null = Vta[r:].T
    undetermined = np.linalg.norm(null, axis=1) > 1e-8 if null.size else np.zeros(pb.n, bool)
    return LinearMap(K, b, cov, None, undetermined)


#: Maximum a posteriori under a Gaussian prior.
MAP = Method("map", "maximum a posteriori with a Gaussian prior", _solve, "solve_map", (PRIOR,), required=("prior",),
             batched=True, std_kind="posterior", extras_type=MAPExtras, hint="a prior the data contradict?",
             linear_map=lambda S, **kw: map_linear_map(S, kw["prior"], kw["sigma"], names=kw.get("names"),
                                                       rcond=kw.get("rcond")))
