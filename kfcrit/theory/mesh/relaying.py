"""Estimate relaying and smart sensors (theory §13 [beyond]).

Estimate relaying (Gupta, Dana, Hespanha, Murray, Hassibi, "Data transmission over networks
for estimation and control", IEEE TAC 54(8), 2009): every node forwards, on every outgoing
hop and every period, the latest time-stamped estimate it holds. Hop h erases a period's
transmission with probability d_h, independently across hops and periods. For ONE sensor
(whose local estimate the nodes relay) the scheme is optimal and E[P_t] is bounded iff

.. math::

    p_{cut}\\,ρ(A)^2 < 1,\\qquad
    p_{cut} = \\max_{\\text{cuts } (𝒱_s, 𝒱_t)} \\prod_{h:\\ 𝒱_s → 𝒱_t} d_h,

the maximum over cuts with the sensor in 𝒱_s and the estimator in 𝒱_t of the product of the
drop probabilities of the hops from 𝒱_s to 𝒱_t (directed hops). Taking −log, p_cut =
exp(−min-cut) with capacities −log d_h: a max-flow (Edmonds–Karp, written here; d_h = 0 gives
an infinite capacity and, if every cut has such a hop, p_cut = 0). With retries the
per-period drop is d_h = (1 − q_h)^{k_h+1}; slot budgets are not modelled for relaying.

Reading of theory §13 implemented here: the theorem is per sensor, with (A, C_s) detectable
(the sensor runs its own filter). For a network of several sensors :func:`estimate_relaying`
reports each sensor's verdict and, as a **sufficient** condition only, the network is stable
if some sensor s with (A, C_s) detectable has p_cut(s)·ρ(A)² < 1 (the estimator may ignore the
others: the min over such sensors of p_cut(s)). Necessity for several sensors (fusing partial
estimates) is not claimed.

Smart sensor (one hop, the sensor sends its own filter's estimate): the critical arrival
probability is 1 − 1/ρ(A)² for every detectable (A, C) (0 when ρ(A) < 1).
"""
from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import sympy as sp

from kfcrit.errors import KfcritError
from kfcrit.model.exprparse import compare
from kfcrit.model.mesh import Hop, Mesh
from kfcrit.model.network import Network
from kfcrit.model.system import System
from kfcrit.theory.critical.section import structure_of

FLOW_RTOL = 1e-12
"""Residual capacities below this times the largest finite capacity count as saturated."""


@dataclass(frozen=True)
class Cut:
    """The maximising cut: ``source_side`` nodes, the ``hops`` crossing it, and
    p_cut (float; ``p_cut_exact`` a Rational when every crossing drop is exact)."""

    sensor: str
    source_side: tuple[str, ...]
    hops: tuple[str, ...]
    p_cut: float
    p_cut_exact: sp.Expr | None


def hop_drop(hop: Hop) -> tuple[float, sp.Rational | None]:
    """Per-period drop d_h = (1 − q_h)^{k_h+1} (float, exact or None)."""
    exact = (1 - hop.q_exact) ** hop.attempts if hop.q_exact is not None else None
    return (1.0 - hop.q) ** hop.attempts, exact


def max_drop_cut(nodes: Sequence[str], edges: Sequence[tuple[str, str, float]], source: str,
                 sink: str) -> tuple[float, tuple[str, ...], tuple[int, ...]]:
    """max over cuts separating ``source`` from ``sink`` of Π_{crossing edges} drop.

    Parameters
    ----------
    nodes : sequence of str
    edges : sequence of (u, v, drop)
        Directed edges with drop probabilities in [0, 1].
    source, sink : str

    Returns
    -------
    (p_cut, source side, indices of the crossing edges)
    """
    cap = [math.inf if d <= 0.0 else -math.log(d) for _, _, d in edges]
    finite = [c for c in cap if math.isfinite(c)]
    tol = FLOW_RTOL * max(finite + [1.0])
    residual = _max_flow(nodes, edges, cap, source, sink, tol)
    if residual is None:
        crossing = tuple(k for k, (u, v, _) in enumerate(edges) if u == source)
        return 0.0, (source,), crossing
    side = _reachable(nodes, edges, residual, source, tol)
    crossing = tuple(k for k, (u, v, _) in enumerate(edges) if u in side and v not in side)
    value = math.prod(edges[k][2] for k in crossing)
    return value, tuple(n for n in nodes if n in side), crossing


