"""Sinopoli et al. 2004, Lemma 1 (a)–(h) and Lemma 2, as properties of ``kfcrit.theory.covariance.riccati``.

Each property is a plain ``check_*`` function that raises :class:`PropertyViolation` when the
implementation violates it; the Hypothesis tests below call them on generated systems, and
``tests/hostile/test_faults.py`` calls the same functions on deliberately broken implementations to show
that they catch the fault. The checks call ``riccati.g`` etc. through the module, so a
monkeypatched implementation is what they test.

Tolerances (scale-aware, stated once): a matrix inequality M ⪰ 0 computed in float64 is accepted
when λ_min(M) ≥ −tol with

    tol = TOL_FACTOR · n · eps · scale,
    scale = ‖A‖² ‖X‖ + ‖Q‖ + κ(S) ‖A X C'‖² / λ_min(S) + ‖K‖² ‖S‖,   S = C X C' + R,

i.e. a multiple of the rounding error of forming the terms of g_p and φ (the solve with S loses
up to κ(S) digits). Identities (Lemma 1(a)) use the same tolerance entrywise.
"""
from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from hypothesis import example, given, target
from hypothesis import strategies as st

from kfcrit.theory.covariance import riccati

from ..strategies import (
    PAPER_FLOAT_CASES,
    RiccatiInput,
    SystemCase,
    bounded_floats,
    paper_riccati_input,
    pd_matrices,
    psd_matrices,
    riccati_inputs,
    systems,
)

EPS = float(np.finfo(float).eps)
TOL_FACTOR = 1024.0
"""Head-room over the a-priori rounding bound n·eps·scale (stated in the module docstring)."""


class PropertyViolation(AssertionError):
    """A property of the theory does not hold for the implementation under test."""


# --------------------------------------------------------------------------------------------
# tolerances and matrix-inequality assertions


def _norm(M: np.ndarray) -> float:
    return float(np.linalg.norm(M, 2)) if M.size else 0.0


def riccati_scale(case: SystemCase, *points: np.ndarray, K: np.ndarray | None = None) -> float:
    """scale = max over points X of ‖A‖²‖X‖ + ‖Q‖ + κ(S)‖AXC'‖²/λ_min(S) + ‖K‖²‖S‖ (+1 floor)."""
    A, C, Q, R = case.A, case.C, case.Q, case.R
    total = 1.0
    for X in points:
        S = C @ X @ C.T + R
        w = np.linalg.eigvalsh(0.5 * (S + S.T))
        kappa = w[-1] / w[0]
        AXC = A @ X @ C.T
        term = _norm(A) ** 2 * _norm(X) + _norm(Q) + kappa * _norm(AXC) ** 2 / w[0]
        if K is not None:
            term += _norm(K) ** 2 * w[-1]
        total = max(total, term)
    return total


def tolerance(n: int, scale: float) -> float:
    """tol = TOL_FACTOR · n · eps · scale."""
    return TOL_FACTOR * n * EPS * scale


def assert_psd(M: np.ndarray, tol: float, what: str) -> float:
    """Raise :class:`PropertyViolation` unless λ_min((M + M')/2) ≥ −tol; return λ_min / tol
    (the margin in tolerances, for Hypothesis ``target``)."""
    low = float(np.linalg.eigvalsh(0.5 * (M + M.T))[0])
    if not low >= -tol:
        raise PropertyViolation(f"{what}: λ_min = {low:.3e} < −{tol:.3e}")
    return low / tol


def assert_close(M1: np.ndarray, M2: np.ndarray, tol: float, what: str) -> None:
    """Raise :class:`PropertyViolation` unless max |M1 − M2| ≤ tol."""
    err = float(np.max(np.abs(M1 - M2), initial=0.0))
    if not err <= tol:
        raise PropertyViolation(f"{what}: max |difference| = {err:.3e} > {tol:.3e}")


# --------------------------------------------------------------------------------------------
# the properties, as plain check functions


