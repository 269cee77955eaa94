"""What the data can tell: the scaled QR reduction and rank analysis, collinearity diagnostics,
plausibility checks of a flight and of a fit, wavelet de-noising.

Depends on :mod:`casep.io` (the flight) and :mod:`casep.units`; never on an estimator.

- :mod:`casep.analysis.problem`: :class:`Problem`, the regression of a flight built once
- :mod:`casep.analysis.linalg`: TSQR reduction of the column-scaled regression, rank analysis
- :mod:`casep.analysis.diagnostics`: condition indices, variance decomposition, VIF, CRLB
- :mod:`casep.analysis.checks`: ``check_flight`` (units, impossible data), ``check_fit``
- :mod:`casep.analysis.denoise`: wavelet de-noising of dv
- :mod:`casep.analysis.noise`: the noise model of the rows (white / Gauss-Markov per axis, REML),
  whitening, the whiteness test
- :mod:`casep.analysis.robust`: the robust filter on the innovations (glitches, row weights)
- :mod:`casep.analysis.rows`: ``prepare_rows``, the rows every method solves
"""


from casep._lazy import attach

# Imported on first use (PEP 562), see casep._lazy.
__getattr__, __dir__ = attach(__name__, {
    "casep.analysis.checks": ("check_fit", "check_flight"),
    "casep.analysis.diagnostics": ("Diagnostics", "diagnose"),
    "casep.analysis.linalg": ("RankAnalysis", "ReducedSystem", "analyze_rank", "reduce_qr", "reduce_qr_blocks"),
    "casep.analysis.problem": ("Problem",),
    "casep.analysis.noise": ("NoiseModel",),
    "casep.analysis.noise_fit": ("fit_noise",),
    "casep.analysis.whiteness": ("whiteness_test",),
    "casep.analysis.robust": ("robust_filter",),
    "casep.analysis.rows": ("Rows", "prepare_rows")}, globals())

__all__ = ["check_fit", "check_flight", "Diagnostics", "diagnose", "RankAnalysis", "ReducedSystem",
           "analyze_rank", "reduce_qr", "reduce_qr_blocks", "Problem", "NoiseModel", "fit_noise", "whiteness_test",
           "robust_filter", "Rows", "prepare_rows"]