def _max_flow(nodes: Sequence[str], edges: Sequence[tuple[str, str, float]],
              cap: Sequence[float], s: str, t: str, tol: float) -> dict | None:
    """Edmonds–Karp; returns residual capacities {(u, v): r}, or None for an infinite flow."""
    res: dict[tuple[str, str], float] = {}
    for (u, v, _), c in zip(edges, cap):
        res[(u, v)] = res.get((u, v), 0.0) + c
        res.setdefault((v, u), 0.0)
    adj: dict[str, list[str]] = {n: [] for n in nodes}
    for (u, v) in res:
        adj[u].append(v)
    while True:
        parent = {s: s}
        queue = deque([s])
        while queue and t not in parent:
            u = queue.popleft()
            for v in adj[u]:
                if v not in parent and res[(u, v)] > tol:
                    parent[v] = u
                    queue.append(v)
        if t not in parent:
            return res
        path, v = [], t
        while v != s:
            path.append((parent[v], v))
            v = parent[v]
        push = min(res[e] for e in path)
        if math.isinf(push):
            return None
        for (u, v) in path:
            res[(u, v)] -= push
            if not math.isinf(res[(v, u)]):
                res[(v, u)] += push


def _reachable(nodes, edges, res, s, tol) -> set[str]:
    seen, stack = {s}, [s]
    while stack:
        u = stack.pop()
        for (a, b), r in res.items():
            if a == u and b not in seen and r > tol:
                seen.add(b)
                stack.append(b)
    return seen


def sensor_cut(mesh: Mesh, sensor: str) -> Cut:
    """p_cut of ``sensor`` over every hop of the mesh (module docstring)."""
    names = tuple(n.name for n in mesh.nodes)
    drops = [hop_drop(h) for h in mesh.hops]
    edges = [(h.source, h.target, d[0]) for h, d in zip(mesh.hops, drops)]
    value, side, crossing = max_drop_cut(names, edges, sensor, mesh.gateway)
    exact: Any = None
    if all(drops[k][1] is not None for k in crossing):
        exact = sp.Integer(1)
        for k in crossing:
            exact = exact * drops[k][1]
    return Cut(sensor, side, tuple(mesh.hops[k].name for k in crossing), value, exact)


# ---------------------------------------------------------------------------------------------
# verdicts
# ---------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Spectral:
    """ρ(A)² as a float and exactly when the structure analysis gives it."""

    rho2: float
    rho2_exact: sp.Expr | None


def mesh_spectral_radius2(system: System) -> Spectral:
    """ρ(A)² of a system (from :func:`kfcrit.theory.critical.section.structure_of`)."""
    st = structure_of(system)
    top = max(st.eigen, key=lambda e: e.mod2)
    return Spectral(float(top.mod2), top.mod2_expr)


@dataclass(frozen=True)
class RelayingCondition:
    """One sensor under estimate relaying: p_cut·ρ(A)² against 1 (``stable`` None when
    undecided at float precision); ``detectable``: (A, C_s) is detectable."""

    sensor: str
    cut: Cut
    value: float
    value_exact: sp.Expr | None
    detectable: bool
    stable: bool | None
    reason: str


@dataclass(frozen=True)
class RelayingResult:
    """Per-sensor verdicts and the network statement (sufficient only when N > 1)."""

    sensors: tuple[RelayingCondition, ...]
    rho2: Spectral
    network_stable: bool | None
    basis: str


def _below_one(value: float, expr: sp.Expr | None) -> bool | None:
    if expr is not None:
        try:
            return compare(expr, 1, "relaying", "p_cut rho^2 - 1") < 0
        except KfcritError:
            pass
    if abs(value - 1.0) <= 1e-12:
        return None
    return value < 1.0


def relaying_condition(network: Network, mesh: Mesh, sensor: str,
                     rho: Spectral | None = None) -> RelayingCondition:
    """Gupta et al.'s condition for one sensor: (A, C_s) detectable and p_cut·ρ(A)² < 1."""
    rho = rho or mesh_spectral_radius2(network.stacked_system())
    cut = sensor_cut(mesh, sensor)
    value = cut.p_cut * rho.rho2
    expr = (cut.p_cut_exact * rho.rho2_exact
            if cut.p_cut_exact is not None and rho.rho2_exact is not None else None)
    detectable = structure_of(network.received_system([sensor])).detectable
    below = _below_one(value, expr)
    if not detectable:
        return RelayingCondition(sensor, cut, value, expr, False, False,
                               "(A, C_s) is not detectable: this sensor alone cannot")
    if below is None:
        return RelayingCondition(sensor, cut, value, expr, True, None,
                               "p_cut·ρ(A)² is 1 to float precision")
    return RelayingCondition(sensor, cut, value, expr, True, below,
                           f"p_cut·ρ(A)² = {value:.6g} {'<' if below else '≥'} 1 "
                           "(Gupta et al. 2009)")


