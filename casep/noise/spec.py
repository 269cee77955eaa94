"""The noise part of a fit request, as one checked value: :class:`NoiseSpec` (with
:class:`casep.estimators.spec.FitSpec`, which holds it).

Its check (:meth:`NoiseSpec.__post_init__`) is the one check of the noise kind, tau, the robust fit, the
std kind, the outlier exclusion and the de-noising: :func:`casep.regression.rows.prepare_rows` and every
path to the noise layer take a NoiseSpec or make one. A refusal names the option by its command-line flag
and API keyword (:func:`casep.exceptions.refusal`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

from casep.exceptions import option_label, refusal

__all__ = ["NoiseSpec", "ROBUST_CHOICES", "STD_CHOICES", "DENOISE_CHOICES", "TAU_RULE", "TAU_AXIS_RULE",
           "FrozenOptions", "frozen_options", "check_chance"]

ROBUST_CHOICES = ("auto", "none", "huber", "bisquare")
STD_CHOICES = ("model", "hac")
DENOISE_CHOICES = ("none", "wavelet")
#: How a correlation time of the noise model reads in a refusal (:func:`casep.noise.model.check_tau`'s rule).
TAU_RULE = ("a number in (0, 1e4] s (a correlation time above 1e4 s exceeds any flight), three of them (x, y, z) "
            "or 'auto'")


class FrozenOptions(dict):
    """A read-only mapping of options (a spec's parts cannot change after its check); pickles as a dict."""

    def _refuse(self, *args: Any, **kwargs: Any) -> None:
        raise TypeError("a FitSpec's options are read-only: make a new spec (dataclasses.replace)")

    __setitem__ = __delitem__ = update = pop = popitem = clear = setdefault = __ior__ = _refuse  # type: ignore[assignment]

    def __reduce__(self) -> tuple[Any, tuple[dict[str, Any]]]:
        return (FrozenOptions, (dict(self),))

    def __hash__(self) -> int:  # type: ignore[override]
        return hash(tuple(sorted((k, repr(v)) for k, v in self.items())))


def frozen_options(mapping: Mapping[str, Any] | None) -> Mapping[str, Any]:
    """`mapping` as a read-only :class:`FrozenOptions` (None: empty)."""
    return FrozenOptions(mapping or {})


@dataclass(frozen=True)
class NoiseSpec:
    """The noise part of a fit request (:mod:`casep.regression.rows`, :mod:`casep.noise.model`).

    Attributes
    ----------
    kind : str
        Noise kind, one of :data:`casep.noise.model.NOISE_KINDS` (``auto``: chosen per axis by
        likelihood).
    tau : float, three floats or None
        Given Gauss-Markov correlation time(s) of the noise model, s (None: REML). A number implies
        Gauss-Markov noise (``kind`` "auto" becomes "gm", "gmw" stays; "white" is an error).
    robust : {"auto", "huber", "bisquare"} or None
        Robust fit (None: never).
    std : {"model", "hac"}
        What the std are: the noise model's, or Newey-West (white-noise least squares).
    exclude_outliers : float or None
        Remove the samples flagged at this family-wise false-alarm chance and fit again.
    denoise : {"wavelet"} or None
        De-noise dv first (:func:`casep.noise.denoise.denoise`); the noise model is then white
        and no robust fit runs (the de-noised residuals are no noise sample).
    wavelet_options : mapping
        Keywords of :func:`casep.noise.denoise.denoise`.
    """

    kind: str = "auto"
    tau: Any = None
    robust: str | None = "auto"
    std: str = "model"
    exclude_outliers: float | None = None
    denoise: str | None = None
    wavelet_options: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        from casep.noise.model import NOISE_KINDS

        set_ = object.__setattr__  # frozen: the normal form is set once, here
        for name, value, choices in (("noise", self.kind, NOISE_KINDS), ("robust", self.robust, ROBUST_CHOICES),
                                     ("std", self.std, STD_CHOICES), ("denoise", self.denoise, DENOISE_CHOICES)):
            if not (value in choices or (value is None and name in ("robust", "denoise"))):
                raise refusal(name, None, " | ".join(choices), value)
        if self.robust == "none":
            set_(self, "robust", None)
        check_chance("exclude_outliers", self.exclude_outliers)
        if self.denoise == "none":
            set_(self, "denoise", None)
        set_(self, "wavelet_options", frozen_options(self.wavelet_options))
        if self.wavelet_options and self.denoise != "wavelet":
            raise ValueError(f"{option_label('wavelet_options', '--wavelet')} given without "
                             f"{option_label('denoise')} 'wavelet'")
        if isinstance(self.tau, str) and self.tau == "auto":
            set_(self, "tau", None)  # REML: as when not given
        set_(self, "tau", _checked_tau(self.tau))
        if isinstance(self.tau, (list, np.ndarray)):
            set_(self, "tau", tuple(float(v) for v in np.ravel(self.tau)))  # a value: hashable, unchanged
        if self.tau is not None:
            if self.kind == "white":
                raise ValueError(f"{option_label('tau')} given with {option_label('noise')} 'white': a correlation "
                                 "time means noise 'gm'")
            set_(self, "kind", "gmw" if self.kind == "gmw" else "gm")  # gmw: the white part still by REML
        if self.denoise == "wavelet":
            if self.kind in ("gm", "gmw") or self.robust not in (None, "auto") or self.exclude_outliers is not None \
                    or self.std != "model":
                raise ValueError(f"{option_label('denoise')} 'wavelet' removes the noise a noise model, a robust fit "
                                 "or HAC std describe: use them without de-noising")
            set_(self, "kind", "white")  # the de-noised residuals are no noise sample to fit a model on
            set_(self, "robust", None)


#: The rule of one axis's correlation time (:func:`casep.noise.model.check_tau`'s), in a refusal naming the axis.
TAU_AXIS_RULE = "a number in (0, 1e4] s (a correlation time above 1e4 s exceeds any flight)"


def _checked_tau(tau: Any) -> Any:
    """`tau` as given, once the noise model's rule (:func:`casep.noise.model.check_tau`) accepts it; a mapping
    ``{"x": .., "y": .., "z": ..}`` becomes three values. A refused value of one axis is named by its axis."""
    from casep.noise.model import AXES, check_tau

    if isinstance(tau, Mapping):
        wrong = sorted(set(map(str, tau)) ^ set(AXES))
        if wrong:
            raise refusal("tau", None, "one value per axis x, y and z when given per axis", dict(tau),
                          part=f"axis {', '.join(wrong)}")
        tau = tuple(tau[a] for a in AXES)
    try:
        check_tau(tau)  # the noise model's own rule for a correlation time, checked here, at the edge
    except (ValueError, TypeError):
        if isinstance(tau, (tuple, list, np.ndarray)) and np.size(tau) == 3:
            for a, v in zip(AXES, np.ravel(np.asarray(tau, dtype=object))):
                try:
                    check_tau(v)
                except (ValueError, TypeError):
                    raise refusal("tau", None, TAU_AXIS_RULE, v,
                                  part=f"axis {a}") from None
        raise refusal("tau", None, TAU_RULE, tau) from None
    return tau


def check_chance(name: str, value: Any) -> None:
    """A family-wise false-alarm chance of the outlier flags (`outliers`, `exclude_outliers`): None or in (0, 1)."""
    if value is None:
        return
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not 0.0 < float(value) < 1.0:
        raise refusal(name, None, "a false-alarm chance in (0, 1) (e.g. 0.01)", value)
