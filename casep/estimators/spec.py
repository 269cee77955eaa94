"""What a user asks of a fit, as one checked value: :class:`FitSpec` and its :class:`NoiseSpec`.

A request is built once, where it enters casep (the keywords of :func:`casep.separate`, the
arguments of ``casep separate``, a manifest), and checked there by one validator
(:meth:`FitSpec.__post_init__`): the method and its options (by the registry's rules,
:func:`casep.estimators.registry.check_method_options`), sigma, the noise kind
(:func:`casep.noise.model.check_noise_kind`), the robust fit, the std kind, the outlier
exclusion and the de-noising. Everything downstream (:func:`casep.workflows.solve.fit`) takes
the spec as checked.

Who owns ``tau`` is decided here, once: a method that takes ``tau`` as its own option (GLS: one
correlation time for every axis) gets it in :attr:`FitSpec.options`; for every other method it is
the noise model's (:attr:`NoiseSpec.tau`, a number meaning Gauss-Markov noise).

Options the caller did not give are :data:`NOT_GIVEN` (a sentinel), never recognised by being
equal to their default: ``separate(..., p0=1e6, options={"p0": 1.0})`` is "given both", whatever
the values.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

__all__ = ["FitSpec", "NoiseSpec", "NOT_GIVEN", "NotGiven", "merge_options", "check_robust_method", "check_chance",
           "ROBUST_BY_THEMSELVES", "ROBUST_CHOICES", "STD_CHOICES", "DENOISE_CHOICES"]

ROBUST_CHOICES = ("auto", "none", "huber", "bisquare")
STD_CHOICES = ("model", "hac")
DENOISE_CHOICES = ("none", "wavelet")


class NotGiven:
    """The type of :data:`NOT_GIVEN`: an argument the caller left out (falsy, one instance)."""

    _one: NotGiven | None = None

    def __new__(cls) -> NotGiven:
        if cls._one is None:
            cls._one = super().__new__(cls)
        return cls._one

    def __repr__(self) -> str:
        return "NOT_GIVEN"

    def __bool__(self) -> bool:
        return False

    def __reduce__(self) -> str:
        return "NOT_GIVEN"  # pickled as the module's one instance (Monte Carlo workers)


#: An argument the caller did not give (distinct from every value, its default included).
NOT_GIVEN = NotGiven()


class FrozenOptions(dict):
    """A read-only mapping of options (a spec's parts cannot change after its check); pickles as a dict."""

    def _refuse(self, *args: Any, **kwargs: Any) -> None:
        raise TypeError("a FitSpec's options are read-only: make a new spec (dataclasses.replace)")

    __setitem__ = __delitem__ = update = pop = popitem = clear = setdefault = __ior__ = _refuse  # type: ignore[assignment]

    def __reduce__(self) -> tuple[Any, tuple[dict[str, Any]]]:
        return (FrozenOptions, (dict(self),))

    def __hash__(self) -> int:  # type: ignore[override]
        return hash(tuple(sorted((k, repr(v)) for k, v in self.items())))


def _frozen(mapping: Mapping[str, Any] | None) -> Mapping[str, Any]:
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
        from casep.noise.model import check_noise_kind, check_tau

        set_ = object.__setattr__  # frozen: the normal form is set once, here
        check_noise_kind(self.kind)
        if self.robust is not None and self.robust not in ROBUST_CHOICES:
            raise ValueError(f"`robust` must be one of {', '.join(ROBUST_CHOICES)} or None, got {self.robust!r}")
        if self.robust == "none":
            set_(self, "robust", None)
        if self.std not in STD_CHOICES:
            raise ValueError(f"`std` must be one of {', '.join(STD_CHOICES)}, got {self.std!r}")
        check_chance("exclude_outliers", self.exclude_outliers)
        if self.denoise is not None and self.denoise not in DENOISE_CHOICES:
            raise ValueError(f"`denoise` must be 'none' or 'wavelet', got {self.denoise!r}")
        if self.denoise == "none":
            set_(self, "denoise", None)
        set_(self, "wavelet_options", _frozen(self.wavelet_options))
        if self.wavelet_options and self.denoise != "wavelet":
            raise ValueError("`wavelet_options` given without `denoise='wavelet'`")
        if isinstance(self.tau, str) and self.tau == "auto":
            set_(self, "tau", None)  # REML: as when not given
        check_tau(self.tau)  # the noise model's own rule for a correlation time, checked here, at the edge
        if isinstance(self.tau, (list, np.ndarray)):
            set_(self, "tau", tuple(float(v) for v in np.ravel(self.tau)))  # a value: hashable, unchanged
        if self.tau is not None:
            if self.kind == "white":
                raise ValueError("`tau` given with noise 'white': a correlation time means noise 'gm'")
            set_(self, "kind", "gmw" if self.kind == "gmw" else "gm")  # gmw: the white part still by REML
        if self.denoise == "wavelet":
            if self.kind in ("gm", "gmw") or self.robust not in (None, "auto") or self.exclude_outliers is not None \
                    or self.std != "model":
                raise ValueError("`denoise='wavelet'` removes the noise a noise model, a robust fit or HAC std "
                                 "describe: use them without de-noising")
            set_(self, "kind", "white")  # the de-noised residuals are no noise sample to fit a model on
            set_(self, "robust", None)


@dataclass(frozen=True)
class FitSpec:
    """One fit request: method, its options, sigma, noise (module notes). Checked when made.

    Build it from keywords with :meth:`build` (as :func:`casep.separate` does), or directly
    (``FitSpec("ridge", {"lam": 0.1}, noise=NoiseSpec("gm"))``); pass it as
    ``casep.separate(flight, spec=...)`` or to :func:`casep.workflows.solve.fit`.

    Attributes
    ----------
    method : str
        A registered method (:data:`casep.estimators.registry.METHODS`).
    options : mapping
        The method's options the caller gave (others take their defaults), checked by the
        registry's rules; ``bounds``/``prior`` as tables or their JSON files.
    sigma : float or None
        Known noise std, m/s (None: estimated). With radar: a mapping ``{(station, type): std}``.
    noise : NoiseSpec
    outliers : float or None
        Flag rows by their studentized residual at this family-wise false-alarm chance.
    keywords : mapping
        Solver keywords of the method that are not options (PCR's ``max_condition_index``).
    """

    method: str = "ols"
    options: Mapping[str, Any] = field(default_factory=dict)
    sigma: Any = None
    noise: NoiseSpec = field(default_factory=NoiseSpec)
    outliers: float | None = None
    keywords: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        from casep.estimators.registry import METHODS, SIGMA, check_method_options

        set_ = object.__setattr__
        if self.method not in METHODS:
            raise ValueError(f"`method` must be one of {', '.join(METHODS)}, got {self.method!r}")
        if not isinstance(self.noise, NoiseSpec):
            raise TypeError(f"`noise` must be a NoiseSpec, got {type(self.noise).__name__}")
        meth = METHODS[self.method]
        opts = {k: v for k, v in dict(self.options).items() if v is not None and v is not NOT_GIVEN}
        noise = self.noise
        if "tau" in opts and "tau" not in meth.options:  # not the method's own: the noise model's
            if noise.tau is not None:
                raise ValueError("option `tau` given both as the method's option and the noise model's")
            noise = dataclasses.replace(noise, tau=opts.pop("tau"))
        elif "tau" in meth.options and noise.tau is not None:  # the method's own (gls: one tau)
            if "tau" in opts:
                raise ValueError("option `tau` given both as the method's option and the noise model's")
            opts["tau"] = noise.tau
            noise = dataclasses.replace(noise, tau=None)
        check_method_options(self.method, opts)  # the registry's rules: the one check of the options
        keywords = {k: v for k, v in dict(self.keywords).items() if v is not None and v is not NOT_GIVEN}
        for k, v in keywords.items():
            if k not in {o.name for o in meth.keywords}:
                takers = [n for n, m in METHODS.items() if k in {o.name for o in m.keywords}]
                raise ValueError(f"`{k}` is not taken by method `{self.method}`; it is a keyword of "
                                 f"{', '.join(takers) or 'no method'}. Use: method={takers[0] if takers else '...'!r}, "
                                 "or leave it out")
            keywords[k] = meth.option(k).check(v)
        if self.sigma is not None and not isinstance(self.sigma, Mapping):
            set_(self, "sigma", SIGMA.check(self.sigma))
        check_chance("outliers", self.outliers)
        _check_noise_for(meth, noise)
        set_(self, "options", _frozen(opts))
        set_(self, "keywords", _frozen(keywords))
        set_(self, "noise", noise)

    @classmethod
    def build(cls, method: str = "ols", *, options: Mapping[str, Any] | None = None, sigma: Any = None,
              noise: str = "auto", tau: Any = None, robust: str | None = "auto", std: str = "model",
              exclude_outliers: float | None = None, denoise: str | None = None,
              wavelet_options: Mapping[str, Any] | None = None, outliers: float | None = None,
              **option_keywords: Any) -> FitSpec:
        """A spec from keywords: :func:`casep.separate`'s, the command line's, a manifest's.

        `option_keywords` are method options given as keywords (``lam=0.1``, or solver keywords
        such as ``max_condition_index``); :data:`NOT_GIVEN` ones are left out. An option given
        both as a keyword and in `options` is an error, whatever its values.

        ``tau="auto"`` (or None) is REML; a number is the noise model's correlation time (the
        method's own option for a method that takes ``tau``).
        """
        from casep.estimators.registry import METHODS, OPTIONS

        all_opts = merge_options(options, option_keywords)
        meth = METHODS.get(method)
        kw_names = {o.name for m in METHODS.values() for o in m.keywords} - set(OPTIONS)
        keywords = {k: all_opts.pop(k) for k in list(all_opts) if k in kw_names}
        for k in all_opts:
            if k not in OPTIONS:
                raise ValueError(f"unknown option `{k}`: no registered method takes it; the options are "
                                 f"{', '.join(OPTIONS)}")
        if isinstance(tau, str) and tau == "auto":
            tau = None
        if tau is not None and meth is not None and "tau" in meth.options:
            if "tau" in all_opts:
                raise ValueError("option `tau` given both as a keyword and in `options`")
            all_opts["tau"], tau = tau, None
        if isinstance(all_opts.get("tau"), str) and all_opts["tau"] == "auto" and (meth is None or
                                                                                    "tau" not in meth.options):
            all_opts.pop("tau")  # "auto" for the noise model: REML, as when not given
        ns = NoiseSpec(noise, tau, robust, std, exclude_outliers, denoise, dict(wavelet_options or {}))
        return cls(method, all_opts, sigma, ns, outliers, keywords)

    def to_dict(self) -> dict[str, Any]:
        """The request as plain data (options as given; files by name)."""
        return {"method": self.method, "options": dict(self.options), "sigma": self.sigma,
                "noise": {**dataclasses.asdict(self.noise), "wavelet_options": dict(self.noise.wavelet_options)},
                "outliers": self.outliers, "keywords": dict(self.keywords)}


def merge_options(options: Mapping[str, Any] | None, keywords: Mapping[str, Any]) -> dict[str, Any]:
    """The method options given in `options` and as keywords (:data:`NOT_GIVEN` ones left out), as one mapping.

    An option in both is an error whatever the values (a value equal to the default is given too).
    """
    given = {k: v for k, v in keywords.items() if v is not NOT_GIVEN}
    both = sorted(set(options or {}) & set(given))
    if both:
        raise ValueError(f"option(s) {', '.join(f'`{k}`' for k in both)} given both as a keyword and in `options`")
    return {**dict(options or {}), **given}


def check_chance(name: str, value: Any) -> None:
    """A family-wise false-alarm chance of the outlier flags (`outliers`, `exclude_outliers`): None or in (0, 1)."""
    if value is None:
        return
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not 0.0 < float(value) < 1.0:
        raise ValueError(f"`{name}` must be a false-alarm chance in (0, 1) (e.g. 0.01), got {value!r}")


#: Methods robust by themselves: a robust filter in front of one is refused (the glitches weighed twice).
ROBUST_BY_THEMSELVES = ("huber",)


def check_robust_method(method: str, robust: str | None) -> None:
    """Refuse a robust fit (`robust` huber or bisquare) in front of a method that is robust by itself."""
    if method in ROBUST_BY_THEMSELVES and robust not in (None, "auto", "none"):
        raise ValueError(f"`robust={robust!r}` with method `{method}`: Huber's M-estimator is robust already (it "
                         "down-weights large residuals itself; a robust filter in front of it would weigh the glitches "
                         f"twice). Use: robust 'none' or 'auto' with method `{method}`, or another method with robust "
                         f"{robust!r}")


def _check_noise_for(meth: Any, noise: NoiseSpec) -> None:
    """What a method and the noise request must agree on (HAC std, a method with its own noise model, a method
    robust by itself)."""
    from casep.estimators.registry import METHODS

    check_robust_method(meth.name, noise.robust)

    if meth.own_noise_model is not None:
        if noise.kind == "white":
            raise ValueError(f"method `{meth.name}` assumes Gauss-Markov noise: noise 'white' contradicts it "
                             "(use method ols)")
        if noise.std != "model":
            raise ValueError(f"method `{meth.name}` takes no `std`: HAC std are for white-noise least squares "
                             "(method ols)")
    elif noise.std == "hac" and (noise.kind != "white" or not meth.hac):
        hac = ", ".join(k for k, m in METHODS.items() if m.hac)
        raise ValueError(f"`std='hac'` is the Newey-West std of a white-noise least-squares fit: use it with "
                         f"method {hac} and noise 'white' (in coloured noise, noise 'auto' or 'gm' gives honest std)")
