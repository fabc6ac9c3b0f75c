"""Eigen-structure decisions (kfcrit.theory.structure.eigen): exact path, numeric path, fallbacks.

Expected facts are hand derivations (stated next to each case) or a second method (brute force
for the simplest rational; the numeric path against the exact path).
"""
from __future__ import annotations

import json
import math
import time
from fractions import Fraction

import numpy as np
import pytest
import sympy as sp
from hypothesis import given
from hypothesis import strategies as st

from kfcrit.model.system import System
from kfcrit.theory.structure.eigen import (
    MAX_DENOMINATOR,
    Fallback,
    certified_structure,
    eigen_structure,
    simplest_rational,
)


def _sys(A, C, Q=None) -> System:
    n, m = len(A), len(C)
    Q = Q if Q is not None else np.eye(n).astype(int).tolist()
    return System(A, C, Q, np.eye(m).astype(int).tolist())


# --------------------------------------------------------------------------- simplest rational

def _brute_simplest(lo: Fraction, hi: Fraction) -> Fraction:
    q = 1
    while True:
        p = math.ceil(lo * q)
        if Fraction(p, q) <= hi:
            return Fraction(p, q)
        q += 1


@pytest.mark.parametrize("lo, hi, expected", [
    (Fraction(333, 1000), Fraction(334, 1000), Fraction(1, 3)),
    (Fraction(1, 2) - Fraction(1, 10**9), Fraction(1, 2) + Fraction(1, 10**9), Fraction(1, 2)),
    (Fraction(314, 100), Fraction(31416, 10000), Fraction(157, 50)),
    (Fraction(2), Fraction(2), Fraction(2)),
])
def test_simplest_rational_known(lo, hi, expected):
    assert simplest_rational(lo, hi) == expected


@given(st.integers(0, 10**6), st.integers(1, 10**4))
def test_simplest_rational_matches_brute_force(a, width):
    lo = Fraction(a, 10**6)
    hi = lo + Fraction(width, 10**7)
    got = simplest_rational(lo, hi)
    assert lo <= got <= hi
    assert got.denominator == _brute_simplest(lo, hi).denominator


# --------------------------------------------------------------------------- exact path

def _pair(s):
    assert len(s.pairs) == 1
    return s.pairs[0]


def test_third_turn_rotation_exact():
    # A = [[1, -√3], [√3, 1]]: eigenvalues 1 ± j√3 = 2 e^{±jπ/3}; z = e^{∓2jπ/3}, order 3.
    s = eigen_structure(_sys([[1, "-sqrt(3)"], ["sqrt(3)", 1]], [[1, 0]]))
    assert s.path == "exact"
    assert [e.mod2_expr for e in s.eigen] == [4, 4]
    p = _pair(s)
    assert (p.q, p.rank, p.size, p.degenerate) == (3, 1, 2, True)
    assert s.diagonalizable and s.detectable and s.controllable_Q


def test_fifth_turn_rotation_exact():
    # 2·rotation(2π/5) written with cos/sin: z = e^{∓4jπ/5} has order 5.
    A = [["2*cos(2*pi/5)", "-2*sin(2*pi/5)"], ["2*sin(2*pi/5)", "2*cos(2*pi/5)"]]
    s = eigen_structure(_sys(A, [[1, 0]]))
    assert s.path == "exact"
    assert _pair(s).q == 5


def test_atan_four_thirds_is_irrational():
    # [[3,-4],[4,3]]: eigenvalues 3 ± 4j, z = (3−4j)/(3+4j) = (−7 − 24j)/25; its minimal
    # polynomial 25x² + 14x + 25 is not monic, so z is not a root of unity.
    s = eigen_structure(_sys([[3, -4], [4, 3]], [[1, 0]]))
    assert s.path == "exact" and _pair(s).q is None
    assert s.eigen[0].mod2_expr == 25


def test_rank_two_output_makes_pair_non_degenerate():
    s = eigen_structure(_sys([[0, -2], [2, 0]], [[1, 0], [0, 1]]))
    p = _pair(s)
    assert (p.rank, p.degenerate, p.q) == (2, False, 2)
    assert s.blocks[0].one_step_observable


def test_jordan_block_not_diagonalizable():
    s = eigen_structure(_sys([[2, 1], [0, 2]], [[1, 0]]))
    assert s.path == "exact" and not s.diagonalizable
    assert s.eigen[0].multiplicity == 2 and s.eigen[0].geometric == 1
    assert s.detectable  # the eigenvector e1 is seen by C = [1, 0]


