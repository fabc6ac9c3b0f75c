"""The large-block path of p_up (matrix-free Newton, Stein certificate, verified float64 check)
at a moderate size, against an independent MARE iteration (tests/theory/mare_oracle.py; docs/theory.md §3)."""
from __future__ import annotations

import numpy as np
import pytest

from kfcrit.model.system import System
from kfcrit.theory.upper import bracket, floatcheck, newton

from .mare_oracle import mare_bounded, random_unstable_system


@pytest.fixture
def large_path(monkeypatch):
    """Send every unstable block with more than 8 states to the large-block method."""
    monkeypatch.setattr(newton, "NEWTON_MAX_REDUCED", 8)
    monkeypatch.setattr(newton, "KRYLOV_MIN_REDUCED", 9)
    yield


def test_large_path_contains_an_independent_mare_estimate(large_path):
    s = random_unstable_system(60, 12, 3)
    ub = bracket.upper_bound(s, tol=1e-4, method="newton")
    assert ub.solver["reduced_states"] > 8 and "operator_applications" in ub.solver
    assert ub.certified
    lo, hi = ub.interval
    assert "float64" in ub.certificate.verified_by
    # independent MARE iteration: bounded just above hi, growing without bound just below lo
    # (3e-3 away: near the threshold the iteration needs ~1/(p - p_up) steps either way)
    assert mare_bounded(s.a, s.c, min(1.0, hi + 3e-3), steps=20000)
    assert not mare_bounded(s.a, s.c, lo - 3e-3, steps=20000)


def _certificate(s: System):
    ub = bracket.upper_bound(s, tol=1e-4, method="newton")
    return ub, ub.extras["X"], ub.extras["K"]


def test_float_check_accepts_the_certificate_and_rejects_perturbed_ones(large_path):
    s = random_unstable_system(60, 12, 3)
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

    s = random_unstable_system(30, 6, 3)
    rec = analyze_system(s, AnalysisOptions(simulate=False, quick=True))
    solver = rec["upper_bound"]["solver"]
    assert solver["reduced_states"] > 8 and "operator_applications" in solver
    assert record_from_json(rec.to_dict()) == rec


def _spectral_radius2(A: np.ndarray) -> float:
    return float(max(abs(np.linalg.eigvals(A)))) ** 2


def test_face_root_bracket_is_certified_at_both_ends_beyond_the_ball_limit(large_path):
    """n = 70 > 60: p_low comes from float eigenvalues (not rigorous) unless the face-root path
    proves ρ(A)² from below; both ends must then be labelled certified, and the bracket must
    contain p_low = 1 − 1/ρ(A)² and be consistent with an independent MARE iteration."""
    s = random_unstable_system(70, 14, 3)
    tol = 1e-6
    ub = bracket.upper_bound(s, tol=tol, method="newton")
    assert "face root" in ub.solver.get("certificate_from", "")
    assert ub.certified and ub.status == "determined"
    assert ub.lower_evidence.certified and ub.lower_evidence.kind == "theorem"
    lo, hi = ub.interval
    assert hi - lo <= tol * (1 + 1e-9)
    p_low = 1 - 1 / _spectral_radius2(s.a)
    assert lo <= p_low <= hi
    assert mare_bounded(s.a, s.c, min(1.0, hi + 3e-3), steps=20000)
    assert not mare_bounded(s.a, s.c, lo - 3e-3, steps=20000)


def test_face_certificate_is_rejected_when_tampered(large_path):
    from kfcrit.theory.upper import stein
    from kfcrit.theory.upper.cone import reduce_system

    s = random_unstable_system(60, 12, 3)
    red_d, d = stein.dominant_split(reduce_system(s))
    p_low = 1 - 1 / _spectral_radius2(s.a)
    hi = p_low + 5e-7
    Xz, Kz = stein.face_certificate_matrices(red_d, d, hi)
    ok, *_ = floatcheck.verify_upper_float_basis(s.a, s.c, hi, red_d.Z, Xz, Kz, sharp=d)
    assert ok
    # below p_low no certificate exists (Sinopoli Thm 3): the same matrices must fail there
    bad, *_ = floatcheck.verify_upper_float_basis(s.a, s.c, p_low - 5e-7, red_d.Z, Xz, Kz,
                                                  sharp=d)
    assert not bad
    # a gain that no longer cancels the dominant modes
    Kb = Kz.copy()
    Kb[:d] *= 0.9
    bad, *_ = floatcheck.verify_upper_float_basis(s.a, s.c, hi, red_d.Z, Xz, Kb, sharp=d)
    assert not bad
    # the dominant block of X shrunk: its margin (1 − (1−p)ρ²)·X₁₁ no longer covers the rest
    Xb = Xz.copy()
    Xb[:d, :d] *= 1e-3
    bad, *_ = floatcheck.verify_upper_float_basis(s.a, s.c, hi, red_d.Z, Xb, Kz, sharp=d)
    assert not bad


