"""Numerical kernels of the sensor-network analysis (theory §9): received sets, the noise-free
expected map, its threshold along a path in (p_1..p_N), and checked certificates.

Received sets S ⊆ {1..N} are rows of a boolean matrix ``masks`` (K × N). With independent
Bernoulli links π(S) = Π_{i∈S} p_i Π_{i∉S} (1 − p_i). A *collection* is either every set
(K = 2^N, exact) or a sub-collection 𝒞 containing ∅; then the probability of every set outside
𝒞 is added to ∅ ("treated as total loss"). That is the jump-linear system in which the sets
outside 𝒞 use the gain K_S = 0, so a certificate for it is a certificate for the network (a
valid sufficient condition; theory §3's argument with one mode per received set).

The noise-free expected map (Q = R = 0, homogeneous regulariser ε·tr X) is

.. math::

    G^ε_p(X) = A X A' + ε t I − A X C' W C X A',\\quad
    W = \\sum_S w_S\\, D_S (D_S (C X C' + ε t I) D_S + I − D_S)^{-1} D_S,

with t = tr X, D_S the diagonal 0/1 selector of the rows of S and w_S the collection's
weights: the per-set inverses are one batched NumPy solve. The optimal gain of set S is
K_S = −A X C' B_S (zero columns outside S), F_S = A + K_S C, and
G^ε_p(X) = Σ_S w_S (F_S X F_S' + ε t (I + K_S K_S')) (Sinopoli Lemma 1(a) term by term), so the
envelope Jacobian in X is Σ_S w_S F_S ⊗ F_S (plus the ε term).

A certificate is X ≻ 0 and gains K_S with X − Σ_S w_S F_S X F_S' ≻ 0; it is checked in ball
arithmetic (python-flint) on the exact A, C, with the weights formed exactly from the float
arrival probabilities (:func:`verify_network_certificate`).
"""
from __future__ import annotations

import heapq
import math
from collections.abc import Callable
from dataclasses import dataclass

import flint
import numpy as np

from kfcrit.errors import NumericalError
from kfcrit.theory.covariance.riccati import symmetrize, unvech, vech
from kfcrit.theory.upper.certify import PRECISION_BITS, arb_from_float, arb_from_sympy, definite_margin

EXACT_MAX_SENSORS = 12
"""Up to this many sensors every received set is enumerated (2^N, vectorised)."""
COLLECTION_BUDGET = 4096
"""Beyond EXACT_MAX_SENSORS: the most likely received sets kept (the rest count as total loss)."""
NEWTON_EPS = 1e-9
"""Regulariser of the threshold Newton (Q = R = ε·tr X·I): its root is a little above the
plain threshold, and its eigenvector X_ε ≻ 0 with gains K_ε is a certificate there."""
CONGRUENCE_MAX_BYTES = 1 << 30
"""Most memory of one batch of vech congruence operators (K × N_v × N_v floats, with its
temporaries); beyond, the certificate search is refused rather than run out of memory."""
POWER_FLOOR = 1e-12
"""Homogeneous regulariser floor of the plain map (keeps C_S X C_S' + εtI invertible)."""


# ---------------------------------------------------------------------------------------------
# received sets and their probabilities
# ---------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Collection:
    """Received sets (``masks``, K × N booleans; row 0 is ∅) and whether they are all of them."""

    masks: np.ndarray
    complete: bool

    @property
    def size(self) -> int:
        return int(self.masks.shape[0])


def all_received_sets(N: int) -> Collection:
    """Every subset of {0..N−1}: row k holds the bits of k (row 0 = ∅, row 2^N − 1 = all)."""
    k = np.arange(2 ** N)[:, None]
    masks = ((k >> np.arange(N)[None, :]) & 1).astype(bool)
    masks.setflags(write=False)
    return Collection(masks, True)


