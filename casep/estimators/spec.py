"""What a user asks of a fit, as one checked value: :class:`FitSpec` and its :class:`NoiseSpec`.

A request is built once, where it enters casep (the keywords of :func:`casep.separate`, the
arguments of ``casep separate``, a manifest), and checked there by one validator
(:meth:`FitSpec.__post_init__`): the method and its options (by the registry's rules,
:func:`casep.estimators.registry.check_method_options`), sigma, the noise kind
(:class:`casep.noise.spec.NoiseSpec`), the robust fit, the std kind, the outlier
exclusion and the de-noising. Everything downstream (:func:`casep.estimators.solve.fit`) takes
the spec as checked.

Who owns ``tau`` is decided here, by one rule (:func:`_tau_owner`, when the spec is made): a method
that takes ``tau`` as its own option (GLS: one correlation time for every axis) gets it in
:attr:`FitSpec.options`; for every other method it is the noise model's (:attr:`NoiseSpec.tau`, a
number meaning Gauss-Markov noise), wherever the caller put it.

Options the caller did not give are :data:`NOT_GIVEN` (a sentinel), never recognised by being
equal to their default: ``separate(..., p0=1e6, options={"p0": 1.0})`` is "given both", whatever
the values.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any, Mapping

from casep.exceptions import option_label, refusal
from casep.noise.spec import (  # the noise part of the request (below the estimators: the rows take it)
    DENOISE_CHOICES,
    ROBUST_CHOICES,
    STD_CHOICES,
    NoiseSpec,
    check_chance,
    frozen_options,
)

__all__ = ["FitSpec", "NoiseSpec", "NOT_GIVEN", "NotGiven", "merge_options", "check_robust_method", "check_chance",
           "ROBUST_BY_THEMSELVES", "ROBUST_CHOICES", "STD_CHOICES", "DENOISE_CHOICES"]


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


@dataclass(frozen=True)
class FitSpec:
    """One fit request: method, its options, sigma, noise (module notes). Checked when made.

    Build it from keywords with :meth:`build` (as :func:`casep.separate` does), or directly
    (``FitSpec("ridge", {"lam": 0.1}, noise=NoiseSpec("gm"))``); pass it as
    ``casep.separate(flight, spec=...)`` or to :func:`casep.estimators.solve.fit`.

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
            raise refusal("method", None, " | ".join(METHODS), self.method)
        if not isinstance(self.noise, NoiseSpec):
            raise TypeError(f"{option_label('noise')} of a FitSpec must be a NoiseSpec, "
                            f"got {type(self.noise).__name__}")
        meth = METHODS[self.method]
        opts = {k: v for k, v in dict(self.options).items() if v is not None and v is not NOT_GIVEN}
        noise = self.noise
        opts, noise = _tau_owner(meth, opts, noise)
        check_method_options(self.method, opts)  # the registry's rules: the one check of the options
        keywords = {k: v for k, v in dict(self.keywords).items() if v is not None and v is not NOT_GIVEN}
        for k, v in keywords.items():
            if k not in {o.name for o in meth.keywords}:
                takers = [n for n, m in METHODS.items() if k in {o.name for o in m.keywords}]
                label = METHODS[takers[0]].option(k).label if takers else option_label(k)
                raise ValueError(f"{label} is not taken by method `{self.method}`; it is a keyword of "
                                 f"{', '.join(takers) or 'no method'}. Use: method={takers[0] if takers else '...'!r}, "
                                 "or leave it out")
            keywords[k] = meth.option(k).check(v)
        if self.sigma is not None and not isinstance(self.sigma, Mapping):
            set_(self, "sigma", SIGMA.check(self.sigma))
        check_chance("outliers", self.outliers)
        _check_noise_for(meth, noise)
        set_(self, "options", frozen_options(opts))
        set_(self, "keywords", frozen_options(keywords))
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

        ``tau="auto"`` (or None) is REML; a number is a correlation time, the noise model's or the
        method's own (who owns it: :func:`_tau_owner`, applied when the spec is made).
        """
        from casep.estimators.registry import METHODS, OPTIONS

        all_opts = merge_options(options, option_keywords)
        kw_names = {o.name for m in METHODS.values() for o in m.keywords} - set(OPTIONS)
        keywords = {k: all_opts.pop(k) for k in list(all_opts) if k in kw_names}
        for k in all_opts:
            if k not in OPTIONS:
                raise ValueError(f"unknown {option_label(k)}: no registered method takes it; the options are "
                                 f"{', '.join(OPTIONS)}")
        ns = NoiseSpec(noise, tau, robust, std, exclude_outliers, denoise, dict(wavelet_options or {}))
        return cls(method, all_opts, sigma, ns, outliers, keywords)

    @property
    def tau_given(self) -> tuple[float, float, float] | None:
        """The correlation time per axis the request states, s (the noise model's or the method's own: who owns it,
        :func:`_tau_owner`), None when it leaves tau to REML (:func:`casep.noise.model.check_tau`)."""
        from casep.noise.model import check_tau

        return check_tau(self.noise.tau if self.noise.tau is not None else self.options.get("tau"))

    def about(self, names: Any, at: Any) -> FitSpec:
        """The request for the correction ``x = D - at`` of a fit linearised at `at` (natural units, one value per name
        of `names`: an iteration's pass solves for the step from where the passes stand): a prior's means and the
        bounds moved by ``-at`` (:func:`casep.estimators.map.shift_prior`,
        :func:`casep.estimators.bounded.shift_bounds`; std, correlations and open sides kept), so that the prior and
        the box stay on the coefficients ``D`` and not on the step. The spec itself when it has neither as a table,
        or `at` is 0."""
        from casep.estimators.bounded import shift_bounds
        from casep.estimators.map import shift_prior

        shift = {str(n): float(v) for n, v in zip(names, at) if math.isfinite(v) and v != 0.0}
        tables = {k: f(self.options[k], shift) for k, f in (("prior", shift_prior), ("bounds", shift_bounds))
                  if isinstance(self.options.get(k), Mapping)}
        if not shift or not tables:
            return self
        return dataclasses.replace(self, options={**self.options, **tables})

    def to_dict(self) -> dict[str, Any]:
        """The request as plain data (options as given; files by name)."""
        return {"method": self.method, "options": dict(self.options), "sigma": self.sigma,
                "noise": {**dataclasses.asdict(self.noise), "wavelet_options": dict(self.noise.wavelet_options)},
                "outliers": self.outliers, "keywords": dict(self.keywords)}


def _tau_owner(meth: Any, opts: dict[str, Any], noise: NoiseSpec) -> tuple[dict[str, Any], NoiseSpec]:
    """Who owns ``tau``, the one rule: a method that declares ``tau`` among its options (GLS: one correlation
    time for every axis) owns it, checked by its rule; for every other method it is the noise model's
    (:attr:`NoiseSpec.tau`: three values allowed, "auto" meaning REML). Given both ways: an error, whatever
    the values. Returns the method options and the noise request with tau where it belongs."""
    in_opts = opts.pop("tau", None)
    if in_opts is not None and noise.tau is not None:
        raise ValueError(f"{option_label('tau')} given both as the method's option and the noise model's")
    if "tau" in meth.options:
        tau = noise.tau if in_opts is None else in_opts
        if tau is not None:
            opts["tau"] = tau
        return opts, noise if noise.tau is None else dataclasses.replace(noise, tau=None)
    return opts, noise if in_opts is None else dataclasses.replace(noise, tau=in_opts)


def merge_options(options: Mapping[str, Any] | None, keywords: Mapping[str, Any]) -> dict[str, Any]:
    """The method options given in `options` and as keywords (:data:`NOT_GIVEN` ones left out), as one mapping.

    An option in both is an error whatever the values (a value equal to the default is given too).
    """
    given = {k: v for k, v in keywords.items() if v is not NOT_GIVEN}
    both = sorted(set(options or {}) & set(given))
    if both:
        raise ValueError(f"{', '.join(option_label(k) for k in both)} given both as a keyword and in `options`")
    return {**dict(options or {}), **given}


#: Methods robust by themselves: a robust filter in front of one is refused (the glitches weighed twice).
ROBUST_BY_THEMSELVES = ("huber",)


def check_robust_method(method: str, robust: str | None) -> None:
    """Refuse a robust fit (`robust` huber or bisquare) in front of a method that is robust by itself."""
    if method in ROBUST_BY_THEMSELVES and robust not in (None, "auto", "none"):
        raise ValueError(f"{option_label('robust')} {robust!r} with method `{method}`: Huber's M-estimator is "
                         "robust already (it down-weights large residuals itself; a robust filter in front of it "
                         "would weigh the glitches "
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
            raise ValueError(f"method `{meth.name}` takes no {option_label('std')}: HAC std are for white-noise "
                             "least squares (method ols)")
    elif noise.std == "hac" and (noise.kind != "white" or not meth.hac):
        hac = ", ".join(k for k, m in METHODS.items() if m.hac)
        raise ValueError(f"{option_label('std')} 'hac' is the Newey-West std of a white-noise least-squares fit: "
                         f"use it with method {hac} and noise 'white' (in coloured noise, noise 'auto' or 'gm' gives "
                         "honest std)")
