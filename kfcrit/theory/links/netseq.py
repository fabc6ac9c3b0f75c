"""Sensor networks without enumerating received sets: one-sensor maps (docs/theory.md §15).

With the one-sensor maps of docs/theory.md §15.5 the sufficient surface of a network costs
polynomially in the number N of sensors. For gains K_i (n × m_i) let F_i = I − K_i C_i and

.. math::

    M_i(X) = (1 - p_i)\\,X + p_i\\,F_i X F_i',\\qquad
    𝓛_p(X) = A\\,(M_N \\circ \\cdots \\circ M_1)(X)\\,A' .

A **certificate** is X ≻ 0 with X − 𝓛_p(X) ≻ 0 (equivalently ρ(𝓛_p) < 1). Expanding the
product, 𝓛_p(X) = Σ_S π(S)(A Π_{i∈S} F_i) X (·)', so it is the jump-linear certificate of
docs/theory.md §9.3 with product-form gains K_S (one per received set), and it proves mean
stability for any noise covariance R (the suboptimal filter with those gains has a bounded
error covariance); §15.4 (Theorem C) shows it also bounds E[P_t] for block-diagonal R.

On ``vech`` coordinates (dimension n_v = n(n+1)/2) 𝓛_p is the matrix
T_A Π_i ((1 − p_i) I + p_i T_{F_i}), with T_F the matrix of X ↦ F X F'; building it costs
O(N n_v³). Along a coordinate path (p_i = s, the others fixed) it is affine in s:
L(s) = L_0 + s L_1, with prefix and suffix products shared by all sensors.

Gains come from the noise-free sequential map (docs/theory.md §15.4 with Q = R → 0):
power iteration at the operating point, then policy iteration (Stein solve X = 𝓛(X) + I,
gains optimal at X for each intermediate update) and a fixed-gain threshold search. These only
*guide* the search: every certificate is checked in ball arithmetic (python-flint) on the
exact A and C (:func:`verify_sequential`).
"""
from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import flint
import numpy as np

from kfcrit.theory.covariance.riccati import symmetrize, unvech, vech
from kfcrit.theory.links.netkernels import congruence_batch
from kfcrit.theory.upper.certify import PRECISION_BITS, arb_from_float, arb_from_sympy, definite_margin

GAIN_REG = 1e-12
"""Relative regulariser of the noise-free gains: K = Y C'(C Y C' + GAIN_REG·tr(Y)·I)^{-1}."""
POLICY_ROUNDS = 6
"""Most policy-iteration rounds (Stein solve, new gains) per point or threshold search."""
BISECT_STEPS = 60
"""Bisection steps of a fixed-gain threshold (on ρ(L(s)) < 1)."""
KIND = ("X > 0 and X - A M_N(...M_1(X))A' > 0, M_i(Y) = (1-p_i) Y + p_i F_i Y F_i', "
        "F_i = I - K_i C_i (product-form gains over every received set, docs/theory.md §15.5)")


# ---------------------------------------------------------------------------------------------
# the plant and the operator
# ---------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class SeqPlant:
    """Float A (n × n) and the sensors' output blocks C_i (m_i × n)."""

    a: np.ndarray
    blocks: tuple[np.ndarray, ...]

    @property
    def n(self) -> int:
        return int(self.a.shape[0])

    @property
    def size(self) -> int:
        return len(self.blocks)

    def ta(self) -> np.ndarray:
        """T_A, the matrix of X ↦ A X A' on vech coordinates."""
        return congruence_batch(self.a[None])[0]


def closed_loops(plant: SeqPlant, gains: Sequence[np.ndarray]) -> np.ndarray:
    """F_i = I − K_i C_i for every sensor (N × n × n)."""
    eye = np.eye(plant.n)
    return np.stack([eye - K @ C for K, C in zip(gains, plant.blocks)])