def check_exact_symmetry(inp: RiccatiInput) -> None:
    """Invariant of kfcrit.theory.covariance.riccati: g_p, φ, f_0, f_1 return exactly symmetric matrices."""
    c = inp.case
    outputs = {
        "g_p": riccati.g(c.A, c.C, c.Q, c.R, inp.X, inp.p),
        "phi": riccati.phi(c.A, c.C, c.Q, c.R, inp.K, inp.X, inp.p),
        "f_0": riccati.f_loss(c.A, c.Q, inp.X),
        "f_1": riccati.f_arrival(c.A, c.C, c.Q, c.R, inp.X),
    }
    for name, M in outputs.items():
        if not np.array_equal(M, M.T):
            raise PropertyViolation(f"{name}(X) is not exactly symmetric: "
                                    f"max |M − M'| = {np.max(np.abs(M - M.T)):.3e}")


def check_mare_formula(inp: RiccatiInput) -> None:
    """g_p(X) = A X A' + Q − p A X C'(C X C' + R)^{-1} C X A' (eq. 16), f_0 = g_0, f_1 = g_1."""
    c, X, p = inp.case, inp.X, inp.p
    AXC = c.A @ X @ c.C.T
    Sinv = np.linalg.inv(c.C @ X @ c.C.T + c.R)
    expected = c.A @ X @ c.A.T + c.Q - p * AXC @ Sinv @ AXC.T
    tol = tolerance(c.n, riccati_scale(c, X))
    assert_close(riccati.g(c.A, c.C, c.Q, c.R, X, p), expected, tol, "g_p vs eq. (16)")
    assert_close(riccati.f_loss(c.A, c.Q, X), c.A @ X @ c.A.T + c.Q, tol, "f_0 vs A X A' + Q")
    assert_close(riccati.f_arrival(c.A, c.C, c.Q, c.R, X),
                 c.A @ X @ c.A.T + c.Q - AXC @ Sinv @ AXC.T, tol, "f_1 vs g_1")


def check_lemma1a(inp: RiccatiInput) -> None:
    """Lemma 1(a): with K_X = −A X C'(C X C' + R)^{-1}, g_p(X) = φ(K_X, X)."""
    c, X, p = inp.case, inp.X, inp.p
    KX = riccati.optimal_gain(c.A, c.C, c.R, X)
    expected_KX = -c.A @ X @ c.C.T @ np.linalg.inv(c.C @ X @ c.C.T + c.R)
    tol = tolerance(c.n, riccati_scale(c, X, K=KX))
    assert_close(KX, expected_KX, tol / max(1.0, _norm(c.C @ X @ c.C.T + c.R)), "K_X formula")
    assert_close(riccati.g(c.A, c.C, c.Q, c.R, X, p),
                 riccati.phi(c.A, c.C, c.Q, c.R, KX, X, p), tol, "g_p(X) vs φ(K_X, X)")


def check_lemma1b(inp: RiccatiInput) -> None:
    """Lemma 1(b): g_p(X) ⪯ φ(K, X) for every K, with the completed square
    φ(K, X) − g_p(X) = p (K − K_X) S (K − K_X)',  S = C X C' + R."""
    c, X, K, p = inp.case, inp.X, inp.K, inp.p
    G = riccati.g(c.A, c.C, c.Q, c.R, X, p)
    P = riccati.phi(c.A, c.C, c.Q, c.R, K, X, p)
    KX = -c.A @ X @ c.C.T @ np.linalg.inv(c.C @ X @ c.C.T + c.R)
    tol = tolerance(c.n, riccati_scale(c, X, K=K - KX) + riccati_scale(c, X, K=K))
    assert_psd(P - G, tol, "φ(K, X) − g_p(X)")
    D = K - KX
    assert_close(P - G, p * D @ (c.C @ X @ c.C.T + c.R) @ D.T, tol, "completed square")


def check_lemma1c(inp: RiccatiInput) -> float:
    """Lemma 1(c): X ⪯ Y ⇒ g_p(X) ⪯ g_p(Y)."""
    c = inp.case
    tol = tolerance(c.n, riccati_scale(c, inp.X, inp.Y))
    return assert_psd(riccati.g(c.A, c.C, c.Q, c.R, inp.Y, inp.p)
                      - riccati.g(c.A, c.C, c.Q, c.R, inp.X, inp.p), tol, "g_p(Y) − g_p(X)")


