"""Ground versus flight: do a ground calibration and a flight estimate agree?

Two independent estimates of the same coefficients (a ground test and a flight are different
data), ``g ~ N(D, C_g)`` and ``f ~ N(D, C_f)``, differ by ``d = f - g ~ N(0, C_g + C_f)`` when both
are right. On the coefficients both determine (a finite estimate and variance in each):

- per coefficient: ``z_j = d_j / sqrt((C_g + C_f)_jj)``, two-sided ``p_j = 2 (1 - Phi(|z_j|))``;
- overall: ``chi2 = d^T (C_g + C_f)^+ d`` with ``dof = rank(C_g + C_f)`` (eigen-decomposition,
  eigenvalues below 1e-12 of the largest dropped), ``p = P(chi2_dof > chi2)``.

The covariances are used whole (the correlations of a calibration's scale and bias, of a
flight's collinear coefficients). The flight estimate must not already contain the ground result
(a MAP estimate with it as prior is correlated with it):
:func:`casep.workflows.prior_consistency.flight_prior_consistency` refits the flight alone for that
reason (its own fit: least squares under its noise model, as ``casep separate FLIGHT`` fits it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from casep.regression.linalg import covariance_std
from casep.results import deprecated_alias

__all__ = ["Consistency", "consistency", "ground_prior", "ground_versus_flight",
           "ground_flight_checks",
           "as_gaussian", "DISAGREE_P", "DISAGREE_Z"]

#: Overall p-value below which the two are said to disagree.
DISAGREE_P = 1e-3
#: |z| above which a coefficient is listed as disagreeing.
DISAGREE_Z = 3.0


@dataclass(frozen=True)
class Consistency:
    """Per-coefficient and overall consistency of two estimates (module notes).

    The result protocol (:mod:`casep.results`): ``success`` is :attr:`consistent` (status 0; 1 when
    the two disagree), ``message`` the verdict.
    """

    names: tuple[str, ...]
    units: tuple[str, ...]
    ground: np.ndarray
    ground_std: np.ndarray
    flight: np.ndarray
    flight_std: np.ndarray
    difference: np.ndarray
    difference_std: np.ndarray
    z: np.ndarray
    p: np.ndarray
    chi2: float
    dof: int
    p_value: float
    left_out: tuple[str, ...] = ()
    labels: tuple[str, str] = ("ground", "flight")

    @property
    def disagree(self) -> list[str]:
        """Coefficients with ``|z|`` above :data:`DISAGREE_Z`."""
        return [n for n, z in zip(self.names, self.z) if abs(z) > DISAGREE_Z]

    @property
    def consistent(self) -> bool:
        """Overall p-value at least :data:`DISAGREE_P`."""
        return not self.p_value < DISAGREE_P

    @property
    def success(self) -> bool:
        """The two estimates agree (:attr:`consistent`)."""
        return self.consistent

    @property
    def status(self) -> int:
        """0: consistent; 1: they disagree (overall p-value below :data:`DISAGREE_P`)."""
        return 0 if self.consistent else 1

    @property
    def message(self) -> str:
        """The verdict in one line."""
        a, b = self.labels
        return (f"{a} and {b} consistent (chi2 {self.chi2:.4g} on {self.dof} dof, p {self.p_value:.3g})"
                if self.consistent else f"{a} and {b} DISAGREE (p {self.p_value:.3g} < {DISAGREE_P:g})")

    summary = deprecated_alias("to_dict", "summary")
    report = deprecated_alias("text", "report")

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dict (per coefficient and overall)."""
        def f(v):
            v = float(v)
            return v if math.isfinite(v) else None

        return {
            "labels": list(self.labels),
            "overall": {"chi2": f(self.chi2), "dof": int(self.dof), "p_value": f(self.p_value),
                        "consistent": self.consistent},
            "coefficients": [{"name": n, "unit": u, self.labels[0]: f(g), f"{self.labels[0]}_std": f(gs),
                              self.labels[1]: f(fl), f"{self.labels[1]}_std": f(fs), "difference": f(d),
                              "difference_std": f(ds), "z": f(z), "p": f(p)}
                             for n, u, g, gs, fl, fs, d, ds, z, p in zip(
                                 self.names, self.units, self.ground, self.ground_std, self.flight, self.flight_std,
                                 self.difference, self.difference_std, self.z, self.p)],
            "disagree": self.disagree,
            "left_out": list(self.left_out),
        }

    def text(self) -> str:
        """Readable table and verdict."""
        a, b = self.labels
        lines = [f"{a} versus {b} ({len(self.names)} coefficients both determine; difference {b} - {a})",
                 f"{'coefficient':<12} {'unit':<10} {a:>12} {'std':>10} {b:>12} {'std':>10} {'z':>8}"]
        for n, u, g, gs, fl, fs, z in zip(self.names, self.units, self.ground, self.ground_std, self.flight,
                                          self.flight_std, self.z):
            lines.append(f"{n:<12} {u:<10} {g:>12.5g} {gs:>10.3g} {fl:>12.5g} {fs:>10.3g} {z:>8.3g}"
                         + ("  <-" if abs(z) > DISAGREE_Z else ""))
        verdict = ("consistent" if self.consistent else
                   f"they DISAGREE (p < {DISAGREE_P:g}): an error that one of the two does not model, a unit or "
                   "sign mistake, or a change of the instrument between the ground test and the flight")
        lines.append(f"overall: chi2 {self.chi2:.4g} on {self.dof} dof, p {self.p_value:.3g}: {verdict}")
        if self.disagree:
            lines.append(f"|z| > {DISAGREE_Z:g}: {', '.join(self.disagree)}")
        if self.left_out:
            lines.append(f"not compared (one of the two does not determine them): {', '.join(self.left_out)}")
        return "\n".join(lines)