def factors(plant: SeqPlant, p: np.ndarray, gains: Sequence[np.ndarray]
            ) -> tuple[np.ndarray, np.ndarray]:
    """(T_{F_i}, M_i) on vech coordinates, M_i = (1 − p_i) I + p_i T_{F_i} (each N × n_v × n_v)."""
    T = congruence_batch(closed_loops(plant, gains))
    nv = T.shape[-1]
    M = (1.0 - p)[:, None, None] * np.eye(nv)[None] + p[:, None, None] * T
    return T, M


def operator(plant: SeqPlant, p: np.ndarray, gains: Sequence[np.ndarray]) -> np.ndarray:
    """The matrix of 𝓛_p = T_A M_N ⋯ M_1 (n_v × n_v).

    .. math:: 𝓛_p(X) = A\\,(M_N \\circ \\cdots \\circ M_1)(X)\\,A'
    """
    T = congruence_batch(closed_loops(plant, gains))
    return operator_from(plant.ta(), T, p)


def operator_from(ta: np.ndarray, T: np.ndarray, p: np.ndarray) -> np.ndarray:
    """T_A Π_{k=N..1} ((1 − p_k) I + p_k T_k) for precomputed T_k = T_{F_k} (fixed gains)."""
    L = ta
    for k in range(T.shape[0] - 1, -1, -1):
        pk = float(p[k])
        if pk == 0.0:
            continue
        L = L @ T[k] if pk == 1.0 else (1.0 - pk) * L + pk * (L @ T[k])
    return L


def radius(L: np.ndarray) -> float:
    """Spectral radius of a square matrix (float guide, never a proof)."""
    v = np.linalg.eigvals(L)
    return float(np.max(np.abs(v))) if np.all(np.isfinite(v)) else math.inf


def stein(L: np.ndarray, n: int) -> np.ndarray | None:
    """X solving X = 𝓛(X) + I when ρ(𝓛) < 1 (a certificate candidate, X ⪰ I), else None."""
    if not np.all(np.isfinite(L)) or radius(L) >= 1.0:
        return None
    try:
        x = np.linalg.solve(np.eye(L.shape[0]) - L, vech(np.eye(n)))
    except np.linalg.LinAlgError:
        return None
    X = unvech(x, n)
    return X if np.all(np.isfinite(X)) else None


# ---------------------------------------------------------------------------------------------
# gains from the noise-free sequential map
# ---------------------------------------------------------------------------------------------

def sequential_gains(plant: SeqPlant, p: np.ndarray, X: np.ndarray,
                     reg: float = GAIN_REG) -> tuple[list[np.ndarray], np.ndarray]:
    """Gains optimal at each intermediate update of the noise-free sequential map, and its value.

    .. math::

        K_i = Y_{i-1} C_i'(C_i Y_{i-1} C_i' + ρ I)^{-1},\\quad
        Y_i = Y_{i-1} - p_i K_i C_i Y_{i-1},\\quad h_0(X) = A Y_N A'

    with Y_0 = X and ρ = ``reg``·tr X.
    """
    Y = symmetrize(np.asarray(X, dtype=float))
    r = reg * max(float(np.trace(Y)), 1e-300)
    gains = []
    for pi, C in zip(p, plant.blocks):
        YC = Y @ C.T
        if C.shape[0] == 1:
            K = YC / (float((C @ YC)[0, 0]) + r)
        else:
            K = np.linalg.solve(C @ YC + r * np.eye(C.shape[0]), YC.T).T
        gains.append(K)
        Y = symmetrize(Y - float(pi) * (K @ YC.T))
    return gains, symmetrize(plant.a @ Y @ plant.a.T)


def power_gains(plant: SeqPlant, p: np.ndarray, iterations: int = 80,
                eps: float = 1e-10) -> tuple[list[np.ndarray], np.ndarray]:
    """Gains at the normalised power iterate of X ↦ h_0(X) + ε tr(X) I (a search guide)."""
    n = plant.n
    X = np.eye(n) / n
    for _ in range(iterations):
        _, Y = sequential_gains(plant, p, X)
        Y = Y + eps * float(np.trace(X)) * np.eye(n)
        t = float(np.trace(Y))
        if not (np.isfinite(t) and t > 0):
            break
        X = 0.5 * (X + Y / t)
    gains, _ = sequential_gains(plant, p, X + 1e-6 * np.eye(n) / n)
    return gains, X