def check_lemma1d(inp: RiccatiInput) -> None:
    """Lemma 1(d): p ≤ p2 ⇒ g_p(X) ⪰ g_p2(X)."""
    c = inp.case
    tol = tolerance(c.n, riccati_scale(c, inp.X))
    assert_psd(riccati.g(c.A, c.C, c.Q, c.R, inp.X, inp.p)
               - riccati.g(c.A, c.C, c.Q, c.R, inp.X, inp.p2), tol, "g_p1(X) − g_p2(X)")


def check_lemma1e(inp: RiccatiInput) -> float:
    """Lemma 1(e): g_p(αX + (1−α)Y) ⪰ α g_p(X) + (1−α) g_p(Y)."""
    c, a = inp.case, inp.alpha
    Z = a * inp.X + (1 - a) * inp.Y

    def gp(M: np.ndarray) -> np.ndarray:
        return riccati.g(c.A, c.C, c.Q, c.R, M, inp.p)

    tol = tolerance(c.n, riccati_scale(c, inp.X, inp.Y, Z))
    return assert_psd(gp(Z) - a * gp(inp.X) - (1 - a) * gp(inp.Y), tol, "concavity defect")


def check_lemma1f(inp: RiccatiInput) -> None:
    """Lemma 1(f): g_p(X) ⪰ (1−p) A X A' + Q."""
    c, X, p = inp.case, inp.X, inp.p
    tol = tolerance(c.n, riccati_scale(c, X))
    assert_psd(riccati.g(c.A, c.C, c.Q, c.R, X, p) - (1 - p) * c.A @ X @ c.A.T - c.Q, tol,
               "g_p(X) − (1−p)AXA' − Q")


def gramian(A: np.ndarray, Q: np.ndarray, p: float, steps: int) -> np.ndarray:
    """W = Σ_{k<steps} (1−p)^k A^k Q A'^k (≻ 0 for steps ≥ n when (A, Q^{1/2}) controllable)."""
    W = np.zeros_like(Q)
    Ak = np.eye(A.shape[0])
    for k in range(steps):
        W = W + (1 - p) ** k * Ak @ Q @ Ak.T
        Ak = A @ Ak
    return W


def check_lemma1g(inp: RiccatiInput, X: np.ndarray | None = None) -> None:
    """Lemma 1(g), quantitative: if X ⪰ g_p(X) − εI (ε ≥ 0 the defect), then
    λ_min(X) ≥ λ_min(W_n) − ε Σ_{k<n} ‖A‖^{2k},  W_n = Σ_{k<n} (1−p)^k A^k Q A'^k.

    Derivation: X ⪰ (1−p)AXA' + Q − εI by (f); iterate n times and drop the PSD remainder.
    With ε = 0 and (A, Q^{1/2}) controllable this is X ≻ 0, Sinopoli's statement.
    """
    c, p = inp.case, inp.p
    X = inp.X if X is None else X
    n = c.n
    tol = tolerance(n, riccati_scale(c, X))
    eps_defect = max(0.0, -float(np.linalg.eigvalsh(X - riccati.g(c.A, c.C, c.Q, c.R, X, p))[0]))
    growth = sum(_norm(c.A) ** (2 * k) for k in range(n))
    floor = float(np.linalg.eigvalsh(gramian(c.A, c.Q, p, n))[0])
    low = float(np.linalg.eigvalsh(X)[0])
    if not low >= floor - (eps_defect + tol) * growth:
        raise PropertyViolation(f"Lemma 1(g): λ_min(X) = {low:.3e} below λ_min(W_n) = "
                                f"{floor:.3e} − defect {eps_defect:.3e}·{growth:.3e}")