def likely_received_sets(p: np.ndarray, budget: int = COLLECTION_BUDGET) -> Collection:
    """The ``budget`` most likely received sets under p (best-first search), ∅ first.

    Sets are grown from the most likely one (i ∈ S iff p_i ≥ 1/2) by flipping sensors in order
    of increasing cost |log(p_i/(1 − p_i))|, the standard k-best enumeration of a product
    distribution; ∅ is always included (it carries the mass of the sets left out).
    """
    p = np.clip(np.asarray(p, dtype=float), 0.0, 1.0)
    N = p.size
    base = p >= 0.5
    with np.errstate(divide="ignore"):
        cost = np.abs(np.log(np.maximum(p, 1e-300)) - np.log(np.maximum(1 - p, 1e-300)))
    order = np.argsort(cost, kind="stable")
    c = cost[order]
    out = [base.copy()]
    # heap of (cost, last flipped position, flipped tuple)
    heap: list[tuple[float, int, tuple[int, ...]]] = [(float(c[0]), 0, (0,))] if N else []
    while heap and len(out) < budget:
        tot, last, flips = heapq.heappop(heap)
        m = base.copy()
        for j in flips:
            m[order[j]] = ~m[order[j]]
        out.append(m)
        if last + 1 < N:
            heapq.heappush(heap, (tot + float(c[last + 1]), last + 1, flips + (last + 1,)))
            heapq.heappush(heap, (tot - float(c[last]) + float(c[last + 1]), last + 1,
                                  flips[:-1] + (last + 1,)))
    masks = np.array(out, dtype=bool).reshape(-1, N)
    empty = ~masks.any(axis=1)
    if empty.any():
        masks = np.vstack([masks[empty][:1], masks[~empty]])
    else:
        masks = np.vstack([np.zeros((1, N), dtype=bool), masks[:-1] if len(masks) >= budget
                           else masks])
    masks.setflags(write=False)
    return Collection(masks, False)


def collection_for(p: np.ndarray, N: int) -> Collection:
    """Every set for N ≤ :data:`EXACT_MAX_SENSORS`, else the most likely ones at ``p``."""
    return all_received_sets(N) if N <= EXACT_MAX_SENSORS else likely_received_sets(p)


