"""How robust p_c is: the eigen-structure of systems within a relative tolerance, nearby
cases that change the class, and the robust critical value (theory §4)."""
from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import numpy as np
import sympy as sp

from kfcrit.io.typed import ABSENT
from kfcrit.model.system import System
from kfcrit.records.contract import LowCase, NearbyCase, RobustCriticalValue
from kfcrit.theory.critical.classify import (
    block_lower,
    classify_structure,
    eig_text,
    is_mod,
    lower_of,
    mod_text,
)
from kfcrit.theory.critical.values import LONG_NUMBER, Num, mtol, num_text, pair_value
from kfcrit.theory.structure.eigen import (
    MAX_DENOMINATOR,
    NUMERIC_FLOOR,
    Structure,
    cmp_exact,
    simplest_rational,
    structure_at,
)

# --------------------------------------------------------------------------- robustness

@dataclass(frozen=True)
class _Sensitivity:
    """First-order sensitivity of the spectrum of A to a perturbation E with ‖E‖₂ ≤ tol·‖A‖₂.

    ``kappa[i]`` = ‖P_i‖₂, P_i the spectral projector of the i-th distinct eigenvalue (for a simple
    eigenvalue ‖P_i‖ = κ(λ_i) = ‖x‖‖y‖/|y^H x| from its right/left eigenvectors x, y); ``delta[i]``
    the radius of its neighbourhood (see :func:`_sensitivity`); ``eps`` = tol·‖A‖₂.
    """

    eps: float
    kappa: tuple[float, ...]
    delta: tuple[float, ...]

    def subspace(self, a: np.ndarray, st: Structure, ids: list[int]) -> float:
        """Bound on how far the invariant subspace span{V_I} turns under A + E (≤ 1).

        Stewart's theorem on invariant subspaces (Stewart–Sun, Thm V.2.7): in a Schur form
        A = Z [[T₁₁, T₁₂], [0, T₂₂]] Z^H with the eigenvalues of I in T₁₁, and ‖E‖₂ ≤ ε, put
        δ = sep(T₁₁, T₂₂) − 2ε, γ = ε, η = ‖T₁₂‖ + ε. If γη/δ² < 1/4, A + E has an invariant
        subspace span{Z(I; X)} with ‖X‖₂ ≤ 2γ/δ, so the subspace turns by at most that.

        .. math:: \\operatorname{sep}(T_{11}, T_{22}) = \\sigma_{\\min}(I \\otimes T_{22}
                  - T_{11}^T \\otimes I)

        Only the separation of the two spectral parts enters: a defective eigenvalue *outside*
        I does not make the subspace of I sensitive unless it is close to I's eigenvalues.
        Above :data:`STEWART_MAX_STATES` states the first-order estimate is used (each Stewart
        bound costs a Schur reordering and a Sylvester separation)."""
        if a.shape[0] > STEWART_MAX_STATES:
            return self._first_order_turn(st, ids)
        turn = subspace_turn(a, st, ids, self.eps)
        return turn if turn is not None else self._first_order_turn(st, ids)

    def _first_order_turn(self, st: Structure, ids: list[int]) -> float:
        """First-order estimate for large blocks: δv_i = Σ_{j∉I} v_j (y_j^H E v_i)/((λ_i − λ_j)
        y_j^H v_j), norm ≤ ε Σ_{j∉I} κ_j/|λ_i − λ_j| (1.0 when some κ_j is infinite)."""
        tot = 0.0
        for j, ej in enumerate(st.eigen):
            if j in ids:
                continue
            gap = min(abs(st.eigen[i].value - ej.value) for i in ids)
            if gap == 0 or not math.isfinite(self.kappa[j]):
                return 1.0
            tot += self.kappa[j] / gap
        return min(1.0, self.eps * tot)


_SEP_MAX_ORDER = 600
STEWART_MAX_STATES = 100
"""Largest n whose invariant-subspace turns use Stewart's bound (first order beyond)."""
"""Largest k·(n − k) for which sep(T₁₁, T₂₂) is computed from the Kronecker form."""


