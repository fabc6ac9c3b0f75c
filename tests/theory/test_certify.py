"""Rigorous certificate checks (kfcrit.theory.upper.certify): hand-derived cases, re-verification, tampering.

Expected outcomes come from hand derivations: for the scalar system a = 2, c = 1 and K = −2
(F = 0), L_{K,p}(x) = 4(1−p)x, so x = 1 certifies p exactly when p > 3/4; and the noise-free
map is G_p(x) = 4(1−p)x, so x = 1 is a lower certificate exactly when p < 3/4.
"""
from __future__ import annotations

import math

import flint
import numpy as np
import pytest

from kfcrit.model.system import System
from kfcrit.theory.upper import certify
from kfcrit.theory.upper.bracket import upper_bound


def scalar(a="2", c="1") -> System:
    return System([[a]], [[c]], [[1]], [[1]])


@pytest.mark.parametrize("p, ok", [(0.76, True), (0.75 + 2**-40, True), (0.75, False),
                                   (0.74, False), (0.0, False)])
def test_upper_check_scalar_hand_derivation(p, ok):
    res = certify.verify_upper(scalar(), p, np.array([[1.0]]), np.array([[-2.0]]))
    assert res.ok is ok
    if ok:  # the margin is that of the equilibrated matrix D M D (here 1×1: scaled to 1)
        assert 0 < res.margin <= 1.0


@pytest.mark.parametrize("p, ok", [(0.74, True), (0.75 - 2**-40, True), (0.75, False),
                                   (0.8, False)])
def test_lower_check_scalar_hand_derivation(p, ok):
    assert certify.verify_lower(scalar(), p, np.array([[1.0]])).ok is ok


def test_definite_margin_known_matrices():
    assert certify.definite_margin(flint.arb_mat([[1, 1], [1, 1]])) is None       # singular
    assert certify.definite_margin(flint.arb_mat([[1, 2], [2, 1]])) is None       # indefinite
    m = certify.definite_margin(flint.arb_mat([[2, 1], [1, 2]]))                # λ = 1, 3
    assert m is not None and 0 < m <= 0.5 + 1e-12     # diag scaling gives [[1, .5], [.5, 1]]
    # very different scales on the diagonal: equilibration still proves definiteness
    assert certify.definite_margin(flint.arb_mat([[1e20, 0], [0, 1e-20]])) is not None


def test_irrational_system_entries_are_enclosed():
    # A = [[1, −√3], [√3, 1]] (rotation-third-turn); F = 0 with K = −A C^{-1}, C = I
    s = System([[1, "-sqrt(3)"], ["sqrt(3)", 1]], [[1, 0], [0, 1]], [[1, 0], [0, 1]],
               [[1, 0], [0, 1]])
    K = -s.a  # rounded √3: F = A + K is tiny but nonzero, proof must still go through
    # L(X) = (1−p) A X A' + p F F' ≈ 4(1−p) I: p = 0.76 is certifiable, p = 0.74 is not
    assert certify.verify_upper(s, 0.76, np.eye(2), K).ok
    assert not certify.verify_upper(s, 0.74, np.eye(2), K).ok


@pytest.fixture(scope="module")
def general_certificate():
    s = System([["5/4", 0], [1, "11/10"]], [[1, 1]], [[20, 0], [0, 20]], [["5/2"]])
    ub = upper_bound(s, tol=1e-9, method="newton")
    return s, ub


def test_certificate_reverifies(general_certificate):
    s, ub = general_certificate
    ex = ub.extras
    assert ub.certified
    assert certify.verify_upper(s, ub.interval[1], ex["X_basis"], ex["K_basis"],
                                basis=ex["basis"]).ok
    # p_up = 57/121 (Sinopoli general example) lies in the certified bracket
    assert ub.interval[0] <= 57 / 121 <= ub.interval[1]


