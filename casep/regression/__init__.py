"""The regression ``y = S D + e`` of a flight: the :class:`Problem` built once, its scaled QR
reduction and rank, several flights stacked, the rows every method solves, studentized residuals.

Layer 3: depends on :mod:`casep.noise` (the rows whitened for a noise model), :mod:`casep.model`
(S_V), :mod:`casep.io` (the flight) and casep's root modules; never on a check or an estimator
(the checks of a flight before estimation are :mod:`casep.checks`').

- :mod:`casep.regression.problem`: :class:`Problem`, the regression of a flight built once
- :mod:`casep.regression.linalg`: TSQR reduction of the column-scaled regression, rank analysis
- :mod:`casep.regression.joint`: :class:`JointProblem`, several flights with shared coefficients; :class:`Flights`,
  several flights as one problem to fit
- :mod:`casep.regression.rows`: :func:`prepare_rows`, the rows every method solves (noise model,
  robust weights, removed samples)
- :mod:`casep.regression.outliers`: externally studentized residuals, outlier flags
"""

from casep._lazy import attach

# Imported on first use (PEP 562), see casep._lazy.
__getattr__, __dir__ = attach(__name__, {
    "casep.regression.problem": ("Problem",),
    "casep.regression.linalg": ("RankAnalysis", "ReducedSystem", "analyze_rank", "reduce_qr", "reduce_qr_blocks"),
    "casep.regression.joint": ("JointProblem", "Flights"),
    "casep.regression.rows": ("Rows", "prepare_rows"),
    "casep.regression.outliers": ("OutlierFlags", "flag_outliers", "studentized_residuals"),
}, globals())

__all__ = ["Problem", "RankAnalysis", "ReducedSystem", "analyze_rank", "reduce_qr", "reduce_qr_blocks",
           "JointProblem", "Flights", "Rows", "prepare_rows", "OutlierFlags", "flag_outliers", "studentized_residuals"]
