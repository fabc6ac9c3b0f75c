"""Critical values: the paper cases, hand-derived cases, robustness, invariances (Hypothesis).

Every expected value comes from tests/data/cases/expected.json (derived from the papers) or
from a hand derivation written next to the case with MATH.md §4:
non-degenerate p_c = 1 − |λ_1|^{-2}; degenerate pair p_c = 1 − |λ_1|^{-2q/(q−1)}.
"""
from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from kfcrit.io.systemfile import read_system_file
from kfcrit.model.channels import Bernoulli, GilbertElliott
from kfcrit.model.exprparse import parse_expression
from kfcrit.model.system import System
from kfcrit.theory.critical import classify as critical_classify
from kfcrit.theory.critical import robust as critical_robust
from kfcrit.theory.critical import section as critical
from kfcrit.theory.critical import values as critical_values
from kfcrit.theory.structure.eigen import eigen_structure

from ..conftest import SHARED_CASES

ROOT = Path(__file__).resolve().parents[2]
REPORTS = ROOT / "reports"
EXPECTED = json.loads((SHARED_CASES / "expected.json").read_text())
CASES = sorted(k for k in EXPECTED if not k.startswith("_"))
CONTRACT = {"classification", "critical_value", "robust_critical_value", "lower_bound",
            "block_lower_bound", "structure", "theory", "warnings"}


def _sys(A, C, Q=None, R=None, Sigma0=None) -> System:
    n, m = len(A), len(C)
    Q = Q if Q is not None else np.eye(n).astype(int).tolist()
    R = R if R is not None else np.eye(m).astype(int).tolist()
    return System(A, C, Q, R, Sigma0)


def _same(expression: str, expected: str) -> bool:
    a = parse_expression(expression, "got")
    b = parse_expression(expected, "expected")
    return sp.simplify(a - b) == 0 and sp.simplify(sp.sympify(expression) - b) == 0


# --------------------------------------------------------------------------- paper cases

@pytest.mark.parametrize("name", CASES)
def test_expected_cases(name):
    spec = read_system_file(REPORTS / name)
    exp = EXPECTED[name]
    d = critical.critical_section(spec.system, channel=spec.channel)
    assert CONTRACT <= set(d)
    json.dumps(d, allow_nan=False)
    assert d["classification"] == exp["classification"]
    cv = d["critical_value"]
    assert cv["exact"] is True
    assert _same(cv["expression"], exp["critical_value"])
    assert abs(cv["value"] - float(parse_expression(exp["critical_value"], "e"))) <= 1e-12
    assert _same(d["lower_bound"]["expression"], exp["lower_bound"])
    assert d["robust_critical_value"] is None  # exact cases far from any other decision
    if "q" in exp:
        pairs = d["structure"]["equal_modulus_pairs"]
        assert [p["q"] for p in pairs if p["degenerate"]] == [exp["q"]]


def test_lower_bound_interface():
    spec = read_system_file(REPORTS / "sinopoli-general.yaml")
    lb = critical_classify.lower_bound(spec.system)
    assert set(lb) == {"value", "expression"} and _same(lb["expression"], "9/25")


# --------------------------------------------------------------------------- hand derivations

HAND = [
    # ρ(A) = 1/2 < 1: p_c = 0
    ("stable", [["1/2", 1], [0, "1/3"]], [[1, 0]], "stable", "0"),
    # rotation by π/2 of modulus 1, one output: critically stable degenerate pair, p_c = 0
    ("critical rotation", [[0, -1], [1, 0]], [[1, 0]], "degenerate-second-order", "0"),
    # ±2j: θ = π/2, z = e^{∓jπ} = −1, q = 2: 1 − 2^{−4} = 15/16
    ("quarter turn", [[0, -2], [2, 0]], [[1, 0]], "degenerate-second-order", "15/16"),
    # 1 ± j = √2 e^{±jπ/4}, z = e^{∓jπ/2}, q = 4: 1 − (√2)^{−8/3} = 1 − 2^{−4/3}
    ("eighth turn", [[1, -1], [1, 1]], [[1, 0]], "degenerate-second-order", "1 - 2**(-4/3)"),
    # 3 ± 4j, |λ| = 5, angle atan(4/3) irrational: 1 − 1/25
    ("atan(4/3)", [[3, -4], [4, 3]], [[1, 0]], "degenerate-second-order", "24/25"),
    # 2 e^{±2πj/5}: z = e^{∓4πj/5}, q = 5: 1 − 2^{−2·5/4} = 1 − 2^{−5/2}
    ("fifth turn", [["2*cos(2*pi/5)", "-2*sin(2*pi/5)"], ["2*sin(2*pi/5)", "2*cos(2*pi/5)"]],
     [[1, 0]], "degenerate-second-order", "1 - 2**(-5/2)"),
    # T diag(2, −2) T^{-1} with T = [[1, 1], [0, 1]] is [[2, 4], [0, −2]]; C = [1, 1] T^{-1}
    # = [1, 0]: the Mo–Sinopoli degenerate pair in disguise, 15/16
    ("similar pair", [[2, 4], [0, -2]], [[1, 0]], "degenerate-second-order", "15/16"),
    # same pair with a stable third state (Thm 3 ≥, Thm 8 ≤): still 15/16
    ("pair + stable", [[2, 0, 0], [0, -2, 0], [0, 0, "1/2"]], [[1, 1, 1]],
     "degenerate-second-order", "15/16"),
    # C invertible, Jordan block: Sinopoli §IV, p_c = p_low = 3/4
    ("jordan, C = I", [[2, 1], [0, 2]], [[1, 0], [0, 1]], "non-diagonalizable", "3/4"),
    # one unstable eigenvalue, Jordan block among the stable ones: Sinopoli §IV, 1 − 1/9
    ("single unstable", [[3, 0, 0], [0, "1/2", 1], [0, 0, "1/2"]], [[1, 1, 0]],
     "non-diagonalizable", "8/9"),
]


