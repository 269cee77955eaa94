"""A prior (a ground calibration, an earlier flight's result) against the flight estimated alone.

The estimate with a prior (``casep separate --method map --prior``) contains it, so the comparison refits the flight
without it, as its own fit (:func:`flight_prior_consistency`), and compares the two
(:func:`casep.calibration.consistency.consistency`); :func:`with_prior_consistency` records it in the result.
"""

from __future__ import annotations

import dataclasses
import warnings
from typing import Any, Mapping

__all__ = ["conflict_message", "flight_prior_consistency", "with_prior_consistency"]


def flight_prior_consistency(flight: Any, model: Any, prior: Mapping[str, Any], *, sigma: float | None = None,
                             spec: Any = None, iterate: bool | None = None) -> Any:
    """Consistency of a prior (e.g. a ground calibration) with the flight estimated alone: a
    :class:`casep.calibration.consistency.Consistency`.

    ``casep separate --prior`` reports it: the MAP estimate contains the prior, so the flight is
    fitted again without it and compared on the coefficients it determines. The flight alone is the
    flight's own fit, the one ``casep separate FLIGHT`` makes and ``casep fuse`` combines:
    :func:`casep.workflows.separate.separate` with the request of the estimate that used the prior
    (`spec`: its noise model, robust fit, std kind, sigma and de-noising) but method ``ols`` and no
    prior, so that the flight's std are those of its noise (a white-noise
    fit of Gauss-Markov rows would understate them and double the chi-square).

    Parameters
    ----------
    flight : FlightData or path
    model : ErrorModel or str
    prior : mapping
        The prior (natural units), as ``casep separate --prior`` reads it.
    sigma : float, optional
        Noise std, m/s (default: `spec`'s, else estimated).
    spec : FitSpec, optional
        The request of the estimate that used the prior (default: the default request).
    iterate : bool, optional
        As :func:`casep.workflows.separate.separate`'s.
    """
    from casep.calibration.consistency import consistency
    from casep.exceptions import CasepWarning
    from casep.model.loader import load_model
    from casep.workflows.separate import separate

    model = load_model(model)
    alone = _flight_alone_spec(spec, sigma)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", CasepWarning)  # the separation itself reports the flight's conditioning
        res = separate(flight, model, spec=alone, iterate=iterate)
    return consistency(prior, res, labels=("prior", "flight alone"))


def _flight_alone_spec(spec: Any = None, sigma: float | None = None) -> Any:
    """The request of a flight estimated alone: `spec` (a :class:`casep.FitSpec`; default the default request)
    with method ``ols``, no method option (the prior) and no outlier flags, its noise model, sigma and
    de-noising kept; `sigma` given replaces the spec's."""
    from casep.estimators.spec import FitSpec

    spec = FitSpec() if spec is None else spec
    return FitSpec("ols", {}, spec.sigma if sigma is None else sigma, spec.noise)


def with_prior_consistency(result: Any, flight: Any, model: Any, prior: Mapping[str, Any], *,
                           sigma: float | None = None, spec: Any = None,
                           iterate: bool | None = None) -> tuple[Any, Any]:
    """The prior (a ground calibration, say) compared with the flight estimated alone, recorded in the result.

    Parameters
    ----------
    result : EstimateResult
        The estimate that used `prior`.
    flight : FlightData
        Its flight.
    model : ErrorModel
    prior : mapping
        The prior as :func:`read_coefficient_file` returns it.
    sigma : float, optional
        Noise std, m/s (default: `spec`'s, else estimated).
    spec : FitSpec, optional
        The request of `result`: the flight alone is fitted under its noise model (method ``ols``, no prior).
    iterate : bool, optional
        As :func:`casep.workflows.separate.separate`'s.

    Returns
    -------
    result : EstimateResult
        A copy with ``diagnostics["prior_consistency"]``: the comparison's summary, or
        ``{"not_compared": why}`` when the flight alone determines none of the prior's coefficients
        (a :class:`~casep.exceptions.CasepWarning` says so). When the two disagree (the comparison's verdict,
        :attr:`casep.calibration.consistency.Consistency.consistent`: overall p below
        :data:`casep.calibration.consistency.DISAGREE_P`) the copy is failed, status
        :data:`casep.estimators.registry.STATUS_PRIOR_CONFLICT`, naming the coefficients that disagree most
        (:func:`conflict_message`): the estimate would average a prior the flight contradicts into it.
    consistency : Consistency or None
        :func:`flight_prior_consistency`, None when not compared.
    """
    from casep.exceptions import CasepWarning

    cons = None
    try:
        cons = flight_prior_consistency(flight, model, prior, sigma=sigma, spec=spec, iterate=iterate)
        summary = cons.to_dict()
    except ValueError as exc:  # the flight alone determines none of the prior's coefficients
        cons, summary = None, {"not_compared": str(exc)}
        warnings.warn(f"prior not compared with the flight alone: {exc}", CasepWarning, stacklevel=2)
    result = dataclasses.replace(result, diagnostics={**result.diagnostics, "prior_consistency": summary})
    if cons is not None and not cons.consistent:
        from casep.estimators.registry import STATUS_PRIOR_CONFLICT, failed

        result = failed(result, STATUS_PRIOR_CONFLICT, conflict_message(cons))
    return result, cons


def conflict_message(cons: Any, most: int = 3) -> str:
    """Why an estimate with a prior the flight alone disagrees with fails: the verdict (chi-square, p), the `most`
    coefficients furthest apart (prior, flight alone, z) and what to do."""
    import numpy as np

    from casep.calibration.consistency import DISAGREE_Z

    z = np.abs(np.nan_to_num(np.asarray(cons.z, dtype=float)))
    beyond = int(np.sum(z > DISAGREE_Z))
    order = [int(j) for j in np.argsort(-z, kind="stable")[:max(1, min(most, beyond))]]
    where = (f"{beyond} coefficient(s) more than {DISAGREE_Z:g} std apart, furthest" if beyond else
             f"no coefficient more than {DISAGREE_Z:g} std apart alone (the two disagree on a combination of "
             "correlated coefficients), furthest")
    listed = "; ".join(f"{cons.names[j]} {cons.ground[j]:.4g} +- {cons.ground_std[j]:.2g} {cons.units[j]} in the "
                       f"prior, {cons.flight[j]:.4g} +- {cons.flight_std[j]:.2g} in the flight alone "
                       f"(z {cons.z[j]:.3g})"
                       for j in order)
    return (f"failed: prior conflict: the flight alone DISAGREES with the prior (chi2 {cons.chi2:.4g} on {cons.dof} "
            f"dof, p {cons.p_value:.3g}); {where}: {listed}. The estimate would average the two, an estimate of "
            "neither: check that the prior is of this instrument (serial, units, axes, sign "
            "conventions) and, if the instrument changed since, drop the prior (estimate without --prior)")
