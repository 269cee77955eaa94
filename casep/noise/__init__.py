"""The noise of the rows: its model, its fit, the robust filter, the whiteness test, its identification
and wavelet de-noising.

Layer 2: depends only on casep's root modules (:mod:`casep._kernels`, :mod:`casep.results`,
:mod:`casep.exceptions`); a problem is taken as given (its rows, times and rank), never imported,
so :mod:`casep.regression` can whiten its rows with this package.

- :mod:`casep.noise.model`: :class:`NoiseModel` (white, Gauss-Markov or Gauss-Markov plus white per
  axis), whitening
- :mod:`casep.noise.fit`: :func:`fit_noise`, the REML fit of the noise model (``noise="auto"``: by a
  likelihood-ratio test)
- :mod:`casep.noise.known`: REML of the tracking noise beside a known noise term in state-space form
  (the IMU's own noise of ``casep separate --imu``), never an N x N matrix
- :mod:`casep.noise.whiteness`: the Ljung-Box test of whitened residuals, gaps and segments
- :mod:`casep.noise.robust`: the robust filter on the innovations (glitches, row weights)
- :mod:`casep.noise.identification`: Allan deviation and the noise processes it shows
- :mod:`casep.noise.denoise`: wavelet de-noising of dv
"""

from casep._lazy import attach

# Imported on first use (PEP 562), see casep._lazy.
__getattr__, __dir__ = attach(__name__, {
    "casep.noise.model": ("NoiseModel", "NOISE_KINDS", "whiten", "whiten_blocks"),
    "casep.noise.fit": ("fit_noise",),
    "casep.noise.whiteness": ("WhitenessTest", "whiteness_test", "ljung_box"),
    "casep.noise.robust": ("RobustWeights", "robust_filter"),
    "casep.noise.identification": ("NoiseIdentification", "identify_noise", "allan_deviation"),
    "casep.noise.denoise": ("DenoiseResult", "denoise", "denoise_signal"),
}, globals())

__all__ = ["NoiseModel", "NOISE_KINDS", "whiten", "whiten_blocks", "fit_noise", "WhitenessTest", "whiteness_test",
           "ljung_box", "RobustWeights", "robust_filter", "NoiseIdentification", "identify_noise",
           "allan_deviation", "DenoiseResult", "denoise", "denoise_signal"]