def subspace_turn(a: np.ndarray, st: Structure, ids: list[int], eps: float) -> float | None:
    """Stewart's bound 2ε/δ on the turn of span{V_I} (see :meth:`_Sensitivity.subspace`);
    1.0 when it does not apply (parts not separated), None when sep is too large to compute."""
    import scipy.linalg as sla

    n = a.shape[0]
    w = np.linalg.eigvals(a)
    chosen: list[int] = []
    for i in ids:
        e = st.eigen[i]
        free = sorted((k for k in range(n) if k not in chosen), key=lambda k: abs(w[k] - e.value))
        chosen.extend(free[:e.multiplicity])
    k = len(chosen)
    if k >= n:
        return 0.0
    inside, outside = w[chosen], np.delete(w, chosen)
    gap = float(np.min(np.abs(inside[:, None] - outside[None, :])))
    if gap == 0.0:
        return 1.0
    if k * (n - k) > _SEP_MAX_ORDER:
        return None
    T, _, sdim = sla.schur(a.astype(complex), output="complex",
                           sort=lambda x: bool(np.min(np.abs(inside - x)) < gap / 2))
    if sdim != k:
        return 1.0
    T11, T12, T22 = T[:k, :k], T[:k, k:], T[k:, k:]
    S = np.kron(np.eye(k), T22) - np.kron(T11.T, np.eye(n - k))
    sep = float(np.linalg.svd(S, compute_uv=False).min())
    delta = sep - 2 * eps
    eta = float(np.linalg.norm(T12, 2)) + eps
    if delta <= 0 or eps * eta / delta ** 2 >= 0.25:
        return 1.0
    return min(1.0, 2 * eps / delta)


def _sensitivity(system: System, st: Structure, tol: float) -> _Sensitivity:
    """Neighbourhood radii δ_i of the eigenvalues of A + E, ‖E‖₂ ≤ tol·‖A‖₂ (Bauer–Fike /
    first-order perturbation theory, e.g. Stewart–Sun, Matrix Perturbation Theory, Ch. IV–V).

    * semisimple λ_i (geometric = algebraic multiplicity): the eigenvalues of A + E near λ_i lie
      within δ_i = κ_i·tol·‖A‖₂ + O(tol²), κ_i = ‖P_i‖₂ (spectral projector; κ(λ) for a simple
      eigenvalue, = 1 for normal A);
    * defective λ_i (largest possible Jordan block k = algebraic − geometric + 1): the first-order
      bound does not exist, the eigenvalues move like ‖E‖^{1/k} (Lidskii); we use
      δ_i = ‖A‖₂·tol^{1/k} (the leading-order scale with unit constant — an estimate, not a bound).

    Moduli |λ| can move by δ_i, arguments arg λ by about δ_i/|λ_i|; δ_i is capped at ‖A‖₂ + 1.
    """
    a = np.asarray(system.a, dtype=float)
    n = a.shape[0]
    norm = max(st.norm_A, np.finfo(float).tiny)
    eps = tol * norm
    big = 1.0 / NUMERIC_FLOOR
    try:
        w, V = np.linalg.eig(a)
        Vinv = np.linalg.inv(V)
        ok = bool(np.all(np.isfinite(Vinv)))
    except np.linalg.LinAlgError:
        w, V, Vinv, ok = np.zeros(n), None, None, False
    used: set[int] = set()
    kappa, delta = [], []
    for e in st.eigen:
        order = sorted((k for k in range(n) if k not in used),
                       key=lambda k: abs(w[k] - e.value))[:e.multiplicity]
        used.update(order)
        if e.geometric < e.multiplicity:
            kappa.append(math.inf)
            k = e.multiplicity - e.geometric + 1
            delta.append(min(norm * tol ** (1.0 / k), norm + 1.0))
            continue
        if not ok:
            kap = big
        elif len(order) == 1:
            kap = float(np.linalg.norm(V[:, order[0]]) * np.linalg.norm(Vinv[order[0], :]))
        else:
            kap = float(np.linalg.norm(V[:, order] @ Vinv[order, :], 2))
        kap = min(max(kap, 1.0), big)
        kappa.append(kap)
        delta.append(min(eps * kap, norm + 1.0))
    return _Sensitivity(eps, tuple(kappa), tuple(delta))