def improve(plant: SeqPlant, p: np.ndarray, gains: Sequence[np.ndarray],
            rounds: int = POLICY_ROUNDS) -> tuple[np.ndarray | None, list[np.ndarray], float]:
    """Policy iteration at fixed p: Stein solve, then the gains optimal at its solution.

    Returns (X, gains, ρ) of the best stabilising gains found (X None when none stabilise).
    Each round does not increase ρ(𝓛_p) in exact arithmetic (docs/theory.md §15.5); a round
    that does is rejected.
    """
    gains = list(gains)
    L = operator(plant, p, gains)
    rho = radius(L)
    X = stein(L, plant.n)
    if X is None:
        return None, gains, rho
    for _ in range(rounds):
        new, _ = sequential_gains(plant, p, X)
        L2 = operator(plant, p, new)
        r2 = radius(L2)
        X2 = stein(L2, plant.n)
        if X2 is None or r2 >= rho * (1 - 1e-12):
            break
        X, gains, rho = X2, new, r2
    return X, gains, rho


# ---------------------------------------------------------------------------------------------
# fixed-gain thresholds along paths
# ---------------------------------------------------------------------------------------------

OperatorPath = Callable[[float], np.ndarray]
"""s ↦ the matrix of 𝓛_{p(s)} for fixed gains."""


def coordinate_family(plant: SeqPlant, p: np.ndarray, gains: Sequence[np.ndarray]
                      ) -> Callable[[int], tuple[np.ndarray, np.ndarray]]:
    """For each sensor i the affine pair (L_0, L_1) of 𝓛 with p_i = s, others at p.

    .. math:: L(s) = T_A\\,S_i\\,((1-s) I + s T_{F_i})\\,P_i = L_0 + s L_1,

    P_i = M_{i−1}⋯M_1, S_i = M_N⋯M_{i+1}; the prefix and suffix products are built once.
    """
    T, M = factors(plant, p, gains)
    N, nv = M.shape[0], M.shape[1]
    pre = [np.eye(nv)]
    for k in range(N):
        pre.append(M[k] @ pre[-1])
    suf = [plant.ta()]
    for k in range(N - 1, -1, -1):
        suf.append(suf[-1] @ M[k])
    suf = suf[::-1]           # suf[k] = T_A M_{N-1}⋯M_k (0-based), suf[N] = T_A

    def pair(i: int) -> tuple[np.ndarray, np.ndarray]:
        left, right = suf[i + 1], pre[i]
        L0 = left @ right
        return L0, left @ (T[i] - np.eye(nv)) @ right
    return pair


def fixed_gain_threshold(op: OperatorPath, lo: float, hi: float,
                         steps: int = BISECT_STEPS, atol: float = 1e-13) -> float | None:
    """Least s in [lo, hi] with ρ(op(s)) < 1 by bisection (``lo`` if it holds there; None if
    not even at ``hi``). A guide: the certificate is checked separately."""
    if radius(op(lo)) < 1.0:
        return lo
    if radius(op(hi)) >= 1.0:
        return None
    a, b = lo, hi
    for _ in range(steps):
        mid = 0.5 * (a + b)
        if mid in (a, b) or b - a < atol:
            break
        if radius(op(mid)) < 1.0:
            b = mid
        else:
            a = mid
    return b