def check_lemma1h(inp: RiccatiInput, points: list[np.ndarray], weights: list[float]) -> None:
    """Lemma 1(h) in sample form: for a discrete random X (points, weights),
    (1−p) A E[X] A' + Q ⪯ E[g_p(X)] ⪯ g_p(E[X])."""
    c, p = inp.case, inp.p
    w = np.asarray(weights, dtype=float) / float(np.sum(weights))
    EX = sum(wi * Xi for wi, Xi in zip(w, points))
    Eg = sum(wi * riccati.g(c.A, c.C, c.Q, c.R, Xi, p) for wi, Xi in zip(w, points))
    tol = tolerance(c.n, riccati_scale(c, EX, *points))
    assert_psd(Eg - (1 - p) * c.A @ EX @ c.A.T - c.Q, tol, "E[g(X)] − (1−p)A E[X] A' − Q")
    assert_psd(riccati.g(c.A, c.C, c.Q, c.R, EX, p) - Eg, tol, "g(E[X]) − E[g(X)]")


def mare_orbit(case: SystemCase, X0: np.ndarray, p: float, steps: int) -> list[np.ndarray]:
    """X_0, g_p(X_0), …, g_p^steps(X_0) computed with the implementation under test."""
    out = [X0]
    for _ in range(steps):
        out.append(riccati.g(case.A, case.C, case.Q, case.R, out[-1], p))
    return out


def check_lemma2(case: SystemCase, X0: np.ndarray, Y0: np.ndarray, p: float,
                 steps: int = 12) -> None:
    """Lemma 2 for h = g_p (monotone by Lemma 1(c)), X_0 ⪯ Y_0:
    X_1 ⪰ X_0 ⇒ X_{t+1} ⪰ X_t;  X_1 ⪯ X_0 ⇒ X_{t+1} ⪯ X_t;  X_t ⪯ Y_t for all t."""
    xs = mare_orbit(case, X0, p, steps)
    ys = mare_orbit(case, Y0, p, steps)
    tol0 = tolerance(case.n, riccati_scale(case, X0, Y0, xs[1]))
    up = float(np.linalg.eigvalsh(xs[1] - xs[0])[0]) >= 0.0
    down = float(np.linalg.eigvalsh(xs[0] - xs[1])[0]) >= 0.0
    for t in range(steps):
        # errors accumulate along the orbit: tolerance grows with t and with the iterates' size
        tol = (t + 1) * tolerance(case.n, riccati_scale(case, xs[t], xs[t + 1], ys[t])) + tol0
        if up:
            assert_psd(xs[t + 1] - xs[t], tol, f"Lemma 2 (non-decreasing), t = {t}")
        if down:
            assert_psd(xs[t] - xs[t + 1], tol, f"Lemma 2 (non-increasing), t = {t}")
        assert_psd(ys[t] - xs[t], tol, f"Lemma 2 (order preserved), t = {t}")


def exact_mare(A: sp.Matrix, C: sp.Matrix, Q: sp.Matrix, R: sp.Matrix, X: sp.Matrix,
               p: sp.Expr) -> sp.Matrix:
    """g_p(X) in exact rational arithmetic (independent of kfcrit.theory.covariance.riccati)."""
    S = C * X * C.T + R
    return A * X * A.T + Q - p * A * X * C.T * S.inv() * C * X * A.T


def check_lemma1g_exact(A: sp.Matrix, C: sp.Matrix, Q: sp.Matrix, R: sp.Matrix, X: sp.Matrix,
                        p: sp.Expr) -> None:
    """Lemma 1(g), exact contrapositive: (A, Q^{1/2}) controllable and X ⪰ 0 singular ⇒
    X − g_p(X) is not PSD (decided in rational arithmetic)."""
    n = A.shape[0]
    ctrb = sp.Matrix.hstack(*[A ** k * Q for k in range(n)])
    if ctrb.rank() < n or X.det() != 0:
        return
    if (X - exact_mare(A, C, Q, R, X, p)).is_positive_semidefinite:
        raise PropertyViolation("Lemma 1(g): a singular X satisfies X ⪰ g_p(X)")


# --------------------------------------------------------------------------------------------
# Hypothesis tests

PAPER_EXAMPLES = [paper_riccati_input(name) for name in
                  ("sinopoli-scalar", "sinopoli-general", "sinopoli-single-unstable",
                   "mo-degenerate-diagonal", "rotation-third-turn")]


