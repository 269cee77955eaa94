"""What casep judges of the data and of a fit: plausibility checks of a flight and of a fit,
collinearity and the Cramer-Rao bound, a late start of tracking, a tracking time offset.

Layer 4: depends on :mod:`casep.regression` (the problem judged), :mod:`casep.noise`,
:mod:`casep.io` and casep's root modules; never on an estimator.

- :mod:`casep.checks.flight`: :func:`flight_problem`, a flight's :class:`~casep.Problem`
  after the checks before estimation (the one way casep builds a flight's problem)
- :mod:`casep.checks.plausibility`: :func:`check_flight` (units, impossible data), :func:`check_fit`
  (residuals: noise-free data, spikes, time offset), :func:`check_sigma`
- :mod:`casep.checks.diagnostics`: condition indices, variance decomposition, VIF, CRLB
- :mod:`casep.checks.late_start`: tracking that starts after lift-off without the model's initial terms
- :mod:`casep.checks.time_offset`: the tracking time-offset test
- :mod:`casep.checks.saturation`: readings held at a sensor's full scale (calibration and navigation)
"""

from casep._lazy import attach

# Imported on first use (PEP 562), see casep._lazy.
__getattr__, __dir__ = attach(__name__, {
    "casep.checks.flight": ("flight_problem", "check_before_estimation"),
    "casep.checks.plausibility": ("check_fit", "check_flight", "check_sigma"),
    "casep.checks.diagnostics": ("Diagnostics", "diagnose", "diagnose_noise", "crlb_covariance"),
    "casep.checks.late_start": ("late_start_evidence", "warn_late_start"),
    "casep.checks.time_offset": ("TimeOffsetTest", "time_offset_test"),
    "casep.checks.saturation": ("held_full_scale", "HeldFullScale", "check_full_scale"),
}, globals())

__all__ = ["flight_problem", "check_before_estimation", "check_fit", "check_flight", "check_sigma", "Diagnostics",
           "diagnose", "diagnose_noise", "crlb_covariance", "late_start_evidence", "warn_late_start", "TimeOffsetTest",
           "time_offset_test", "held_full_scale", "HeldFullScale", "check_full_scale"]