def estimate_relaying(network: Network, mesh: Mesh) -> RelayingResult:
    r"""Estimate relaying for every sensor of the mesh (names equal to the network's).

    One sensor: Gupta et al.'s theorem (necessary and sufficient). Several: stable if some
    detecting sensor's verdict is stable (sufficient only; module docstring).

    .. math::

        \sup_t E[P_t] < \infty \iff p_{cut}\, \rho(A)^2 < 1,

    p_cut the max-cut product of the drop probabilities between the sensor and the estimator.

    Parameters
    ----------
    network : Network
        The plant and sensors.
    mesh : Mesh
        The routes (each sensor's estimate relayed hop by hop).

    Returns
    -------
    RelayingResult
        One :class:`RelayingCondition` per sensor (cut, p_cut·ρ(A)², stable), ρ(A)² and
        ``network_stable`` (True, False, or None when no single sensor decides).

    Raises
    ------
    kfcrit.errors.InputError
        A network sensor that the mesh does not have (field ``sensor``).

    References
    ----------
    Gupta, Dana, Hespanha, Murray & Hassibi (2009), IEEE TAC 54(8); docs/theory.md §13
    (estimate relaying).

    Examples
    --------
    >>> from fractions import Fraction
    >>> from kfcrit.model.mesh import build_mesh
    >>> from kfcrit.model.network import Network, Sensor
    >>> from kfcrit.theory.mesh.relaying import estimate_relaying
    >>> mesh = build_mesh([("s", "sensor"), ("r", "relay"), ("g", "gateway")],
    ...                   [("s", "r", Fraction(1, 2)), ("r", "g", Fraction(1, 2))])
    >>> net = Network(A=[["5/4"]], Q=1, sensors=[Sensor("s", [[1]], 1)])
    >>> res = estimate_relaying(net, mesh)
    >>> res.sensors[0].value_exact, res.network_stable     # p_cut·ρ² = (1/2)(25/16)
    (25/32, True)
    """
    rho = mesh_spectral_radius2(network.stacked_system())
    rows = tuple(relaying_condition(network, mesh, s, rho) for s in mesh.sensors)
    if len(rows) == 1:
        return RelayingResult(rows, rho, rows[0].stable,
                              "one sensor: p_cut·ρ(A)² < 1 iff stable (Gupta et al. 2009)")
    if any(r.stable for r in rows):
        return RelayingResult(rows, rho, True, "sufficient: a detecting sensor has "
                              "p_cut·ρ(A)² < 1 (the estimator may use it alone)")
    return RelayingResult(rows, rho, None, "no single detecting sensor suffices; fusing "
                          "several sensors' estimates is outside Gupta et al.'s theorem")


@dataclass(frozen=True)
class SmartSensor:
    """Critical arrival probability of a smart sensor on one hop (None: not detectable)."""

    value: float | None
    exact: sp.Expr | None
    reason: str


def smart_sensor_critical_value(system: System) -> SmartSensor:
    r"""1 − 1/ρ(A)² for detectable (A, C) (0 when ρ(A) < 1); None when not detectable.

    A smart sensor sends its local estimate over one hop, so the estimator's error depends on the
    losses only through ρ(A):

    .. math::

        p_c = \max\bigl(1 - 1/\rho(A)^2,\ 0\bigr).

    Parameters
    ----------
    system : System
        The plant and the smart sensor's output matrix.

    Returns
    -------
    SmartSensor
        ``value`` (float or None), ``exact`` (sympy expression or None) and ``reason``.

    Raises
    ------
    AttributeError
        ``system`` is not a :class:`~kfcrit.System`.

    References
    ----------
    Gupta et al. (2009); docs/theory.md §13 (smart sensor).

    Examples
    --------
    >>> from kfcrit import System
    >>> from kfcrit.theory.mesh.relaying import smart_sensor_critical_value
    >>> smart_sensor_critical_value(System(A=[["5/4"]], C=[[1]], Q=1, R=1)).exact
    9/25
    >>> smart_sensor_critical_value(System(A=[[0, -2], [2, 0]], C=[[1, 0]], Q=1, R=1)).exact
    3/4
    """
    st = structure_of(system)
    if not st.detectable:
        return SmartSensor(None, None, "(A, C) is not detectable")
    if st.stable:
        return SmartSensor(0.0, sp.Integer(0), "ρ(A) < 1")
    rho = mesh_spectral_radius2(system)
    expr = sp.radsimp(1 - 1 / rho.rho2_exact) if rho.rho2_exact is not None else None
    return SmartSensor(1.0 - 1.0 / rho.rho2, expr,
                       "smart sensor: the estimate carries all past measurements, so only "
                       "ρ(A) matters (theory §13)")