def test_repeated_diagonalizable_eigenvalue():
    # A = 2I (3x3) is diagonalizable; C = I has full rank on the 3-dim eigenspace.
    s = eigen_structure(_sys([[2, 0, 0], [0, 2, 0], [0, 0, 2]], np.eye(3).astype(int).tolist()))
    assert s.diagonalizable and s.eigen[0].geometric == 3 and s.detectable


def test_undetectable_and_uncontrollable():
    # Unstable mode 2 on e1 invisible to C = [0, 1]; Q = diag(0, 1) does not excite e1.
    s = eigen_structure(_sys([[2, 0], [0, "1/2"]], [[0, 1]], Q=[[0, 0], [0, 1]]))
    assert not s.detectable and not s.controllable_Q
    # A stable invisible mode does not break detectability (PBH only on |λ| ≥ 1).
    s2 = eigen_structure(_sys([["1/2", 0], [0, 2]], [[0, 1]]))
    assert s2.detectable


def test_equal_moduli_from_different_factors():
    # 2 (rational) and 2 e^{±jπ/3} (from x² − 2x + 4): three eigenvalues of modulus 2.
    A = [[2, 0, 0], [0, 1, "-sqrt(3)"], [0, "sqrt(3)", 1]]
    s = eigen_structure(_sys(A, [[1, 1, 0]]))
    assert s.path == "exact"
    assert len(s.blocks) == 1 and s.blocks[0].size == 3 and s.blocks[0].rank == 1
    # pairs: (2, 2e^{jπ/3}) q = 6, (2, 2e^{-jπ/3}) q = 6, conjugates q = 3
    assert sorted(p.q for p in s.pairs) == [3, 6, 6]


def test_observability_index():
    # Chain e3 → e2 → e1 seen through e1: needs three steps.
    s = eigen_structure(_sys([[2, 1, 0], [0, 2, 1], [0, 0, 2]], [[1, 0, 0]]))
    assert s.observability_index == 3


def test_record_is_json():
    s = eigen_structure(_sys([[1, "-sqrt(3)"], ["sqrt(3)", 1]], [[1, 0]]))
    d = s.to_dict()
    json.dumps(d, allow_nan=False)
    assert d["path"] == "exact" and d["eigenvalues"][0]["modulus_expression"] == "2"
    assert {"indices", "modulus", "one_step_observable", "rank", "size"} <= set(
        d["equi_blocks"][0])


# --------------------------------------------------------------------------- numeric path

def test_fallback_large_n():
    n = 7
    A = np.diag([2.0, -2.0, 0.5, 0.4, 0.3, 0.2, 0.1]).tolist()
    s = eigen_structure(_sys(A, [[1.0] * n]))
    assert s.path == "numeric" and "n > " in s.path_reason
    assert s.pairs[0].q == 2 and s.pairs[0].degenerate


def test_fallback_irreducible_cubic():
    # companion matrix of x³ − 2: the real root and the complex pair have equal moduli, a
    # coincidence between non-conjugate CRootOf eigenvalues the exact path does not certify
    s = eigen_structure(_sys([[0, 0, 2], [1, 0, 0], [0, 1, 0]], [[1, 0, 0]]))
    assert s.path == "numeric" and "degree" in s.path_reason
    # moduli all 2^(1/3): one equi-block of three; q of the pairs: e^{±2πj/3} ratios → 3
    assert len(s.blocks) == 1 and s.blocks[0].size == 3
    assert all(p.q == 3 for p in s.pairs)


@pytest.mark.parametrize("A, C", [
    ([[1, "-sqrt(3)"], ["sqrt(3)", 1]], [[1, 0]]),
    ([[2, 0, 0, 0], [0, -2, 0, 0], [0, 0, 3, 0], [0, 0, 0, -3]], [[1, 0, 1, 0], [0, 1, 0, 1]]),
    ([[2, 1], [0, 2]], [[1, 0]]),
    ([[1, -1], [1, 1]], [[1, 2]]),
])
def test_numeric_path_agrees_with_exact(A, C):
    system = _sys(A, C)
    ex, nu = eigen_structure(system), eigen_structure(system, force_numeric=True)
    assert ex.path == "exact" and nu.path == "numeric"
    assert ex.diagonalizable == nu.diagonalizable and ex.detectable == nu.detectable
    assert [b.size for b in ex.blocks] == [b.size for b in nu.blocks]
    assert [b.rank for b in ex.blocks] == [b.rank for b in nu.blocks]
    assert [p.q for p in ex.pairs] == [p.q for p in nu.pairs]
    assert np.allclose([e.mod2 for e in ex.eigen], [e.mod2 for e in nu.eigen], rtol=1e-9)


