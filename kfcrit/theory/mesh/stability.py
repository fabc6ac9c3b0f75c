"""Mean stability of the Kalman filter for ANY joint law π(S) of the received sensor set,
i.i.d. in time (theory §13, generalising §9), and the mesh facts built on it.

The expected map g(X) = A X A' + Q − Σ_S π(S) A X C_S'(C_S X C_S' + R_S)^{-1} C_S X A' is
monotone and concave for any law (Sinopoli's Lemma 1 term by term), so:

* **necessary**: for every sensor set T, with ρ_T the largest |λ| among the eigenvalues of A
  not observable through C_T,

  .. math:: P(S_t ⊆ T)\\,ρ_T^2 < 1

  (if every sensor outside T is lost for k steps, probability P(S ⊆ T)^k, those modes grow
  like ρ_T^{2k}). P(S ⊆ T) grows with T, so the maximal unobservable sets of
  :func:`kfcrit.theory.links.network.necessary_constraints` suffice; the binding T is the one with
  the largest value. Exact (sympy) when the law and ρ_T² are.
* **sufficient**: gains K_S and X ≻ 0 with

  .. math:: X ≻ \\sum_S π(S) (A + K_S C_S) X (A + K_S C_S)'

  found by power iteration on the noise-free expected map with weights π (the batched kernels
  of :mod:`kfcrit.theory.links.netkernels`), policy iteration and a Stein solve, and checked in
  ball arithmetic with the weights formed exactly from an exact law.
* **exact region**: the proof in :mod:`kfcrit.theory.links.network` (modal one-step observability)
  uses π only through P(S ⊆ B_j); it holds verbatim for any law, so where
  :func:`kfcrit.theory.links.network.modal_one_step` applies the region is exactly the necessary
  one (a claim beyond theory §13 until reviewed).

**Bottleneck hop** (:func:`hop_headrooms`): for hop h let σ ↦ π_σ be the law with the hop's
per-attempt success q_h replaced by σ ∈ [0, 1]; P_σ(S ⊆ T) is non-increasing in σ (every
route's delivery is non-decreasing in each hop outcome). The hop's critical success is
σ*_h = inf{σ : the necessary condition holds under π_σ}, its headroom q_h − σ*_h. A hop is
*critical* when the necessary condition fails with σ = 0 (its loss alone reaches the
necessary boundary); the bottleneck is the critical hop with the smallest headroom (a hop
that cannot restore the condition even at σ = 1 has σ* = None and counts as headroom −∞;
ties: hop order). σ*_h is found by float bisection to 1e-12.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import flint
import numpy as np
import sympy as sp

from kfcrit.errors import InputError
from kfcrit.model.mesh import Mesh
from kfcrit.model.network import Network
from kfcrit.theory.covariance.riccati import symmetrize, unvech, vech
from kfcrit.theory.facts import StabilityFacts
from kfcrit.theory.links import netkernels as nk
from kfcrit.theory.links.network import Constraint, factor_sign, modal_one_step, necessary_constraints
from kfcrit.theory.mesh.law import JointLaw, mesh_law
from kfcrit.theory.upper.certify import (
    PRECISION_BITS,
    arb_exact_number,
    arb_from_float,
    arb_from_sympy,
    definite_margin,
)

# ---------------------------------------------------------------------------------------------
# facts
# ---------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class ConstraintValue:
    """P(S ⊆ T)·ρ_T² for one maximal unobservable set T (``unobservable`` names T)."""

    unobservable: tuple[str, ...]
    eigenvalue: str
    modulus2: float
    probability: float
    value: float
    value_exact: sp.Expr | None
    holds: bool | None


@dataclass(frozen=True)
class NecessaryFact:
    """Whether every P(S ⊆ T)·ρ_T² < 1 (None: undecided at float precision); ``binding`` is
    the constraint with the largest value (None when A has no mode with |λ| ≥ 1)."""

    holds: bool | None
    binding: ConstraintValue | None
    constraints: tuple[ConstraintValue, ...]


@dataclass(frozen=True)
class SufficientFact:
    """A checked certificate X ≻ Σ π(S) F_S X F_S' (``certified``), its rigorous margins,
    whether the weights were exact, and the power-iteration radius estimate."""

    certified: bool
    weights: str
    min_eig_x: float | None
    margin: float | None
    radius: float | None
    reason: str


@dataclass(frozen=True)
class LawStability:
    """The stability facts under one joint law, with the evidence behind each.

    ``facts`` is what :mod:`kfcrit.analysis.verdict` reads (the necessary condition holds,
    fails or is undecided; a certificate is checked; the exact-region proof applies);
    ``exact`` says whether the facts decide (one of the three holds).
    """

    facts: StabilityFacts
    exact: bool
    reason: str
    necessary: NecessaryFact
    sufficient: SufficientFact
    exact_region: bool | None
    exact_region_reason: str


# ---------------------------------------------------------------------------------------------
# the law in network order
# ---------------------------------------------------------------------------------------------

def aligned_probabilities(network: Network, law: JointLaw) -> tuple[Any, ...]:
    """π in the bit order of ``network``'s sensors (the law's sensors must be the same names)."""
    if sorted(law.sensors) != sorted(network.names):
        raise InputError(f"law sensors {', '.join(law.sensors)} differ from the network's "
                         f"{', '.join(network.names)}", field="law.sensors")
    perm = [law.sensors.index(n) for n in network.names]
    out = []
    for k in range(2 ** network.size):
        j = sum(1 << perm[i] for i in range(network.size) if k >> i & 1)
        out.append(law.probabilities[j])
    return tuple(out)


def _owner(network: Network) -> np.ndarray:
    return np.concatenate([np.full(s.m, i) for i, s in enumerate(network.sensors)])


# ---------------------------------------------------------------------------------------------
# necessary
# ---------------------------------------------------------------------------------------------

def _within(pi: Sequence[Any], mask: int) -> Any:
    out: Any = 0
    for k, v in enumerate(pi):
        if k & ~mask == 0:
            out = out + v
    return out


def _constraint_value(network: Network, c: Constraint, pi: Sequence[Any],
                      exact: bool) -> ConstraintValue:
    mask = sum(1 << i for i in c.blind)
    P = _within(pi, mask)
    value = float(P) * c.mod2
    expr = sp.sympify(P) * c.mod2_expr if exact and c.mod2_expr is not None else None
    s = factor_sign(value, expr)
    names = tuple(network.names[i] for i in sorted(c.blind))
    return ConstraintValue(names, c.eigenvalue, c.mod2, float(P), value, expr,
                           None if s is None else s < 0)


def necessary_fact(network: Network, law: JointLaw,
                   constraints: Sequence[Constraint] | None = None) -> NecessaryFact:
    """The necessary condition P(S ⊆ T)·ρ_T² < 1 over the maximal unobservable sets."""
    cons = necessary_constraints(network) if constraints is None else constraints
    pi = aligned_probabilities(network, law)
    vals = tuple(_constraint_value(network, c, pi, law.exact) for c in cons)
    if not vals:
        return NecessaryFact(True, None, ())
    binding = max(vals, key=lambda v: v.value)
    holds: bool | None = True
    if any(v.holds is False for v in vals):
        holds = False
    elif any(v.holds is None for v in vals):
        holds = None
    return NecessaryFact(holds, binding, vals)


# ---------------------------------------------------------------------------------------------
# sufficient
# ---------------------------------------------------------------------------------------------

def _radius(plant: nk.Plant, col: nk.Collection, w: np.ndarray, iterations: int = 300
            ) -> tuple[float, np.ndarray]:
    """Cone spectral radius of the noise-free expected map with weights w (power iteration)."""
    n = plant.a.shape[0]
    rows = plant.row_masks(col)
    X = np.eye(n) / n
    r = float("nan")
    for _ in range(iterations):
        B = nk.set_inverses(plant, rows, X, nk.POWER_FLOOR * float(np.trace(X)))
        Y = nk.expected_map(plant, B, X, w, 0.0)
        r = float(np.trace(Y))
        if not np.isfinite(r) or r <= 0:
            return r, X
        Y = Y / r
        done = np.abs(Y - X).max() < 1e-11
        X = 0.5 * (X + Y)
        if done:
            break
    return r, X


def _stein(plant: nk.Plant, w: np.ndarray, gains: np.ndarray) -> np.ndarray | None:
    """X = Σ w_S F_S X F_S' + I when that operator's spectral radius is below 1."""
    n = plant.a.shape[0]
    F = plant.a[None] + gains @ plant.c[None]
    L = np.tensordot(w, nk.congruence_batch(F), axes=1)
    if max(abs(np.linalg.eigvals(L))) >= 1:
        return None
    return unvech(np.linalg.solve(np.eye(L.shape[0]) - L, vech(np.eye(n))), n)


def _float_ok(plant: nk.Plant, col: nk.Collection, w: np.ndarray, X: np.ndarray,
              gains: np.ndarray) -> bool:
    K = np.where(plant.row_masks(col)[:, None, :], gains, 0.0)
    F = plant.a[None] + K @ plant.c[None]
    D = symmetrize(X - np.einsum("k,kij,jl,kml->im", w, F, X, F))
    try:
        return bool(np.linalg.eigvalsh(symmetrize(X)).min() > 0
                    and np.linalg.eigvalsh(D / np.trace(X)).min() > 1e-13)
    except np.linalg.LinAlgError:
        return False


def verify_law_certificate(network: Network, pi: Sequence[Any], exact: bool, X: np.ndarray,
                           gains: np.ndarray) -> tuple[bool, float | None, float | None]:
    """Ball check of X ≻ 0 and X − Σ_S π(S) F_S X F_S' ≻ 0 on the exact A, C (weights exact
    for an exact law, else the float weights as given). Returns (ok, λ_min(X) lower bound,
    margin lower bound)."""
    old = flint.ctx.prec
    flint.ctx.prec = PRECISION_BITS
    try:
        st = network.stacked_system()
        A, C = arb_from_sympy(st.A), arb_from_sympy(st.C)
        Xa = arb_from_float(symmetrize(np.asarray(X, dtype=float)))
        mx = definite_margin(Xa)
        if mx is None:
            return False, None, None
        rows = nk.all_received_sets(network.size).masks[:, _owner(network)]
        total = flint.arb_mat(A.nrows(), A.nrows())
        for k, v in enumerate(pi):
            w = arb_exact_number(sp.Rational(v)) if exact else flint.arb(float(v))
            K = np.where(rows[k][None, :], gains[k], 0.0)
            F = A + arb_from_float(K) * C if rows[k].any() else A
            total += (F * Xa * F.transpose()) * w
        return (mm := definite_margin(Xa - total)) is not None, mx, mm
    finally:
        flint.ctx.prec = old


def sufficient_fact(network: Network, law: JointLaw, certify: bool = True) -> SufficientFact:
    """Search and check a certificate for the law (see the module docstring)."""
    st = network.stacked_system()
    plant = nk.Plant(st.a, st.c, _owner(network))
    col = nk.all_received_sets(network.size)
    pi = aligned_probabilities(network, law)
    w = np.array([float(v) for v in pi])
    kind = "exact" if law.exact else "float"
    r, X = _radius(plant, col, w)
    if not (np.isfinite(r) and r < 1.0):
        return SufficientFact(False, kind, None, None, r, "power iteration: radius ≥ 1")
    n = plant.a.shape[0]
    Xn = symmetrize(X) / np.trace(X)
    for eta in (1e-9, 1e-6, 1e-3, 1e-1):
        Xg = Xn + eta * np.eye(n) / n
        for _ in range(6):
            K = nk.policy_gains(plant, col, Xg, 1e-9)
            Xs = _stein(plant, w, K)
            if Xs is None:
                break
            if _float_ok(plant, col, w, Xs, K):
                if not certify:
                    return SufficientFact(True, kind, None, None, r, "float64 check only")
                ok, mx, mm = verify_law_certificate(network, pi, law.exact, Xs, K)
                if ok:
                    return SufficientFact(True, kind, mx, mm, r, "proven in ball arithmetic")
            Xg = Xs / np.trace(Xs)
    return SufficientFact(False, kind, None, None, r, "no certificate passed the check")


# ---------------------------------------------------------------------------------------------
# the facts for any law
# ---------------------------------------------------------------------------------------------

def law_stability(network: Network, law: JointLaw, *, certify: bool = True,
                  constraints: Sequence[Constraint] | None = None,
                  exact_region: tuple[bool | None, str] | None = None) -> LawStability:
    r"""Necessary and sufficient facts of mean stability under the joint law ``law``.

    For any joint law π(S) of the received set that is i.i.d. in time:

    .. math::

        P(S_t \subseteq T)\, \rho_T^2 < 1 \ \text{for every } T \ \text{(necessary)},\qquad
        X \succ \sum_S \pi(S) F_S X F_S' \ \text{(sufficient)}.

    Parameters
    ----------
    network : Network
        The plant and the sensors' rows (names must match ``law.sensors``).
    law : JointLaw
        π(S), i.i.d. in time.
    certify : bool
        Check certificates in ball arithmetic (else float64 only).
    constraints, exact_region : optional
        Precomputed :func:`necessary_constraints` and :func:`modal_one_step` (reused across
        the N − 1 cases).

    Returns
    -------
    LawStability
        ``facts`` (necessary, sufficient, exact region), ``reason``, the binding necessary
        constraint and the certificate.

    Raises
    ------
    kfcrit.errors.InputError
        The law's sensors differ from the network's (field ``law.sensors``).

    References
    ----------
    Sinopoli et al. (2004), Theorem 3 and Lemma 3 (per received set); docs/theory.md §9.2, §9.3
    and §13; §14 for empirical laws.

    Examples
    --------
    >>> from fractions import Fraction
    >>> from kfcrit.model.mesh import build_mesh
    >>> mesh = build_mesh([("s1", "sensor"), ("s2", "sensor"), ("r", "relay"), ("g", "gateway")],
    ...                   [("s1", "r", Fraction(9, 10)), ("s2", "r", Fraction(9, 10)),
    ...                    ("r", "g", Fraction(4, 5))])
    >>> from kfcrit.model.network import Network, Sensor
    >>> net = Network(A=[["5/4"]], Q=1, sensors=[Sensor("s1", [[1]], 1), Sensor("s2", [[1]], 1)])
    >>> from kfcrit.theory.mesh.law import mesh_law
    >>> from kfcrit.theory.mesh.stability import law_stability
    >>> res = law_stability(net, mesh_law(mesh))
    >>> res.facts.necessary, res.facts.sufficient, res.necessary.binding.value_exact
    (True, True, 13/40)
    """
    nec = necessary_fact(network, law, constraints)
    region, why = exact_region if exact_region is not None else modal_one_step(network)
    if nec.holds is False:
        b = nec.binding
        suf = SufficientFact(False, "exact" if law.exact else "float", None, None, None,
                             "not searched: the necessary condition fails")
        why_nec = (f"P(S ⊆ {{{', '.join(b.unobservable)}}})·|λ|² = {b.value:.6g} ≥ 1 "
                   f"for eigenvalue {b.eigenvalue}")
        return LawStability(_facts(nec, suf, region, why_nec), True, why_nec, nec, suf,
                            region, why)
    suf = sufficient_fact(network, law, certify)
    if suf.certified:
        return LawStability(_facts(nec, suf, region, ""), True, "certificate checked; the "
                            "necessary condition holds", nec, suf, region, why)
    if nec.holds and region:
        return LawStability(_facts(nec, suf, region, ""), True, "the necessary condition holds "
                            "and the region is exactly the necessary one (modal one-step "
                            "observability; a claim until reviewed)", nec, suf, region, why)
    reason = ("the necessary condition is at equality to 1e-12" if nec.holds is None
              else "between the necessary and the sufficient surface")
    return LawStability(_facts(nec, suf, region, ""), False, reason, nec, suf, region, why)


def _facts(nec: NecessaryFact, suf: SufficientFact, region: bool | None,
           why_nec: str) -> StabilityFacts:
    return StabilityFacts(
        necessary=nec.holds, sufficient=suf.certified, exact_region=bool(region),
        necessary_basis=why_nec or "P(S ⊆ T)·ρ_T² < 1 for every sensor set T (theory §13)",
        sufficient_basis=("certificate X ≻ Σ π(S) F_S X F_S' checked in ball arithmetic"
                          if suf.certified else ""))


# ---------------------------------------------------------------------------------------------
# the mesh analysis
# ---------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Marginal:
    """A sensor's marginal arrival probability P(i ∈ S) (``exact`` a Rational or None)."""

    sensor: str
    value: float
    exact: sp.Expr | None


