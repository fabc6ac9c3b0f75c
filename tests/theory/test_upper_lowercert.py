"""The certified lower end of an interior p_up root for large unstable blocks (verified
float64 enclosure of the exact unstable pair, docs/theory.md §3, "Certified lower end for large
blocks"), against an independent MARE iteration (tests/theory/mare_oracle.py)."""
from __future__ import annotations

import numpy as np
import pytest

from kfcrit.model.system import System
from kfcrit.theory.upper import bracket, floatcheck, krylov, lowercert, newton

from .mare_oracle import mare_bounded, random_unstable_system


def _mare_threshold(A: np.ndarray, C: np.ndarray, lo: float, hi: float,
                    width: float) -> tuple[float, float]:
    """[a, b] with the MARE iteration unbounded at a and bounded at b, b − a ≤ width."""
    assert not mare_bounded(A, C, lo, steps=40000) and mare_bounded(A, C, hi, steps=40000)
    while hi - lo > width:
        mid = 0.5 * (lo + hi)
        if mare_bounded(A, C, mid, steps=40000):
            hi = mid
        else:
            lo = mid
    return lo, hi


@pytest.fixture
def large_path(monkeypatch):
    """Send every unstable block with more than 8 states to the large-block method."""
    monkeypatch.setattr(newton, "NEWTON_MAX_REDUCED", 8)
    monkeypatch.setattr(newton, "KRYLOV_MIN_REDUCED", 9)
    yield


def test_certified_lower_end_matches_an_independent_mare_iteration(large_path):
    """n = 40 with 19 unstable states and three outputs: an interior root (p* > p_low). Both
    ends are proven, and the bracket sits inside the MARE threshold estimated independently
    (P from 0 with Q = R = I diverges below p_up and converges above)."""
    s = random_unstable_system(40, 3, 2)
    tol = 1e-6
    ub = bracket.upper_bound(s, tol=tol, method="newton")
    low = ub.lower_evidence
    assert ub.certified and ub.status == "determined"
    assert low.kind == "certificate" and low.certified
    assert low.check.ok and "Stewart" in low.check.verified_by
    lo, hi = ub.interval
    assert lo == low.value and 0 < hi - lo <= tol * (1 + 1e-9)
    p_low = 1 - 1 / max(abs(np.linalg.eigvals(s.a))) ** 2
    assert lo > p_low + 1e-3                                          # not a face root
    a, b = _mare_threshold(s.a, s.c, lo - 0.05, hi + 0.05, 4e-3)
    assert lo <= b and hi >= a
    enc = ub.solver["lower_enclosure"]
    assert enc["perturbation"] > 0 and enc["eigen_gap"] > 0


def _binary(s: System):
    """Offsets of a system given as NumPy floats: its entries are the floats themselves."""
    return floatcheck.no_offsets(s.a), floatcheck.no_offsets(s.c)


def _ball_and_root(s: System):
    """The enclosed unstable pair and the threshold Newton root computed on its midpoint."""
    from kfcrit.theory.upper.cone import UNSTABLE_TOL

    S, D, k = lowercert.real_eigenbasis(s.a, UNSTABLE_TOL)
    ball, why = lowercert.enclose_unstable_pair(s.a, s.c, S, D, k, *_binary(s))
    assert ball is not None, why
    X0, ok = krylov.mare_start(ball.T0, ball.C0, 0.85)
    assert ok
    p_low = 1 - 1 / max(abs(np.linalg.eigvals(s.a))) ** 2
    thr = krylov.threshold_newton_krylov(ball.T0, ball.C0, X0 / np.trace(X0), 0.85, p_low)
    assert thr.converged
    return ball, thr


