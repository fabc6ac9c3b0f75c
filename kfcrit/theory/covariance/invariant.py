"""Support of the invariant distribution of the random Riccati equation (scalar systems).

Kar–Sinopoli–Moura (docs/theory.md §5): for 0 < p < 1 the RRE P_{t+1} = f_{γ_t}(P_t) converges weakly to
a unique invariant law μ_p whose support is K = closure{ f_{i_1}∘…∘f_{i_s}(P*) } (P* the fixed
point of the arrival map f_1), independent of p. For a scalar system (a, c, q, r), c ≠ 0,

    f_0(X) = a² X + q,        f_1(X) = a² r X / (c² X + r) + q,

both increasing, f_1([P*, ∞)) = [P*, f_1(∞)) with f_1(∞) = a² r / c² + q and
f_0([P*, ∞)) = [f_0(P*), ∞). When f_1(∞) < f_0(P*) (that is r/c² < P*) the two images are
disjoint and G_0 = (f_1(∞), f_0(P*)) carries no mass. Since K = f_0(K) ∪ cl f_1(K) and, by
induction, the intervals f_w([P*, ∞)) of the words w of one length are disjoint, every image
f_w(G_0) is a hole of K as well; in particular the holes
G_n = f_0^n(G_0) = (f_0^n(f_1(∞)), f_0^{n+1}(P*)) separate the self-similar pieces
S_n = K ∩ [f_0^n(P*), f_0^n(f_1(∞))] = f_0(S_{n−1}), i.e. S_n = a² S_{n−1} + q.

Example (A = √2, C = Q = R = 1): P* = 1 + √2, f_1(∞) = 3, G_0 = (3, 3 + 2√2), S_n = 2 S_{n−1} + 1.
Exact (sympy) where the system is exact; floats otherwise.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import sympy as sp

from kfcrit.errors import ExpressionError, InputError
from kfcrit.io.typed import ABSENT
from kfcrit.model.exprparse import compare
from kfcrit.model.system import System
from kfcrit.records.covariance import (
    Invariant,
    InvariantGap,
    InvariantGapLevel,
    InvariantMaps,
    SelfSimilarity,
    SupportPointsRecord,
    ValueExpression,
)

MAX_DEPTH = 20
"""Largest word length for the numeric support points (2^(depth+1) − 1 compositions)."""
GAP_LEVELS = 5
HOLE_DEPTH = 3
UNDECIDED_GAP = ("cannot decide whether f1(inf) < f0(P*) (the two agree to more digits than the "
                 "certified comparison evaluates): the holes of the support are not reported")
OVERFLOW = ("the support of the invariant law reaches beyond the float64 range (about 1.8e308): "
            "values there are shown exactly only, numeric points beyond it are left out")


def gap_is_open(lo: sp.Expr, hi: sp.Expr) -> bool | None:
    """Whether ``lo < hi`` (f_1(∞) < f_0(P*): the first hole G_0 exists), certified.

    Decided by :func:`kfcrit.model.exprparse.compare` (exact for rationals, otherwise evalf with
    certain digits, never ``bool`` of a sympy relational); None when undecidable (the values
    agree beyond the working precision and are not provably equal).
    """
    try:
        return compare(hi, lo) > 0
    except ExpressionError:
        return None


def _finite(x: Any) -> float | None:
    """A float view of an exact value, None beyond the float64 range."""
    with np.errstate(over="ignore", invalid="ignore"):
        try:
            v = float(x)
        except (OverflowError, TypeError, ValueError):
            return None
    return v if np.isfinite(v) else None


@dataclass(frozen=True)
class ScalarMaps:
    """The scalar loss and arrival maps with exact (sympy) coefficients."""

    a2: sp.Expr
    c2: sp.Expr
    q: sp.Expr
    r: sp.Expr

    @classmethod
    def of(cls, system: System) -> ScalarMaps:
        if system.n != 1 or system.m != 1:
            raise InputError("the invariant-distribution support is computed for scalar systems "
                             "(n = m = 1) only", field="A")
        c2 = sp.nsimplify(system.C[0, 0] ** 2) if system.exact else system.C[0, 0] ** 2
        if c2 == 0:
            raise InputError("C = 0: arrivals carry no information", field="C")
        return cls(sp.radsimp(system.A[0, 0] ** 2), sp.radsimp(c2), system.Q[0, 0],
                   system.R[0, 0])

    def f0(self, X: Any) -> Any:
        """Loss map a² X + q (sympy or float; floats beyond the range become inf, silently)."""
        if isinstance(X, sp.Basic):
            return self.a2 * X + self.q
        with np.errstate(over="ignore", invalid="ignore"):
            return float(self.a2) * X + float(self.q)

    def f1(self, X: Any) -> Any:
        """Arrival map a² r X / (c² X + r) + q (sympy or float)."""
        if isinstance(X, sp.Basic):
            return sp.radsimp(self.a2 * self.r * X / (self.c2 * X + self.r) + self.q)
        a2, c2, q, r = (float(v) for v in (self.a2, self.c2, self.q, self.r))
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            return a2 * r * X / (c2 * X + r) + q

    def f1_limit(self) -> sp.Expr:
        """f_1(∞) = a² r / c² + q."""
        return sp.radsimp(self.a2 * self.r / self.c2 + self.q)

    def fixed_point(self) -> sp.Expr:
        """P*: the non-negative root of c² X² + (r − a² r − q c²) X − q r = 0."""
        b = self.r - self.a2 * self.r - self.q * self.c2
        disc = b * b + 4 * self.c2 * self.q * self.r
        return sp.radsimp((-b + sp.sqrt(disc)) / (2 * self.c2))


@dataclass(frozen=True, eq=False)
class SupportPoints:
    """Support points f_w(P*) for all words |w| ≤ depth, sorted, and the exact first holes."""

    depth: int
    fixed_point: sp.Expr
    points: np.ndarray = field(repr=False)
    holes: tuple[tuple[float, float], ...] = ()
    first_gap: tuple[sp.Expr, sp.Expr] | None = None
    gap_decided: bool = True
    """False when whether G_0 exists could not be decided (no holes are then reported)."""
    overflow: bool = False
    """True when some support points lie beyond the float64 range (they are left out)."""

    def largest_gaps(self, count: int = 8, upto: float | None = None) -> list[tuple[float, float]]:
        """The ``count`` widest intervals between consecutive support points ≤ ``upto``.

        Finite-depth points are sparse at the top of their range (deeper words fill it in), so
        only a bounded window is meaningful; :func:`invariant_section` uses the first pieces.
        """
        x = self.points if upto is None else self.points[self.points <= upto]
        if x.size < 2:
            return []
        widths = np.diff(x)
        order = np.argsort(widths)[::-1][:count]
        return sorted((float(x[i]), float(x[i + 1])) for i in order)


def support_points(system: System, depth: int) -> SupportPoints:
    """Support points {f_{i_1}∘…∘f_{i_s}(P*) : s ≤ depth} of μ_p and its holes f_w(G_0).

    Parameters
    ----------
    system : System
        A scalar system (n = m = 1) with C ≠ 0.
    depth : int
        Largest word length s (0 … MAX_DEPTH).

    Returns
    -------
    SupportPoints
        ``points`` (unique, sorted, finite floats), ``holes`` f_w(G_0) for |w| < min(depth, 3)
        (empty when f_1(∞) ≥ f_0(P*), i.e. the images overlap, or when that is undecidable:
        ``gap_decided`` False), ``first_gap`` G_0 exactly; ``overflow`` when points beyond the
        float64 range were left out.
    """
    if isinstance(depth, bool) or not isinstance(depth, int) or not 0 <= depth <= MAX_DEPTH:
        raise InputError(f"must be an integer in [0, {MAX_DEPTH}]", field="depth")
    maps = ScalarMaps.of(system)
    pstar = maps.fixed_point()
    level = np.array([float(pstar)])
    allpts = [level]
    for _ in range(depth):
        level = np.unique(np.concatenate([maps.f0(level), maps.f1(level)]))
        allpts.append(level)
    points = np.unique(np.concatenate(allpts))
    finite = np.isfinite(points)
    overflow = not bool(finite.all())
    points = points[finite]
    lo, hi = maps.f1_limit(), maps.f0(pstar)
    below = gap_is_open(lo, hi)
    first = (lo, hi) if below else None
    holes: list[tuple[float, float]] = []
    if first is not None:
        words: list[tuple[float, float]] = [(float(lo), float(hi))]
        holes.extend(words)
        for _ in range(min(depth, HOLE_DEPTH) - 1):
            words = [(float(f(np.array(a))), float(f(np.array(b)))) for a, b in words
                     for f in (maps.f0, maps.f1)]
            holes.extend(words)
    kept = [h for h in holes if np.isfinite(h[0]) and np.isfinite(h[1])]
    overflow = overflow or len(kept) < len(holes)
    return SupportPoints(depth=depth, fixed_point=pstar, points=points,
                         holes=tuple(sorted(kept)), first_gap=first,
                         gap_decided=below is not None, overflow=overflow)


def gap_levels(system: System, levels: int = GAP_LEVELS) -> list[dict[str, Any]]:
    """The holes G_n = (f_0^n(f_1(∞)), f_0^{n+1}(P*)), n = 0 … levels−1, exactly.

    Empty when G_0 does not exist or when that cannot be decided (:func:`gap_is_open`); an
    end beyond the float64 range has ``lower``/``upper`` None (its expression is exact).
    """
    maps = ScalarMaps.of(system)
    lo, hi = maps.f1_limit(), maps.f0(maps.fixed_point())
    if not gap_is_open(lo, hi):
        return []
    out = []
    for n in range(levels):
        out.append({"n": n, "lower": _finite(lo), "upper": _finite(hi),
                    "lower_expression": sp.sstr(sp.nsimplify(lo) if lo.is_Rational else lo),
                    "upper_expression": sp.sstr(hi), "lower_exact": lo, "upper_exact": hi})
        lo, hi = sp.expand(maps.f0(lo)), sp.expand(maps.f0(hi))
    return out


def invariant_section(system: System) -> Invariant | None:
    """The ``invariant`` record section for scalar systems; None otherwise.

    Parameters
    ----------
    system : System
        The system (the section exists for n = m = 1 with C ≠ 0).

    Returns
    -------
    Invariant or None
        ``fixed_point`` P*, the two ``maps``, ``arrival_limit`` f_1(∞), ``first_gap`` G_0
        (None without a first-level hole), ``gap_levels`` G_n, ``self_similarity``,
        ``support_points``, ``holes``, ``note``, and ``warnings`` (only when there are some:
        values beyond the float64 range, an undecidable first hole). Numbers beyond the
        float64 range are None (their expressions stay exact); nothing here prints a NumPy
        warning.
    """
    if system.n != 1 or system.m != 1 or system.C[0, 0] == 0:
        return None
    maps = ScalarMaps.of(system)
    sup = support_points(system, 12)
    pstar = sup.fixed_point
    limit = maps.f1_limit()
    a2, q, r, c2 = maps.a2, maps.q, maps.r, maps.c2
    X = sp.Symbol("X", positive=True)
    gap = None
    if sup.first_gap is not None:
        lo, hi = sup.first_gap
        gap = InvariantGap(lower=_finite(lo), upper=_finite(hi), lower_expression=sp.sstr(lo),
                           upper_expression=sp.sstr(hi), width=_finite(hi - lo))
    window = _finite(maps.f0(maps.f0(limit)))  # the pieces S_0, S_1, S_2
    levels = [InvariantGapLevel(n=g["n"], lower=g["lower"], upper=g["upper"],
                                lower_expression=g["lower_expression"],
                                upper_expression=g["upper_expression"])
              for g in gap_levels(system)] if sup.gap_decided else []
    exact_values = (pstar, limit, *(sup.first_gap or ()))
    overflow = sup.overflow or window is None or any(_finite(v) is None for v in exact_values) \
        or any(g.lower is None or g.upper is None for g in levels)
    warnings = [f"invariant support: {OVERFLOW}"] if overflow else []
    if not sup.gap_decided:
        warnings.append(f"invariant support: {UNDECIDED_GAP}")
    if gap is not None:
        note = ("support of the invariant law (Kar-Sinopoli-Moura Thm 10): independent of p; "
                "the holes carry no mass for every 0 < p < 1")
    elif not sup.gap_decided:
        note = UNDECIDED_GAP
    else:
        note = "the images of f0 and f1 overlap (r/c^2 >= P*): no first-level hole"
    return Invariant(
        fixed_point=ValueExpression(value=_finite(pstar), expression=sp.sstr(pstar)),
        maps=InvariantMaps(loss=f"f0(X) = {sp.sstr(a2 * X + q)}",
                           arrival=f"f1(X) = {sp.sstr(a2 * r * X / (c2 * X + r) + q)}"),
        arrival_limit=ValueExpression(value=_finite(limit), expression=sp.sstr(limit)),
        first_gap=gap,
        gap_levels=levels,
        self_similarity=SelfSimilarity(scale=_finite(a2), offset=_finite(q),
                                       statement=f"S_n = {sp.sstr(a2)}*S_(n-1) + {sp.sstr(q)}",
                                       pieces="S_n = supp(mu) within [f0^n(P*), f0^n(f1(inf))]"),
        support_points=SupportPointsRecord(
            depth=int(sup.depth), count=int(sup.points.size),
            min=float(sup.points[0]) if sup.points.size else None,
            window=[_finite(pstar), window],
            largest_gaps=[[float(v) for v in g] for g in sup.largest_gaps(upto=window)]),
        holes=[[float(v) for v in h] for h in sup.holes],
        note=note,
        # also copied into the record's warnings by the analysis
        warnings=warnings if warnings else ABSENT,
    )