def as_gaussian(source) -> tuple[tuple, tuple | None, np.ndarray, np.ndarray, str]:
    """``(names, units or None, mean, covariance, method)`` of an EstimateResult, a Calibration, a
    result/calibration JSON (dict or path) or a prior mapping ``{name: {mean, std}, "correlation": ...}``."""
    from casep.estimators.result import EstimateResult

    if hasattr(source, "result") and hasattr(source, "sensors"):  # a Calibration
        source = source.result
    if isinstance(source, (str, bytes)) or hasattr(source, "__fspath__"):
        from casep.io.files import read_json_table

        source = read_json_table(source, "result")
    if isinstance(source, Mapping) and "coefficients" in source and "covariance" in source:
        source = EstimateResult.from_json(dict(source))
    if isinstance(source, EstimateResult):
        if source.covariance is None:
            raise ValueError(f"the {source.method} result has no covariance: it cannot be compared")
        return tuple(source.names), tuple(source.units), np.asarray(source.estimate, float), \
            np.array(source.covariance, dtype=float), source.method
    if isinstance(source, Mapping):
        from casep.estimators.map import parse_prior

        names = tuple(k for k in source if k != "correlation")
        mu, sd = parse_prior(source, names)
        C = np.diag(sd**2)
        corr = source.get("correlation")
        if isinstance(corr, Mapping):
            idx = [names.index(n) for n in corr["names"]]
            rho = np.asarray(corr["matrix"], dtype=float)
            C[np.ix_(idx, idx)] = rho * np.outer(sd[idx], sd[idx])
        return names, None, mu, C, "prior"
    raise TypeError(f"cannot compare a {type(source).__name__}: give a result, a calibration, a JSON or a "
                    "prior mapping")


def consistency(ground, flight, *, names: Sequence[str] | None = None,
                labels: tuple[str, str] = ("ground", "flight")) -> Consistency:
    """Per-coefficient z and overall chi-square of two independent estimates (module notes).

    Parameters
    ----------
    ground, flight
        EstimateResult, Calibration, result JSON (dict or path) or prior mapping (natural units).
    names : sequence of str, optional
        Compare only these coefficients.

    Raises
    ------
    ValueError
        No coefficient in common, a coefficient in different units, a flight estimate that used a
        prior (not independent of the ground result).
    """
    from scipy.stats import chi2 as chi2_dist
    from scipy.stats import norm

    gn, gu, gm, gC, _ = as_gaussian(ground)
    fn, fu, fm, fC, fmethod = as_gaussian(flight)
    from casep.estimators.registry import METHODS

    if fmethod in METHODS and "prior" in METHODS[fmethod].required:
        raise ValueError("the flight estimate is a MAP estimate: it contains its prior and is not independent of "
                         "the ground result. Use: a flight-only estimate (--method ols), or "
                         "casep.workflows.prior_consistency.flight_prior_consistency()")
    common = [n for n in gn if n in fn and (names is None or n in names)]
    if not common:
        raise ValueError(f"no coefficient in common between the {labels[0]} ({', '.join(gn[:6])}...) and the "
                         f"{labels[1]} ({', '.join(fn[:6])}...) estimates")
    units = []
    for n in common:
        ug = gu[gn.index(n)] if gu else None
        uf = fu[fn.index(n)] if fu else None
        if ug and uf and ug != uf:
            raise ValueError(f"`{n}` is in {ug} in the {labels[0]} estimate but in {uf} in the {labels[1]}: "
                             "the same name must carry the same unit")
        units.append(ug or uf or "")
    gi = [gn.index(n) for n in common]
    fi = [fn.index(n) for n in common]
    ok = [k for k in range(len(common))
          if np.isfinite(gm[gi[k]]) and np.isfinite(fm[fi[k]]) and np.isfinite(gC[gi[k], gi[k]])
          and np.isfinite(fC[fi[k], fi[k]]) and gC[gi[k], gi[k]] > 0 and fC[fi[k], fi[k]] >= 0]
    left = tuple(common[k] for k in range(len(common)) if k not in ok)
    if not ok:
        raise ValueError(f"no coefficient is determined by both estimates (left out: {', '.join(left)})")
    gi = [gi[k] for k in ok]
    fi = [fi[k] for k in ok]
    nm = tuple(common[k] for k in ok)
    un = tuple(units[k] for k in ok)
    d = fm[fi] - gm[gi]
    C = gC[np.ix_(gi, gi)] + fC[np.ix_(fi, fi)]  # Cov(f - g) of independent estimates
    C = (C + C.T) / 2
    sd = np.sqrt(np.diag(C))
    z = d / sd
    p = 2.0 * norm.sf(np.abs(z))
    # chi2 = d^T C^+ d in correlation coordinates (scale-free eigenvalue cut)
    R = C / np.outer(sd, sd)
    lam, V = np.linalg.eigh(R)
    keep = lam > 1e-12 * lam.max()
    proj = V[:, keep].T @ z
    chi2 = float(np.sum(proj**2 / lam[keep]))
    dof = int(keep.sum())
    return Consistency(names=nm, units=un, ground=gm[gi], ground_std=np.sqrt(np.diag(gC)[gi]), flight=fm[fi],
                       flight_std=covariance_std(fC)[fi], difference=d, difference_std=sd, z=z,
                       p=p, chi2=chi2, dof=dof, p_value=float(chi2_dist.sf(chi2, dof)), left_out=left, labels=labels)


