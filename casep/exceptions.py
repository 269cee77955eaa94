"""casep's warning classes (errors are ValueError/TypeError subclasses next to their modules)."""

from __future__ import annotations

__all__ = ["CasepWarning", "IllConditionedWarning"]


class CasepWarning(UserWarning):
    """Legal but harmful input or settings (e.g. a wavelet level past the boundary limit)."""


class IllConditionedWarning(CasepWarning):
    """The regression is ill-conditioned: the message gives the number and the coefficients."""