@pytest.mark.parametrize("label, A, C, cls, expected", HAND, ids=[h[0] for h in HAND])
def test_hand_cases(label, A, C, cls, expected):
    d = critical.critical_section(_sys(A, C))
    assert d["classification"] == cls
    assert _same(d["critical_value"]["expression"], expected)
    assert abs(d["critical_value"]["value"] - float(sp.N(parse_expression(expected, "e")))) \
        <= 1e-12
    assert d["block_lower_bound"]["value"] >= d["lower_bound"]["value"] - 1e-15


def test_not_detectable():
    d = critical.critical_section(_sys([[2, 0], [0, "1/2"]], [[0, 1]]))
    assert d["classification"] == "not-detectable"
    assert d["critical_value"]["value"] is None
    assert "diverges" in d["critical_value"]["reason"]


def test_three_equal_moduli_bracket():
    # 2 and 2 e^{±2πj/3}, one output: a degenerate equi-block of order 3, no closed form.
    # Pairs: (2e^{2πj/3}, 2e^{−2πj/3}) has z of order 3 → 1 − 2^{−3} = 7/8; the pairs with the
    # real eigenvalue have z of order 3 as well → 7/8. Block lower bound 7/8 > p_low = 3/4.
    A = [[2, 0, 0], [0, -1, "-sqrt(3)"], [0, "sqrt(3)", -1]]
    d = critical.critical_section(_sys(A, [[1, 1, 0]]))
    assert d["classification"] == "degenerate"
    assert d["critical_value"]["value"] is None
    assert _same(d["block_lower_bound"]["expression"], "7/8")
    assert _same(d["lower_bound"]["expression"], "3/4")


def test_jordan_block_bracket():
    d = critical.critical_section(_sys([[2, 1], [0, 2]], [[1, 0]]))
    assert d["classification"] == "non-diagonalizable"
    assert d["critical_value"]["value"] is None
    assert _same(d["block_lower_bound"]["expression"], "3/4")


def test_numeric_path_cross_check():
    # Second method: the float path on the same systems gives the same values to 1e-9.
    for _, A, C, cls, expected in HAND[:8]:
        s = _sys(A, C)
        st_num = eigen_structure(s, force_numeric=True)
        d = critical.critical_section(s, structure=st_num)
        assert d["structure"]["path"] == "numeric"
        assert d["classification"] == cls
        assert abs(d["critical_value"]["value"] - float(sp.N(parse_expression(expected, "e")))) \
            <= 1e-9


def test_expressions_are_parseable_with_latex():
    d = critical.critical_section(_sys([[1, -1], [1, 1]], [[1, 0]]))
    cv = d["critical_value"]
    parse_expression(cv["expression"], "x")
    assert cv["latex"] == sp.latex(sp.sympify(cv["expression"]))


# --------------------------------------------------------------------------- robust value

@pytest.mark.parametrize("r3", [1.7320508075688772, "1.7320508075688772"],
                         ids=["binary float", "decimal text"])
def test_third_turn_with_floats(r3):
    # √3 entered as the float 1.7320508075688772: the exact rational is not √3, so φ/2π is
    # irrational (Thm 10, p_c = 1 − 1/|λ|² ≈ 3/4), but within 1e-9 of 1/3 (q = 3, p_c ≈ 7/8).
    neg = -r3 if isinstance(r3, float) else f"-{r3}"
    s = _sys([[1, neg], [r3, 1]], [[1, 0]])
    d = critical.critical_section(s, tolerance=1e-9)
    assert d["classification"] == "degenerate-second-order"
    assert abs(d["critical_value"]["value"] - 0.75) < 1e-12
    rob = d["robust_critical_value"]
    assert rob is not None and abs(rob["value"] - 0.875) < 1e-12 and rob["tolerance"] == 1e-9
    assert "q = 3" in rob["nearby_case"]
    assert any("q = 3" in w for w in d["warnings"])
    # the nearby case is |λ| = 2, q = 3 exactly: 1 − 4^{−3/2} = 7/8 (not the entered modulus)
    assert _same(rob["expression"], "7/8")
    # with a much smaller tolerance the nearby rational is out of reach
    assert critical.critical_section(s, tolerance=1e-20)["robust_critical_value"] is None


