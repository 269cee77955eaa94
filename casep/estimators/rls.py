"""Recursive least squares (RLS) and recursive extended least squares (RELS), paper Eq. (14).

Notes
-----
Samples are processed in time order; at each sample the three axes are sequential scalar
measurements ``z = h theta + e`` with variance ``1 / w`` (the paper's weight)::

    P     <- P / lambda                                   (forgetting, once per sample;
                                                           stabilized: see the wind-up safeguard)
    K     =  P h^T (1 / w + h P h^T)^-1
    theta <- theta + K (z - h theta)
    P     <- P - K h P

starting from ``theta_0 = 0`` and ``P_0 = p0 I`` with coefficients in *natural units*. With
``lambda = 1`` the result is exactly the ridge-type closed form::

    theta_N = (P_0^-1 + w S^T S)^-1 w S^T y,  P_N = (P_0^-1 + w S^T S)^-1

so ``p0`` acts as a prior variance in natural units (1e6 is far from diffuse for
coefficients of size 1e-3 ug/g^2), and ``p0 -> inf`` gives least squares.

**RELS** (``noise_order = n_c >= 1``) models the error of each axis as a moving average of
a white sequence, ``e_i(k) = v_i(k) + c_1 v_i(k-1) + ... + c_nc v_i(k-n_c)``, with the MA
coefficients ``c`` shared by the three axes. The parameter vector becomes
``[D; c]`` (36 + n_c) and each axis' regressor ``[S_V,i(k), v_i(k-1), ..., v_i(k-n_c)]``,
where the unknown ``v`` are replaced by residuals of the recursion: *a-posteriori*
``v_i(k) = z_i(k) - h_i(k) theta_k`` (after the update; default, the classical ELS choice
with better convergence) or *a-priori* innovations ``z_i(k) - h_i(k) theta_{k-1}``.
``c`` starts at 0 with prior variance ``p0``.

Numerics: the recursion runs on internally scaled coordinates (columns of S divided by their
norms, so ``P_0`` becomes ``p0 diag(c^2)``) in Bierman's U-D factorised form
``P = U diag(d) U^T``, which keeps P symmetric positive definite even at p0 = 1e6 on this
ill-conditioned problem; compiled with numba (:func:`casep._kernels.rels_ud`).

Wind-up safeguard (``lambda < 1``): plain exponential forgetting, ``P <- P / lambda``, makes
P grow as ``lambda^-k`` in every direction the data do not excite, and on this
ill-conditioned problem the estimate winds up (1e16 at ``lambda = 0.9`` on the 20 Hz paper
flight). casep therefore uses *stabilized forgetting* (Kulhavy & Zarrop, "On a general
concept of forgetting", Int. J. Control 58(4), 1993; Kulhavy, "Restricted exponential
forgetting in real-time identification", Automatica 23(5), 1987): what is forgotten is
replaced by the prior, not by nothing::

    P^-1 <- lambda P^-1 + (1 - lambda) P_0^-1          (once per sample, before the data)
    theta: the same blend of the information vectors, prior mean 0

implemented as the division of D by ``lambda`` followed by one U-D pseudo-measurement
``0 = theta_j + v_j``, ``Var v_j = P_0,jj / (1 - lambda)``, per coefficient (measured: 0.07 s -> 0.7 s for the
19,501-sample 100 Hz paper flight). Unrolled, it is the exact minimiser of the regularised
exponentially weighted least squares::

    theta_N = argmin  w sum_k lambda^(N-1-k) |y_k - S_k theta|^2 + theta^T P_0^-1 theta
    P_N     = (P_0^-1 + w sum_k lambda^(N-1-k) S_k^T S_k)^-1   <=  P_0

so P never exceeds the prior (a direction the data do not excite returns to ``P_0``
instead of growing without bound) and the estimate stays bounded. ``lambda = 1`` is
untouched. A bound is not a cure: with a memory of ``1 / (1 - lambda)`` samples far
shorter than this problem needs, the estimate is mostly the prior and
:func:`casep.estimators._base.finish` marks the result failed when its residual RMS is several
times the least-squares one.

Standard deviations: ``sqrt(diag(sigma^2 w P_N))``, the posterior std of the Gaussian model
with noise variance ``sigma^2`` and prior covariance ``sigma^2 w P_0`` (how RLS reads P_0);
``sigma`` is estimated from the final residuals (the whitened innovations for RELS) unless
given. With ``lambda < 1`` P is no longer a covariance and the std is indicative only.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Unpack

import numpy as np

from casep.estimators._base import STATUS_PRIOR_CONFLICT, Prepared, finish
from casep.estimators._options import Choices, Interval, Labels, Method, Option

if TYPE_CHECKING:
    from casep.estimators.ols import LinearMap
    from casep.estimators.result import EstimateResult
    from casep.regression.problem import Problem

__all__ = ["solve_rls", "DEFAULT_P0", "RLS", "RELS", "RLSExtras"]

#: The paper's initial covariance scale (P0 = 1e6 I, natural units).
DEFAULT_P0 = 1e6
_MAX_HISTORY = 2000  # rows of estimate history kept by default

#: Its options (``casep separate --p0 --weight --forgetting --noise-order``) and solver keywords.
P0 = Option("p0", "--p0", DEFAULT_P0, (Interval(float, 0, 1e30, "right"),),
            "P0 = p0 I, natural units (a prior variance)",
            # Measured on the paper flight (20 Hz, U-D recursion on unit-norm columns): |RLS - OLS| is 6e-5 OLS
            # std at p0 = 1e14, 8e-9 at 1e20, 5e-5 at 1e30, 5e-2 at 1e40 and 930 at 1e50 (the error grows like
            # p0 * eps).
            why="natural units^2; beyond it the RLS recursion loses its digits, and 1e14 already gives least "
                "squares on the paper flight")
WEIGHT = Option("weight", "--weight", 1.0, (Interval(float, 1e-12, 1e12),), "measurement weight w (variance 1/w)",
                # w is a measurement precision 1/variance; beyond 1e+-12 (m/s)^-2, w^-1/2 is 1e-6 .. 1e6 m/s.
                why="(m/s)^-2; 1 / weight is the measurement variance")
FORGETTING = Option("forgetting", "--forgetting", 1.0, (Interval(float, 0.5, 1, "both"),),
                    "forgetting factor (stabilized)",
                    # A memory of about 1 / (1 - lambda) samples: below 0.5 that is under two samples (nothing
                    # left to estimate 30-odd coefficients from), and P / lambda overflows as lambda nears 1e-308.
                    why="a memory of about 1 / (1 - forgetting) samples; useful: 0.99 .. 1")
NOISE_ORDER = Option("noise_order", "--noise-order", 1, (Interval(int, 1),), "MA order of the noise model")
RESIDUALS = Option("residuals", "--residuals", "posterior", (Choices(("posterior", "prior")),),
                   "which residuals feed the RELS regressor")
HISTORY_STRIDE = Option("history_stride", "--history-stride", None, (Interval(int, 1),),
                        "keep the estimate every this many samples (default: about 2000 rows)")
_ANY_ORDER = Option("noise_order", "--noise-order", 0, (Interval(int, 0),), "noise-model order (0: plain RLS)")


@dataclass(frozen=True)
class RLSExtras:
    """RLS/RELS: prior scale ``p0`` (P0 = p0 I, scaled coordinates), measurement weight,
    forgetting factor, MA order, the RELS noise model ``v(k) = e(k) - sum_j c_j v(k-j)``
    (coefficients, their posterior std, innovation RMS in m/s; empty/None for RLS) and the stride of
    the estimate history (samples between its rows, given or about N / 2000)."""

    p0: float
    weight: float
    forgetting: float
    noise_order: int
    ma_coefficients: tuple[float, ...] = ()
    ma_std: tuple[float, ...] = ()
    innovation_rms: float | None = None
    history_stride: int | None = None

    def describe(self, res: Any) -> list[str]:
        """Its part of the settings line."""
        out = [f"p0 {self.p0:.4g}, weight {self.weight:.4g}, forgetting {self.forgetting:.6g}"]
        if np.isfinite(res.sigma):  # the prior std P0 means to this result: sigma sqrt(w p0)
            out.append(f"effective prior std {res.sigma * np.sqrt(self.weight * self.p0):.4g} (natural units)")
        if self.ma_coefficients:
            ma = ", ".join(f"c{j + 1} {c:.4g} +- {e:.2g}" for j, (c, e) in enumerate(zip(self.ma_coefficients,
                                                                                      self.ma_std)))
            rms = "-" if self.innovation_rms is None else f"{self.innovation_rms:.4g}"
            out.append(f"MA({len(self.ma_coefficients)}) noise model {ma}; innovation RMS {rms} m/s")
        return out

    @staticmethod
    def old_form(settings: dict, diagnostics: dict, extras: dict | None) -> tuple[dict, dict, dict | None]:
        """A result file of an earlier casep: the RELS noise model also in ``diagnostics["noise_model"]``."""
        diagnostics = dict(diagnostics)
        nm = diagnostics.pop("noise_model", None)
        if extras is None and all(isinstance(settings.get(k), (int, float)) for k in ("p0", "weight", "forgetting")):
            nm = nm or {}
            extras = {"p0": settings["p0"], "weight": settings["weight"], "forgetting": settings["forgetting"],
                      "noise_order": int(settings.get("noise_order") or 0),
                      "ma_coefficients": nm.get("ma_coefficients", []), "ma_std": nm.get("ma_std", []),
                      "innovation_rms": nm.get("innovation_rms"), "history_stride": settings.get("history_stride")}
        return settings, diagnostics, extras


def solve_rls(S: np.ndarray | Problem, y: np.ndarray | None = None, *, p0: float = DEFAULT_P0, weight: float = 1.0,
              forgetting: float = 1.0, noise_order: int = 0, residuals: str = "posterior",
              history_stride: int | None = None, **labels: Unpack[Labels]) -> EstimateResult:
    """RLS (``noise_order=0``) or RELS (``noise_order >= 1``) estimate of ``D``.

    Parameters
    ----------
    S : (N, 3, n) array_like or Problem
        Regression matrix in natural units, samples in time order.
    y : (N, 3) array_like
        Velocity error, m/s.
    p0 : float, optional
        ``P_0 = p0 I`` in natural units (default 1e6, as in the paper).
    weight : float, optional
        The paper's ``w``: measurement variance ``1 / w`` (default 1).
    forgetting : float, optional
        Forgetting factor ``lambda`` in [0.5, 1] (default 1: none); stabilized towards the
        prior so that P never exceeds P_0 (see Notes of the module).
    noise_order : int, optional
        RELS noise-model order ``n_c >= 0`` (0: plain RLS).
    residuals : {"posterior", "prior"}, optional
        Which residuals feed the RELS regressor (see Notes of the module).
    history_stride : int, optional
        Keep the estimate every this many samples (default: about 2000 rows).
    **labels
        ``names``, ``units``, ``si_factors``, ``rcond`` as :func:`casep.solve_ols`; ``sigma``: noise
        std for the reported std, m/s (default: estimated).

    Returns
    -------
    EstimateResult
        ``method`` "rls" or "rels"; ``history`` (natural-unit estimates after samples
        0, stride, 2 stride, ...; the MA coefficients last) and ``history_std`` (their std
        ``sqrt(diag(sigma^2 w P_k))`` with the final sigma; diag(P_k) from the U-D factors as
        ``sum_j U_ij^2 D_j``, computed at the history rows only);
        ``extras`` (:class:`RLSExtras`): the RELS noise model (MA coefficients, their std, the
        innovation RMS) and the history stride used.
    """
    nc = _ANY_ORDER.check(noise_order)
    opts: dict[str, Any] = {"p0": p0, "weight": weight, "forgetting": forgetting, "residuals": residuals,
                            "history_stride": history_stride}
    return (RELS.call(S, y, noise_order=nc, **opts, **labels) if nc else RLS.call(S, y, **opts, **labels))


def _solve(pb: Prepared, *, method: Method, p0: float, weight: float, forgetting: float, noise_order: int,
           residuals: str = "posterior", history_stride: int | None = None) -> EstimateResult:
    from casep._kernels import rels_ud  # numba: compiled on first use

    if len(pb.shape) != 2 or pb.shape[1] != 3:
        raise ValueError(f"`S` must be (N, 3, n) in time order for a recursive method, got rows of shape {pb.shape}")
    N = pb.shape[0]
    stride = history_stride if history_stride is not None else max(1, -(-N // _MAX_HISTORY))  # found: extras
    n, nc = pb.n, int(noise_order)
    c = pb.red.scale
    live = c > 0  # zero columns stay out of the recursion (estimate = prior mean, reported null)
    cl = c[live]
    p = int(live.sum())
    x = np.zeros(p + nc)
    U = np.zeros((p + nc, p + nc))  # unit upper triangular, stored transposed
    D = np.concatenate([p0 * cl**2, np.full(nc, p0)])  # P_0 = p0 diag(c^2) in scaled coords
    D0 = D.copy()  # the prior, which stabilized forgetting pulls towards
    past = np.zeros((3, nc + 1))  # each axis' last residuals (RELS regressors), carried across blocks
    hist = np.zeros((-(-N // stride), p + nc))  # rows for samples 0, stride, 2 stride, ... < N
    hist_var = np.zeros_like(hist)  # diag(P) at the same rows, scaled coordinates
    innov_ss = 0.0
    restart = set(pb.problem.segment_starts) - {0}  # several flights: each its own noise
    for sl, S_b, y_b in pb.problem.blocks():  # S_V block by block (regenerated, never whole)
        if sl.start in restart:
            past[:] = 0.0  # RELS: a new flight's noise does not continue the last one's
        H = np.ascontiguousarray(S_b[:, :, live] / cl)  # scaled regressors
        innov = rels_ud(H, np.ascontiguousarray(y_b), x, U, D, weight, forgetting, nc, residuals == "posterior",
                        stride, hist, hist_var, D0, past, sl.start)
        innov_ss += float(np.sum(innov**2))
    Ut = U.T + np.eye(p + nc)  # U = Ut.T with unit diagonal: P = U diag(D) U^T
    L = Ut * np.sqrt(D)
    P = L @ L.T
    x_nat = np.zeros(n)
    x_nat[live] = x[:p] / cl
    fit = pb.residuals(x_nat)  # dv - S_V D_hat, block by block
    if nc:
        from casep._kernels import lfilter  # scipy.signal.lfilter without importing scipy.signal

        # Whitened residuals per axis: v(k) = e(k) - sum_j c_j v(k - j)
        white = lfilter([1.0], np.r_[1.0, x[p:]], fit.reshape(N, 3), axis=0)
    else:
        white = fit.reshape(N, 3)
    dof = max(pb.m - p - nc, 1)
    sig = float(np.sqrt(np.sum(white**2) / dof)) if pb.sigma is None else pb.sigma
    cov_s = sig**2 * weight * P  # posterior covariance, scaled coordinates
    cov = np.full((n, n), 0.0)
    inv = 1.0 / cl
    cov[np.ix_(live, live)] = cov_s[:p, :p] * np.outer(inv, inv)
    hist_nat = hist.copy()
    hist_nat[:, :p] /= cl
    history = np.zeros((hist.shape[0], n + nc))
    history[:, np.flatnonzero(live)] = hist_nat[:, :p]
    history[:, n:] = hist_nat[:, p:]
    history_std = _history_std(hist_var, sig**2 * weight, live, cl, n)
    diagnostics: dict[str, Any] = {"effective_prior_std": float(sig * np.sqrt(weight * p0))}
    ma = tuple(float(v) for v in x[p:])
    ma_std = tuple(float(np.sqrt(cov_s[p + j, p + j])) for j in range(nc))
    innovation_rms = float(np.sqrt(innov_ss / (3 * N))) if nc else None
    res = finish(
        pb, method, x_nat, cov, sig,
        settings={"p0": p0, "weight": weight, "forgetting": forgetting, "noise_order": nc,
                  "residuals": residuals, "history_stride": history_stride,
                  "sigma": "estimated" if pb.sigma is None else pb.sigma},
        diagnostics=diagnostics, history=history, residuals=fit, history_std=history_std,
        extras=RLSExtras(float(p0), float(weight), float(forgetting), int(nc), ma, ma_std, innovation_rms,
                         int(stride)),
    )
    if forgetting < 1.0:  # P is then no covariance and the prior no belief: the std are indicative only
        return res
    return prior_conflict(pb.problem, res, sig * np.sqrt(weight * p0), sig)


#: |z| of the least-squares estimate against the prior above this: prior-data conflict (Gaussian P ~ 6e-7).
PRIOR_CONFLICT_Z = 5.0


def prior_conflict(problem, res: EstimateResult, prior_std: float, sigma: float) -> EstimateResult:
    """Prior-data conflict of RLS's prior ``N(0, prior_std^2 I)`` (natural units): fail the result
    (status :data:`STATUS_PRIOR_CONFLICT`) when the data put a coefficient far outside it.

    Under the model, the least-squares estimate is distributed as ``N(0, prior_std^2 + C_LS,jj)``
    (prior predictive, Box 1980); ``z_j = D_LS,j / sqrt(prior_std^2 + C_LS,jj)`` above
    :data:`PRIOR_CONFLICT_Z` means the prior excludes what the data say, and the posterior is pulled
    towards 0 by far more than its std (a prior std 1e-6 of the truth: the estimate 69 std off).
    ``diagnostics["prior_conflict"]`` records the largest z values.
    """
    import warnings

    from casep.estimators._base import failed
    from casep.estimators.ols import solve_ols

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # conditioning: said by the RLS result itself
        ls = solve_ols(problem, sigma=sigma)
    ls_std = np.asarray(ls.std, dtype=float)  # least squares always defines its std
    ok = np.isfinite(ls.estimate) & np.isfinite(ls_std)
    z = np.where(ok, np.abs(np.nan_to_num(ls.estimate)) / np.sqrt(prior_std**2 + np.nan_to_num(ls_std) ** 2), 0.0)
    if not np.any(z > PRIOR_CONFLICT_Z):
        return res
    order = np.argsort(-z)[: min(5, int(np.sum(z > PRIOR_CONFLICT_Z)))]
    rows = [{"name": res.names[j], "least_squares": float(ls.estimate[j]), "least_squares_std": float(ls_std[j]),
             "z": float(z[j])} for j in order]
    listed = "; ".join(f"{r['name']}: least squares {r['least_squares']:.4g} +- {r['least_squares_std']:.2g} "
                       f"{res.units[res.names.index(r['name'])]}, z = {r['z']:.3g}" for r in rows)
    import dataclasses

    res = dataclasses.replace(res, diagnostics={**res.diagnostics, "prior_conflict": rows})
    return failed(res, STATUS_PRIOR_CONFLICT,
                  f"failed: prior-data conflict: the data put {int(np.sum(z > PRIOR_CONFLICT_Z))} coefficient(s) more "
                  f"than {PRIOR_CONFLICT_Z:g} std outside the prior N(0, {prior_std:.3g}^2) (p0 = "
                  f"{res.settings.get('p0', float('nan')):g}); {listed}. The estimate is pulled towards 0 by more than "
                  "its std: raise p0 (the prior variance, natural units) or use a prior that admits the data"
                  + ("; on noise-free data the prior's scale, sigma, is estimated from residuals that shrink with "
                     "the prior's pull: give sigma (--sigma) as well" if problem.is_noise_free() and res.settings.get(
                         "sigma") == "estimated" else ""))


def _history_std(hist_var: np.ndarray, scale2: float, live: np.ndarray, cl: np.ndarray, n: int) -> np.ndarray:
    """Natural-unit std at the history rows: sqrt(sigma^2 w diag(P_k)) / c (NaN for zero columns)."""
    p = int(live.sum())
    std_s = np.sqrt(scale2 * np.clip(hist_var, 0.0, None))  # sqrt(diag(sigma^2 w P_k)), scaled coordinates
    out = np.full((hist_var.shape[0], n + hist_var.shape[1] - p), np.nan)
    out[:, np.flatnonzero(live)] = std_s[:, :p] / cl  # theta = theta_scaled / c
    out[:, n:] = std_s[:, p:]  # MA coefficients are unscaled
    return out


# ------------------------------------------------------------------ linear map (batched Monte Carlo)
__all__ += ["rls_linear_map"]


def rls_linear_map(S: np.ndarray, *, p0: float = DEFAULT_P0, weight: float = 1.0,
                   rcond: float | None = None) -> LinearMap:
    """The linear map of :func:`solve_rls` without forgetting and without noise model.

    With ``lambda = 1`` and ``noise_order = 0`` the recursion ends at the closed form
    ``theta_N = (P_0^-1 + w S^T S)^-1 w S^T y`` (module Notes), a fixed linear map of ``y``.
    Computed without normal equations on the scaled system (``z = c D``, ``Z = S / c = Q R``,
    zero columns left out as the recursion does) as the least-squares solution of::

        [ sqrt(w) R              ] z = [ sqrt(w) Q^T y ]
        [ diag(1 / (sqrt(p0) c)) ]     [ 0             ]

    Parameters
    ----------
    S : (N, 3, n) or (m, n) array_like
        Regression matrix in natural units.
    p0, weight : float, optional
        As :func:`solve_rls`.
    rcond : float, optional
        Rank threshold for the reported undetermined coefficients.

    Returns
    -------
    casep.estimators.ols.LinearMap
        Covariance ``w P_N`` per unit noise variance, ``dof = m - p`` (``p`` nonzero columns).
    """
    from casep.estimators.ols import LinearMap, scaled_factors

    p0, weight = P0.check(p0), WEIGHT.check(weight)
    pb, Q, U, s, Vt = scaled_factors(S, rcond)
    c = pb.red.scale
    live = c > 0
    R = (U * s) @ Vt  # R of Z = Q R
    A = np.vstack([np.sqrt(weight) * R[:, live], np.diag(1.0 / (np.sqrt(p0) * c[live]))])
    Ua, sa, Vta = np.linalg.svd(A, full_matrices=False)  # A has full column rank (prior rows)
    Ainv = (Vta.T / sa) @ Ua[:pb.n].T  # columns of A^+ acting on sqrt(w) Q^T y
    K = np.zeros((pb.n, pb.m))
    K[live] = np.sqrt(weight) * (Ainv @ Q.T) / c[live][:, None]  # z = A^+ [sqrt(w) Q^T y; 0], D = z / c
    P = (Vta.T / sa**2) @ Vta  # (A^T A)^-1 = P_N, scaled coordinates
    cov = np.zeros((pb.n, pb.n))
    cov[np.ix_(live, live)] = weight * P / np.outer(c[live], c[live])  # w P_N per unit sigma^2
    return LinearMap(K, np.zeros(pb.n), cov, float(pb.m - int(live.sum())), ~pb.ra.estimable)


#: RLS, paper Eq. (14); its linear map holds without forgetting (the closed form of the module Notes).
RLS = Method("rls", "recursive least squares, paper Eq. (14), Bierman U-D", _solve, "solve_rls",
             (P0, WEIGHT, FORGETTING), keywords=(RESIDUALS, HISTORY_STRIDE), fixed={"noise_order": 0},
             recursive=True, batched=True, std_kind="posterior", extras_type=RLSExtras,
             hint="forgetting too strong for this flight?",
             linear_map=lambda S, **kw: rls_linear_map(S, p0=kw.get("p0", DEFAULT_P0), weight=kw.get("weight", 1.0),
                                                       rcond=kw.get("rcond")))
#: RELS: RLS with a moving-average noise model (its memory restarts at each flight of several).
RELS = Method("rels", "recursive extended least squares (MA noise model)", _solve, "solve_rls",
              (P0, WEIGHT, FORGETTING, NOISE_ORDER), keywords=(RESIDUALS, HISTORY_STRIDE), recursive=True,
              noise_in_time=True,
              std_kind="posterior", extras_type=RLSExtras, hint="forgetting too strong for this flight?")