def with_paper_examples(test):
    """Decorate a test taking ``inp`` with ``@example`` for each of the papers' systems."""
    for inp in PAPER_EXAMPLES:
        test = example(inp=inp)(test)
    return test


@given(inp=riccati_inputs())
@with_paper_examples
def test_exact_symmetry(inp: RiccatiInput) -> None:
    check_exact_symmetry(inp)


@given(inp=riccati_inputs())
@with_paper_examples
def test_mare_formula(inp: RiccatiInput) -> None:
    check_mare_formula(inp)


@given(inp=riccati_inputs())
@with_paper_examples
def test_lemma1a_gain_attains_g(inp: RiccatiInput) -> None:
    check_lemma1a(inp)


@given(inp=riccati_inputs())
@with_paper_examples
def test_lemma1b_g_is_min_over_gains(inp: RiccatiInput) -> None:
    check_lemma1b(inp)


@given(inp=riccati_inputs())
@with_paper_examples
def test_lemma1c_monotone(inp: RiccatiInput) -> None:
    target(-min(check_lemma1c(inp), 1e6), label="closeness to a monotonicity violation")


@given(inp=riccati_inputs())
@with_paper_examples
def test_lemma1d_decreasing_in_p(inp: RiccatiInput) -> None:
    check_lemma1d(inp)


@given(inp=riccati_inputs())
@with_paper_examples
def test_lemma1e_concave(inp: RiccatiInput) -> None:
    target(-min(check_lemma1e(inp), 1e6), label="closeness to a concavity violation")


@given(inp=riccati_inputs())
@with_paper_examples
def test_lemma1f_lower_bound(inp: RiccatiInput) -> None:
    check_lemma1f(inp)


@given(inp=riccati_inputs())
@with_paper_examples
def test_lemma1g_quantitative_on_any_x(inp: RiccatiInput) -> None:
    check_lemma1g(inp)


@st.composite
def stable_supersolutions(draw: st.DrawFn) -> tuple[RiccatiInput, np.ndarray]:
    """(input, X) with X ⪰ g_p(X) by construction: X = A X A' + Q + E (A stable, E ⪰ 0).

    Then g_p(X) ⪯ A X A' + Q ⪯ X for every p, C, R.
    """
    inp = draw(riccati_inputs(kind="stable"))
    c = inp.case
    E = draw(psd_matrices(c.n))
    n = c.n
    # vec(X) = (I − A⊗A)^{-1} vec(Q + E): the Lyapunov equation, solved directly
    rhs = (c.Q + E).reshape(-1)
    X = np.linalg.solve(np.eye(n * n) - np.kron(c.A, c.A), rhs).reshape(n, n)
    return inp, 0.5 * (X + X.T)


@given(data=stable_supersolutions())
def test_lemma1g_supersolutions_are_definite(data: tuple[RiccatiInput, np.ndarray]) -> None:
    inp, X = data
    check_lemma1g(inp, X)
    # and the qualitative statement: X ≻ 0 (Q ≻ 0 here, so W_n ⪰ Q ≻ 0)
    assert np.linalg.eigvalsh(X)[0] > 0


@given(inp=riccati_inputs(max_n=3), data=st.data())
@example(inp=PAPER_EXAMPLES[1], data=None)
@example(inp=PAPER_EXAMPLES[2], data=None)
def test_lemma1h_jensen_sample_form(inp: RiccatiInput, data: st.DataObject | None) -> None:
    n = inp.case.n
    if data is None:  # @example: a two-point distribution
        points, weights = [inp.X, inp.Y], [0.3, 0.7]
    else:
        points = data.draw(st.lists(psd_matrices(n), min_size=1, max_size=6), label="points")
        weights = data.draw(st.lists(bounded_floats(0.01, 1.0), min_size=len(points),
                                     max_size=len(points)), label="weights")
    check_lemma1h(inp, points, weights)