def test_numeric_tolerances_reported():
    s = eigen_structure(_sys([[2, 0], [0, -2]], [[1, 1]]), force_numeric=True)
    assert s.tolerances["max_denominator"] == MAX_DENOMINATOR
    assert s.tolerances["modulus_relative"] > 0


def test_float_rotation_exact_path_with_large_surd():
    # A = [[a, -b], [c, a]] entered as floats with a² + bc ≈ 1: eigenvalues a ± j√(bc), |λ|² =
    # a² + bc exactly (a rational). The discriminant −4bc is a large rational whose square root
    # sympy rewrites (square factors pulled out); the exact path must still convert it. With
    # C = 0, (C, A) is detectable iff no eigenvalue has |λ| ≥ 1 (PBH), i.e. iff a² + bc < 1.
    A = [[0.5403023058681398, -0.5609855267969309], [1.2622174352931448, 0.5403023058681398]]
    s = eigen_structure(_sys(A, [[0, 0]]))
    assert s.path == "exact"
    from fractions import Fraction as F
    a, b, c = (F(v) for v in (A[0][0], -A[0][1], A[1][0]))
    assert (a * a + b * c >= 1) == (not s.detectable)
    assert not s.observable


def test_observable_flag():
    assert eigen_structure(_sys([[2, 1], [0, 3]], [[1, 0]])).observable
    assert not eigen_structure(_sys([[2, 0], [0, 3]], [[1, 0]])).observable


def test_standard_form_in_record():
    # [[2, 4], [0, −2]], C = [1 0]: eigenvectors v₁ = e₁ (λ = 2) and v₂ ∝ (−1, 1) (λ = −2:
    # A(−1, 1) = (2, −2)). One equi-block {2, −2} with C·V = [C v₁, C v₂], both nonzero.
    s = _sys([[2, 4], [0, -2]], [[1, 0]])
    form = eigen_structure(s).to_dict()["standard_form"]
    assert form["eigenvalues"] == ["2", "-2"]
    (blk,) = form["equi_blocks"]
    assert blk["indices"] == [0, 1] and blk["eigenvalues"] == ["2", "-2"]
    assert all(sp.sympify(col[0]) != 0 for col in blk["C_columns"])
    # numeric path: unit eigenvectors, |C v₁| = 1, |C v₂| = 1/√2
    num = eigen_structure(s, force_numeric=True).to_dict()["standard_form"]
    (blk,) = num["equi_blocks"]
    mags = [abs(complex(*col[0])) for col in blk["C_columns"]]
    assert abs(mags[0] - 1) < 1e-12 and abs(mags[1] - 2 ** -0.5) < 1e-12
    json.dumps(num)


def test_numeric_path_uses_given_tolerance():
    # moduli 2 and 2 − 1e-12 (relative gap 5e-13): merged at tolerance 1e-9, not at 1e-13
    s = _sys([[2.0, 0], [0, -(2 - 1e-12)]], [[1, 1]])
    loose = eigen_structure(s, force_numeric=True, tolerance=1e-9)
    tight = eigen_structure(s, force_numeric=True, tolerance=1e-13)
    assert len(loose.blocks) == 1 and len(tight.blocks) == 2


# --------------------------------------------------------------------------- certified enclosures

# 6×6 a + b·sqrt(2) (fixed integers): χ_A has an eigenvalue of degree 12 over Q, beyond the
# radical/CRootOf algebra; the certified-enclosure stage decides it on the exact path.
_SURD_A = [[-1, 1, -2, -1, -1, -1], [2, 1, 2, 2, -2, -2], [2, -2, -2, -2, 2, -1],
           [-1, -2, 0, 0, 2, 1], [2, -2, 0, 0, 1, -2], [-1, 0, -2, 2, 1, 1]]
_SURD_B = [[0, 0, 0, -1, -1, -1], [1, 0, 1, -1, 1, 1], [1, -1, 0, -1, 1, 1],
           [0, -1, -1, -1, -1, -1], [1, 0, 1, -1, 0, 1], [0, -1, 0, 1, 0, 0]]


def _surd_system(C):
    A = [[f"{a} + {b}*sqrt(2)" for a, b in zip(ra, rb)] for ra, rb in zip(_SURD_A, _SURD_B)]
    return _sys(A, C)


def _surd_float():
    return np.array(_SURD_A, float) + np.sqrt(2) * np.array(_SURD_B, float)


