"""Exact arithmetic in cyclotomic fields Q(ζ_L), for entries that are trigonometric functions of
rational multiples of π.

Every cos(aπ/b) and sin(aπ/b) lies in Q(ζ_L) for 2b | L (and 4 | L for a sine):

.. math:: \\cos\\frac{a\\pi}{b} = \\frac{\\zeta^{k} + \\zeta^{-k}}{2}, \\quad
          \\sin\\frac{a\\pi}{b} = \\frac{\\zeta^{k} - \\zeta^{-k}}{2i}, \\quad
          \\zeta = e^{2\\pi i/L},\\ k = \\frac{aL}{2b},\\ i = \\zeta^{L/4}.

An element is a rational polynomial in ζ reduced modulo the cyclotomic polynomial Φ_L (exact,
python-flint ``fmpq_poly``). This gives the exact test behind an equal-modulus pair
λ_b = w·λ_a with w = e^{2πi r/q}: the common roots of χ_A(x) and w^{-n}χ_A(w x) are exactly the
eigenvalues μ with w·μ also an eigenvalue (:func:`shifted_gcd`); which eigenvalues they are is
then read from certified eigenvalue balls (:mod:`kfcrit.theory.structure.certified`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import sympy as sp

MAX_FIELD_DEGREE = 256
"""Largest φ(L) for which the cyclotomic arithmetic is attempted."""


@dataclass(frozen=True)
class CycloField:
    """Q(ζ_L): elements are ``fmpq_poly`` reduced modulo Φ_L."""

    L: int
    modulus: Any

    @classmethod
    def of(cls, L: int) -> CycloField:
        from flint import fmpq_poly, fmpz_poly

        return cls(L, fmpq_poly(fmpz_poly.cyclotomic(L).coeffs()))

    @property
    def degree(self) -> int:
        return self.modulus.degree()

    def reduce(self, a: Any) -> Any:
        return a % self.modulus

    def zeta(self, k: int) -> Any:
        """ζ_L^k."""
        from flint import fmpq_poly

        k %= self.L
        return self.reduce(fmpq_poly([0] * k + [1]))

    def const(self, r: sp.Rational | int) -> Any:
        from flint import fmpq, fmpq_poly

        r = sp.Rational(r)
        return fmpq_poly([fmpq(int(r.p), int(r.q))])

    def mul(self, a: Any, b: Any) -> Any:
        return self.reduce(a * b)

    def inv(self, a: Any) -> Any:
        """a⁻¹ (a ≠ 0) from the extended gcd with Φ_L."""
        if a.is_zero():
            raise ZeroDivisionError("inverse of 0 in Q(ζ_L)")
        g, s, _ = a.xgcd(self.modulus)
        return self.reduce(s * self.const(1) / g.coeffs()[0])

    def embed(self, a: Any, other: CycloField) -> Any:
        """a ∈ Q(ζ_L) as an element of Q(ζ_M), L | M (ζ_L = ζ_M^{M/L})."""
        from flint import fmpq_poly

        step = other.L // self.L
        coeffs = a.coeffs()
        out = [0] * (step * max(len(coeffs) - 1, 0) + 1)
        for k, c in enumerate(coeffs):
            out[k * step] = c
        return other.reduce(fmpq_poly(out))

    def value(self, a: Any) -> Any:
        """a as an acb ball at the current flint precision."""
        from flint import acb, arb

        z = acb(arb(2) / self.L).exp_pi_i()
        out = acb(0)
        for c in reversed(a.coeffs()):
            out = out * z + acb(arb(c))
        return out


def _needed_order(expr: sp.Expr) -> int | None:
    """Least L with every trigonometric atom of ``expr`` in Q(ζ_L); None when an atom is not a
    cos/sin of a rational multiple of π or the tree holds anything but +, ×, integer powers."""
    if expr.is_Rational:
        return 1
    if isinstance(expr, (sp.cos, sp.sin)):
        r = expr.args[0] / sp.pi
        if not r.is_Rational:
            return None
        L = 2 * int(r.q)
        return math.lcm(L, 4) if isinstance(expr, sp.sin) else L
    if expr.is_Add or expr.is_Mul:
        L = 1
        for a in expr.args:
            k = _needed_order(a)
            if k is None:
                return None
            L = math.lcm(L, k)
        return L
    if expr.is_Pow and expr.exp.is_Integer:
        return _needed_order(expr.base)
    return None


def has_trigonometric_atoms(entries: list[sp.Expr]) -> bool:
    """Some entry holds cos(·) or sin(·)."""
    return any(e.has(sp.cos, sp.sin) for e in entries)


def cyclotomic_order(entries: list[sp.Expr]) -> int | None:
    """Least L with every entry in Q(ζ_L) (by :func:`_needed_order`; apply :func:`trig_form`
    first to read radicals that sympy made of cos/sin), None if some entry is not of that form
    or φ(L) > ``MAX_FIELD_DEGREE``."""
    L = 1
    for e in entries:
        k = _needed_order(e)
        if k is None:
            return None
        L = math.lcm(L, k)
    # φ(L) ≥ √(L/2): a larger L cannot qualify (and is never factored, which could be slow)
    if L > 2 * MAX_FIELD_DEGREE**2:
        return None
    return L if int(sp.totient(L)) <= MAX_FIELD_DEGREE else None


def element(F: CycloField, expr: sp.Expr) -> Any:
    """The element of Q(ζ_L) equal to ``expr`` (``expr`` accepted by :func:`_needed_order`)."""
    if expr.is_Rational:
        return F.const(expr)
    if isinstance(expr, (sp.cos, sp.sin)):
        r = expr.args[0] / sp.pi
        k = int(r.p) * (F.L // (2 * int(r.q)))
        if isinstance(expr, sp.cos):
            return F.reduce((F.zeta(k) + F.zeta(-k)) * F.const(sp.Rational(1, 2)))
        # 1/(2i) = −i/2, i = ζ^{L/4}
        return F.mul(F.zeta(k) - F.zeta(-k), F.zeta(F.L // 4) * F.const(sp.Rational(-1, 2)))
    if expr.is_Add:
        out = F.const(0)
        for a in expr.args:
            out = out + element(F, a)
        return F.reduce(out)
    if expr.is_Mul:
        out = F.const(1)
        for a in expr.args:
            out = F.mul(out, element(F, a))
        return out
    if expr.is_Pow and expr.exp.is_Integer:
        b = element(F, expr.base)
        k = int(expr.exp)
        out = F.const(1)
        for _ in range(abs(k)):
            out = F.mul(out, b)
        return out if k >= 0 else F.inv(out)
    raise ValueError(f"not an element of Q(ζ_{F.L}): {sp.sstr(expr)[:40]}")


def charpoly(F: CycloField, A: list[list[Any]]) -> list[Any]:
    """Coefficients [c_n = 1, c_{n−1}, …, c_0] of det(xI − A) over Q(ζ_L) (Faddeev–LeVerrier:
    M_k = A M_{k−1} + c_{n−k+1} I, c_{n−k} = −tr(A M_k)/k)."""
    n = len(A)
    zero, one = F.const(0), F.const(1)

    def matmul(X: list[list[Any]], Y: list[list[Any]]) -> list[list[Any]]:
        return [[F.reduce(sum((X[i][k] * Y[k][j] for k in range(n)), zero)) for j in range(n)]
                for i in range(n)]
    coeffs = [one]
    M = [[zero] * n for _ in range(n)]
    for k in range(1, n + 1):
        M = [[M[i][j] + (coeffs[-1] if i == j else zero) for j in range(n)] for i in range(n)]
        AM = matmul(A, M)
        tr = F.reduce(sum((AM[i][i] for i in range(n)), zero))
        coeffs.append(F.reduce(tr * F.const(sp.Rational(-1, k))))
        M = AM
    return coeffs


def _poly_prem(F: CycloField, a: list[Any], b: list[Any]) -> list[Any]:
    """Pseudo-remainder of a by b (coefficient lists, leading first) over Q(ζ_L): each step
    a ← lc(b)·a − lc(a)·x^d·b, so no field inverse is needed (inverses mod Φ_L are the costly
    operation); the result is a nonzero multiple of the true remainder."""
    a = list(a)
    while len(a) >= len(b) and a:
        la, lb = a[0], b[0]
        for i in range(len(a)):
            a[i] = F.mul(a[i], lb)
        for i in range(len(b)):
            a[i] = F.reduce(a[i] - F.mul(la, b[i]))
        a.pop(0)
        while a and a[0].is_zero():
            a.pop(0)
    return a


def poly_gcd(F: CycloField, a: list[Any], b: list[Any]) -> list[Any]:
    """A gcd of two polynomials over Q(ζ_L), up to a nonzero constant factor (Euclid with
    pseudo-remainders; coefficient lists, leading first). Its roots are the common roots."""
    while b:
        a, b = b, _poly_prem(F, a, b)
    return a


def monic(F: CycloField, g: list[Any]) -> list[Any]:
    """g divided by its leading coefficient (one field inverse)."""
    inv = F.inv(g[0])
    return [F.mul(c, inv) for c in g]


def shifted_gcd(F: CycloField, chi: list[Any], w_power: int) -> list[Any]:
    """gcd(χ(x), w^{−n}χ(w x)) with w = ζ_L^{w_power}: its roots are the roots μ of χ with w·μ
    also a root."""
    shifted = [F.mul(c, F.zeta(w_power * (-k))) for k, c in enumerate(chi)]
    return poly_gcd(F, chi, shifted)


def poly_at(F: CycloField, g: list[Any], z: Any) -> Any:
    """g(z) for an acb ball z (Horner, coefficients as balls)."""
    from flint import acb

    out = acb(0)
    for c in g:
        out = out * z + F.value(c)
    return out


def real_expression(F: CycloField, a: Any) -> sp.Expr:
    """A real element Σ c_k ζ^k as the exact sympy number Σ c_k cos(2πk/L)."""
    out = sp.Integer(0)
    for k, c in enumerate(a.coeffs()):
        if c != 0:
            r = sp.Rational(int(c.p), int(c.q))
            out += r if k == 0 else r * sp.cos(2 * sp.pi * sp.Rational(k, F.L))
    return out


_TABLE_DENOMINATORS = tuple(d for d in range(1, 241) if 240 % d == 0)
"""Denominators b of the angles aπ/b that sympy rewrites into radicals (all divide 240)."""


def trig_form(expr: sp.Expr) -> sp.Expr:
    """``expr`` itself when :func:`_needed_order` reads it, else an equal unevaluated
    c·cos(aπ/b) or c·sin(aπ/b) (c rational, b | 240) when one is *proved* equal to it, else
    ``expr``.

    sympy rewrites cos(π/30) into nested radicals; this recovers the trigonometric form. The
    candidate comes from a float search (c = v / cos(aπ/b) close to a fraction with denominator
    ≤ 1000); it is accepted only if ``expand(expr − c·cos(aπ/b)) == 0`` with sympy's own
    radical form of c·cos(aπ/b) — an exact identity."""
    if _needed_order(expr) is not None or not expr.is_number:
        return expr
    try:
        v = float(sp.N(expr, 30))
    except (TypeError, ValueError):
        return expr
    if not math.isfinite(v) or v == 0:
        return expr
    from fractions import Fraction

    for b in _TABLE_DENOMINATORS:
        for a in range(1, 2 * b):
            if math.gcd(a, b) != 1:
                continue
            for fn, f in ((sp.cos, math.cos), (sp.sin, math.sin)):
                base = f(math.pi * a / b)
                if abs(base) < 1e-3:
                    continue
                ratio = v / base
                c = Fraction(ratio).limit_denominator(1000)
                if c == 0 or abs(float(c) - ratio) > 1e-12 * abs(ratio):
                    continue
                r = sp.Rational(c.numerator, c.denominator)
                angle = sp.pi * sp.Rational(a, b)
                if sp.expand(expr - r * fn(angle)) == 0:
                    return sp.Mul(r, fn(angle, evaluate=False), evaluate=False)
    return expr