def _sigma_min(st: Structure, c: np.ndarray, ids: list[int]) -> float:
    """Least singular value of C·Q, Q an orthonormal basis of span{V_I} (the distance of C
    restricted to the invariant subspace from rank deficiency)."""
    B = np.hstack([st.eigen[i].basis for i in ids])
    if B.size == 0 or c.shape[0] < B.shape[1]:
        return 0.0          # fewer outputs than columns: rank deficient for every C
    Q, _ = np.linalg.qr(B)
    return float(np.linalg.svd(c @ Q, compute_uv=False).min())


def _nearby_q(turn: float, width: float, q: int | None) -> int | None:
    """Least denominator q' ≤ MAX_DENOMINATOR of a rational within ``width`` of φ/2π (or q)."""
    width = min(width, 0.5)
    frac = simplest_rational(Fraction(turn) - Fraction(width), Fraction(turn) + Fraction(width))
    cand = frac.denominator if frac.denominator <= MAX_DENOMINATOR else None
    if q is None:
        return cand
    return q if cand is None else min(q, cand)


def _nearby_mod2(e: Any, tol: float) -> tuple[float, sp.Expr | None]:
    """|λ|² of the nearby case, exactly: the simplest rational within relative 4·tol of |λ|²
    (a point of the neighbourhood: e.g. |λ|² = 1 + 1.7320508075688772² → 4), else the exact
    |λ|² when it is short, else the float."""
    if tol > 0 and e.mod2 > 0:
        m2, w = Fraction(e.mod2), Fraction(4 * tol)
        lo, hi = m2 * (1 - w), m2 * (1 + w)
        frac = simplest_rational(lo, hi)
        if frac.denominator <= MAX_DENOMINATOR and abs(frac.numerator) <= 10**9:
            x = sp.Rational(frac.numerator, frac.denominator)
            return float(x), x
    if e.mod2_expr is not None and not LONG_NUMBER.search(sp.sstr(e.mod2_expr)):
        return e.mod2, e.mod2_expr
    return e.mod2, None


def _nearby_pair_value(e: Any, q: int | None, tol: float) -> Num:
    mod2, expr = _nearby_mod2(e, tol)
    above = cmp_exact(expr, 1) > 0 if expr is not None else mod2 > 1
    return pair_value(mod2, q, expr, above)