@dataclass(frozen=True)
class HopHeadroom:
    """A hop's critical per-attempt success σ*_h and headroom q_h − σ*_h (module docstring);
    ``critical``: its total loss alone breaks the necessary condition. σ* None: no σ ≤ 1
    satisfies the necessary condition."""

    hop: str
    q: float
    critical_q: float | None
    headroom: float | None
    critical: bool


@dataclass(frozen=True)
class FailureCase:
    """N − 1: a dead relay (every hop to or from it) or a dead hop; the sensors that lose
    every route; the facts with the element dead."""

    kind: str
    element: str
    lost_sensors: tuple[str, ...]
    facts: LawStability


@dataclass(frozen=True)
class MeshAnalysis:
    """Everything :func:`mesh_analysis` finds about a mesh at its hops' q."""

    law: JointLaw
    facts: LawStability
    marginals: tuple[Marginal, ...]
    all_lost: float
    all_lost_exact: sp.Expr | None
    product_of_losses: float
    product_of_losses_exact: sp.Expr | None
    hops: tuple[HopHeadroom, ...]
    bottleneck: str | None
    n_minus_1: tuple[FailureCase, ...]
    routing: str


def _holds_at(network: Network, mesh: Mesh, cons: Sequence[Constraint], k: int,
              sigma: float) -> bool:
    law = mesh_law(mesh, override={k: float(sigma)})
    return necessary_fact(network, law, cons).holds is True


