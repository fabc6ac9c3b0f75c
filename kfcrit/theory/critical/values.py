"""Numbers of the critical-value analysis: exact-or-float values, the Mo–Sinopoli closed forms
(theory §4) and the critical-value record."""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any

import sympy as sp

from kfcrit.io.typed import to_json
from kfcrit.model.exprparse import MAX_DIGITS, exact_text
from kfcrit.records.contract import (
    BlockLowerBound,
    Classification,
    CriticalValueRecord,
    LowerBound,
    RobustCriticalValue,
)
from kfcrit.records.structure import Theory
from kfcrit.theory.structure.eigen import (
    NUMERIC_TOLERANCES,
    Structure,
    cmp_exact,
)

_LONG_LITERAL = re.compile(rf"\d{{{MAX_DIGITS + 1},}}")
LONG_NUMBER = re.compile(r"\d{13,}")

CLASSIFICATIONS = ("stable", "non-degenerate", "degenerate-second-order", "degenerate",
                   "non-diagonalizable", "not-detectable")

# --------------------------------------------------------------------------- numbers

@dataclass(frozen=True)
class Num:
    """A probability: float value and, when known exactly, the sympy expression."""

    value: float
    expr: sp.Expr | None = None
    text: str | None = None

    @property
    def expression(self) -> str:
        """Text readable by sympy and :func:`kfcrit.model.exprparse.parse_expression`."""
        if self.expr is None:
            return repr(self.value)
        full = sp.sstr(self.expr)
        out = self.text if self.text is not None and len(self.text) < len(full) else full
        # the safe parser caps literals at MAX_DIGITS digits: long integers in Horner form
        return exact_text(self.expr) if _LONG_LITERAL.search(out) else out

    @property
    def latex(self) -> str:
        """LaTeX of the exact expression (or of the float)."""
        return sp.latex(self.expr) if self.expr is not None else repr(self.value)

    def to_dict(self) -> dict[str, Any]:
        return {"value": self.value, "expression": self.expression}


def num_of(expr: sp.Expr | None, value: float | None = None) -> Num:
    if expr is None:
        return Num(float(value))
    expr = sp.nsimplify(expr) if isinstance(expr, sp.Float) else expr
    return Num(float(sp.N(expr, 30)), expr)


def _above_one(mod2: float, mod2_expr: sp.Expr | None) -> bool:
    """|λ|² > 1, decided exactly when ``mod2_expr`` is given (then max(·, 0) needs no sympy Max)."""
    if mod2_expr is None:
        return mod2 > 1.0
    return cmp_exact(mod2_expr, 1) > 0


_ZERO = Num(0.0, sp.Integer(0))


def mtol(st: Structure | None) -> float:
    """The numeric path's modulus tolerance (relative) of ``st``."""
    tol = st.tolerances.get("modulus_relative") if st is not None else None
    return tol if tol is not None else NUMERIC_TOLERANCES["modulus_relative"]


def eig_above(e: Any, st: Structure | None = None) -> bool:
    """|λ| > 1 as decided by the structure (exactly on the exact path; on the numeric path
    |λ| within the modulus tolerance of 1 counts as critically stable)."""
    if e.unit_cmp is not None:
        return e.unit_cmp > 0
    return e.mod2 > 1 + 2 * mtol(st)


def on_circle(e: Any, st: Structure | None = None) -> bool:
    return e.unit_cmp == 0 if e.unit_cmp is not None else abs(e.mod2 - 1) <= 2 * mtol(st)


def nondegenerate_value(mod2: float, mod2_expr: sp.Expr | None = None,
                        above: bool | None = None) -> Num:
    """Mo–Sinopoli Thm 4: p = max(1 − |λ|^{−2}, 0), with |λ|² = ``mod2``.

    ``above`` (|λ| > 1), when given, is the exact decision of the structure analysis.
    """
    if not (above if above is not None else _above_one(mod2, mod2_expr)):
        return _ZERO if mod2_expr is not None else Num(0.0)
    if mod2_expr is not None:
        return num_of(1 - 1 / mod2_expr)
    return Num(1.0 - 1.0 / mod2)