def _nearby_cases(system: System, st: Structure, tol: float) -> tuple[list[tuple[Num, str]],
                                                                     list[str]]:
    """Worse cases for some A + E, C + F with ‖E‖ ≤ tol·‖A‖, ‖F‖ ≤ tol·‖C‖: (value, description)
    and plain warnings. Neighbourhoods from :func:`_sensitivity`: |λ_i| moves by δ_i, arg λ_i by
    δ_i/|λ_i|, and σ_min of C on an invariant subspace by ‖C‖·(tol + η_I), η_I the first-order
    turn of that subspace (:meth:`_Sensitivity.subspace`)."""
    c = system.c
    a = np.asarray(system.a, dtype=float)
    sens = _sensitivity(system, st, tol)
    dl = sens.delta
    normc = max(st.norm_C, np.finfo(float).tiny)

    def ctol(ids: list[int]) -> float:
        return normc * (tol + sens.subspace(a, st, ids))

    cases: list[tuple[Num, str]] = []
    notes: list[str] = []
    near = [i for i, e in enumerate(st.eigen) if e.modulus + dl[i] >= 1]

    def rad(i: int) -> str:
        return (f"δ = {dl[i]:.3g}" + (f", κ = {sens.kappa[i]:.3g}"
                                      if math.isfinite(sens.kappa[i]) else ", defective"))
    for i in near:
        if i not in st.undetectable and _sigma_min(st, c, [i]) <= ctol([i]):
            where = ("|λ| ≥ 1" if st.relevant(i) else
                     f"|λ| {is_mod(st, i)} < 1 but within {rad(i)} of the unit circle")
            cases.append((Num(1.0, sp.Integer(1)),
                          f"eigenvalue {eig_text(st, i)} ({where}) is within relative {tol:g} of "
                          "being unobservable: a nearby system is not detectable"))
        elif not st.relevant(i):
            notes.append(f"eigenvalue {eig_text(st, i)} (|λ| {is_mod(st, i)} < 1) is within "
                         f"{rad(i)} of the unit circle: a system within relative {tol:g} is "
                         "critically stable or unstable (p_c moves continuously from 0)")
    pairs = {(p.a, p.b): p for p in st.pairs}
    for ia, i in enumerate(near):
        for j in near[ia + 1:]:
            ei, ej = st.eigen[i], st.eigen[j]
            pair = pairs.get((i, j))
            if pair is None and abs(ei.modulus - ej.modulus) > dl[i] + dl[j]:
                continue
            exact_def = pair is not None and pair.degenerate
            smin = 0.0 if exact_def else _sigma_min(st, c, [i, j])
            if not (exact_def or smin <= ctol([i, j])):
                continue
            turn = pair.turn if pair is not None else _turn_of(ej.value / ei.value)
            width = (dl[i] / max(ei.modulus, 1e-300) + dl[j] / max(ej.modulus, 1e-300)) \
                / (2 * math.pi)
            q_now = pair.q if (pair is not None and pair.degenerate) else None
            qn = _nearby_q(turn, width, pair.q if pair is not None else None)
            if exact_def and qn == q_now:
                continue
            hi = i if ei.mod2 >= ej.mod2 else j
            val = _nearby_pair_value(st.eigen[hi], qn, tol)
            why = []
            if pair is None:
                why.append(f"moduli {mod_text(st, i)} and {mod_text(st, j)} differ by at most "
                           f"δ_i + δ_j ({rad(i)}; {rad(j)}) for perturbations of relative size "
                           f"{tol:g} (a nearby system has an equal-modulus pair)")
            if not exact_def:
                why.append("the pair's columns of C·V have rank 1" if smin == 0.0 else
                           f"the pair's columns of C·V are within relative {tol:g} of rank 1")
            if qn is not None and qn != q_now:
                why.append(f"φ/2π ≈ {turn:.12g} is within {width:.3g} of a rational with q = {qn}")
            desc = (f"eigenvalues {eig_text(st, i)}, {eig_text(st, j)}: "
                    + "; ".join(w for w in why if w)
                    + (f" → degenerate pair with q = {qn}, p_c = {val.expression}" if qn != 1
                       else " → equal eigenvalues seen through one column: not detectable"))
            cases.append((val, desc))
    for b in st.blocks:
        if b.relevant and b.one_step_observable and b.size >= 3 \
                and _sigma_min(st, c, list(b.members)) <= ctol(list(b.members)):
            notes.append(f"equi-block at |λ| {is_mod(st, b.members[0])} is within relative "
                         f"{tol:g} of a degenerate block of order {b.size}, for which the papers "
                         "give no closed form")
    return cases, notes


def _strict_tolerance(system: System, st: Structure) -> float:
    """Float64 resolution of the numeric decisions: 64 ulp · max κ (the rounding error of the
    computed eigenvalues relative to ‖A‖), at most 1e-3."""
    sens = _sensitivity(system, st, NUMERIC_FLOOR)
    kmax = max([k for k in sens.kappa if math.isfinite(k)] or [1.0])
    return min(NUMERIC_FLOOR * kmax, 1e-3)


def headline_structure(system: System, st: Structure) -> tuple[Structure, Structure | None]:
    """The structure behind the headline p_c and, on the numeric path, the one decided at the
    user's tolerance when that is looser than float64 resolution.

    The headline is the system as entered: on the numeric path its decisions are made at float64
    resolution (:func:`_strict_tolerance`), so that moduli, ranks and angles which only *agree
    within the tolerance* are kept apart. What the tolerance merges is a nearby system — it
    enters the robust value (:func:`_tolerance_alternative`), never the headline."""
    if st.path != "numeric":
        return st, None
    strict = _strict_tolerance(system, st)
    if strict >= mtol(st):
        return st, None
    return structure_at(st, system, strict), st