def test_dominant_radius_lower_bound_is_below_and_close_to_numpy():
    from kfcrit.theory.upper import stein
    from kfcrit.theory.upper.cone import reduce_system

    for n, m, seed in ((40, 8, 1), (70, 14, 3)):
        s = random_unstable_system(n, m, seed)
        red_d, d = stein.dominant_split(reduce_system(s))
        low = floatcheck.dominant_radius_lower(s.a, red_d.Z, d)
        rho2 = _spectral_radius2(s.a)
        assert low is not None and low <= rho2 and rho2 - low < 1e-6


def test_dominant_radius_lower_bound_refuses_a_wrong_basis():
    s = random_unstable_system(40, 8, 1)
    rng = np.random.default_rng(5)
    Z, _ = np.linalg.qr(rng.normal(size=(40, 40)))      # not an invariant-subspace basis
    assert floatcheck.dominant_radius_lower(s.a, Z, 2) is None


def test_accurate_product_encloses_the_exact_product_tightly():
    from fractions import Fraction

    rng = np.random.default_rng(2)
    L, R = rng.normal(size=(25, 50)), rng.normal(size=(50, 2))
    L[:, :25] *= 1e8                   # heavy cancellation for the plain float product
    R[:25] *= 1e-8
    mid, rad = floatcheck.accurate_product(L, R)
    for i in (0, 7, 24):
        for j in (0, 1):
            exact = sum(Fraction(L[i, k]) * Fraction(R[k, j]) for k in range(50))
            assert abs(Fraction(mid[i, j]) - exact) <= Fraction(rad[i, j])
            assert rad[i, j] <= 1e-14 * (abs(mid[i, j]) + 1.0)


def test_stein_sylvester_solves_the_one_term_equation():
    import scipy.linalg as sla

    from kfcrit.theory.upper import stein

    rng = np.random.default_rng(4)
    N, _ = sla.schur(0.3 * rng.normal(size=(9, 9)), output="real")   # with 2 × 2 blocks
    M = 0.3 * rng.normal(size=(5, 5))
    R = rng.normal(size=(5, 9))
    X = stein.stein_sylvester(M, N, R)
    # independent: the Kronecker form (I − N ⊗ M) vec X = vec R
    x = np.linalg.solve(np.eye(45) - np.kron(N, M), R.reshape(-1, order="F"))
    assert np.allclose(X, x.reshape(5, 9, order="F"), atol=1e-12)


def test_own_gmres_solves_a_nonsymmetric_system():
    from kfcrit.theory.upper.krylov import gmres_solve

    rng = np.random.default_rng(1)
    M = np.eye(200) + 0.3 * rng.normal(size=(200, 200)) / np.sqrt(200)
    b = rng.normal(size=200)
    x, count, ok = gmres_solve(lambda v: M @ v, b, 1e-12, 20, 30)
    assert ok and count > 0
    assert np.linalg.norm(M @ x - b) <= 1e-11 * np.linalg.norm(b)


def _system_seeded(n: int, m: int, seed: int) -> System:
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, n))
    A *= 1.3 / max(abs(np.linalg.eigvals(A)))
    return System(A, rng.normal(size=(m, n)), np.eye(n), np.eye(m))


def test_interior_root_upper_end_is_certified_and_matches_an_independent_mare(large_path):
    """A root p* > p_low (three outputs for 19 unstable states): the preconditioned Stein
    certificate proves the upper end; the lower end is proven on the enclosed unstable pair
    (tests/theory/test_upper_lowercert.py)."""
    s = _system_seeded(40, 3, 2)
    tol = 1e-6
    ub = bracket.upper_bound(s, tol=tol, method="newton")
    assert ub.solver["certificate_from"].startswith("stein")
    assert ub.certified and ub.status == "determined"
    assert ub.lower_evidence.certified and ub.lower_evidence.kind == "certificate"
    lo, hi = ub.interval
    assert hi - lo <= tol * (1 + 1e-9)
    assert lo > 1 - 1 / _spectral_radius2(s.a) + 1e-3        # not a face root
    assert mare_bounded(s.a, s.c, min(1.0, hi + 3e-3), steps=20000)
    assert not mare_bounded(s.a, s.c, lo - 3e-3, steps=20000)


def test_certificate_widths_start_at_the_request_and_widen():
    from kfcrit.theory.upper.large import WIDER_WIDTHS, certificate_widths

    assert certificate_widths(1e-9, 0.5) == [5e-10, *WIDER_WIDTHS]
    assert certificate_widths(1e-6, 0.5) == [5e-7, 1e-6, 1e-5, 1e-4]
    assert certificate_widths(1e-3, 0.5) == [5e-4]