def ground_prior(ground, flight_model) -> dict:
    """A ground calibration as the prior of a flight model: its names, units and covariance exactly.

    The coefficients of the flight model that the ground test estimated keep their ground value,
    std and correlations (the covariance block: marginalising the ground-only ones, such as the
    gyro scale that rotations excite); a name the flight model has in another unit is an error.

    Parameters
    ----------
    ground : Calibration, EstimateResult, calibration JSON (dict or path)
    flight_model : ErrorModel or str

    Returns
    -------
    dict
        ``{name: {"mean", "std"}, ..., "correlation": {"names", "matrix"}}`` (natural units), as
        ``casep separate --method map --prior`` reads it.
    """
    from casep.model.loader import load_model

    model = load_model(flight_model)
    names, units, mean, C, _ = as_gaussian(ground)
    if units is None:
        raise ValueError("a ground prior needs the ground result's units (a result or calibration JSON)")
    keep = []
    for j, n in enumerate(names):
        if n not in model.names:
            continue
        fu = model.units[model.index(n)]
        if units[j] != fu:
            raise ValueError(f"ground `{n}` is in {units[j]}, flight model `{model.name}` has it in {fu}")
        if np.isfinite(mean[j]) and np.isfinite(C[j, j]) and C[j, j] > 0:
            keep.append(j)
    if not keep:
        raise ValueError(f"the ground result shares no estimated coefficient with flight model `{model.name}`")
    Ck = C[np.ix_(keep, keep)]
    sd = np.sqrt(np.diag(Ck))
    out: dict = {names[j]: {"mean": float(mean[j]), "std": float(s)} for j, s in zip(keep, sd)}
    out["correlation"] = {"names": [names[j] for j in keep], "matrix": (Ck / np.outer(sd, sd)).tolist()}
    return out


def ground_versus_flight(results: Sequence, labels: Sequence[str]) -> tuple[list, str]:
    """For ``casep fuse``: ground calibrations among `results` mapped to their flight model, and the
    consistency of each with each flight result (text). :func:`ground_flight_checks` also returns the
    :class:`Consistency` of each pair."""
    out, _, text = ground_flight_checks(results, labels)
    return out, text


def ground_flight_checks(results: Sequence, labels: Sequence[str]) -> tuple[list, list[Consistency], str]:
    """Ground calibrations among `results` mapped to their flight model, the consistency of each with
    each flight result, and its text.

    A result of a calibration model with a ``flight_model`` (``platform36_ground``) becomes the
    Gaussian of its shared coefficients under the flight model's name (:func:`ground_prior`), so
    it fuses with the flights; the text holds one consistency table per (ground, flight) pair.
    """
    import dataclasses

    from casep.calibration.model import calibration_models, load_calibration_model
    from casep.estimators.result import EstimateResult

    known = set(calibration_models())
    out, grounds, flights, text, checks = [], [], [], [], []
    for r, lab in zip(results, labels):
        if isinstance(r, EstimateResult) and r.model in known:
            cm = load_calibration_model(r.model)
            if not cm.flight_model:
                raise ValueError(f"{lab}: calibration model `{r.model}` names no flight model; it cannot be fused "
                                 "with flights")
            pr = ground_prior(r, cm.flight_model)
            nm = pr["correlation"]["names"]
            idx = [r.names.index(n) for n in nm]
            cov = r.covariance[np.ix_(idx, idx)] if r.covariance is not None else None
            r = dataclasses.replace(r, names=tuple(nm), units=tuple(r.units[i] for i in idx),
                                    estimate=r.estimate[idx], std=r.std[idx] if r.std is not None else None,
                                    covariance=cov, si_factors=r.si_factors[idx],
                                    model=cm.flight_model, reasons={})
            grounds.append((r, lab))
        else:
            flights.append((r, lab))
        out.append(r)
    for g, gl in grounds:
        for f, fl in flights:
            try:
                c = consistency(g, f, labels=(f"ground {gl}", f"flight {fl}"))
            except ValueError as exc:
                text.append(f"ground {gl} versus flight {fl}: not compared ({exc})")
                continue
            checks.append(c)
            text.append(c.text())
    return out, checks, "\n\n".join(text)