def pair_value(mod2: float, q: int | None, mod2_expr: sp.Expr | None = None,
               above: bool | None = None) -> Num:
    """Mo–Sinopoli Thm 5: p = max(1 − |λ|^{−2/(1 − D_M)}, 0), D_M = 1/q (0 if irrational).

    ``q = 1`` (z = 1: equal eigenvalues seen through one column) means not detectable: p = 1.
    """
    if q == 1:
        return Num(1.0, sp.Integer(1))
    if q is None:
        return nondegenerate_value(mod2, mod2_expr, above)
    if not (above if above is not None else _above_one(mod2, mod2_expr)):
        return _ZERO if mod2_expr is not None else Num(0.0)
    if mod2_expr is not None:
        v = num_of(1 - mod2_expr ** sp.Rational(-q, q - 1))
        # compact unexpanded form, e.g. 1 - (m)**(-3/2), when it is shorter (long rationals)
        exp = f"-{q}" if q == 2 else f"-{q}/{q - 1}"
        base = sp.sstr(mod2_expr)
        base = base if mod2_expr.is_Integer and mod2_expr > 0 else f"({base})"
        return Num(v.value, v.expr, f"1 - {base}**({exp})")
    return Num(1.0 - mod2 ** (-q / (q - 1)))


# --------------------------------------------------------------------------- record

@dataclass(frozen=True)
class CriticalValue:
    """The critical value of one system and everything that decided it.

    :meth:`sections` gives the record's sections as their classes (classification,
    critical_value, robust_critical_value, lower_bound, block_lower_bound, structure, theory);
    ``to_dict()`` their plain JSON data with ``warnings`` [str] (and the structure's wall-clock
    ``seconds``).
    """

    classification: str
    value: Num | None
    reason: str
    lower: Num
    block_lower: Num | None
    block_reason: str
    robust: RobustCriticalValue | None
    structure: Structure
    theory: Theory
    warnings: tuple[str, ...] = field(default=())
    basis: str | None = None
    """For a value from coinciding bounds: "theorem" or "claim" (a [beyond] identity)."""

    def critical_record(self) -> CriticalValueRecord:
        """The ``critical_value`` section: p_c, whether it is exact, its expression and why."""
        if self.value is None:
            return CriticalValueRecord(value=None, exact=None, expression=None, latex=None,
                                       reason=self.reason)
        exact = self.structure.path == "exact"
        reason = self.reason
        if exact and self.value.expr is None:
            reason += (" (every decision exact; |λ₁|² is an algebraic number of degree ≥ 3, "
                       "so the value is given in double precision)")
        return CriticalValueRecord(value=float(self.value.value),
                                   exact=exact and self.value.expr is not None,
                                   expression=self.value.expression, latex=self.value.latex,
                                   reason=reason, basis=self.basis)

    def sections(self) -> dict[str, Any]:
        """The record's sections of the critical value, each as its class, by record key."""
        blow = self.block_lower
        return {"classification": Classification(self.classification),
                "critical_value": self.critical_record(),
                "robust_critical_value": self.robust,
                "lower_bound": LowerBound(value=float(self.lower.value),
                                          expression=self.lower.expression),
                "block_lower_bound": BlockLowerBound(
                    value=float(blow.value) if blow is not None else None,
                    expression=blow.expression if blow is not None else None,
                    reason=self.block_reason),
                "structure": self.structure.record(), "theory": self.theory}

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON data of :meth:`sections`, with ``warnings`` and the structure's
        wall-clock ``seconds``."""
        out = {k: self.structure.to_dict(v) if k == "structure" else to_json(v)
               for k, v in self.sections().items()}
        out["warnings"] = list(self.warnings)
        return out


def num_text(v: Num) -> str:
    """The expression of a value that may carry only its text (an alternative's expression)."""
    return v.text if v.expr is None and v.text is not None else v.expression