@given(inp=riccati_inputs())
@with_paper_examples
def test_lemma2_orbit_from_zero_and_order(inp: RiccatiInput) -> None:
    # X_0 = 0 gives X_1 = Q ⪰ X_0: the non-decreasing case; Y_0 = Y ⪰ 0 = X_0: order preserved
    c = inp.case
    check_lemma2(c, np.zeros((c.n, c.n)), inp.Y, inp.p)


@given(data=stable_supersolutions())
def test_lemma2_orbit_from_supersolution(data: tuple[RiccatiInput, np.ndarray]) -> None:
    # X_0 ⪰ g_p(X_0) by construction: the non-increasing case; Y_0 = X_0 + Y ⪰ X_0
    inp, X0 = data
    assert np.linalg.eigvalsh(X0 - riccati.g(inp.case.A, inp.case.C, inp.case.Q, inp.case.R,
                                             X0, inp.p))[0] >= -1e-9 * np.linalg.norm(X0)
    check_lemma2(inp.case, X0, X0 + inp.Y, inp.p)


# --- Lemma 1(g), exact ------------------------------------------------------------------------

@st.composite
def exact_lemma1g_inputs(draw: st.DrawFn) -> tuple[sp.Matrix, ...]:
    """Small exact systems with a rank-one Q = b b' and a singular PSD X = u u'."""
    n = draw(st.integers(1, 3))
    ints = st.integers(-2, 2)
    A = sp.Matrix(n, n, draw(st.lists(ints, min_size=n * n, max_size=n * n)))
    b = sp.Matrix(n, 1, draw(st.lists(ints, min_size=n, max_size=n)))
    C = sp.Matrix(1, n, draw(st.lists(ints, min_size=n, max_size=n)))
    u = sp.Matrix(n, 1, draw(st.lists(ints, min_size=n, max_size=n)))
    X = u * u.T if n > 1 else sp.zeros(1, 1)
    p = sp.Rational(draw(st.integers(0, 8)), 8)
    return A, C, b * b.T, sp.Matrix([[sp.Rational(draw(st.integers(1, 5)), 2)]]), X, p


@given(data=exact_lemma1g_inputs())
def test_lemma1g_exact_singular_x_is_never_a_supersolution(data: tuple[sp.Matrix, ...]) -> None:
    check_lemma1g_exact(*data)


def test_lemma1g_exact_paper_case_has_controllable_pair() -> None:
    # the scalar example: X = 0 is singular, g_p(0) = Q = 1 > 0, so 0 ⪰ g_p(0) fails
    c = {k: sp.Matrix(v) for k, v in
         (("A", [[sp.Rational(-5, 4)]]), ("C", [[1]]), ("Q", [[1]]), ("R", [[sp.Rational(5, 2)]]))}
    X = sp.zeros(1, 1)
    assert not (X - exact_mare(c["A"], c["C"], c["Q"], c["R"], X, sp.Rational(1, 2)))[0] >= 0
    check_lemma1g_exact(c["A"], c["C"], c["Q"], c["R"], X, sp.Rational(1, 2))


# --- the tolerances themselves: they must not be so loose that they hide real errors ------------

@pytest.mark.parametrize("name", sorted(PAPER_FLOAT_CASES))
def test_tolerance_is_far_below_the_scale_of_the_terms(name: str) -> None:
    case = PAPER_FLOAT_CASES[name]
    X = np.eye(case.n)
    scale = riccati_scale(case, X)
    assert tolerance(case.n, scale) < 1e-9 * scale


@given(case=systems(max_n=3), Q=st.integers(1, 3).flatmap(lambda n: pd_matrices(n)))
def test_systems_strategy_has_the_constructed_spectrum(case: SystemCase, Q: np.ndarray) -> None:
    # the strategy's reference spectral radius agrees with an eigen-solver (cond(V) ≤ 10, so the
    # eigenvalues are well conditioned except for equal-modulus defective-looking clusters)
    rho = max(abs(np.linalg.eigvals(case.A)))
    assert abs(rho - case.spectrum.radius) <= 1e-6 * max(1.0, case.spectrum.radius)
    assert np.linalg.eigvalsh(Q)[0] > 0