@pytest.mark.parametrize("C, classification", [
    (np.eye(6).astype(int).tolist(), "non-degenerate"),   # C = I: every block observable
    ([[1, 0, 0, 0, 0, 1]], "degenerate"),                 # m = 1: two degenerate pairs
])
def test_certified_stage_decides_surd_system(C, classification):
    from kfcrit.theory.critical import section as critical
    system = _surd_system(C)
    s = eigen_structure(system)
    assert s.path == "exact" and "certified enclosures" in s.path_reason
    assert "degree 12" in s.path_reason          # why the radical algebra did not run
    assert s.diagonalizable and s.detectable and s.controllable_Q
    # independent check: numpy on the float matrix, with the moduli far apart (conjugate
    # pairs aside), so float64 decides the same equi-blocks beyond doubt
    w = np.linalg.eigvals(_surd_float())
    mods = np.sort(np.abs(w))[::-1]
    distinct = sorted({round(float(x), 6) for x in mods}, reverse=True)
    assert min(-np.diff(distinct)) > 0.1
    assert np.allclose([e.modulus for e in s.eigen], mods, rtol=1e-12)
    assert [b.size for b in s.blocks] == [
        int(np.sum(np.abs(mods - d) < 1e-5)) for d in distinct]
    nu = eigen_structure(system, force_numeric=True)
    assert [b.rank for b in s.blocks] == [b.rank for b in nu.blocks]
    assert all(p.q is None and p.turn_text == "irrational" for p in s.pairs)
    rec = critical.critical_section(system)
    assert rec["classification"] == classification
    assert rec["structure"]["path"] == "exact"
    if classification == "non-degenerate":
        assert abs(rec["critical_value"]["value"] - (1 - mods[0] ** -2)) < 1e-12
        assert rec["critical_value"]["exact"] is False   # |λ₁|² has degree ≥ 3: a float
    assert abs(rec["lower_bound"]["value"] - (1 - mods[0] ** -2)) < 1e-12
    json.dumps(s.to_dict(), allow_nan=False)


@pytest.mark.parametrize("A, C, why", [
    ([[2, 0], [0, -2]], [[1, 1]], "moduli not separated"),      # 2 = |−2|, not conjugate
    ([[2, 1], [0, 2]], [[1, 0]], "not isolated"),               # Jordan block
    ([[2, 0], [0, "1/2"]], [[0, 1]], "C·v not certified nonzero"),   # undetectable
])
def test_certified_stage_hands_over(A, C, why):
    # What balls cannot certify (equal moduli of non-conjugates, roots of unity, multiple
    # eigenvalues, exact zeros) the certified stage refuses; the exact algebra decides it.

    system = _sys(A, C)
    with pytest.raises(Fallback, match=why):
        certified_structure(system, time.monotonic(), "test")
    assert eigen_structure(system).path == "exact"


@pytest.mark.parametrize("A, q, mod2", [
    ([[0, -2], [2, 0]], 2, 4),                         # ±2j: z = −1, |λ|² = 4
    ([[1, "-sqrt(3)"], ["sqrt(3)", 1]], 3, 4),         # 2e^{±jπ/3}: z = e^{∓2πj/3}
    ([["2*cos(pi/7)", "-2*sin(pi/7)"], ["2*sin(pi/7)", "2*cos(pi/7)"]], 7, 4),
    ([["3/2*cos(pi/30)", "-3/2*sin(pi/30)"], ["3/2*sin(pi/30)", "3/2*cos(pi/30)"]], 30,
     sp.Rational(9, 4)),
])
def test_certified_stage_proves_rational_angles(A, q, mod2):
    # r·R(θ): eigenvalues r e^{±jθ}, z = e^{∓2jθ}, order of e^{2jθ} by hand: θ = π/2 → q = 2,
    # π/3 → 3, π/7 → 7, π/30 → 30 (2θ = 2π/30); |λ|² = r² (r = 2, 2, 2, 3/2).
    # Roots of unity are proved in Q(ζ_L), not only excluded.
    system = _sys(A, [[1, 0]])
    s = certified_structure(system, time.monotonic(), "test")
    assert s.path == "exact" and "proved exactly" in s.path_reason
    assert [p.q for p in s.pairs] == [q] and s.pairs[0].degenerate
    assert [e.mod2_expr for e in s.eigen] == [mod2, mod2]


def test_certified_stage_refutes_a_near_rational_angle():
    # [[2c, −s], [s, 2c]], c = cos(π/7), s = sin(π/7): eigenvalues 2c ± j·s, not a rotation;
    # z = λ̄/λ has φ/2π = −2·atan(s/(2c))/2π, irrational; no exact identity may be claimed.
    system = _sys([["2*cos(pi/7)", "-sin(pi/7)"], ["sin(pi/7)", "2*cos(pi/7)"]], [[1, 0]])
    s = eigen_structure(system)
    assert s.path == "exact"
    assert [p.q for p in s.pairs] == [None]
    lam = np.linalg.eigvals(system.a.astype(float))
    assert np.allclose(sorted(e.mod2 for e in s.eigen), sorted(abs(lam) ** 2), rtol=1e-14)