def test_moduli_nearly_equal():
    # 2 and −(2 − 1e−12), C = [1, 1]: non-degenerate (p_c = 3/4) but within 1e-9 of the
    # degenerate pair diag(2, −2) (q = 2, p_c = 15/16).
    d = critical.critical_section(_sys([[2, 0], [0, "-(2 - 1e-12)"]], [[1, 1]]))
    assert d["classification"] == "non-degenerate" and _same(d["critical_value"]["expression"],
                                                             "3/4")
    assert _same(d["robust_critical_value"]["expression"], "15/16")
    assert d["warnings"]


def test_nearly_equal_real_eigenvalues_flag_detectability():
    # 2 and 2 − 1e−12 through one output: nearby, the repeated eigenvalue 2 with one output is
    # not detectable, so no p < 1 is safe: robust value 1.
    d = critical.critical_section(_sys([[2, 0], [0, "2 - 1e-12"]], [[1, 1]]))
    assert d["robust_critical_value"]["value"] == 1.0
    assert "not detectable" in d["robust_critical_value"]["nearby_case"]


def test_near_rank_drop():
    # diag(2, −2) with C = [[1, 1], [0, 1e−12]]: rank 2 exactly, rank 1 within 1e-9.
    d = critical.critical_section(_sys([[2, 0], [0, -2]], [[1, 1], [0, "1e-12"]]))
    assert d["classification"] == "non-degenerate"
    assert _same(d["robust_critical_value"]["expression"], "15/16")


def test_exact_irrational_angle_not_flagged():
    # atan(4/3): no rational with q ≤ 1000 within 1e-9 of φ/2π.
    assert critical.critical_section(_sys([[3, -4], [4, 3]], [[1, 0]]))[
        "robust_critical_value"] is None


# --------------------------------------------------------------------------- theory

def test_theory_moment_thresholds_and_channels():
    spec = read_system_file(REPORTS / "mo-nondegenerate-four.yaml")
    th = critical.critical_section(spec.system, channel=spec.channel)["theory"]
    mt = {m["q"]: m for m in th["moment_thresholds"]}
    # 1 − 3^{−2} = 8/9, 1 − 3^{−4} = 80/81; Cor. 2 applies (non-degenerate, all unstable)
    assert _same(mt[1]["expression"], "8/9") and _same(mt[2]["expression"], "80/81")
    assert mt[1]["applies"] and mt[2]["applies"]
    assert "stochastically bounded" in th["stochastic_boundedness"]
    assert any("Consequence" in s for s in th["almost_sure"])
    # single-unstable case has stable eigenvalues: Cor. 2 does not apply
    spec = read_system_file(REPORTS / "sinopoli-single-unstable.yaml")
    th = critical.critical_section(spec.system)["theory"]
    assert not any(m["applies"] for m in th["moment_thresholds"])
    ge = GilbertElliott(sp.Rational(1, 10), sp.Rational(1, 2))
    th = critical.critical_section(spec.system, channel=ge)["theory"]
    assert "Gilbert" in th["almost_sure"][0]
    th = critical.critical_section(spec.system, channel=Bernoulli(sp.Integer(1)))["theory"]
    assert "standard Kalman filter" in th["almost_sure"][0]


# --------------------------------------------------------------------------- invariances

BASES = [
    ([[2, 0], [0, -2]], [[1, 1]]),
    ([[0, -2], [2, 0]], [[1, 0]]),
    ([[1, -1], [1, 1]], [[1, 2]]),
    ([[2, 0, 0], [0, -2, 0], [0, 0, 3]], [[1, 1, 0], [0, 1, 1]]),
    ([["5/4", 0], [1, "11/10"]], [[1, 1]]),
    ([[2, 1], [0, 2]], [[1, 0]]),
]


@st.composite
def unimodular(draw, n):
    """T = L·U with unit triangular integer factors: det T = 1, exact rational inverse."""
    L = sp.eye(n)
    U = sp.eye(n)
    for i in range(n):
        for j in range(i):
            L[i, j] = draw(st.integers(-2, 2))
            U[j, i] = draw(st.integers(-2, 2))
    return L * U


@settings(max_examples=25)
@given(data=st.data())
def test_similarity_invariance(data):
    A, C = BASES[data.draw(st.integers(0, len(BASES) - 1))]
    base = critical.critical_section(_sys(A, C))
    n = len(A)
    T = data.draw(unimodular(n))
    Am = T * sp.Matrix([[parse_expression(str(v), "A") for v in r] for r in A]) * T.inv()
    Cm = sp.Matrix(C) * T.inv()
    moved = critical.critical_section(System(Am, Cm, sp.eye(n), sp.eye(len(C))))
    assert moved["classification"] == base["classification"]
    for key in ("critical_value", "block_lower_bound"):
        if base[key]["value"] is None:
            assert moved[key]["value"] is None
        else:
            assert _same(moved[key]["expression"], base[key]["expression"])


@settings(max_examples=25)
@given(st.integers(0, len(BASES) - 1), st.fractions(min_value=1/100, max_value=100),
       st.fractions(min_value=1/100, max_value=100), st.fractions(min_value=1/100,
                                                                 max_value=100),
       st.integers(-3, 3))
