"""Systems beyond the exact path's size go to the numeric path at once, with the reason the
exact stages would give (and the record's exact matrix text is sympy's)."""
from __future__ import annotations

import sympy as sp

from kfcrit.model.system import System, entry_text
from kfcrit.theory.structure.eigen import EXACT_MAX_STATES, structure_of


def _system(entry) -> System:
    n = EXACT_MAX_STATES + 1
    A = [[entry if i == j else (sp.Rational(1, 3) if j == i + 1 else 0) for j in range(n)]
         for i in range(n)]
    return System(A=A, C=[[1] * n], Q=sp.eye(n), R=[[1]])


def test_rational_system_beyond_the_exact_size():
    st = structure_of(_system(sp.Rational(5, 4)))
    n = EXACT_MAX_STATES + 1
    assert st.path == "numeric"
    assert st.path_reason == (f"numeric float64 path: n = {n} > {EXACT_MAX_STATES}; certified "
                              f"enclosures: n = {n} > {EXACT_MAX_STATES}; decisions use the "
                              "stated tolerances")


def test_transcendental_system_beyond_the_exact_size_states_the_refusal():
    st = structure_of(_system(sp.pi / 2))
    assert st.path == "numeric"
    assert "not all algebraic numbers" in st.path_reason
    assert f"certified enclosures: n = {EXACT_MAX_STATES + 1} >" in st.path_reason


def test_entry_text_is_sympys():
    for e in (sp.Rational(-3, 4), sp.Integer(0), sp.Integer(-7), sp.Rational(10**30 + 1, 3),
              sp.sqrt(2) / 3, sp.Float(0.1), sp.pi):
        assert entry_text(e) == sp.sstr(e)