def test_diag_two_minus_two_handover_keeps_exact_value():
    from kfcrit.theory.critical import section as critical
    system = _sys([[2, 0], [0, -2]], [[1, 1]])
    s = eigen_structure(system)
    assert s.path == "exact" and "certified" not in s.path_reason
    assert _pair(s).q == 2 and _pair(s).degenerate
    rec = critical.critical_section(system)
    assert rec["classification"] == "degenerate-second-order"
    assert sp.simplify(sp.sympify(rec["critical_value"]["expression"]) - sp.Rational(15, 16)) == 0


def test_certified_stage_agrees_with_exact_algebra():
    # 5·e^{±j·atan(4/3)} (φ/2π irrational, C sees one combination: degenerate pair) and a
    # stable real mode: the exact algebra and the certified stage decide the same facts.

    system = _sys([[3, -4, 0], [4, 3, 0], [0, 0, "1/2"]], [[1, 0, 1]])
    ex = eigen_structure(system)
    ce = certified_structure(system, time.monotonic(), "cross-check")
    assert ex.path == ce.path == "exact" and "certified" in ce.path_reason
    assert [b.size for b in ce.blocks] == [b.size for b in ex.blocks]
    assert [b.rank for b in ce.blocks] == [b.rank for b in ex.blocks]
    assert [(p.q, p.degenerate) for p in ce.pairs] == [(p.q, p.degenerate) for p in ex.pairs]
    assert [e.unit_cmp for e in ce.eigen] == [e.unit_cmp for e in ex.eigen]
    assert np.allclose([e.mod2 for e in ce.eigen], [e.mod2 for e in ex.eigen], rtol=1e-14)
    assert (ce.detectable, ce.diagonalizable, ce.controllable_Q, ce.observable) == (
        ex.detectable, ex.diagonalizable, ex.controllable_Q, ex.observable)


# --------------------------------------------------------------------------- float64 resolution

def test_ill_conditioned_cluster_does_not_average_away_instability():
    # Issue 18 item 4: A = V·diag(6/5, 1/2, 1/3, …, 1/7)·V⁻¹, V = I + 60·(strict upper ones),
    # cond(V) ≈ 1e13, n = 7 (numeric path). The first-order error bounds 64·ε·‖A‖·κ overlap,
    # so
    # float64 cannot resolve the spectrum — but the unstable 6/5 must not vanish into a mean.
    # Hand value: C = [1 … 1], C·v_i = 1 + 60·(i − 1) ≠ 0, one |λ| > 1: 1 − (5/6)² = 11/36.
    from kfcrit.theory.critical import section as critical
    n = 7
    V = np.eye(n) + np.triu(np.full((n, n), 60.0), 1)
    A = V @ np.diag([6 / 5, 1 / 2, 1 / 3, 1 / 4, 1 / 5, 1 / 6, 1 / 7]) @ np.linalg.inv(V)
    s = System(A, np.ones((1, n)), np.eye(n), np.eye(1))
    st_ = eigen_structure(s)
    assert st_.path == "numeric" and not st_.stable
    assert st_.unresolved and "not resolved in float64" in st_.unresolved[0]
    assert abs(st_.eigen[0].modulus - 1.2) < 1e-6
    d = critical.critical_section(s)
    assert d["classification"] != "stable"
    assert abs(d["critical_value"]["value"] - 11 / 36) < 1e-6
    assert "RESOLUTION FAILED" in d["critical_value"]["reason"]
    assert any("could not resolve" in w for w in d["warnings"])


def test_split_jordan_blocks_stay_one_eigenvalue():
    # constant-acceleration tracker on two axes (Jordan blocks of size 3 at 1, NumPy input n = 6):
    # the computed eigenvalues split by ~ε^(1/3) ≈ 6e-6 and are one eigenvalue of multiplicity 6
    J = np.array([[1.0, 0.1, 0.005], [0.0, 1.0, 0.1], [0.0, 0.0, 1.0]])
    A = np.kron(np.eye(2), J)
    s = System(A, np.kron(np.eye(2), np.array([[1.0, 0.0, 0.0]])), np.eye(6), np.eye(2))
    st_ = eigen_structure(s)
    assert st_.path == "numeric" and not st_.unresolved
    assert len(st_.eigen) == 1 and st_.eigen[0].multiplicity == 6 and st_.eigen[0].geometric == 2
    assert abs(st_.eigen[0].modulus - 1) < 1e-9 and not st_.diagonalizable