def test_noise_scaling_invariance(k, sq, sr, s0, off):
    # Mo–Sinopoli Thm 2: p_c depends on (A, C) only (Q, R, Σ0 ≻ 0).
    A, C = BASES[k]
    n, m = len(A), len(C)
    base = critical.critical_section(_sys(A, C))
    L = sp.eye(n)
    if n > 1:
        L[1, 0] = off
    Q = (L * L.T) * sp.Rational(sq.numerator, sq.denominator)
    moved = critical.critical_section(System(A, C, Q, sp.eye(m) * sp.Rational(sr.numerator,
                                                                             sr.denominator),
                                             sp.eye(n) * sp.Rational(s0.numerator,
                                                                     s0.denominator)))
    assert moved["classification"] == base["classification"]
    assert moved["critical_value"]["value"] == base["critical_value"]["value"]


EIGS = [2, -2, 3, -3, sp.Rational(3, 2), sp.Rational(1, 2), 1, -1]


@settings(max_examples=30)
@given(st.lists(st.sampled_from(EIGS), min_size=2, max_size=4, unique=True),
       st.data())
def test_block_monotonicity(eigs, data):
    # Mo–Sinopoli Thm 3: p_c(A, C) ≥ p_c(A_I, C_I) for every index set I (diagonal form).
    n = len(eigs)
    m = data.draw(st.integers(1, 2))
    C = [[data.draw(st.integers(-2, 2)) for _ in range(n)] for _ in range(m)]
    full = critical.critical_section(_sys(sp.diag(*eigs).tolist(), C))
    if full["classification"] == "not-detectable":
        return
    known_full = full["critical_value"]["value"]
    floor_full = full["block_lower_bound"]["value"]
    for mask in range(1, 2**n - 1):
        idx = [i for i in range(n) if mask >> i & 1]
        sub = critical.critical_section(_sys(sp.diag(*[eigs[i] for i in idx]).tolist(),
                                             [[row[i] for i in idx] for row in C]))
        v = sub["critical_value"]["value"]
        if v is None:
            continue
        if known_full is not None:
            assert known_full >= v - 1e-12
        assert floor_full >= v - 1e-12


def test_cubic_eigenvalues_exact_path():
    # Companion matrix of f = x³ − 2x² + 5x − 2 (no rational root: f(±1), f(±2) ≠ 0, so
    # irreducible): one real root r ∈ (0, 1) and a complex pair with |λ|² = 2/r > 1 (product of
    # the roots is 2). One output: degenerate pair; its angle is irrational (z = λ̄/λ is not a
    # root of unity: checked exactly), so Thm 10 gives p_c = 1 − 1/|λ|² = 1 − r/2.
    A = [[0, 0, 2], [1, 0, -5], [0, 1, 2]]
    d = critical.critical_section(_sys(A, [[1, 0, 0]]))
    assert d["structure"]["path"] == "exact"
    assert d["classification"] == "degenerate-second-order"
    r = min(np.roots([1, -2, 5, -2]), key=lambda z: abs(z.imag)).real
    assert abs(d["critical_value"]["value"] - (1 - r / 2)) <= 1e-12
    assert d["structure"]["equal_modulus_pairs"][0]["q"] is None


def test_sextic_conjugate_pairs_with_rational_angle():
    # λ = s(1 + j√3) = 2s e^{jπ/3} for the three real roots s of y³ − 3y − 1 (|s| distinct):
    # λ is a root of Res_y(y³ − 3y − 1, x² − 2xy + 4y²) = x⁶ + 12x⁴ + 16x³ + 144x² + 96x + 64,
    # irreducible of degree 6. Each conjugate pair has z = e^{∓2jπ/3} (q = 3). With one output
    # both unstable pairs are degenerate: no closed form (two equi-blocks), block lower bound
    # 1 − (2 s_max)^{−2·3/2} = 1 − (2 s_max)^{−3} (Thm 3 with Thm 9).
    c = [1, 0, 12, 16, 144, 96, 64]
    n = 6
    A = [[0] * n for _ in range(n)]
    for i in range(1, n):
        A[i][i - 1] = 1
    for i in range(n):
        A[i][n - 1] = -c[n - i]
    d = critical.critical_section(_sys(A, [[1, 0, 0, 0, 0, 0]]))
    assert d["structure"]["path"] == "exact"
    assert d["classification"] == "degenerate"
    assert [p["q"] for p in d["structure"]["equal_modulus_pairs"]] == [3, 3]
    s_max = max(abs(np.roots([1, 0, -3, -1])))
    assert abs(d["block_lower_bound"]["value"] - (1 - (2 * s_max) ** -3)) <= 1e-12


# --------------------------------------------------------------------------- reason texts

