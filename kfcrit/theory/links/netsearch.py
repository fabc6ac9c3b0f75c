"""Searching and certifying the sufficient surface of a network with one-sensor maps
(docs/theory.md §15.5–§15.6): the sequential counterpart of the received-set search in
:mod:`kfcrit.theory.links.network`.

A boundary along a path p(s) is a certified interval [s_nec, s_cert]: s_nec from the necessary
surface (closed form, docs/theory.md §9.2), s_cert where a product-form certificate

.. math:: X \\succ 0,\\qquad X - A\\,(M_N\\circ\\cdots\\circ M_1)(X)\\,A' \\succ 0

is proven in ball arithmetic. The search alternates a fixed-gain threshold (bisection on the
spectral radius of the operator, affine in s on a coordinate path) with policy iteration of the
gains; it only guides. The cost is polynomial in the number N of sensors: O(N n_v³) per operator.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from kfcrit.model.network import Network
from kfcrit.theory.critical.section import structure_of
from kfcrit.theory.links import netseq as ns

CERT_STEPS = (0.5, 1.0, 10.0, 100.0, 1e3, 1e4, 1e5, 1e6)
"""Certificates are tried at the fixed-gain threshold + step·tol for these steps."""
COARSE_GAP = 1e-6
"""A first fixed-gain threshold this far above the start of the path triggers the coarse search."""
COARSE_STEPS = 10
"""Bisection steps of the coarse search with fresh power-iteration gains."""
COARSE_BUDGET = 8
"""Most coarse bisections per analysis (each costs COARSE_STEPS power iterations); beyond,
the brackets keep the end found from the seed gains (certified, wider)."""
COARSE_POWER = 50
"""Power iterations per point of the coarse search."""
MODAL_TOL = 1e-9
"""Relative tolerance of the float rank decisions of the modal gains."""

Path = Callable[[float], tuple[np.ndarray, np.ndarray]]


@dataclass(frozen=True)
class Boundary:
    """Where a path p(s) crosses into 𝓢: s_c ∈ [s_nec, s_cert] (None: not found)."""

    s_nec: float | None
    s_cert: float | None
    check: dict[str, Any] | None
    note: str


def modal_gains(network: Network, tol: float = MODAL_TOL) -> list[np.ndarray] | None:
    """Gains that cancel every unstable mode a sensor sees (docs/theory.md §15.6).

    With W_i a real basis of the span of the eigenvectors w_j (|λ_j| ≥ 1) that sensor i sees
    (C_i w_j ≠ 0),

    .. math:: K_i = W_i\\,(C_i W_i)^{+},\\qquad K_i C_i W_i = W_i ,

    so F_i = I − K_i C_i maps every seen mode to 0, fixes every unseen one and moves nothing out
    of the unstable subspace. None when a mode with |λ| ≥ 1 is not diagonalizable or some sensor
    sees its modes through dependent outputs (C_i W_i without full column rank).
    """
    st = structure_of(network.stacked_system())
    rel = [e for k, e in enumerate(st.eigen) if st.relevant(k)]
    n = network.n
    if not rel:
        return [np.zeros((n, s.m)) for s in network.sensors]
    if any(e.geometric != e.multiplicity for e in rel):
        return None
    W = np.hstack([np.asarray(e.basis, dtype=complex) for e in rel])
    c = network.stacked_system().c
    scale = max(float(np.linalg.norm(c, 2)), 1.0)
    out = []
    for sl in network.row_slices():
        Ci = c[sl]
        CW = Ci @ W
        seen = np.linalg.norm(CW, axis=0) > tol * scale
        if not seen.any():
            out.append(np.zeros((n, Ci.shape[0])))
            continue
        if np.linalg.matrix_rank(CW[:, seen], tol * scale) != int(seen.sum()):
            return None
        Ws = W[:, seen]
        U, sv, _ = np.linalg.svd(np.hstack([Ws.real, Ws.imag]), full_matrices=False)
        Wr = U[:, sv > tol * max(sv.max(), 1.0)]
        out.append(Wr @ np.linalg.pinv(Ci @ Wr))
    return out


@dataclass
class SeqContext:
    """The sequential search of one network at operating point ``p`` (docs/theory.md §15)."""

    network: Network
    p: np.ndarray
    tol: float
    ball: bool
    seed: list[np.ndarray] | None = None
    stats: dict[str, Any] = field(default_factory=lambda: {"newton": 0, "bisection": 0,
                                                          "certificates": 0})

    def __post_init__(self) -> None:
        st = self.network.stacked_system()
        self.plant = ns.SeqPlant(st.a, tuple(st.c[sl] for sl in self.network.row_slices()))
        self.exact = ns.ExactPlant.of(st.A, [st.C[sl.start:sl.stop, :]
                                             for sl in self.network.row_slices()])
        self._base: list[np.ndarray] | None = None
        self._coarse_left = COARSE_BUDGET
        self._family = None

    # ---- gains and certificates --------------------------------------------------------------

    def base_gains(self) -> list[np.ndarray]:
        """Seed gains: the modal gains when given, else policy-improved power-iteration gains
        at the operating point."""
        if self._base is None:
            if self.seed is not None:
                self._base = list(self.seed)
            else:
                g, _ = ns.power_gains(self.plant, self.p)
                X, g2, _ = ns.improve(self.plant, self.p, g)
                self._base = g2 if X is not None else g
        return self._base

    def certify(self, p: np.ndarray, X: np.ndarray | None, gains: list[np.ndarray]
                ) -> ns.SeqCheck | None:
        """Float filter, then the ball check (None when X is None or the float test fails).

        The check is made at p one float below each nonzero p_i: a float within half an ulp of
        an exact arrival probability then never exceeds it, and the region is an up-set
        (docs/theory.md §9.1), so the certificate also holds at the exact values.
        """
        p = np.where(p > 0.0, np.nextafter(p, 0.0), 0.0)
        if X is None or not ns.float_ok(self.plant, p, X, gains):
            return None
        self.stats["certificates"] += 1
        if not self.ball:
            return ns.SeqCheck(True, tuple(map(float, p)), None, None, "float64 check only",
                               ball=False)
        chk = ns.verify_sequential(self.exact, p, X, gains)
        return chk if chk.ok else None

    def try_at(self, p: np.ndarray, X0: np.ndarray | None = None):
        """A certificate at p from the seed gains (then power-iteration gains), or None."""
        seeds = [self.base_gains()]
        for g in seeds + [None]:
            if g is None:
                g, _ = ns.power_gains(self.plant, p)
            X, gains, _ = ns.improve(self.plant, p, g)
            chk = self.certify(p, X, gains)
            if chk is not None:
                return chk, X
        return None, X0

    # ---- boundaries ----------------------------------------------------------------------------

    def coordinate_boundary(self, i: int, p: np.ndarray, s_nec: float | None) -> Boundary:
        """Certified crossing of the sufficient surface along p_i = s ∈ [0, 1] (others at
        ``p``, which must be the operating point)."""
        def point(s: float) -> np.ndarray:
            q = self.p.copy()
            q[i] = min(max(s, 0.0), 1.0)
            return q

        def family(gains: list[np.ndarray]) -> Callable[[float], np.ndarray]:
            if gains is self._base:
                if self._family is None:
                    self._family = ns.coordinate_family(self.plant, self.p, gains)
                pair = self._family
            else:
                pair = ns.coordinate_family(self.plant, self.p, gains)
            L0, L1 = pair(i)
            return lambda s: L0 + s * L1
        return self._search(point, family, 0.0, 1.0, s_nec)

    def path_boundary(self, path: Path, lo: float, hi: float, s_nec: float | None) -> Boundary:
        """Certified crossing of the sufficient surface along a general path on [lo, hi]."""
        def point(s: float) -> np.ndarray:
            return path(s)[0]

        ta = self.plant.ta()

        def family(gains: list[np.ndarray]) -> Callable[[float], np.ndarray]:
            T = ns.congruence_batch(ns.closed_loops(self.plant, gains))
            return lambda s: ns.operator_from(ta, T, point(s))
        return self._search(point, family, lo, hi, s_nec)

    def _search(self, point: Callable[[float], np.ndarray],
                family: Callable[[list[np.ndarray]], Callable[[float], np.ndarray]],
                lo: float, hi: float, s_nec: float | None) -> Boundary:
        """Fixed-gain threshold, certificate just above it, policy step; repeat."""
        if s_nec is None:
            return Boundary(None, None, None, "the necessary surface is not crossed on the path")
        start = min(max(s_nec, lo), hi)
        gains = self.base_gains()
        best: tuple[float, dict[str, Any]] | None = None
        reseeded = False
        for _ in range(ns.POLICY_ROUNDS):
            self.stats["bisection"] += 1
            op = family(gains)
            s_k = ns.fixed_gain_threshold(op, start, hi, atol=self.tol * 1e-2)
            if s_k is None:
                if reseeded:
                    break
                reseeded = True
                g, _ = ns.power_gains(self.plant, point(hi))
                _, gains, _ = ns.improve(self.plant, point(hi), g)
                continue
            if best is not None and s_k >= best[0] - self.tol:
                break
            if best is None and s_k > start + COARSE_GAP:
                gains = self._coarse(point, start, s_k, gains)
                op = family(gains)
                s_k = ns.fixed_gain_threshold(op, start, hi, atol=self.tol * 1e-2) or s_k
            found = self._certify_above(point, op, gains, s_k, start, hi,
                                        best[0] if best else None)
            if found is not None:
                best = found
            if s_k <= start:
                break
            s_up = min(hi, s_k + 10 * self.tol)
            X = ns.stein(op(s_up), self.plant.n)
            if X is None:
                break
            gains, _ = ns.sequential_gains(self.plant, point(s_up), X)
        if best is None:
            return Boundary(start, None, None, "no product-form certificate found on the path")
        return Boundary(start, best[0], best[1], "one-sensor maps (docs/theory.md §15), certified")

    def _coarse(self, point: Callable[[float], np.ndarray], a: float, b: float,
                gains: list[np.ndarray]) -> list[np.ndarray]:
        """Gains from a coarse bisection on [a, b] with fresh power-iteration gains at each
        point (policy iteration from barely stabilising gains converges slowly)."""
        self.stats["newton"] += 1
        g, _ = ns.power_gains(self.plant, point(a), iterations=COARSE_POWER)
        if ns.radius(ns.operator(self.plant, point(a), g)) < 1.0:
            return g
        self._coarse_left -= 1
        if self._coarse_left < 0:
            return gains
        for _ in range(COARSE_STEPS):
            mid = 0.5 * (a + b)
            g, _ = ns.power_gains(self.plant, point(mid), iterations=COARSE_POWER)
            if ns.radius(ns.operator(self.plant, point(mid), g)) < 1.0:
                b, gains = mid, g
            else:
                a = mid
        return gains

    def _certify_above(self, point, op, gains, s_k: float, start: float, hi: float,
                       bound: float | None) -> tuple[float, dict[str, Any]] | None:
        """The first certified s among s_k + step·tol (s_k itself when it is the start)."""
        cands = [s_k] if s_k <= start else []
        cands += [max(s_k + step * self.tol, start) for step in CERT_STEPS]
        for s in cands:
            if s > hi or (bound is not None and s >= bound):
                break
            X = ns.stein(op(s), self.plant.n)
            chk = self.certify(point(s), X, gains)
            if chk is not None:
                return s, chk.to_dict()
        return None
