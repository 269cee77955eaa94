"""What an estimate's ``std_kind`` and ``sigma_source`` may be, and what each means."""

__all__ = ["STD_KIND_MEANINGS", "SIGMA_SOURCE_MEANINGS", "SIGMA_SOURCES", "SIGMA_FOUND", "AXES", "EXTRAS_TYPES",
           "extras_type"]

AXES = ("x", "y", "z")

#: What the reported ``std`` mean (``EstimateResult.std_kind``, set by each solver; the
#: registry's ``Method.std_kind`` declares each method's kind):
STD_KIND_MEANINGS = {
    "sampling": "spread of the estimate over noise draws (for a biased method: around its mean)",
    "posterior": "std of the posterior under the method's prior (MAP's prior; RLS/RELS's P0)",
    "conditional": "given the active set of the bounds: understated (bounded, when a bound is active)",
}

#: Where ``sigma`` came from (``EstimateResult.sigma_source``):
#: "estimated": residual std of the fit, sqrt(RSS / (m - rank)), of the whitened residuals for GLS/RELS;
#: "given": the caller's ``sigma``;
#: "wavelet": the wavelet transform's estimate from the raw finest details (set by ``separate``
#: when dv was de-noised and no sigma was given);
#: "robust": Huber's MAD scale of the residuals.
#: No method estimates sigma from a prior, so there is no "prior"/"posterior" source.
SIGMA_SOURCE_MEANINGS = {
    "estimated": "residual std of the fit (whitened residuals for GLS/RELS)",
    "given": "given by the caller",
    "wavelet": "wavelet estimate from the raw finest details (dv de-noised, no sigma given)",
    "robust": "Huber's MAD scale of the residuals",
    "whitened": "rows divided by their own noise std (several flights: flights[].sigma; radar: per station and "
                "measurement type), so dimensionless and 1 when those std are right",
    "fused": "fused results: each input's own sigma (settings.fused)",
    "external": "a result file of another tool that states no sigma (docs/guide/result-files.md)",
}
SIGMA_SOURCES = tuple(SIGMA_SOURCE_MEANINGS)

#: How a sigma that a method or the de-noising found (not the caller's) reads in the settings line.
SIGMA_FOUND = {"robust": "robust estimate", "wavelet": "wavelet estimate from the raw finest details"}

#: The extras dataclass of each registered method (``Method.extras_type``, declared beside its solver, with
#: ``describe``); filled by :mod:`casep.estimators.registry`, which the package imports first.
EXTRAS_TYPES: dict[str, type] = {}


def extras_type(method: str) -> type | None:
    """The extras dataclass a registered `method` declares (None for an unregistered name)."""
    return EXTRAS_TYPES.get(method)