def hop_headrooms(network: Network, mesh: Mesh,
                  constraints: Sequence[Constraint] | None = None) -> tuple[HopHeadroom, ...]:
    """σ*_h and the headroom of every hop (float bisection; module docstring)."""
    cons = necessary_constraints(network) if constraints is None else constraints
    out = []
    for k, h in enumerate(mesh.hops):
        critical = not _holds_at(network, mesh, cons, k, 0.0)
        if not critical:
            out.append(HopHeadroom(h.name, h.q, 0.0, h.q, False))
            continue
        if not _holds_at(network, mesh, cons, k, 1.0):
            out.append(HopHeadroom(h.name, h.q, None, None, True))
            continue
        lo, hi = 0.0, 1.0
        while hi - lo > 1e-12:
            mid = 0.5 * (lo + hi)
            lo, hi = (lo, mid) if _holds_at(network, mesh, cons, k, mid) else (mid, hi)
        out.append(HopHeadroom(h.name, h.q, hi, h.q - hi, True))
    return tuple(out)


def _bottleneck(rows: Sequence[HopHeadroom]) -> str | None:
    crit = [(r.headroom if r.headroom is not None else -np.inf, k, r.hop)
            for k, r in enumerate(rows) if r.critical]
    return min(crit)[2] if crit else None