def test_a_lower_end_above_the_root_is_not_certified(large_path):
    s = random_unstable_system(40, 3, 2)
    ub = bracket.upper_bound(s, tol=1e-6, method="newton")
    p_star = ub.extras["p_star"]
    ball, thr = _ball_and_root(s)
    assert abs(thr.value - p_star) < 1e-8                      # the same root in the eigenbasis
    below = p_star - 1e-4
    Y, _ = lowercert.lower_candidate(ball, thr.K, below)
    assert Y is not None and lowercert.verify_lower_ball(ball, below, Y).ok
    for p in (p_star + 1e-6, p_star + 1e-3, ub.interval[1]):
        check = lowercert.verify_lower_ball(ball, p, Y)
        assert not check.ok and check.reason
    # nor the eigenvector itself, nor a candidate solved above the root (not positive definite)
    X = thr.X / np.trace(thr.X)
    X = np.triu(X) + np.triu(X, 1).T
    assert not lowercert.verify_lower_ball(ball, p_star + 1e-6, X).ok
    Ya, _ = lowercert.lower_candidate(ball, thr.K, p_star + 1e-4)
    assert Ya is None or not lowercert.verify_lower_ball(ball, p_star + 1e-4, Ya).ok


def test_a_wider_ball_is_refused_where_the_margin_is_small(large_path):
    """The Weyl shift grows with the radii: a ball of radius 1e-6 on T cannot carry a margin
    of order (p* − lo) = 1e-7, while the true radii (~1e-14) do."""
    from dataclasses import replace

    s = random_unstable_system(40, 3, 2)
    ball, thr = _ball_and_root(s)
    p = thr.value - 1e-7
    Y, _ = lowercert.lower_candidate(ball, thr.K, p)
    assert Y is not None and lowercert.verify_lower_ball(ball, p, Y).ok
    assert not lowercert.verify_lower_ball(replace(ball, tau=1e-6), p, Y).ok
    assert not lowercert.verify_lower_ball(replace(ball, gamma=1e-5), p, Y).ok


def test_enclosure_refuses_a_basis_that_is_not_invariant():
    s = random_unstable_system(30, 4, 1)
    S, D, k = lowercert.real_eigenbasis(s.a, 1e-9)
    rng = np.random.default_rng(7)
    Q, _ = np.linalg.qr(rng.normal(size=S.shape))
    ball, why = lowercert.enclose_unstable_pair(s.a, s.c, Q, D, k, *_binary(s))
    assert ball is None and "Stewart" in why
    ball, why = lowercert.enclose_unstable_pair(s.a, s.c, S, D, k, *_binary(s))
    assert ball is not None and ball.tau < 1e-10 and ball.gamma < 1e-10


def test_real_eigenbasis_and_its_separation():
    s = random_unstable_system(30, 4, 1)
    S, D, k = lowercert.real_eigenbasis(s.a, 1e-9)
    assert np.abs(s.a @ S - S @ D).max() < 1e-12
    lam = np.linalg.eigvals(s.a)
    unstable = np.abs(lam) >= 1 - 1e-9
    assert k == int(unstable.sum())
    true_gap = np.abs(lam[unstable][:, None] - lam[~unstable][None, :]).min()
    low = lowercert.separation_lower(D, k)
    assert low <= true_gap and low > 0.99 * true_gap


def test_spectral_norm_bound_is_an_upper_bound():
    rng = np.random.default_rng(3)
    for shape in ((7, 7), (12, 5), (5, 12)):
        M = rng.normal(size=shape)
        rad = 1e-9 * np.abs(rng.normal(size=shape))
        bound = lowercert.spectral_norm_up((M, rad))
        assert bound >= np.linalg.norm(M, 2) + 0.0
        assert bound <= 1.01 * (np.linalg.norm(M, 2) + np.linalg.norm(rad))
        # every matrix of the interval, e.g. its corners
        assert bound >= np.linalg.norm(M + rad * np.sign(M), 2)
    assert floatcheck.verified_definite_margin(floatcheck.point(np.eye(3))) is not None


def test_an_interior_root_record_is_typed_end_to_end(large_path):
    from kfcrit.analysis.record import AnalysisOptions, analyze_system
    from kfcrit.analysis.sections import record_from_json

    s = random_unstable_system(40, 3, 2)
    rec = analyze_system(s, AnalysisOptions(simulate=False, quick=True))
    section = rec["upper_bound"]
    assert section["lower_evidence"]["certified"]
    assert "lower_enclosure" in section["solver"]
    assert record_from_json(rec.to_dict()) == rec


