"""The large-block path of p_up (matrix-free Newton, Stein certificate, verified float64 check)
at a moderate size, against an independent MARE iteration written here (docs/theory.md §3)."""
from __future__ import annotations

import numpy as np
import pytest

from kfcrit.model.system import System
from kfcrit.theory.upper import bracket, floatcheck, newton


def _system(n: int, m: int, seed: int) -> System:
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, n))
    A *= 1.3 / max(abs(np.linalg.eigvals(A)))
    return System(A, rng.normal(size=(m, n)), np.eye(n), np.eye(m))


def _mare_bounded(A: np.ndarray, C: np.ndarray, p: float, steps: int = 4000) -> bool:
    """X ← A X A' + I − p A X C'(C X C' + I)⁻¹ C X A' from 0: bounded (converged) or not."""
    n, m = A.shape[0], C.shape[0]
    X = np.zeros((n, n))
    for _ in range(steps):
        AXC = A @ X @ C.T
        Y = A @ X @ A.T + np.eye(n) - p * AXC @ np.linalg.solve(C @ X @ C.T + np.eye(m), AXC.T)
        Y = 0.5 * (Y + Y.T)
        if np.trace(Y) > 1e9:
            return False
        if np.abs(Y - X).max() <= 1e-10 * np.abs(Y).max():
            return True
        X = Y
    return False


@pytest.fixture
def large_path(monkeypatch):
    """Send every unstable block with more than 8 states to the large-block method."""
    monkeypatch.setattr(newton, "NEWTON_MAX_REDUCED", 8)
    monkeypatch.setattr(newton, "KRYLOV_MIN_REDUCED", 9)
    yield


def test_large_path_contains_an_independent_mare_estimate(large_path):
    s = _system(60, 12, 3)
    ub = bracket.upper_bound(s, tol=1e-4, method="newton")
    assert ub.solver["reduced_states"] > 8 and "operator_applications" in ub.solver
    assert ub.certified
    lo, hi = ub.interval
    assert "float64" in ub.certificate["verified_by"]
    # independent MARE iteration: bounded just above hi, growing without bound just below lo
    # (3e-3 away: near the threshold the iteration needs ~1/(p - p_up) steps either way)
    assert _mare_bounded(s.a, s.c, min(1.0, hi + 3e-3), steps=20000)
    assert not _mare_bounded(s.a, s.c, lo - 3e-3, steps=20000)


def _certificate(s: System):
    ub = bracket.upper_bound(s, tol=1e-4, method="newton")
    return ub, ub.extras["X"], ub.extras["K"]


def test_float_check_accepts_the_certificate_and_rejects_perturbed_ones(large_path):
    s = _system(60, 12, 3)
    ub, X, K = _certificate(s)
    p = ub.interval[1]
    X = np.triu(X) + np.triu(X, 1).T
    ok, *_ = floatcheck.verify_upper_float(s.a, s.c, 0.999, X, K)
    assert isinstance(ok, bool)
    # a wrong gain: the error system is not mean-square stable with K = 0 at p (ρ(A) = 1.3)
    bad, *_ = floatcheck.verify_upper_float(s.a, s.c, p, X, np.zeros_like(K))
    assert not bad
    # a wrong probability: far below p_low nothing can be certified
    bad, *_ = floatcheck.verify_upper_float(s.a, s.c, 0.0, X, K)
    assert not bad
    # an indefinite X
    Xn = X.copy()
    Xn[0, 0] = -abs(Xn[0, 0])
    bad, _, _, why = floatcheck.verify_upper_float(s.a, s.c, p, Xn, K)
    assert not bad and "positive definite" in why


def test_float_check_on_a_closed_form_case():
    # scalar a = 2, c = 1: K = -a gives F = 0, X = 1: X - (1-p) a² X = 1 - 4(1-p) > 0 iff p > 3/4
    a, c, X, K = np.array([[2.0]]), np.array([[1.0]]), np.array([[1.0]]), np.array([[-2.0]])
    assert floatcheck.verify_upper_float(a, c, 0.76, X, K)[0]
    assert not floatcheck.verify_upper_float(a, c, 0.75, X, K)[0]
    assert not floatcheck.verify_upper_float(a, c, 0.74, X, K)[0]


def test_basis_check_rejects_a_perturbed_basis_certificate():
    a = np.diag([2.0, 0.5])
    c = np.array([[1.0, 0.0]])
    Z = np.eye(2)
    Xz = np.diag([1.0, 4.0])
    Kz = np.array([[-2.0], [0.0]])
    assert floatcheck.verify_upper_float_basis(a, c, 0.9, Z, Xz, Kz)[0]
    assert not floatcheck.verify_upper_float_basis(a, c, 0.9, Z, Xz, Kz * 0.0)[0]
    assert not floatcheck.verify_upper_float_basis(a, c, 0.9, Z, -Xz, Kz)[0]


def test_rounding_bounds_are_upper_bounds():
    rng = np.random.default_rng(0)
    U, V = rng.normal(size=(30, 40)), rng.normal(size=(40, 20))
    mid, rad = floatcheck.mul(floatcheck.point(U), floatcheck.point(V))
    from fractions import Fraction
    i, j = 3, 7
    exact = sum(Fraction(U[i, k]) * Fraction(V[k, j]) for k in range(40))
    assert abs(Fraction(mid[i, j]) - exact) <= Fraction(rad[i, j])


def test_a_large_block_record_is_typed_end_to_end(large_path, tmp_path):
    """The large-block solver's statistics are fields of the typed record (``analyze`` of a
    system whose unstable block takes that path round-trips through the strict reader)."""
    from kfcrit.analysis.record import AnalysisOptions, analyze_system
    from kfcrit.analysis.sections import record_from_json

    s = _system(30, 6, 3)
    rec = analyze_system(s, AnalysisOptions(simulate=False, quick=True))
    solver = rec["upper_bound"]["solver"]
    assert solver["reduced_states"] > 8 and "operator_applications" in solver
    assert record_from_json(rec.to_dict()) == rec