def _failure_cases(network: Network, mesh: Mesh, cons: Sequence[Constraint],
                   region: tuple[bool | None, str], certify: bool) -> tuple[FailureCase, ...]:
    cases: list[tuple[str, str, list[int]]] = []
    for r in mesh.relays:
        cases.append(("relay", r, [k for k, h in enumerate(mesh.hops)
                                   if r in (h.source, h.target)]))
    cases += [("hop", h.name, [k]) for k, h in enumerate(mesh.hops)]
    out = []
    for kind, name, dead in cases:
        law = mesh_law(mesh, dead_hops=dead)
        lost = tuple(s for s in mesh.sensors
                     if all(set(mesh.route_hops(r)) & set(dead) for r in mesh.routes_of(s)))
        facts = law_stability(network, law, certify=certify, constraints=cons,
                              exact_region=region)
        out.append(FailureCase(kind, name, lost, facts))
    return tuple(out)


def mesh_analysis(network: Network, mesh: Mesh, *, certify: bool = True,
                  n_minus_1: bool = True) -> MeshAnalysis:
    r"""The law, the stability facts, marginals, P(all lost) against Π(1 − marginal), hop
    headrooms and bottleneck, and N − 1 for every relay and every hop.

    .. math::

        P(\text{all lost}) = \pi(\emptyset) \ \text{versus}\ \prod_i (1 - P(i \in S)).

    Parameters
    ----------
    network : Network
        The plant and sensors (names equal to the mesh's sensors).
    mesh : Mesh
        The routes, relays and hops.
    certify : bool
        Ball-check certificates.
    n_minus_1 : bool
        Compute the relay and hop failure cases.

    Returns
    -------
    MeshAnalysis
        ``law``, ``facts`` (a :class:`LawStability`), ``marginals``, ``all_lost`` and
        ``product_of_losses`` (with exact forms), ``hops`` (headrooms), ``bottleneck`` and
        ``n_minus_1``.

    Raises
    ------
    kfcrit.errors.InputError
        The network's sensors differ from the mesh's.

    References
    ----------
    docs/theory.md §13 (multi-hop routes and shared relays) and §9.5 (N − 1 cases).

    Examples
    --------
    >>> from fractions import Fraction
    >>> from kfcrit.model.mesh import build_mesh
    >>> mesh = build_mesh([("s1", "sensor"), ("s2", "sensor"), ("r", "relay"), ("g", "gateway")],
    ...                   [("s1", "r", Fraction(9, 10)), ("s2", "r", Fraction(9, 10)),
    ...                    ("r", "g", Fraction(4, 5))])
    >>> from kfcrit.model.network import Network, Sensor
    >>> net = Network(A=[["5/4"]], Q=1, sensors=[Sensor("s1", [[1]], 1), Sensor("s2", [[1]], 1)])
    >>> from kfcrit.theory.mesh.stability import mesh_analysis
    >>> res = mesh_analysis(net, mesh)
    >>> res.all_lost_exact, res.product_of_losses_exact, res.bottleneck
    (26/125, 49/625, 'r->g')
    """
    law = mesh_law(mesh)
    aligned_probabilities(network, law)
    cons = necessary_constraints(network)
    region = modal_one_step(network)
    facts = law_stability(network, law, certify=certify, constraints=cons, exact_region=region)
    margs = []
    for s in mesh.sensors:
        v = law.marginal(s)
        margs.append(Marginal(s, float(v), v if law.exact else None))
    prod: Any = 1
    for m in margs:
        prod = prod * ((1 - m.exact) if law.exact else (1.0 - m.value))
    rows = hop_headrooms(network, mesh, cons)
    fails = _failure_cases(network, mesh, cons, region, certify) if n_minus_1 else ()
    return MeshAnalysis(law, facts, tuple(margs), float(law.all_lost()),
                        law.all_lost() if law.exact else None, float(prod),
                        prod if law.exact else None, rows, _bottleneck(rows), fails,
                        mesh.routing)