def test_every_mode_unstable_uses_the_pair_itself(large_path):
    """No stable block: the invariant subspace is the whole space and the pair is (A, C)
    (radius 0 for binary-float input); the lower end is still proven and consistent with the
    independent MARE iteration."""
    import scipy.linalg as sla

    rng = np.random.default_rng(0)
    blocks = []
    for _ in range(6):
        r, th = rng.uniform(1.02, 1.3), rng.uniform(0.2, 3.0)
        blocks.append(r * np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]]))
    V = np.eye(12) + 0.3 * rng.normal(size=(12, 12))
    A = V @ sla.block_diag(*blocks) @ np.linalg.inv(V)
    s = System(A, rng.normal(size=(2, 12)), np.eye(12), np.eye(2))
    assert min(abs(np.linalg.eigvals(s.a))) > 1
    ub = bracket.upper_bound(s, tol=1e-6, method="newton")
    assert ub.lower_evidence.certified and "whole space" in ub.lower_evidence.statement
    enc = ub.solver["lower_enclosure"]
    assert enc["eigen_gap"] is None and enc["state_radius"] < 1e-250
    lo, hi = ub.interval
    assert ub.status == "determined" and hi - lo <= 1e-6 * (1 + 1e-9)
    a, b = _mare_threshold(s.a, s.c, lo - 0.05, min(1.0, hi + 0.05), 4e-3)
    assert lo <= b and hi >= a


def test_exact_offsets_enclose_decimal_entries():
    from fractions import Fraction

    s = System([["1/10", "2/3"], ["-7/5", "sqrt(2)"]], [["3/10", "1"]], 1, 1)
    lo, rad = floatcheck.exact_offsets(s.A, s.a)
    exact = [[Fraction(1, 10), Fraction(2, 3)], [Fraction(-7, 5), None]]
    for i in range(2):
        for j in range(2):
            if exact[i][j] is None:                      # not rational: the one-ulp radius
                assert lo[i, j] == 0 and rad[i, j] >= 2 ** -53 * abs(s.a[i, j])
                continue
            err = exact[i][j] - Fraction(s.a[i, j]) - Fraction(lo[i, j])
            assert lo[i, j] != 0 and abs(err) <= Fraction(rad[i, j])
            assert rad[i, j] < 1e-30


def test_decimal_input_is_certified_like_binary_input(large_path):
    """A file's decimals are exact rationals, not the binary floats: the offsets keep the
    enclosure as tight as for binary input (a one-ulp radius on A alone would not)."""
    b = random_unstable_system(40, 3, 2)
    s = System([[repr(float(v)) for v in row] for row in b.a],
               [[repr(float(v)) for v in row] for row in b.c], 1, 1)
    assert s.exact
    ub = bracket.upper_bound(s, tol=1e-6, method="newton")
    assert ub.certified and ub.lower_evidence.certified and ub.status == "determined"
    assert ub.solver["lower_enclosure"]["output_radius"] < 1e-12
    assert "offset" in ub.certificate.verified_by


def test_offset_product_encloses_the_exact_product():
    from fractions import Fraction

    rng = np.random.default_rng(11)
    texts = [[f"{v:.7f}" for v in row] for row in rng.normal(size=(4, 6))]
    s = System([[t for t in row] for row in texts[:4]] + [["0"] * 6] * 2, [["1"] * 6], 1, 1)
    off = floatcheck.exact_offsets(s.A, s.a)
    cols = rng.normal(size=(6, 2))
    mid, rad = floatcheck.offset_product(s.a, off, cols)
    for i in range(4):
        for j in range(2):
            exact = sum(Fraction(texts[i][q]) * Fraction(cols[q, j]) for q in range(6))
            assert abs(Fraction(mid[i, j]) - exact) <= Fraction(rad[i, j])
            assert rad[i, j] <= 1e-15 * (abs(mid[i, j]) + 1)
