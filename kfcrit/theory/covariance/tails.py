"""The power-law tail exponent of the error covariance (a labelled claim from the literature).

For non-degenerate systems with i.i.d. (Bernoulli) losses, Mo & Sinopoli (2012) show that the
stationary error has a power-law tail, P(tr P_∞ > M) ≈ M^{−β}, with

.. math::

    \\beta = \\frac{\\log(1-p)}{-2\\log|\\lambda_1|}
          = \\frac{\\log\\frac{1}{1-p}}{\\log|\\lambda_1|^2},

so E[tr P] < ∞ iff β > 1 (p > 1 − 1/|λ_1|², the critical value again) and the variance is
finite iff β > 2 ((1 − p)|λ_1|⁴ < 1). kfcrit reports β as a claim with its source (docs/theory.md
§11), to be checked by the log–log slope of a simulation, never as a proof.
"""
from __future__ import annotations

from typing import Any

import sympy as sp

from kfcrit.model.system import System
from kfcrit.records.covariance import TailExponentRecord
from kfcrit.theory.critical.compare import compare_probability
from kfcrit.theory.links.markov import Rho2, exact_rate, spectral_radius2

SOURCE = ("Mo & Sinopoli, 'Kalman filtering with intermittent observations: tail distribution "
          "and critical value', IEEE Transactions on Automatic Control 57(3), 2012")
LABEL = "claim (literature, not proven here)"
FORMULA = "beta = log(1 - p) / (-2 log|lambda_1|)"


def _exponent(value: float | None, expression: str | None, applicable: bool,
              finite_mean: bool | None, finite_variance: bool | None,
              statement: str) -> TailExponentRecord:
    """β with its exact expression, or why it does not apply, labelled as a claim with its
    source."""
    return TailExponentRecord(value=value, expression=expression, applicable=applicable,
                              finite_mean=finite_mean, finite_variance=finite_variance,
                              statement=statement, label=LABEL, source=SOURCE, formula=FORMULA)


def tail_exponent(system: System, p: Any, classification: str | None = None,
                  structure: Any | None = None) -> TailExponentRecord:
    """β = log(1 − p)/(−2 log|λ_1|) for a non-degenerate system at arrival probability p.

    Parameters
    ----------
    system : System
    p : number
        Arrival probability (floats by their decimal form, as :func:`markov.exact_rate`).
    classification : str, optional
        From :mod:`kfcrit.theory.critical.section`; the formula is stated for "non-degenerate" systems
        only, every other class gets ``applicable`` False with the reason.
    structure : optional
        The eigen-structure (exact |λ_1|² on its exact path).
    """
    pe = exact_rate(p, "arrival_probability")
    if classification is not None and classification != "non-degenerate":
        return _exponent(None, None, False, None, None,
                         f"the tail exponent formula is stated for non-degenerate systems; "
                         f"this system is {classification}")
    rho = spectral_radius2(system, structure)
    at_most_one = (rho.hi <= 1 if rho.exact is None
                   else sp.sympify(rho.exact - 1).is_nonpositive)
    if at_most_one:
        return _exponent(None, "oo", True, True, True,
                         "rho(A) <= 1: no power-law tail from unstable modes")
    if rho.exact is None and rho.lo <= 1 or at_most_one is None:
        return _exponent(None, None, False, None, None,
                         "rho(A) is not separated from 1 by its enclosure: the tail exponent "
                         "log(1 - p) / (-2 log rho(A)) is not determined")
    if pe == 1:
        return _exponent(None, "oo", True, True, True, "p = 1: no losses, no tail")
    if rho.exact is not None:
        expr = sp.log(1 / (1 - pe)) / sp.log(rho.exact)
        value = float(sp.N(expr, 30))
        text = sp.sstr(expr)
    else:
        mid = (rho.lo + rho.hi) / 2
        value = float(sp.N(sp.log(1 / (1 - pe)) / sp.log(sp.Rational(mid.numerator,
                                                                        mid.denominator)), 30))
        text = None
    return _exponent(value, text, True, _beta_exceeds(pe, rho, 1, value),
                     _beta_exceeds(pe, rho, 2, value),
                     f"P(tr P > M) ~ M^(-{value:.6g}) for large M (non-degenerate system, "
                     "i.i.d. losses); E[tr P] finite iff beta > 1, variance iff beta > 2")


def _beta_exceeds(p: sp.Expr, rho: Rho2, k: int, value: float) -> bool:
    r"""β > k, decided exactly where ρ(A)² is exact (the package's one exact comparison),
    rigorously from the enclosure of ρ(A)² otherwise, and from the float β only when the
    enclosure straddles the boundary.

    .. math::  \beta > k \iff \frac{1}{1-p} > \rho(A)^{2k} \iff p > 1 - \rho(A)^{-2k}
    """
    if rho.exact is not None:
        try:
            return compare_probability(p, 1 - 1 / rho.exact ** k) > 0
        except ArithmeticError:
            return value > k
    pf = sp.Rational(p)
    if pf > 1 - 1 / sp.Rational(rho.hi) ** k:
        return True
    if pf <= 1 - 1 / sp.Rational(rho.lo) ** k:
        return False
    return value > k