# ---------------------------------------------------------------------------------------------
# checking a certificate in ball arithmetic
# ---------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class SeqCheck:
    """Outcome of :func:`verify_sequential` (rigorous lower bounds on the margins)."""

    ok: bool
    p: tuple[float, ...]
    min_eig_x: float | None
    margin: float | None
    reason: str
    ball: bool = True

    def to_dict(self) -> dict:
        how = (f"python-flint arb ball arithmetic ({PRECISION_BITS} bits) on the exact A, C; "
               "p_i as the exact dyadic rationals of the floats" if self.ball else
               "float64 check only")
        return {"ok": self.ok, "p": list(self.p), "received_sets": 0,
                "all_received_sets": True, "min_eig_x_lower": self.min_eig_x,
                "margin_lower": self.margin, "reason": self.reason, "kind": KIND,
                "verified_by": how}


@dataclass(frozen=True)
class ExactPlant:
    """Ball matrices of the exact A and the sensors' exact C_i (built once per network)."""

    a: flint.arb_mat
    blocks: tuple[flint.arb_mat, ...]

    @classmethod
    def of(cls, A_exact, C_blocks_exact) -> ExactPlant:
        old = flint.ctx.prec
        flint.ctx.prec = PRECISION_BITS
        try:
            return cls(arb_from_sympy(A_exact), tuple(arb_from_sympy(C) for C in C_blocks_exact))
        finally:
            flint.ctx.prec = old


def verify_sequential(exact: ExactPlant, p: np.ndarray, X: np.ndarray,
                      gains: Sequence[np.ndarray]) -> SeqCheck:
    """Prove mean stability at ``p``: X ≻ 0 and X − A (M_N ∘ ⋯ ∘ M_1)(X) A' ≻ 0 in balls.

    .. math:: X - A\\,(M_N\\circ\\cdots\\circ M_1)(X)\\,A' \\succ 0,\\quad
              M_i(Y) = (1-p_i) Y + p_i (I - K_i C_i) Y (I - K_i C_i)'
    """
    old = flint.ctx.prec
    flint.ctx.prec = PRECISION_BITS
    try:
        return _verify(exact, p, X, gains)
    finally:
        flint.ctx.prec = old


def _verify(exact: ExactPlant, p: np.ndarray, X: np.ndarray,
            gains: Sequence[np.ndarray]) -> SeqCheck:
    pt = tuple(float(v) for v in p)
    if not np.all(np.isfinite(X)) or not all(np.all(np.isfinite(K)) for K in gains):
        return SeqCheck(False, pt, None, None, "non-finite entry")
    Xa = arb_from_float(symmetrize(np.asarray(X, dtype=float)))
    mx = definite_margin(Xa)
    if mx is None:
        return SeqCheck(False, pt, None, None, "X is not proven positive definite")
    n = Xa.nrows()
    eye = flint.arb_mat(n, n)
    for k in range(n):
        eye[k, k] = 1
    Y = Xa
    for pi, K, C in zip(pt, gains, exact.blocks):
        if pi == 0.0:
            continue
        F = eye - arb_from_float(K) * C
        FYF = F * Y * F.transpose()
        Y = FYF if pi == 1.0 else Y * flint.arb(1 - flint.arb(pi)) + FYF * flint.arb(pi)
    mm = definite_margin(Xa - exact.a * Y * exact.a.transpose())
    if mm is None:
        return SeqCheck(False, pt, mx, None, "X - A M_N(...M_1(X))A' is not proven positive "
                                            "definite")
    return SeqCheck(True, pt, mx, mm, "proven")


def float_ok(plant: SeqPlant, p: np.ndarray, X: np.ndarray, gains: Sequence[np.ndarray]) -> bool:
    """The same test in float64 (a filter before the ball check)."""
    Y = symmetrize(X)
    for pi, F in zip(p, closed_loops(plant, gains)):
        Y = (1.0 - pi) * Y + pi * (F @ Y @ F.T)
    D = symmetrize(X - plant.a @ Y @ plant.a.T)
    try:
        t = float(np.trace(X))
        return bool(np.linalg.eigvalsh(symmetrize(X)).min() > 0
                    and np.linalg.eigvalsh(D / t).min() > 1e-14)
    except np.linalg.LinAlgError:
        return False