def test_tampered_certificates_are_rejected(general_certificate):
    s, ub = general_certificate
    ex = ub.extras
    Z, Xz, Kz, hi = ex["basis"], ex["X_basis"], ex["K_basis"], ub.interval[1]
    # below p_up no certificate can exist: the same one, claimed for a smaller p
    assert not certify.verify_upper(s, 57 / 121 - 1e-4, Xz, Kz, basis=Z).ok
    assert not certify.verify_upper(s, 0.4, Xz, Kz, basis=Z).ok
    # perturbed gain
    assert not certify.verify_upper(s, hi, Xz, Kz + 0.5, basis=Z).ok
    # X not positive definite
    bad = Xz.copy()
    bad[0, 0] = -abs(bad[0, 0])
    assert not certify.verify_upper(s, hi, bad, Kz, basis=Z).ok
    # singular basis
    assert not certify.verify_upper(s, hi, Xz, Kz, basis=np.zeros_like(Z)).ok
    # garbage
    nan = Xz.copy()
    nan[0, 0] = math.nan
    assert not certify.verify_upper(s, hi, nan, Kz, basis=Z).ok
    assert not certify.verify_upper(s, 1.5, Xz, Kz, basis=Z).ok


def test_tampered_lower_certificate_is_rejected():
    # diag(2, -2), C = [1, 1]: p_up = 15/16 (Mo–Sinopoli degenerate example)
    s = System([[2, 0], [0, -2]], [[1, 1]], [[1, 0], [0, 1]], [[1]])
    ub = upper_bound(s, tol=1e-9, method="newton")
    assert ub.interval[0] <= 15 / 16 <= ub.interval[1]
    ev = ub.lower_evidence
    if ev.kind == "certificate":
        assert ev.check.ok
    # a lower certificate claimed above p_up must fail, whatever X
    for X in (np.eye(2), np.array([[1.0, 0.3], [0.3, 2.0]])):
        assert not certify.verify_lower(s, 0.95, X).ok


@pytest.mark.parametrize("A, C", [
    ([["5/4", 0, 0], [0, "9/10", 7], [0, 0, "3/5"]], [[1, 0, 2]]),   # one unstable mode of three
    ([[2, 2], [2, 2]], [[2, 2]]),                                    # eigenvalues 4 and 0
    ([[0, "7/4"], ["-7/4", 0]], [[0, 2]]),                           # rotation, |λ| = 7/4
])
def test_record_certificate_reverifies_from_the_record(A, C):
    """The certificate in the record (small systems) re-verifies from its own matrices."""
    n, m = len(A), len(C)
    s = System(A, C, np.eye(n).tolist(), np.eye(m).tolist())
    d = upper_bound(s, tol=1e-9).to_dict()
    cert, hi = d["certificate"], d["interval"][1]
    assert d["certified"] and "X" in cert
    if cert["matrices_verified"]:
        assert certify.verify_upper(s, hi, np.array(cert["X"]), np.array(cert["K"])).ok
    else:
        om = np.array(cert["output_map"]) if "output_map" in cert else None
        assert certify.verify_upper(s, hi, np.array(cert["X_basis"]), np.array(cert["K_basis"]),
                                    basis=np.array(cert["basis"]), output_map=om).ok
    # and the same matrices do not certify a p clearly below the interval
    lo = d["interval"][0]
    if lo > 0.01:
        assert not certify.verify_upper(s, lo - 0.01, np.array(cert["X"]),
                                        np.array(cert["K"])).ok


def test_output_map_gain_is_formed_exactly():
    # A = 2·I, C = [[1, 1], [0, 1e-12]] (exact). Hand certificate at p = 0.8: K = −A C⁻¹
    # makes F = 0, so X = I gives X − (1−p)·4·I = 0.2 I ≻ 0. As floats, K = −2 C⁻¹ has entries
    # ~2e12; given instead as K_w = −2 I for the compressed output M C ≈ I (M the float
    # inverse of C, so M C = I only up to rounding) the check must form K_w M C in balls on
    # the exact C and accept only what truly holds.
    from fractions import Fraction

    eye = [[1, 0], [0, 1]]
    s = System([[2, 0], [0, 2]], [[1, 1], [0, Fraction(1, 10 ** 12)]], eye, eye)
    M = np.linalg.inv(s.c)                      # float inverse: M C = I only approximately
    ok = certify.verify_upper(s, 0.8, np.eye(2), -2.0 * np.eye(2), output_map=M)
    assert ok.ok                                # F = 2I − 2 M C ≈ 0: margin ≈ 0.2
    # below p_low = 3/4 no (X, K) can pass: (1 − p)·4 > 1
    assert not certify.verify_upper(s, 0.7, np.eye(2), -2.0 * np.eye(2), output_map=M).ok
    # the shape of the map is checked
    assert not certify.verify_upper(s, 0.8, np.eye(2), -2.0 * np.eye(2),
                                    output_map=np.eye(3)).ok


