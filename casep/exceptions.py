"""casep's warning classes (errors are ValueError/TypeError subclasses next to their modules), and the one
message form of a refused option (:func:`refusal`)."""

from __future__ import annotations

from typing import Any

__all__ = ["CasepWarning", "IllConditionedWarning", "PlausibilityWarning", "NoiseFreeWarning",
           "OutlierWarning", "TimeOffsetWarning", "SetupWarning", "MagnitudeWarning", "NoiseLevelWarning",
           "GapWarning", "NoiseNotWhiteWarning", "ConsistencyWarning", "AlignmentWarning", "SaturationWarning",
           "TrackingQualityWarning", "NonlinearityWarning", "UndecidedNoiseWarning",
           "option_label", "refusal", "refused_option"]


class CasepWarning(UserWarning):
    """Legal but harmful input or settings (e.g. a wavelet level past the boundary limit)."""


class IllConditionedWarning(CasepWarning):
    """The regression is ill-conditioned: the message gives the number and the coefficients."""


class PlausibilityWarning(CasepWarning):
    """A flight outside the range of boost flights in SI units (likely a unit mistake): the
    message gives the figure, the plausible range and the unit that would explain it."""


class NoiseFreeWarning(CasepWarning):
    """The residuals are at the rounding level of dv: the reported std reflect rounding only."""


class OutlierWarning(CasepWarning):
    """Isolated values far outside the noise (dv, or single IMU samples): the message names the rows and their
    size."""


class TimeOffsetWarning(CasepWarning):
    """The residuals track the kinematic acceleration (or its derivative): a tracking time offset."""


class SaturationWarning(CasepWarning):
    """A sensor reads its full scale for several samples in a row: it clipped (where, how long, the value)."""


class TrackingQualityWarning(CasepWarning):
    """Tracking epochs that cannot be right (repeated fixes while the vehicle moved, velocity jumps the IMU
    rules out, a drifting clock): what was left out or found, with the times and the numbers."""


class SetupWarning(PlausibilityWarning):
    """Telemetry and tracking disagree with the stated set-up (launch site, azimuth, launch time, time
    scales): the message gives the numbers (pad velocity, first tracked position, time spans)."""


class MagnitudeWarning(CasepWarning):
    """Estimates far beyond the model's declared magnitudes: the message names them and the ratio."""


class NoiseLevelWarning(CasepWarning):
    """A given noise sigma, correlation time (or a prior) that the residuals contradict: the message gives the
    ratio or the interval, and the test."""


class GapWarning(CasepWarning):
    """A gap in tracking (or telemetry) that interpolation would bridge: the rows inside it are left out."""


class BiasedStdWarning(CasepWarning):
    """A regularised estimate used as an input: its std leave out the bias of its regularisation."""


class NonlinearityWarning(CasepWarning):
    """An iterated separation whose pipeline is curved at one std of its own estimate: the message gives by how
    many std the second-order terms move the estimate, that the covariance gains their mean square, and, when the
    second order outgrows the first, that the std are not reliable."""


class NoiseNotWhiteWarning(CasepWarning):
    """A white-noise fit whose residuals are correlated: the message gives the test, its numbers
    and the factor by which the reported std are too small."""


class UndecidedNoiseWarning(CasepWarning):
    """The automatic noise choice on rows too few to tell the noise kinds apart (a short window): the
    message gives the samples, the span, the axes and the margins; the conservative kind is taken."""


class ConsistencyWarning(CasepWarning):
    """Results (or flights) combined into one estimate disagree beyond their std: the message gives
    the chi-square, its degrees of freedom, the p-value and the coefficients that disagree most."""


class AlignmentWarning(CasepWarning):
    """A pad alignment to read with care: a heading found by gyrocompassing (the message says how well
    it is known) or a vehicle that moved during the alignment window."""


def option_label(name: str, flag: str | None = None) -> str:
    """How every message of a fit request names an option, by its command-line flag and API keyword:
    ``option --lambda (`lam`)`` (`flag` defaults to ``--`` and the keyword with ``-`` for ``_``)."""
    return f"option {flag or '--' + name.replace('_', '-')} (`{name}`)"


def refused_option(message: str) -> str:
    """An argparse error in the one form of a refused option: ``argument --sigma: option --sigma (`sigma`) ...``
    -> the option's own text; a type's ``argument --rate: must be ...`` -> ``option --rate (`rate`) must be ...``."""
    import re

    rest = message.partition(": ")[2]
    if rest.startswith("option --"):
        return rest
    own = re.match(r"argument (--[\w-]+)(?:/-\w+)?: (must .*)", message, re.S)
    return f"{option_label(own.group(1)[2:].replace('-', '_'), own.group(1))} {own.group(2)}" if own else message


def refusal(name: str, flag: str | None, rule: str, value: Any, method: str | None = None,
            part: str | None = None) -> ValueError:
    """The one message form of a refused option value, in the API and on the command line:
    ``option --lambda (`lam`) of method `ridge` must be gcv | lcurve | float > 0, got 'aic'``; `part` names the
    part of a value of several parts that is refused (``option --tau (`tau`) for axis y must be ..., got -2.0``)."""
    of = f" of method `{method}`" if method else ""
    at = f" for {part}" if part else ""
    return ValueError(f"{option_label(name, flag)}{of}{at} must be {rule}, got {value!r}")