def set_factors(masks: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Per set and sensor the factor p_i (i ∈ S) or 1 − p_i (i ∉ S), K × N."""
    return np.where(masks, p[None, :], 1.0 - p[None, :])


def weights(col: Collection, p: np.ndarray, dp: np.ndarray | None = None
            ) -> tuple[np.ndarray, np.ndarray | None]:
    """Weights w_S = π(S) (sets outside the collection added to ∅) and their derivative along
    the direction ``dp`` (d/ds of w_S when p moves with dp/ds = ``dp``).

    .. math:: \\frac{dπ(S)}{ds} = \\sum_i dp_i\\,(±1)\\prod_{j≠i} f_j(S)
    """
    f = set_factors(col.masks, p)
    w = np.prod(f, axis=1)
    dw = None
    if dp is not None:
        K, N = f.shape
        left = np.cumprod(np.hstack([np.ones((K, 1)), f[:, :-1]]), axis=1)   # Π_{j<i}
        tail = np.cumprod(f[:, ::-1], axis=1)[:, ::-1]                          # Π_{j≥i}
        right = np.hstack([tail[:, 1:], np.ones((K, 1))])                       # Π_{j>i}
        others = left * right
        sign = np.where(col.masks, 1.0, -1.0)
        dw = (others * sign) @ dp
    if not col.complete:
        w = w.copy()
        w[0] += max(0.0, 1.0 - float(w.sum()))
        if dw is not None:
            dw = dw.copy()
            dw[0] -= float(dw.sum())
    return w, dw


# ---------------------------------------------------------------------------------------------
# the expected map, batched over received sets
# ---------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Plant:
    """Float arrays of the stacked network: A (n × n), C (m × n), the sensor of each row."""

    a: np.ndarray
    c: np.ndarray
    owner: np.ndarray

    def row_masks(self, col: Collection) -> np.ndarray:
        """K × m: row r is received in set S iff its sensor is in S."""
        return col.masks[:, self.owner]


def set_inverses(plant: Plant, rows: np.ndarray, X: np.ndarray, reg: float) -> np.ndarray:
    """B_S = D_S (D_S (C X C' + reg I) D_S + I − D_S)^{-1} D_S for every set (K × m × m)."""
    m = plant.c.shape[0]
    M = symmetrize(plant.c @ X @ plant.c.T) + reg * np.eye(m)
    pair = rows[:, :, None] & rows[:, None, :]
    Ms = np.where(pair, M[None], np.eye(m)[None])
    return np.linalg.inv(Ms) * pair


def expected_map(plant: Plant, B: np.ndarray, X: np.ndarray, w: np.ndarray,
                 eps: float) -> np.ndarray:
    """G^ε(X) = A X A' + ε t I − A X C' (Σ w_S B_S) C X A' (t = tr X)."""
    n = X.shape[0]
    AXC = plant.a @ X @ plant.c.T
    W = np.tensordot(w, B, axes=1)
    return symmetrize(plant.a @ X @ plant.a.T + eps * np.trace(X) * np.eye(n) - AXC @ W @ AXC.T)


def set_gains(plant: Plant, B: np.ndarray, X: np.ndarray) -> np.ndarray:
    """K_S = −A X C' B_S (K × n × m)."""
    AXC = plant.a @ X @ plant.c.T
    return -np.einsum("ij,kjl->kil", AXC, B)


def congruence_batch(F: np.ndarray) -> np.ndarray:
    """Matrices of X ↦ F_S X F_S' on ``vech`` coordinates, batched (K × N_v × N_v).

    Refused (NumericalError naming the limit) when the K × N_v × N_v result and its two
    temporaries would exceed :data:`CONGRUENCE_MAX_BYTES`, N_v = n(n + 1)/2.
    """
    n = F.shape[-1]
    nv = n * (n + 1) // 2
    need = 3 * F.shape[0] * nv * nv * 8
    if need > CONGRUENCE_MAX_BYTES:
        raise NumericalError(
            f"the network certificate needs {F.shape[0]} operators of size {nv} × {nv} "
            f"(n = {n} states, {need / 2 ** 30:.1f} GiB), above the limit of "
            f"{CONGRUENCE_MAX_BYTES / 2 ** 30:.0f} GiB", field="network")
    iu, ju = np.triu_indices(n)
    Fr, Fs = F[:, iu, :], F[:, ju, :]
    T = Fr[:, :, iu] * Fs[:, :, ju] + Fr[:, :, ju] * Fs[:, :, iu]
    T[:, :, iu == ju] *= 0.5
    return T


def network_cone_radius(plant: Plant, col: Collection, p: np.ndarray, X0: np.ndarray | None = None,
                iterations: int = 400, rtol: float = 1e-11, eps: float = 0.0
                ) -> tuple[float, np.ndarray]:
    """Cone spectral radius of G^ε_p by averaged normalised power iteration (as
    :func:`kfcrit.theory.upper.cone.cone_radius`, for the expected map over received sets)."""
    n = plant.a.shape[0]
    rows = plant.row_masks(col)
    w, _ = weights(col, p)
    X = np.eye(n) / n if X0 is None else X0 / np.trace(X0)
    r = float("nan")
    for _ in range(iterations):
        B = set_inverses(plant, rows, X, max(eps, POWER_FLOOR) * float(np.trace(X)))
        Y = expected_map(plant, B, X, w, eps)
        r = float(np.trace(Y))
        if not np.isfinite(r) or r <= 0:
            return r, X
        Y = Y / r
        done = np.abs(Y - X).max() < rtol
        X = 0.5 * (X + Y)
        if done:
            break
    return r, X


# ---------------------------------------------------------------------------------------------
# Newton for the threshold along a path p(s)
# ---------------------------------------------------------------------------------------------

Path = Callable[[float], tuple[np.ndarray, np.ndarray]]
"""s ↦ (p(s), dp/ds); stability improves with s."""


@dataclass(frozen=True)
class Threshold:
    """Root (X, s) of G^ε_{p(s)}(X) = X, tr X = 1, with the gains at the root."""

    s: float
    X: np.ndarray
    gains: np.ndarray
    converged: bool
    iterations: int


def network_threshold_newton(plant: Plant, col: Collection, path: Path, X0: np.ndarray, s0: float,
                     eps: float = NEWTON_EPS, max_iterations: int = 40,
                     atol: float = 1e-13) -> Threshold:
    """Newton on G^ε_{p(s)}(X) = X, tr X = 1 in (X, s) (theory §3's threshold Newton, with one
    term per received set). Jacobian: [Σ w F⊗F − I + ε·vech(I + Σ w K K')·diag', ∂G/∂s;
    diag', 0] with ∂G/∂s = −A X C' (Σ dw_S B_S) C X A'."""
    n = plant.a.shape[0]
    Nv = n * (n + 1) // 2
    iu, ju = np.triu_indices(n)
    diag = (iu == ju).astype(float)
    rows = plant.row_masks(col)
    X, s = symmetrize(X0) / np.trace(X0), float(s0)
    gains = np.zeros((col.size, n, plant.c.shape[0]))
    for it in range(max_iterations + 1):
        p, dp = path(s)
        w, dw = weights(col, p, dp)
        t = float(np.trace(X))
        try:
            B = set_inverses(plant, rows, X, eps * t)
        except np.linalg.LinAlgError:
            return Threshold(s, X, gains, False, it)
        G = expected_map(plant, B, X, w, eps)
        gains = set_gains(plant, B, X)
        res = np.concatenate([vech(G - X), [t - 1.0]])
        if not np.all(np.isfinite(res)):
            return Threshold(s, X, gains, False, it)
        if np.abs(res).max() < atol:
            return Threshold(s, X, gains, True, it)
        if it == max_iterations:
            # the certificate is checked independently: a nearly converged root is enough
            return Threshold(s, X, gains, bool(np.abs(res).max() < 1e-8), it)
        F = plant.a[None] + gains @ plant.c[None]
        J = np.zeros((Nv + 1, Nv + 1))
        J[:Nv, :Nv] = np.tensordot(w, congruence_batch(F), axes=1) - np.eye(Nv)
        KK = np.einsum("k,kij,klj->il", w, gains, gains)
        J[:Nv, :Nv] += eps * np.outer(vech(np.eye(n) + KK), diag)
        AXC = plant.a @ X @ plant.c.T
        J[:Nv, Nv] = -vech(symmetrize(AXC @ np.tensordot(dw, B, axes=1) @ AXC.T))
        J[Nv, :Nv] = diag
        try:
            d = np.linalg.solve(J, -res)
        except np.linalg.LinAlgError:
            return Threshold(s, X, gains, False, it)
        X = X + unvech(d[:Nv], n)
        s = s + float(d[Nv])
        if not np.isfinite(s) or abs(s) > 4:
            return Threshold(s, X, gains, False, it)
    return Threshold(s, X, gains, False, max_iterations)


def stein_solution(plant: Plant, col: Collection, p: np.ndarray, gains: np.ndarray
                   ) -> np.ndarray | None:
    """X solving X = Σ_S w_S F_S X F_S' + I (F_S = A + K_S C); None unless the operator's
    spectral radius is below 1 (then X ⪰ I is a certificate candidate)."""
    n = plant.a.shape[0]
    w, _ = weights(col, p)
    F = plant.a[None] + gains @ plant.c[None]
    L = np.tensordot(w, congruence_batch(F), axes=1)
    if max(abs(np.linalg.eigvals(L))) >= 1:
        return None
    x = np.linalg.solve(np.eye(L.shape[0]) - L, vech(np.eye(n)))
    return unvech(x, n)


def policy_gains(plant: Plant, col: Collection, X: np.ndarray, reg: float) -> np.ndarray:
    """Gains K_S = −A X C_S' (C_S X C_S' + reg I)^{-1} of a covariance-like X, every set."""
    B = set_inverses(plant, plant.row_masks(col), X, reg)
    return set_gains(plant, B, X)


# ---------------------------------------------------------------------------------------------
# checking a certificate in ball arithmetic
# ---------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class NetworkCheck:
    """Outcome of :func:`verify_network_certificate` (rigorous lower bounds on the margins)."""

    ok: bool
    p: tuple[float, ...]
    sets: int
    complete: bool
    min_eig_x: float | None
    margin: float | None
    reason: str

    def to_dict(self) -> dict:
        return {"ok": self.ok, "p": list(self.p), "received_sets": self.sets,
                "all_received_sets": self.complete, "min_eig_x_lower": self.min_eig_x,
                "margin_lower": self.margin, "reason": self.reason,
                "kind": "X > 0 and X - sum_S w_S F_S X F_S' > 0, F_S = A + K_S C_S",
                "verified_by": f"python-flint arb ball arithmetic ({PRECISION_BITS} bits) on "
                               "the exact A, C; weights formed exactly from the float p"}


def verify_network_certificate(A_exact, C_exact, col: Collection, owner: np.ndarray,
                               p: np.ndarray, X: np.ndarray, gains: np.ndarray) -> NetworkCheck:
    """Prove mean stability at ``p``: X ≻ 0 and X − Σ_S w_S (A + K_S C) X (A + K_S C)' ≻ 0.

    The weights are formed in balls from the float p (each an exact dyadic rational):
    w_S = Π_{i∈S} p_i Π_{i∉S}(1 − p_i), and for a sub-collection the rest 1 − Σ_{S≠∅} w_S is
    added to ∅ (gain 0 there). Gains are zeroed outside their set's rows before the check (a
    gain acts only on received rows).
    """
    old = flint.ctx.prec
    flint.ctx.prec = PRECISION_BITS
    try:
        return _verify(A_exact, C_exact, col, owner, p, X, gains)
    finally:
        flint.ctx.prec = old


def _verify(A_exact, C_exact, col, owner, p, X, gains) -> NetworkCheck:
    pt = tuple(float(v) for v in p)
    A = arb_from_sympy(A_exact)
    C = arb_from_sympy(C_exact)
    n = A.nrows()
    if not np.all(np.isfinite(X)) or not np.all(np.isfinite(gains)):
        return NetworkCheck(False, pt, col.size, col.complete, None, None, "non-finite entry")
    Xa = arb_from_float(symmetrize(np.asarray(X, dtype=float)))
    mx = definite_margin(Xa)
    if mx is None:
        return NetworkCheck(False, pt, col.size, col.complete, None, None,
                            "X is not proven positive definite")
    pa = [flint.arb(v) for v in pt]
    rows = col.masks[:, owner]
    total = flint.arb_mat(n, n)
    wsum = flint.arb(0)
    for k in range(col.size):
        w = flint.arb(1)
        for i, inside in enumerate(col.masks[k]):
            w *= pa[i] if inside else (1 - pa[i])
        if not col.complete and k == 0:
            continue
        wsum += w
        K = np.where(rows[k][None, :], gains[k], 0.0)
        F = A + arb_from_float(K) * C if rows[k].any() else A
        total += (F * Xa * F.transpose()) * w
    if not col.complete:
        w0 = 1 - wsum
        total += (A * Xa * A.transpose()) * w0
    mm = definite_margin(Xa - total)
    if mm is None:
        return NetworkCheck(False, pt, col.size, col.complete, mx, None,
                            "X - sum_S w_S F_S X F_S' is not proven positive definite")
    return NetworkCheck(True, pt, col.size, col.complete, mx, mm, "proven")


def certify_at(plant: Plant, A_exact, C_exact, col: Collection, p: np.ndarray,
               X: np.ndarray, gains: np.ndarray | None = None,
               ball: bool = True) -> tuple[NetworkCheck | None, np.ndarray | None,
                                           np.ndarray | None]:
    """Try to certify mean stability at ``p`` from a covariance-like X (e.g. a regularised
    eigenvector near the boundary): X itself with ``gains``, then the Stein solution for the
    gains of X, then two policy-iteration steps. Returns (check, X, gains) of the first that
    passes (in balls when ``ball``, else the float test), or (last check, None, None)."""
    n = plant.a.shape[0]
    last = None
    candidates = []
    if gains is not None:
        candidates.append((X, gains))
    Xn = symmetrize(X) / np.trace(X)
    for eta in (1e-9, 1e-6, 1e-3, 1e-1):
        # gains of X + η I: a near-singular eigenvector leaves some directions' gains free;
        # policy iteration (Stein solve, new gains) then improves stabilising gains
        Xg = Xn + eta * np.eye(n) / n
        found = False
        for _ in range(6):
            K = policy_gains(plant, col, Xg, 1e-9)
            Xs = stein_solution(plant, col, p, K)
            if Xs is None:
                break
            found = True
            candidates.append((Xs, K))
            Xg = Xs / np.trace(Xs)
        if found:
            break
    for Xc, K in candidates:
        if not _float_ok(plant, col, p, Xc, K):
            continue
        if not ball:
            return NetworkCheck(True, tuple(map(float, p)), col.size, col.complete, None, None,
                                "float64 check only"), Xc, K
        chk = verify_network_certificate(A_exact, C_exact, col, plant.owner, p, Xc, K)
        if chk.ok:
            return chk, Xc, K
        last = chk
    return last, None, None


def _float_ok(plant: Plant, col: Collection, p: np.ndarray, X: np.ndarray,
              gains: np.ndarray) -> bool:
    w, _ = weights(col, p)
    rows = plant.row_masks(col)
    K = np.where(rows[:, None, :], gains, 0.0)
    F = plant.a[None] + K @ plant.c[None]
    L = np.einsum("k,kij,jl,kml->im", w, F, X, F)
    D = symmetrize(X - L)
    Xs = symmetrize(X)
    try:
        return bool(np.linalg.eigvalsh(Xs).min() > 0 and np.linalg.eigvalsh(
            D / math.sqrt(np.trace(Xs) ** 2)).min() > 1e-13)
    except np.linalg.LinAlgError:
        return False