def _tolerance_alternative(system: System, st_tol: Structure | None, value: Num | None,
                           blow: Num | None, classification: str) -> NearbyCase | None:
    """Numeric path: the case decided with the user's tolerance, when it differs from the
    headline (decided at float64 resolution)."""
    if st_tol is None:
        return None
    low2 = lower_of(st_tol)
    cls2, val2, reason2 = classify_structure(system, st_tol, low2)
    if cls2 == "not-detectable":
        alt: Num | None = Num(1.0, sp.Integer(1))
    else:
        alt = val2 if val2 is not None else block_lower(st_tol, low2)[0]
    mine = value if value is not None else blow
    if cls2 == classification and alt is not None and mine is not None \
            and abs(alt.value - mine.value) <= 1e-12:
        return None
    return NearbyCase(
        value=float(alt.value) if alt is not None else None,
        expression=alt.expression if alt is not None else None, classification=cls2,
        case=(f"decisions at the tolerance {mtol(st_tol):g} (moduli, ranks and angles "
              f"equal within it are merged): {cls2}"
              + ("" if val2 is not None or cls2 == "not-detectable"
                 else " (block lower bound)") + f"; {reason2}"))


def _turn_of(z: complex) -> float:
    t = math.atan2(z.imag, z.real) / (2 * math.pi)
    return t + 1.0 if t < 0 else t


def robust_value(system: System, st: Structure, st_tol: Structure | None, tolerance: float,
            value: Num | None, blow: Num, classification: str,
            warnings: list[str]) -> RobustCriticalValue | None:
    """The robust critical value: the worst case within ``tolerance`` (``value``, ≥ the
    headline) and, when some case within it is lower, the least one (``low``); every differing
    case decided at the user's tolerance in ``alternatives``. ``warnings`` is extended."""
    base = value if value is not None else blow
    cases, notes = _nearby_cases(system, st, tolerance)
    warnings.extend(notes)
    worse = [(v, d) for v, d in cases if v.value > base.value + 1e-15]
    lower = [(v, d) for v, d in cases if v.value < base.value - 1e-15]
    for _v, d in worse + lower:
        warnings.append(f"within tolerance {tolerance:g} of a different case: {d}")
    alt = _tolerance_alternative(system, st_tol, value, blow, classification)
    if alt is not None:
        warnings.append(f"numeric decision at float64 resolution {mtol(st):.3g}: "
                        f"{classification} with "
                        f"{'p_c' if value is not None else 'block lower bound'} = "
                        f"{base.expression}; on the other side of the tolerance decisions, "
                        f"{alt.case} gives {alt.expression}")
        if alt.value is not None:
            num = Num(alt.value) if alt.expression is None else Num(
                alt.value, None, alt.expression)
            (worse if alt.value > base.value + 1e-15 else
             lower if alt.value < base.value - 1e-15 else []).append((num, alt.case))
    if not (worse or lower or alt):
        return None
    top, top_case = max(worse, key=lambda vd: vd[0].value) if worse else (base, "the headline "
                                                                          "case")
    low: LowCase = ABSENT
    if lower:
        v, d = min(lower, key=lambda vd: vd[0].value)
        low = LowCase(value=float(v.value), expression=num_text(v), case=d)
    return RobustCriticalValue(value=float(top.value), tolerance=_plain_number(tolerance),
                               expression=num_text(top), nearby_case=top_case, low=low,
                               alternatives=[alt] if alt is not None else ABSENT)


def _plain_number(x: float) -> float:
    """``x`` as a Python number: an integer stays an integer (its JSON form is kept: ``0``,
    not ``0.0``), anything else becomes a float."""
    if isinstance(x, (int, np.integer)) and not isinstance(x, (bool, np.bool_)):
        return int(x)
    return float(x)
