"""The two thresholds of a TCP-like closed loop: ν_c (actuation link) and γ_c (sensing link).

theory §12: with acknowledgements, separation holds. The estimator sees the RRE of §1, so its
threshold is the estimation critical value γ_c of (A, C) (:mod:`kfcrit.theory.critical.section`). The
controller's value function follows the *control MARE*

.. math::

    S = A' S A + W - \\bar\\nu\\, A' S B (B' S B + U)^{-1} B' S A,

which is the estimation MARE g_p of §2 for the dual data (A, C, Q, R) := (A', B', W, U) with
p = ν̄ (checked symbolically in ``proofs_checks/check_loop_duality.py``). Its solvability
threshold is therefore the p_up of §3 of the dual pair:

.. math::

    \\nu_c = p_{up}(A', B') \\in \\bigl[1 - 1/\\rho(A)^2,\\ 1 - 1/\\textstyle\\prod |\\lambda_u|^2\\bigr].

Closed forms: scalar ν_c = max(1 − 1/a², 0); B square invertible ν_c = max(1 − 1/ρ(A)², 0)
(the dual of "C invertible", a theorem); one input column ν_c = 1 − 1/Π|λ_u|² (the dual of
the single-output identity, a **claim** of theory §3 [beyond], reported next to the certified
interval). Otherwise the certified interval of :func:`kfcrit.theory.upper.bracket.upper_bound`.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import sympy as sp

from kfcrit.model.system import System, to_matrix
from kfcrit.theory.critical.plow import c_invertible, p_low_bounds
from kfcrit.theory.critical.section import critical_value
from kfcrit.theory.structure.eigen import structure_of
from kfcrit.theory.upper import certify
from kfcrit.theory.upper.bracket import upper_bound

__all__ = ["LoopThresholdFact", "actuation_threshold", "dual_system", "sensing_threshold"]


@dataclass(frozen=True)
class LoopThresholdFact:
    """A critical probability as a fact: its value where known, and an enclosing interval.

    Attributes
    ----------
    name : str
        ``"nu_c"`` (actuation link) or ``"gamma_c"`` (sensing link).
    value : float or None
        The value (float of ``expression`` when exact; None when only bracketed or when no
        threshold exists, e.g. an unstabilisable or undetectable unstable mode).
    interval : tuple of float or None
        ``(lo, hi)`` with lo ≤ threshold ≤ hi (directed roundings of an exact value, or a
        certified bracket); None when no threshold exists.
    exact : bool
        ``expression`` is the exact value (as a theorem or as a claim, see ``basis``).
    expression : str or None
        Exact value as sympy text (``sp.sstr``).
    basis : str
        ``"theorem"``, ``"claim"`` (a MATH [beyond] identity, checked against ``interval``),
        ``"certified-interval"``, ``"numerical"`` or ``"none"`` (no threshold).
    certified : bool
        ``interval`` is proven (both ends rigorous).
    reason : str
        Which result decided it.
    """

    name: str
    value: float | None
    interval: tuple[float, float] | None
    exact: bool
    expression: str | None
    basis: str
    certified: bool
    reason: str

    def contains(self, p: float) -> bool | None:
        """Whether ``p`` is inside ``interval`` (None when there is no interval)."""
        if self.interval is None:
            return None
        return self.interval[0] <= p <= self.interval[1]

    def below(self, p: float) -> bool | None:
        """True when threshold < p is proven by the interval, False when threshold ≥ p is,
        None when p lies inside the interval (undecided) or no threshold exists."""
        if self.interval is None:
            return None
        if p > self.interval[1]:
            return True
        if p <= self.interval[0]:
            return False
        return None


def dual_system(A: Any, B: Any, W: Any = None, U: Any = None) -> System:
    """The dual estimation problem of the control MARE: System(A', B', W, U) with exact entries.

    .. math::

        (A, C, Q, R) := (A', B', W, U), \\qquad p := \\bar\\nu .

    ``W`` and ``U`` default to identities (ν_c does not depend on them; Q, R do not enter p_up).
    """
    A_, _ = to_matrix(A, "A")
    B_, _ = to_matrix(B, "B")
    n, mu = A_.shape[0], B_.shape[1]
    if B_.shape[0] != n:
        raise ValueError(f"B must have {n} rows, got {B_.shape[0]}")
    W = sp.eye(n) if W is None else W
    U = sp.eye(mu) if U is None else U
    return System(A_.T, B_.T, W, U, name="control dual (A', B', W, U)")


def _num_of(expr: sp.Expr) -> tuple[float, tuple[float, float]]:
    down, up = certify.round_expr(expr)
    return float(sp.N(expr, 30)), (down, up)


def _scalar(dual: System) -> LoopThresholdFact:
    a, b = dual.A[0, 0], dual.C[0, 0]
    mod2 = sp.nsimplify(a * a)
    if b == 0 and mod2 > 1:
        return LoopThresholdFact("nu_c", None, None, False, None, "none", True,
                         "scalar, b = 0 and |a| > 1: not stabilisable, no finite threshold")
    expr = sp.Integer(0) if mod2 <= 1 else sp.radsimp(1 - 1 / mod2)
    value, interval = _num_of(expr)
    return LoopThresholdFact("nu_c", value, interval, True, sp.sstr(expr), "theorem", True,
                     "scalar: ν_c = max(1 − 1/a², 0) (the dual of Sinopoli's scalar p_c)")


def _single_column_claim(dual: System) -> sp.Expr | None:
    """1 − 1/Π_{|λ|>1} |λ|² from the exact eigen-structure of A (None off the exact path)."""
    st = structure_of(dual)
    if st.path != "exact":
        return None
    unstable = [e for e in st.eigen if e.unit_cmp is not None and e.unit_cmp > 0]
    if not all(e.mod2_expr is not None for e in unstable):
        return None
    prod = sp.Integer(1)
    for e in unstable:
        prod = prod * e.mod2_expr ** e.multiplicity
    return sp.radsimp(sp.expand(1 - 1 / prod)) if unstable else sp.Integer(0)


def _from_upper(dual: System, tol: float) -> tuple[tuple[float, float], bool, str, Any]:
    ub = upper_bound(dual, tol=tol)
    if ub.extras.get("not_applicable"):
        return None, False, str(ub.extras["not_applicable"]), ub
    lo, hi = ub.interval
    certified = bool(ub.certified and ub.lower_evidence.certified)
    return (float(lo), float(hi)), certified, f"p_up of the dual pair (A', B'): {ub.method}, " \
        f"status {ub.status}", ub


def actuation_threshold(A: Any, B: Any, W: Any = None, U: Any = None,
                        tol: float = 1e-9) -> LoopThresholdFact:
    """ν_c: the actuation-link threshold of the TCP-like loop (MARE solvability of (A', B')).

    .. math::

        \\nu_c = \\inf\\{\\bar\\nu : S = A'SA + W - \\bar\\nu A'SB(B'SB+U)^{-1}B'SA
        \\text{ has a solution } S \\succeq 0\\} = p_{up}(A', B')

    Parameters
    ----------
    A, B : array_like
        Plant matrices (n × n, n × m_u); exact input (integers, fractions, strings, sympy)
        stays exact, binary floats are taken as the rationals they are.
    W, U : array_like, optional
        State and input weights (default identities; ν_c does not depend on them).
    tol : float
        Width of the certified bracket of the general case.

    Returns
    -------
    LoopThresholdFact
        Exact with ``basis="theorem"`` for scalar plants and square invertible B; for one
        input column the closed form is given with ``basis="claim"`` and ``interval`` is the
        certified bracket it was checked against; otherwise the certified bracket.

    Raises
    ------
    kfcrit.errors.InputError
        A or B of the wrong shape (the error names the matrix).

    References
    ----------
    Schenato, Sinopoli, Franceschetti, Poolla & Sastry (2007), "Foundations of control and
    estimation over lossy networks", Proc. IEEE 95(1); docs/theory.md §12
    (TCP-like: ν_c is the MARE threshold p_up of the dual pair); Sinopoli et
    al. (2004), Theorem 5.

    Examples
    --------
    >>> from fractions import Fraction
    >>> from kfcrit.theory.loop.thresholds import actuation_threshold
    >>> nu_c = actuation_threshold([[Fraction(5, 4)]], [[1]])
    >>> nu_c.expression, nu_c.basis, nu_c.certified
    ('9/25', 'theorem', True)
    >>> actuation_threshold([[1, 2]], [[1]])  # doctest: +ELLIPSIS
    Traceback (most recent call last):
        ...
    kfcrit.errors.InputError: A: must be square, got ...
    """
    dual = dual_system(A, B, W, U)
    if dual.n == 1:
        return _scalar(dual)
    inv, how = c_invertible(dual)
    if inv:
        pl = p_low_bounds(dual)
        expr = sp.sympify(pl.expression) if pl.expression is not None else None
        value = float(sp.N(expr, 30)) if expr is not None else pl.up
        return LoopThresholdFact("nu_c", value, (pl.down, pl.up), expr is not None,
                         pl.expression, "theorem", pl.rigorous,
                         f"B square and invertible ({how}): ν_c = max(1 − 1/ρ(A)², 0), the "
                         "dual of 'C invertible' (Sinopoli et al. 2004 Section IV)")
    interval, certified, why, _ = _from_upper(dual, tol)
    if interval is None:
        return LoopThresholdFact("nu_c", None, None, False, None, "none", False,
                         "(A, B) not stabilisable: " + why)
    if dual.m == 1:
        expr = _single_column_claim(dual)
        if expr is not None:
            value, rounded = _num_of(expr)
            inside = interval[0] - 2 * tol <= value <= interval[1] + 2 * tol
            return LoopThresholdFact("nu_c", value, interval, True, sp.sstr(expr), "claim", certified,
                             "one input column: ν_c = 1 − 1/Π|λ_u|² over |λ| > 1, the dual of "
                             "the single-output identity (theory §3 [beyond], a claim); "
                             + ("it lies in" if inside else "it DISAGREES with")
                             + f" the certified bracket [{interval[0]:.12g}, "
                               f"{interval[1]:.12g}] ({why})")
    mid = 0.5 * (interval[0] + interval[1])
    return LoopThresholdFact("nu_c", mid, interval, False, None,
                     "certified-interval" if certified else "numerical", certified, why)


def sensing_threshold(A: Any, C: Any, Q: Any = None, R: Any = None,
                      tol: float = 1e-9) -> LoopThresholdFact:
    """γ_c: the estimation critical value of (A, C) (:func:`kfcrit.theory.critical.section.critical_value`).

    .. math::

        \\gamma_c = \\inf\\{\\bar\\gamma : \\sup_t E[P_t] < \\infty\\}

    Where no theorem gives the value, the interval is [block lower bound, p_up(A, C)].

    Parameters
    ----------
    A, C : array_like
        Plant and output matrices; exact input stays exact.
    Q, R : array_like, optional
        Noise covariances (default identities; γ_c does not depend on them).
    tol : float
        Tolerance of the critical value and width of the p_up bracket.

    Returns
    -------
    LoopThresholdFact
        ``value``, ``interval``, ``exact``, ``expression`` and ``basis`` of γ_c (no value when
        (A, C) is not detectable).

    Raises
    ------
    kfcrit.errors.InputError
        A or C of the wrong shape.

    References
    ----------
    Schenato, Sinopoli, Franceschetti, Poolla & Sastry (2007), "Foundations of control and
    estimation over lossy networks", Proc. IEEE 95(1); docs/theory.md §12
    Mo & Sinopoli, Theorem 4; docs/theory.md §4.

    Examples
    --------
    >>> from fractions import Fraction
    >>> from kfcrit.theory.loop.thresholds import sensing_threshold
    >>> sensing_threshold([[Fraction(5, 4)]], [[1]]).expression
    '9/25'
    """
    A_, _ = to_matrix(A, "A")
    C_, _ = to_matrix(C, "C")
    n, m = A_.shape[0], C_.shape[0]
    system = System(A_, C_, sp.eye(n) if Q is None else Q, sp.eye(m) if R is None else R,
                    name="sensing link (A, C)")
    cv = critical_value(system, tolerance=tol, robust=False)
    if cv.classification == "not-detectable":
        return LoopThresholdFact("gamma_c", None, None, False, None, "none", True, cv.reason)
    if cv.value is not None:
        if cv.value.expr is not None:
            value, interval = _num_of(cv.value.expr)
            return LoopThresholdFact("gamma_c", value, interval, True, sp.sstr(cv.value.expr),
                             cv.basis or "theorem", True, cv.reason)
        v = cv.value.value
        return LoopThresholdFact("gamma_c", v, (v, v), False, None, "numerical", False, cv.reason)
    ub = upper_bound(system, tol=tol)
    lo = cv.block_lower.value if cv.block_lower is not None else cv.lower.value
    hi = float(ub.interval[1])
    return LoopThresholdFact("gamma_c", None, (float(lo), hi), False, None,
                     "certified-interval" if ub.certified else "numerical",
                     bool(ub.certified), f"{cv.classification}: no closed form; bracket "
                     "[block lower bound, p_up(A, C)]")