def test_a_too_narrow_request_gives_a_wider_certified_bracket_not_the_trivial_one(large_path):
    """At a width far below float64's reach near the threshold the verified check fails; the
    bracket must then be certified at a wider width and say so, never fall back to [p_low, 1]
    (nor claim the requested width)."""
    s = random_unstable_system(70, 14, 3)
    tol = 1e-13
    ub = bracket.upper_bound(s, tol=tol, method="newton")
    lo, hi = ub.interval
    assert ub.certified and hi < 1.0
    assert hi - lo > tol and ub.status == "undetermined"
    assert any("certified to width" in w for w in ub.warnings)
    p_low = 1 - 1 / _spectral_radius2(s.a)
    assert lo <= p_low <= hi <= p_low + 1e-4
    assert mare_bounded(s.a, s.c, min(1.0, hi + 3e-3), steps=20000)


def test_stein_widths_widen_before_the_costly_fallback():
    from kfcrit.theory.upper.large import WIDER_WIDTHS, fallback_widths, stein_widths

    assert stein_widths(1e-9) == pytest.approx([0.9e-9, 0.5e-9, *WIDER_WIDTHS], rel=1e-12)
    assert stein_widths(1e-6) == pytest.approx([0.9e-6, 0.5e-6, 1e-6, 1e-5, 1e-4], rel=1e-12)
    assert fallback_widths(1e-9) == [1e-9, WIDER_WIDTHS[-1]]
    assert fallback_widths(1e-3) == [1e-3]


def test_an_interior_root_widens_with_the_stein_certificate_not_the_fallback(large_path,
                                                                            monkeypatch):
    """Far below float64's reach the cheap Stein block certificate is tried at the wider
    widths before any :func:`float_certificate`; the lower end stays at the Newton root (never
    lifted above it) and the widened bracket is reported as such."""
    from kfcrit.theory.upper import large

    tried: list[float] = []
    real = large.stein_block_certificate

    def stein(system, red, K, hi, stats, exact_views, **kw):  # noqa: ANN001, ANN003, ANN202
        tried.append(hi)
        return real(system, red, K, hi, stats, exact_views, **kw)

    def no_fallback(*args, **kwargs):  # noqa: ANN002, ANN003, ANN202
        raise AssertionError("float_certificate called although a Stein width passes")

    monkeypatch.setattr(large, "stein_block_certificate", stein)
    monkeypatch.setattr(large, "float_certificate", no_fallback)
    s = _system_seeded(40, 3, 2)
    tol = 1e-13
    ub = bracket.upper_bound(s, tol=tol, method="newton")
    assert ub.certified and ub.status == "undetermined"
    assert any("certified to width" in w for w in ub.warnings)
    lo, hi = ub.interval
    p_star = ub.extras["p_star"]
    assert lo <= p_star < hi and hi - lo > tol
    # the lower end is the Newton root, or a proven point just below it
    assert lo == p_star or (ub.lower_evidence.certified and p_star - lo <= hi - p_star)
    # 0.9·tol first, then 0.5·tol (skipped when the solve already failed at 0.9·tol), wider
    assert tried[0] == pytest.approx(p_star + 0.9 * tol, abs=1e-15)
    assert tried[1:] == sorted(tried[1:]) and len(tried) >= 2 and hi == tried[-1]
    assert mare_bounded(s.a, s.c, min(1.0, hi + 3e-3), steps=20000)


def test_gmres_gives_up_only_when_the_budget_cannot_suffice():
    from kfcrit.theory.upper.krylov import hopeless

    # stalled: no reduction over two cycles
    assert hopeless([1.0, 0.87, 0.87, 0.87], 1e-7, 17)
    # fast: a factor ~50 per cycle reaches 1e-7 well within the budget
    assert not hopeless([1.0, 0.1, 2e-3, 1e-5, 2e-7], 1e-7, 15)
    # slow after a quick start: about 0.8 per cycle needs ~70 more cycles, 12 are left
    assert hopeless([1.0, 0.7, 0.6, 0.25, 0.06, 0.03, 0.024, 0.019], 1e-7, 12)
    # a slow start alone is not judged before the fifth cycle
    assert not hopeless([1.0, 0.9, 0.85, 0.8], 1e-7, 16)


def test_gmres_with_give_up_still_solves_a_well_conditioned_system():
    from kfcrit.theory.upper.krylov import gmres_solve

    rng = np.random.default_rng(1)
    M = np.eye(200) + 0.3 * rng.normal(size=(200, 200)) / np.sqrt(200)
    b = rng.normal(size=200)
    x, count, ok = gmres_solve(lambda v: M @ v, b, 1e-12, 20, 30, give_up=True)
    assert ok and np.linalg.norm(M @ x - b) <= 1e-11 * np.linalg.norm(b)
    # the cyclic shift with b = e₁ stalls restarted GMRES completely (residual 1 for every
    # restart shorter than n): given up after a few cycles, not 30
    e = np.zeros(200)
    e[0] = 1.0
    x, count, ok = gmres_solve(lambda v: np.roll(v, 1), e, 1e-12, 5, 30, give_up=True)
    assert not ok and count <= 5 * 4
    x, count, ok = gmres_solve(lambda v: np.roll(v, 1), e, 1e-12, 5, 30)
    assert not ok and count >= 5 * 30
