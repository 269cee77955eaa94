"""Two tail probabilities on the command line's path, in the standard library (``math``), and the normal
distribution's ratio of the standard deviation to the median absolute deviation.

``scipy.special`` would give them, at the price of its import (0.1-0.6 s of CPU, with the array-API layer
it brings when it is the first SciPy module loaded): ``casep separate`` needs only these two numbers.
Both agree with SciPy (``ndtr``, ``chdtrc``) to a few units in the last place
(``tests/test_special.py``).
"""

from __future__ import annotations

import math

__all__ = ["normal_sf", "chi2_sf", "MAD_SIGMA"]

#: ``sigma = MAD_SIGMA * MAD`` for Gaussian data: ``1 / Phi^-1(3/4)``.
MAD_SIGMA = 1.482602218505602


def normal_sf(x: float) -> float:
    """``P(Z > x)`` of a standard normal ``Z``: ``erfc(x / sqrt 2) / 2``."""
    return 0.5 * math.erfc(x / math.sqrt(2.0))


def chi2_sf(k: int, x: float) -> float:
    """``P(X > x)`` of a chi-square ``X`` with `k` (a positive integer) degrees of freedom.

    The regularised upper incomplete gamma ``Q(k/2, x/2)`` in its finite closed form (``h = x / 2``)::

        k even:  Q = sum_(i < k/2) exp(-h) h^i / i!
        k odd:   Q = erfc(sqrt h) + sum_(i < (k-1)/2) exp(-h) h^(i + 1/2) / Gamma(i + 3/2)

    each term formed as ``exp(-h + i ln h - ln Gamma(i + 1))`` (no overflow of ``h^i``, no underflow of
    ``exp(-h)`` alone before the powers lift it): every term positive, no cancellation.
    """
    if isinstance(k, bool) or not isinstance(k, int) or k < 1:
        raise ValueError(f"`k` must be a positive int (degrees of freedom), got {k!r}")
    if math.isnan(x):
        return math.nan
    if x <= 0.0:
        return 1.0
    if math.isinf(x):
        return 0.0
    h = 0.5 * x
    log_h = math.log(h)
    if k % 2 == 0:
        terms = [math.exp(-h + i * log_h - math.lgamma(i + 1.0)) for i in range(k // 2)]
    else:
        terms = [math.erfc(math.sqrt(h))] + [math.exp(-h + (i + 0.5) * log_h - math.lgamma(i + 1.5))
                                             for i in range((k - 1) // 2)]
    return min(1.0, math.fsum(terms))  # the terms' rounding can pass 1 by an ulp where Q is 1
