"""Mo–Sinopoli eq. (51)–(52): the determinant of Ξ for a degenerate second-order system.

Source: Mo & Sinopoli, proof of Theorem 9, eqs. (50)–(52). With μ = λ^{-2} (λ = |λ_1|) and
z = e^{jφ} on the unit circle,

    Ξ = Σ_i γ_i μ^i [[1, z^{-i}], [z^i, 1]],
    det Ξ = (Σ γ_i μ^i)² − (Σ γ_i μ^i z^i)(Σ γ_i μ^i z^{-i})
          = Σ_i Σ_{j>i} γ_i γ_j μ^{i+j} (2 − z^{i−j} − z^{j−i}).            (51)

Checked exactly for sums truncated at N terms (the identity is termwise, so it holds for every
N; the diagonal terms cancel without using γ_i² = γ_i). For z = e^{2πjr/q}, the factors
2 − z^l − z^{−l} vanish iff q | l and otherwise lie in [2 − 2cos(2π/q), 4], which gives (52);
note (52) prints "det Ξ =" in the middle where "≤ … ≤" with the restricted double sum is meant.
"""
from __future__ import annotations

import math

import numpy as np
import sympy as sp

from . import Check
from ._algebra import require

STEP = "Mo (51)–(52): det Ξ as a double sum"
SOURCE = "Mo–Sinopoli, proof of Thm 9, eqs. (50)–(52)"


def symbolic(N: int = 6) -> str:
    """(51) with γ_1..γ_N, μ, z symbols (z^{-1} as 1/z)."""
    mu, z = sp.symbols("mu z", nonzero=True)
    gam = sp.symbols(f"gamma1:{N + 1}")
    Xi = sp.zeros(2, 2)
    for i, g in enumerate(gam, start=1):
        Xi += g * mu ** i * sp.Matrix([[1, z ** -i], [z ** i, 1]])
    first = sum(g * mu ** i for i, g in enumerate(gam, start=1))
    plus = sum(g * mu ** i * z ** i for i, g in enumerate(gam, start=1))
    minus = sum(g * mu ** i * z ** -i for i, g in enumerate(gam, start=1))
    double = sum(gam[i - 1] * gam[j - 1] * mu ** (i + j) * (2 - z ** (i - j) - z ** (j - i))
                 for i in range(1, N + 1) for j in range(i + 1, N + 1))
    det = sp.expand(Xi.det())
    require(sp.expand(det - (first ** 2 - plus * minus)) == 0, "det Ξ ≠ first line of (51)")
    require(sp.expand(det - double) == 0, "det Ξ ≠ double sum of (51)")
    return f"det Ξ = both forms of (51) exactly, N = {N} terms"


def exact(max_q: int = 12) -> str:
    """(52)'s bounds: for z = e^{2πjr/q}, gcd(r, q) = 1, l = 1..q: 2 − z^l − z^{−l} = 0 iff q | l,
    else ≥ 2 − 2cos(2π/q) and ≤ 4 (exact, via 2 − 2cos(2πrl/q) = 4 sin²(πrl/q))."""
    count = 0
    for q in range(2, max_q + 1):
        bound = 2 - 2 * sp.cos(2 * sp.pi / q)
        for r in range(1, q):
            if math.gcd(r, q) != 1:
                continue
            for l in range(1, 2 * q + 1):
                factor = 4 * sp.sin(sp.pi * sp.Rational(r * l, q)) ** 2
                if l % q == 0:
                    require(sp.simplify(factor) == 0, f"q={q}, r={r}, l={l}: nonzero")
                else:
                    diff = sp.N(factor - bound, 50)
                    require(diff >= -sp.Float(1e-45) and sp.N(4 - factor, 50) >= 0,
                            f"q={q}, r={r}, l={l}: outside [2 − 2cos(2π/q), 4]")
                count += 1
    return f"zero iff q | l, else in [2 − 2cos(2π/q), 4]: {count} cases, q ≤ {max_q} (50 digits)"


def numeric() -> str:
    """A random arrival sequence, λ = 2, z = e^{2πj/3}, 60 terms: det Ξ (numpy) = double sum."""
    rng = np.random.default_rng(3)
    gam = rng.random(60) < 0.6
    mu, z = 0.25, np.exp(2j * np.pi / 3)
    i = np.arange(1, 61)
    Xi = sum(g * mu ** k * np.array([[1, z ** -k], [z ** k, 1]]) for g, k in zip(gam, i))
    double = sum(gam[a - 1] * gam[b - 1] * mu ** (a + b) * (2 - z ** (a - b) - z ** (b - a))
                 for a in i for b in i if b > a)
    det = np.linalg.det(Xi)
    require(abs(det - double) <= 1e-12 * max(1.0, abs(double)), f"{det} vs {double}")
    return f"det Ξ = {det.real:.6e} = double sum (|Δ| = {abs(det - double):.1e})"


CHECKS = [
    Check(STEP, SOURCE, "sympy symbolic (N = 6 terms)", symbolic),
    Check(STEP, SOURCE, "sympy (exact zeros, 50-digit bounds)", exact),
    Check(STEP, SOURCE, "numeric (numpy det)", numeric),
]


def test_symbolic() -> None:
    symbolic()


def test_exact() -> None:
    exact()


def test_numeric() -> None:
    numeric()