# ---------------------------------------------------------------------------------------------
# re-verification from the JSON record alone, with an independent exact-rational check
# ---------------------------------------------------------------------------------------------


def _fr_matmul(A, B):
    from fractions import Fraction

    Bt = list(zip(*B))
    return [[sum((a * b for a, b in zip(row, col)), Fraction(0)) for col in Bt] for row in A]


def _fr_transpose(A):
    return [list(r) for r in zip(*A)]


def _fr_positive_definite(M) -> bool:
    """Exact LDLᵀ (Gaussian elimination without pivoting): a symmetric rational matrix is
    positive definite iff every pivot is > 0 (Sylvester's criterion)."""
    M = [list(r) for r in M]
    n = len(M)
    for i in range(n):
        piv = M[i][i]
        if piv <= 0:
            return False
        for j in range(i + 1, n):
            f = M[j][i] / piv
            if f:
                for k in range(i, n):
                    M[j][k] -= f * M[i][k]
    return True


def _exact_upper_check(A, C, p, X, K) -> bool:
    """X ≻ 0 and X − (1−p) A X Aᵀ − p F X Fᵀ ≻ 0, F = A + K C, in exact rationals."""
    n = len(A)
    F = [[a + fc for a, fc in zip(ra, rf)] for ra, rf in zip(A, _fr_matmul(K, C))]
    AXA = _fr_matmul(_fr_matmul(A, X), _fr_transpose(A))
    FXF = _fr_matmul(_fr_matmul(F, X), _fr_transpose(F))
    M = [[X[i][j] - (1 - p) * AXA[i][j] - p * FXF[i][j] for j in range(n)] for i in range(n)]
    M = [[(M[i][j] + M[j][i]) / 2 for j in range(n)] for i in range(n)]
    Xs = [[(X[i][j] + X[j][i]) / 2 for j in range(n)] for i in range(n)]
    return _fr_positive_definite(Xs) and _fr_positive_definite(M)


def test_record_of_a_larger_system_reverifies_exactly_from_json():
    import json
    from fractions import Fraction

    from ..data.bench_systems import random_system

    A, C, Q, R = random_system(10, 3, 1)          # n = 10 > 6: matrices recorded too
    s = System(A, C, Q, R)
    d = json.loads(json.dumps(upper_bound(s, tol=1e-9).to_dict(), allow_nan=False))
    cert = d["certificate"]
    assert d["certified"] and {"basis", "X_basis", "K_basis", "X", "K"} <= set(cert)
    # the exact system: binary floats are dyadic rationals, as System keeps them
    Af = [[Fraction(float(v)) for v in row] for row in A]
    Cf = [[Fraction(float(v)) for v in row] for row in C]

    def fr(M):
        return [[Fraction(v) for v in row] for row in M]

    Z, Xz, Kz = fr(cert["basis"]), fr(cert["X_basis"]), fr(cert["K_basis"])
    X = _fr_matmul(_fr_matmul(Z, Xz), _fr_transpose(Z))
    K = _fr_matmul(Z, Kz)
    if "output_map" in cert:
        K = _fr_matmul(K, fr(cert["output_map"]))
    p = Fraction(cert["p"])
    assert cert["p"] == d["interval"][1]
    assert _exact_upper_check(Af, Cf, p, X, K)
    # the same checker rejects the certificate claimed well below the bracket
    assert not _exact_upper_check(Af, Cf, Fraction(d["interval"][0]) - Fraction(1, 100), X, K)
    # and the rounded full-state copies agree with their own flag
    if cert["matrices_verified"]:
        assert _exact_upper_check(Af, Cf, p, fr(cert["X"]), fr(cert["K"]))