def test_float_third_turn_reason_shows_computed_modulus():
    # √3 as the binary float 1.7320508075688772: |λ|² = 1 + 1.7320508075688772² is not 4, so
    # |λ| is not 2 — the reason must not print "= 2" (it did), but the float as computed
    r3 = 1.7320508075688772
    s = System(np.array([[1.0, -r3], [r3, 1.0]]), np.array([[1.0, 0.0]]), np.eye(2), np.eye(1))
    reason = critical.critical_section(s)["critical_value"]["reason"]
    assert "= 2," not in reason and "= 2 " not in reason
    assert "1.9999999999999998" in reason
    assert "binary-float input" in reason          # how the decision was made is stated
    # numeric path: the decision tolerance is stated
    st_num = eigen_structure(s, force_numeric=True)
    reason = critical.critical_section(s, structure=st_num)["critical_value"]["reason"]
    # the numeric path states the tolerance of its headline decisions: float64 resolution
    # (64 ulp · κ), the user's tolerance only widens the robust neighbourhood
    assert "relative tolerance 1.42109e-14" in reason and "= 2," not in reason


def test_reason_texts_use_unicode_math():
    # the rotation by π/3 with C = [1 0]: observability index 2 (C and C A span R²), so the
    # almost-sure text names h²(M₀); the moment note reads |λ₁|^(−2q)
    d = critical.critical_section(_sys([[1, "-sqrt(3)"], ["sqrt(3)", 1]], [[1, 0]]),
                                  channel=Bernoulli(sp.Rational(9, 10)))
    th = d["theory"]
    text = " ".join(th["almost_sure"]) + th["moment_thresholds_note"]
    assert "h²(M₀)" in text and "|λ₁|^(−2q)" in text and "Iₒ = 2" in text
    for ascii_math in ("h^2", "M_0", "λ_1", "P_k", "I_o"):
        assert ascii_math not in text, ascii_math
    d = critical.critical_section(_sys([[2, 0], [0, 3]], [[1, 0], [0, 1]]))
    assert "|λ₁|⁻²" in d["critical_value"]["reason"]


def test_long_exact_numbers_keep_an_exact_expression() -> None:
    """A rational with 70-digit parts is written exactly (never as a float) and reads back."""
    from kfcrit.theory.critical.values import Num

    x = sp.Rational(10**70 + 7, 3 * 10**65 + 1)
    num = Num(float(x), x)
    text = num.expression
    assert "." not in text and "e" not in text.lower()
    assert parse_expression(text, field="t") == x


@pytest.mark.parametrize("bad", [-1e-3, 0.2, float("nan"), "0.01"])
def test_tolerance_message_names_its_range(bad) -> None:
    from kfcrit.errors import InputError
    from kfcrit.theory.critical.section import critical_value

    with pytest.raises(InputError, match=r"\[0, 0\.1\]"):
        critical_value(System([[2]], [[1]], Q=1, R=1), tolerance=bad)


# --------------------------------------------------------------------------- auditor's gaps

def test_eigenvalue_sensitivity_flags_nonnormal_near_pair():
    # A = [[2, 4000], [0, −1.999999]], C = [1, 0]: moduli 2 ≠ 1.999999, so non-degenerate,
    # p_c = 1 − 1/4 = 3/4 (Thm 4). But A + E with E = −5e-7·I, ‖E‖/‖A‖ ≈ 5e-7/4000 ≈ 1.25e-10
    # ≤ 1e-9, has eigenvalues ±1.9999995: an equal-modulus pair, z = −1 (q = 2), rank C_I = 1
    # (one output), so Thm 9 gives 1 − 1.9999995^{−4} ≈ 15/16; the robust value must see it.
    A = [[2, 4000], [0, "-1.999999"]]
    d = critical.critical_section(_sys(A, [[1, 0]]))
    assert d["classification"] == "non-degenerate" and _same(d["critical_value"]["expression"],
                                                             "3/4")
    rob = d["robust_critical_value"]
    assert rob is not None and _same(rob["expression"], "15/16") and "q = 2" in rob["nearby_case"]
    assert rob["value"] > 0.9          # a channel with p = 0.9 is not robustly mean-stable
    # the flagged neighbour is real: A + E is the degenerate pair with p_c = 1 − 1.9999995^{−4}
    E_rel = 5e-7 / np.linalg.norm(np.array([[2, 4000], [0, -1.999999]]), 2)
    assert E_rel <= 1e-9
    near = critical.critical_section(_sys([["1.9999995", 4000], [0, "-1.9999995"]], [[1, 0]]))
    assert near["classification"] == "degenerate-second-order"
    assert abs(near["critical_value"]["value"] - (1 - 1.9999995 ** -4)) <= 1e-12
    # a normal matrix with the same moduli gap (κ = 1, ‖A‖ = 2): δ = 2e-9 per eigenvalue, far
    # below the gap 1e-6, so no nearby pair
    assert critical.critical_section(_sys([[2, 0], [0, "-1.999999"]], [[1, 1]]))[
        "robust_critical_value"] is None


def test_bounds_coincide_single_output():
    # diag(2, −2, 1), C = [1 1 1]: two equi-blocks with |λ| ≥ 1, no closed form. Block lower
    # bound: the pair (2, −2), q = 2 → 1 − 2^{−4} = 15/16 (Thm 3 + Thm 9). Single-output upper
    # bound (MATH §3 [beyond]): 1 − 1/(|2|²·|−2|²) = 1 − 1/16 = 15/16. They coincide.
    d = critical.critical_section(_sys([[2, 0, 0], [0, -2, 0], [0, 0, 1]], [[1, 1, 1]]))
    assert d["classification"] == "degenerate"
    cv = d["critical_value"]
    assert _same(cv["expression"], "15/16") and abs(cv["value"] - 15 / 16) <= 1e-15
    assert cv["basis"] == "claim" and "[beyond]" in cv["reason"]
    assert "block lower bound 15/16" in cv["reason"] and "p_up = 15/16" in cv["reason"]
    assert any("claim" in w for w in d["warnings"])
    # diag(2, −2, 3): block lower max(15/16, 8/9) = 15/16, single-output p_up = 1 − 1/144:
    # the bounds differ, no value
    d = critical.critical_section(_sys([[2, 0, 0], [0, -2, 0], [0, 0, 3]], [[1, 1, 1]]))
    assert d["critical_value"]["value"] is None
    assert _same(d["block_lower_bound"]["expression"], "15/16")


def test_stable_system_near_the_unit_circle():
    # diag(1 − 1e-12, 1/2), C = [0 1]: stable (p_c = 0), but the first mode is unobservable and
    # a perturbation of relative size 1e-12 puts it on the unit circle: not detectable nearby.
    d = critical.critical_section(_sys([["0.999999999999", 0], [0, "1/2"]], [[0, 1]]))
    assert d["classification"] == "stable" and d["critical_value"]["value"] == 0
    rob = d["robust_critical_value"]
    assert rob is not None and rob["value"] == 1.0 and "not detectable" in rob["nearby_case"]
    assert any("not detectable" in w for w in d["warnings"])
    # observable: nearby it is critically stable (p_c still 0 by continuity): a note, no value
    d = critical.critical_section(_sys([["0.999999999999", 0], [0, "1/2"]], [[1, 1]]))
    assert d["robust_critical_value"] is None
    assert any("unit circle" in w for w in d["warnings"])
    # far from the circle: nothing
    d = critical.critical_section(_sys([["1/2", 1], [0, "1/3"]], [[1, 0]]))
    assert d["robust_critical_value"] is None and not any("circle" in w for w in d["warnings"])


def test_numeric_path_names_the_other_side():
    # NumPy input diag(2, −(2 − 1e-12), 0.1, 0.2) goes to the numeric path (binary floats, n > 3).
    # As entered the moduli differ: Thm 4 gives 1 − 2^{−2} = 3/4 (the headline). Within the
    # tolerance 1e-9 they merge: degenerate pair, q = 2, p_c = 1 − 2^{−4} = 15/16 — a nearby
    # system, so the robust value, never the headline.
    A = np.diag([2.0, -(2 - 1e-12), 0.1, 0.2])
    s = System(A, np.ones((1, 4)), np.eye(4), np.eye(1))
    d = critical.critical_section(s)
    assert d["structure"]["path"] == "numeric"
    assert d["classification"] == "non-degenerate"
    assert abs(d["critical_value"]["value"] - 0.75) <= 1e-12
    rob = d["robust_critical_value"]
    assert abs(rob["value"] - 15 / 16) <= 1e-12 and "low" not in rob
    assert any(abs(a["value"] - 15 / 16) <= 1e-9 and a["classification"] ==
               "degenerate-second-order" for a in rob["alternatives"])
    assert any("other side" in w for w in d["warnings"])
    # at 1e-13 the relative gap 5e-13 is outside every neighbourhood (δ = 2e-13 per eigenvalue,
    # κ = 1): 3/4, and nothing nearby
    d = critical.critical_section(s, tolerance=1e-13)
    assert d["classification"] == "non-degenerate"
    assert abs(d["critical_value"]["value"] - 0.75) <= 1e-12
    assert d["robust_critical_value"] is None


def test_float_path_issue_case_nearby_is_never_the_headline():
    # Issue 18 item 2: n = 7 (numeric path), moduli 2 and 1.99999999995, each block one-step
    # observable as entered. Hand values: as entered Thm 4, 1 − 1/4 = 3/4; within 1e-9 the
    # moduli merge into a pair with z = −1 (q = 2) seen through one output: 1 − 2^{−4} = 15/16.
    A = np.diag([2.0, -1.99999999995, 0.5, 0.4, 0.3, 0.2, 0.1])
    d = critical.critical_section(System(A, np.ones((1, 7)), np.eye(7), np.eye(1)))
    assert d["classification"] == "non-degenerate"
    assert abs(d["critical_value"]["value"] - 0.75) <= 1e-12
    assert abs(d["robust_critical_value"]["value"] - 15 / 16) <= 1e-12
    # p = 0.85 lies between them: neither stable nor unstable is robust


def test_pair_value_text_has_no_unit_denominator():
    m = sp.Rational(10**20 + 1, 10**19)
    v2 = critical_values.pair_value(float(m), 2, m)
    assert "/1)" not in v2.expression and "**(-2)" in v2.expression
    assert sp.simplify(sp.sympify(v2.expression) - (1 - m ** -2)) == 0
    v3 = critical_values.pair_value(float(m), 3, m)
    assert sp.simplify(sp.sympify(v3.expression) - (1 - m ** sp.Rational(-3, 2))) == 0


def test_almost_sure_text_for_critically_stable_a():
    # rotation by π/2 of modulus 1: ρ(A) = 1, nothing unstable
    d = critical.critical_section(_sys([[0, -1], [1, 0]], [[1, 0]]),
                                  channel=Bernoulli(sp.Rational(9, 10)))
    text = " ".join(d["theory"]["almost_sure"])
    # the upper a.s. instability consequence (stated for unstable A) is not claimed
    assert "limsup tr Pₖ = ∞" not in text and "critically stable" in text


def test_critical_jordan_block_is_labelled():
    # [[1, 1], [0, 1]], C = [1 0]: ρ(A) = 1, not diagonalizable, detectable. MATH §11 (marginal
    # modes) gives p_c = 0 for any Jordan structure; the reason states that argument.
    d = critical.critical_section(_sys([[1, 1], [0, 1]], [[1, 0]]))
    assert d["classification"] == "non-diagonalizable"
    cv = d["critical_value"]
    assert "docs/theory.md §11" in cv["reason"] and "O(t)" in cv["reason"]   # J₂: ‖Aᵗ‖ = O(t)
    assert cv["value"] == 0 and cv["exact"] is True and "basis" not in cv


# --------------------------------------------------------------------------- marginal modes

def _tracker(T: str = "1/10") -> System:
    """Planar constant-velocity tracker: two Jordan blocks at 1, positions measured."""
    A = [[1, T, 0, 0], [0, 1, 0, 0], [0, 0, 1, T], [0, 0, 0, 1]]
    return _sys(A, [[1, 0, 0, 0], [0, 0, 1, 0]])


def test_marginal_tracker_is_exactly_zero():
    # MATH §11: ρ(A) = 1 (Jordan blocks at 1), detectable ⇒ p_c = 0 exactly, not a bracket
    d = critical.critical_section(_tracker())
    cv = d["critical_value"]
    assert d["classification"] == "non-diagonalizable"
    assert cv["value"] == 0.0 and cv["exact"] is True and cv["expression"] == "0"
    assert "docs/theory.md §11" in cv["reason"] and "Iₒ = 2" in cv["reason"]
    assert "O(t²)" in cv["reason"]      # algebraic 4 − geometric 2 + 1 = 3: ‖Aᵗ‖ = O(t²)


def test_marginal_tracker_mare_bounded_at_small_p():
    # Second method: g_p is concave, so E[P_t] ⪯ V_t with V_{t+1} = g_p(V_t) (Jensen); the
    # MARE iteration at p = 0.05 converges to a fixed point, so E[P_t] stays bounded there.
    from kfcrit.theory.covariance import riccati
    s = _tracker()
    A, C, Q, R = (np.asarray(M, dtype=float) for M in (s.a, s.c, s.q, s.r))
    V = np.eye(4)
    for _ in range(20000):
        V = riccati.g(A, C, Q, R, V, 0.05)
    resid = np.linalg.norm(riccati.g(A, C, Q, R, V, 0.05) - V) / np.linalg.norm(V)
    assert np.isfinite(V).all() and resid < 1e-9


@pytest.mark.parametrize("A, C, cls", [
    # 1 and e^{±2πj/3} seen through one output: a degenerate order-3 block on the unit circle
    ([[1, 0, 0], [0, "-1/2", "-sqrt(3)/2"], [0, "sqrt(3)/2", "-1/2"]], [[1, 1, 0]], "degenerate"),
    # Jordan block at −1 beside a stable mode
    ([[-1, 1, 0], [0, -1, 0], [0, 0, "1/2"]], [[1, 0, 1]], "non-diagonalizable"),
])
def test_marginal_modes_other_structures(A, C, cls):
    d = critical.critical_section(_sys(A, C))
    assert d["classification"] == cls
    assert d["critical_value"]["expression"] == "0" and d["critical_value"]["exact"] is True
    assert "docs/theory.md §11" in d["critical_value"]["reason"]


def test_marginal_undetectable_jordan_is_not_detectable():
    # A = J₂(1), C = [0, 1]: the eigenvector e₁ has C e₁ = 0 and |λ| = 1: no p_c
    d = critical.critical_section(_sys([[1, 1], [0, 1]], [[0, 1]]))
    assert d["classification"] == "not-detectable" and d["critical_value"]["value"] is None


def test_marginal_tracker_numeric_path():
    # a 3-D tracker (n = 6 > binary-float limit) on the numeric path: still 0, argument stated
    A = np.kron(np.eye(3), np.array([[1.0, 0.1], [0.0, 1.0]]))
    C = np.kron(np.eye(3), np.array([[1.0, 0.0]]))
    d = critical.critical_section(System(A, C, np.eye(6), np.eye(3)))
    assert d["structure"]["path"] == "numeric"
    assert d["critical_value"]["value"] == 0.0 and "docs/theory.md §11" in d["critical_value"]["reason"]


def test_defective_stable_eigenvalue_does_not_fake_a_robust_value():
    # Issue 18 item 1: A = [[3/2, 0, 0], [0, 1/2, 1], [0, 0, 1/2]], C = [1, 0, 1]. One unstable
    # eigenvalue 3/2 (Sinopoli §IV): p_c = 1 − (2/3)² = 5/9. The Jordan block at 1/2 lies outside
    # the subspace of 3/2, separated by sep(3/2, J₂(1/2)) = σ_min([[−1, 1], [0, −1]]) = 0.618
    # (= (√5 − 1)/2), and C v = 1 for v = e₁: nothing within 1e-9 is undetectable.
    A = [["3/2", 0, 0], [0, "1/2", 1], [0, 0, "1/2"]]
    d = critical.critical_section(_sys(A, [[1, 0, 1]]))
    assert d["classification"] == "non-diagonalizable"
    assert _same(d["critical_value"]["expression"], "5/9")
    assert d["robust_critical_value"] is None
    assert not any("unobservable" in w for w in d["warnings"])
    # the Stewart bound itself: 2ε/(sep − 2ε), ε = 1e-9·‖A‖₂, sep = (√5 − 1)/2
    st = eigen_structure(_sys(A, [[1, 0, 1]]))
    a = np.array([[1.5, 0, 0], [0, 0.5, 1], [0, 0, 0.5]])
    eps = 1e-9 * np.linalg.norm(a, 2)
    i = next(k for k, e in enumerate(st.eigen) if abs(e.value - 1.5) < 1e-12)
    turn = critical_robust.subspace_turn(a, st, [i], eps)
    assert abs(turn - 2 * eps / ((5 ** 0.5 - 1) / 2 - 2 * eps)) <= 1e-6 * turn


def test_subspace_near_a_defective_eigenvalue_is_still_sensitive():
    # the other side: an eigenvalue 1 + 1e-12 next to a Jordan block at 1 is not separated
    # (sep ≈ 1e-12 < 2ε): the bound says the subspace may turn arbitrarily (1.0)
    st = eigen_structure(_sys([["1 + 10**-12", 0, 0], [0, 1, 1], [0, 0, 1]], [[1, 1, 1]]))
    a = np.array([[1 + 1e-12, 0, 0], [0, 1, 1], [0, 0, 1]])
    i = next(k for k, e in enumerate(st.eigen) if e.multiplicity == 1)
    assert critical_robust.subspace_turn(a, st, [i], 1e-9 * np.linalg.norm(a, 2)) == 1.0


# --------------------------------------------------------------------------- exact comparison

@pytest.mark.parametrize("p, v, sign", [
    # Issue 18 item 3: 9/25 + 10⁻⁴⁰ rounds to the same double as 9/25 but is above it
    (sp.Rational(9, 25) + sp.Rational(1, 10**40), sp.Rational(9, 25), 1),
    ("9/25", "9/25", 0),
    # the double nearest 0.36 is 0.35999999999999998667…, below 9/25
    (0.36, "9/25", -1),
    # √2/4 = 0.35355339059327376220…, the double 0.35355339059327373 is …7308575…
    ("sqrt(2)/4", 0.35355339059327373, 1),
    # equal irrationals written differently: exact zero test (√2·√3 = √6)
    ("sqrt(2)*sqrt(3)", "sqrt(6)", 0),
    ("1 - 2**(-4/3)", "1 - 2**(-4/3)", 0),
    # an irrational gap of 10⁻⁶⁰ (below float and below 40 digits)
    ("cos(pi/7)", "cos(pi/7) + 10**-60", -1),
])
def test_compare_probability_exact(p, v, sign):
    from kfcrit.theory.critical.compare import compare_probability
    assert compare_probability(p, v) == sign
    assert compare_probability(v, p) == -sign


def test_compare_probability_reads_critical_value_records():
    from kfcrit.theory.critical.compare import compare_probability
    spec = read_system_file(REPORTS / "sinopoli-general.yaml")      # p_c = 9/25 exactly
    cv = critical.critical_value(spec.system)
    assert compare_probability(sp.Rational(9, 25) + sp.Rational(1, 10**40), cv.value) == 1
    assert compare_probability(sp.Rational(9, 25), cv.value) == 0
    assert compare_probability(sp.Rational(9, 25), cv.to_dict()["critical_value"]["expression"]) \
        == 0


def test_indexed_root_modulus_reads_as_an_approximation_not_17_digits():
    """x⁵ − x − 1 (companion matrix) has no radical roots: the reason names the degenerate
    block's modulus (its complex pair, from numpy.roots here) to 12 digits marked ≈."""
    A = [[0, 1, 0, 0, 0], [0, 0, 1, 0, 0], [0, 0, 0, 1, 0], [0, 0, 0, 0, 1], [1, 1, 0, 0, 0]]
    d = critical.critical_section(_sys(A, [[1, 0, 0, 0, 0]]))
    reason = d["critical_value"]["reason"]
    pair = max(abs(z) for z in np.roots([1, 0, 0, 0, -1, -1]) if abs(z.imag) > 1e-9)
    assert f"|λ| ≈ {float(pair):.12g}" in reason
    assert not re.search(r"\d\.\d{13,}", reason), reason
