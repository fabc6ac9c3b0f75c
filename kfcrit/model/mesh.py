"""Multi-hop meshes: sensors, relays and one gateway (the estimator) joined by lossy hops
(theory §13 [beyond]).

A :class:`Mesh` is plain validated data; the joint law of the received sensor set, the
stability facts and estimate relaying live in :mod:`kfcrit.theory.mesh`.

* A **node** is a sensor (produces one packet per sampling period), a relay, or the gateway
  (exactly one; it is the estimator and never transmits).
* A **hop** is a directed link ``source → target`` with per-attempt success probability
  q_h (a float, and an exact sympy Rational when the input was exact) and ``retries`` k_h.
  Without a slot budget a hop's per-period outcome succeeds with probability

  .. math:: s_h = 1 - (1 - q_h)^{k_h + 1}

  (``retries=None`` means 0 there). With a slot budget D (``slots_per_period``, TSCH-like: one
  attempt per slot, hops in route order) ``retries=None`` means "no cap but the budget".
* A **route** is a node sequence from a sensor to the gateway along existing hops, without
  repeated nodes. A sensor may have several routes (path diversity). When no routes are given,
  each sensor gets its most reliable path (:func:`most_reliable_route`): Dijkstra on the weights
  −log s_h; :attr:`Mesh.routing` says so.
* ``relay_mode``: ``aggregate`` (default; a transmitting node sends everything it holds in one
  frame per period, so packets sharing the hop share its outcome) or ``forward`` (each packet
  in its own frame: independent attempts per packet on the hop). A node's own ``mode``
  overrides the mesh default for the hops it transmits.

Every invalid input raises :class:`kfcrit.errors.InputError` naming the field, e.g.
``mesh.routes[2]: passes through unknown node 'r9'``.
"""
from __future__ import annotations

import heapq
import math
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Any

import sympy as sp

from kfcrit.errors import InputError

ROLES = ("sensor", "relay", "gateway")
RELAY_MODES = ("aggregate", "forward")
NODE_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_-]{0,39}")
MAX_MESH_SENSORS = 12
"""Most sensors of a mesh (the exact law has 2^N cells)."""
MAX_SLOTS = 10000
"""Largest slot budget accepted."""
ROUTING_GIVEN = "given"
ROUTING_RELIABLE = ("most reliable path per sensor: Dijkstra on -log(1 - (1 - q_h)^(k_h + 1)), "
                    "the per-period hop success")


def probability_pair(value: Any, where: str) -> tuple[float, sp.Rational | None]:
    """(float, exact Rational or None) of a probability in [0, 1].

    ints, :class:`fractions.Fraction`, sympy Rationals and number strings (``"4/5"``,
    ``"0.8"``) are exact; Python and NumPy floats are floats only.
    """
    exact: sp.Rational | None
    if isinstance(value, bool):
        raise InputError("must be a probability, got a boolean", field=where)
    if isinstance(value, sp.Basic):
        if not value.is_Rational:
            raise InputError("must be a rational number in [0, 1]", field=where)
        exact = sp.Rational(value)
    elif isinstance(value, int):
        exact = sp.Integer(value)
    elif isinstance(value, Fraction):
        exact = sp.Rational(value.numerator, value.denominator)
    elif isinstance(value, str):
        try:
            exact = sp.Rational(value.strip())
        except (TypeError, ValueError, SyntaxError):
            raise InputError(f"must be a number, got {value[:40]!r}", field=where) from None
    else:
        try:
            f = float(value)
        except (TypeError, ValueError):
            raise InputError(f"must be a number, got {type(value).__name__}",
                             field=where) from None
        if not (math.isfinite(f) and 0.0 <= f <= 1.0):
            raise InputError(f"must be in [0, 1], got {f:g}", field=where)
        return f, None
    if not 0 <= exact <= 1:
        raise InputError(f"must be in [0, 1], got {exact}", field=where)
    return float(exact), exact


@dataclass(frozen=True)
class Node:
    """A mesh node: ``role`` is ``sensor``, ``relay`` or ``gateway``; ``mode`` (optional)
    overrides the mesh's relay mode for the hops this node transmits."""

    name: str
    role: str
    mode: str | None = None


@dataclass(frozen=True)
class Hop:
    """A directed hop with per-attempt success ``q`` (float), ``q_exact`` (Rational or None)
    and ``retries`` (k_h ≥ 0, or None: see the module docstring)."""

    source: str
    target: str
    q: float
    q_exact: sp.Rational | None = None
    retries: int | None = None

    @property
    def name(self) -> str:
        """``source->target``."""
        return f"{self.source}->{self.target}"

    @property
    def attempts(self) -> int:
        """k_h + 1 attempts per period (retries None counts as 0)."""
        return (self.retries or 0) + 1

    def period_success(self) -> float:
        """s_h = 1 − (1 − q_h)^{k_h+1} in floats."""
        return 1.0 - (1.0 - self.q) ** self.attempts

    def period_success_exact(self) -> sp.Rational | None:
        """s_h exactly (None when q is not exact)."""
        if self.q_exact is None:
            return None
        return 1 - (1 - self.q_exact) ** self.attempts


@dataclass(frozen=True)
class Route:
    """One route of ``sensor``: ``nodes`` from the sensor to the gateway; ``origin`` is
    ``given`` or ``most-reliable``."""

    sensor: str
    nodes: tuple[str, ...]
    origin: str = "given"

    @property
    def pairs(self) -> tuple[tuple[str, str], ...]:
        """Consecutive (source, target) pairs: the route's hops."""
        return tuple(zip(self.nodes[:-1], self.nodes[1:]))

    @property
    def length(self) -> int:
        """Number of hops L."""
        return len(self.nodes) - 1


@dataclass(frozen=True)
class Mesh:
    """A validated mesh (see the module docstring). Build it with :func:`build_mesh`, or
    construct it directly (validated in ``__post_init__``)."""

    nodes: tuple[Node, ...]
    hops: tuple[Hop, ...]
    routes: tuple[Route, ...]
    relay_mode: str = "aggregate"
    slots_per_period: int | None = None
    routing: str = ROUTING_GIVEN
    _hop_index: dict[tuple[str, str], int] = field(default_factory=dict, repr=False,
                                                   compare=False)

    def __post_init__(self) -> None:
        _check_nodes(self.nodes)
        if self.relay_mode not in RELAY_MODES:
            raise InputError(f"must be one of {', '.join(RELAY_MODES)}, got "
                             f"{str(self.relay_mode)[:40]!r}", field="mesh.relay_mode")
        index = _check_hops(self.hops, {n.name: n for n in self.nodes})
        self._hop_index.clear()
        self._hop_index.update(index)
        _check_slots(self.slots_per_period)
        _check_routes(self)

    # -- views ----------------------------------------------------------------------------------
    @property
    def sensors(self) -> tuple[str, ...]:
        """Sensor names in node order (the order of the law's bits)."""
        return tuple(n.name for n in self.nodes if n.role == "sensor")

    @property
    def relays(self) -> tuple[str, ...]:
        """Relay names in node order."""
        return tuple(n.name for n in self.nodes if n.role == "relay")

    @property
    def gateway(self) -> str:
        """The gateway's name."""
        return next(n.name for n in self.nodes if n.role == "gateway")

    @property
    def exact(self) -> bool:
        """Every hop's q is exact."""
        return all(h.q_exact is not None for h in self.hops)

    def node(self, name: str) -> Node:
        """The node called ``name``."""
        for n in self.nodes:
            if n.name == name:
                return n
        raise InputError(f"unknown node {name[:40]!r}", field="node")

    def hop_index(self, source: str, target: str) -> int:
        """Position of the hop ``source → target`` in :attr:`hops`."""
        try:
            return self._hop_index[(source, target)]
        except KeyError:
            raise InputError(f"no hop {source}->{target}", field="hop") from None

    def mode_of(self, node: str) -> str:
        """The relay mode of the hops ``node`` transmits."""
        return self.node(node).mode or self.relay_mode

    def routes_of(self, sensor: str) -> tuple[Route, ...]:
        """The routes of one sensor."""
        return tuple(r for r in self.routes if r.sensor == sensor)

    def route_hops(self, route: Route) -> tuple[int, ...]:
        """Indices of a route's hops, in route order."""
        return tuple(self.hop_index(a, b) for a, b in route.pairs)


# ---------------------------------------------------------------------------------------------
# validation
# ---------------------------------------------------------------------------------------------

def _check_nodes(nodes: Sequence[Node]) -> None:
    seen: set[str] = set()
    for k, n in enumerate(nodes):
        where = f"mesh.nodes[{k}]"
        if not isinstance(n, Node):
            raise InputError("must be a Node", field=where)
        if not isinstance(n.name, str) or not NODE_NAME.fullmatch(n.name):
            raise InputError("must start with a letter and use only letters, digits, '_' or "
                             "'-' (at most 40 characters)", field=f"{where}.name")
        if n.name in seen:
            raise InputError(f"duplicate node name {n.name!r}", field=f"{where}.name")
        seen.add(n.name)
        if n.role not in ROLES:
            raise InputError(f"must be one of {', '.join(ROLES)}, got {str(n.role)[:40]!r}",
                             field=f"{where}.role")
        if n.mode is not None and n.mode not in RELAY_MODES:
            raise InputError(f"must be one of {', '.join(RELAY_MODES)}", field=f"{where}.mode")
    gateways = [n.name for n in nodes if n.role == "gateway"]
    if len(gateways) != 1:
        raise InputError(f"must have exactly one gateway (the estimator), got {len(gateways)}",
                         field="mesh.nodes")
    sensors = [n for n in nodes if n.role == "sensor"]
    if not sensors:
        raise InputError("must have at least one sensor", field="mesh.nodes")
    if len(sensors) > MAX_MESH_SENSORS:
        raise InputError(f"has {len(sensors)} sensors; at most {MAX_MESH_SENSORS} are "
                         "supported (the exact law has 2^N cells)", field="mesh.nodes")


def _check_hops(hops: Sequence[Hop], nodes: Mapping[str, Node]) -> dict[tuple[str, str], int]:
    index: dict[tuple[str, str], int] = {}
    for k, h in enumerate(hops):
        where = f"mesh.hops[{k}]"
        if not isinstance(h, Hop):
            raise InputError("must be a Hop", field=where)
        for end in ("source", "target"):
            name = getattr(h, end)
            if name not in nodes:
                raise InputError(f"unknown node {str(name)[:40]!r}", field=f"{where}.{end}")
        if h.source == h.target:
            raise InputError("a hop must join two different nodes", field=where)
        if nodes[h.source].role == "gateway":
            raise InputError("the gateway is the estimator and does not transmit",
                             field=f"{where}.source")
        if not (isinstance(h.q, float) and 0.0 <= h.q <= 1.0):
            raise InputError(f"must be a float in [0, 1], got {h.q!r}", field=f"{where}.q")
        if h.q_exact is not None and not (isinstance(h.q_exact, sp.Rational)
                                          and float(h.q_exact) == h.q):
            raise InputError("must be a sympy Rational whose float is q", field=f"{where}.q")
        if h.retries is not None and (isinstance(h.retries, bool)
                                      or not isinstance(h.retries, int) or h.retries < 0):
            raise InputError("must be a non-negative integer", field=f"{where}.retries")
        if (h.source, h.target) in index:
            raise InputError(f"duplicate hop {h.name} (also mesh.hops[{index[(h.source, h.target)]}])",
                             field=where)
        index[(h.source, h.target)] = k
    return index


def _check_slots(D: int | None) -> None:
    if D is None:
        return
    if isinstance(D, bool) or not isinstance(D, int) or not 1 <= D <= MAX_SLOTS:
        raise InputError(f"must be an integer in 1..{MAX_SLOTS}", field="mesh.slots_per_period")


def _check_routes(mesh: Mesh) -> None:
    roles = {n.name: n.role for n in mesh.nodes}
    gateway = mesh.gateway
    seen: dict[tuple[str, ...], int] = {}
    for k, r in enumerate(mesh.routes):
        where = f"mesh.routes[{k}]"
        if not isinstance(r, Route):
            raise InputError("must be a Route", field=where)
        if roles.get(r.sensor) != "sensor":
            raise InputError(f"{str(r.sensor)[:40]!r} is not a sensor", field=f"{where}.sensor")
        if len(r.nodes) < 2:
            raise InputError("must list at least the sensor and the gateway", field=where)
        for name in r.nodes:
            if name not in roles:
                raise InputError(f"passes through unknown node {str(name)[:40]!r}", field=where)
        if r.nodes[0] != r.sensor:
            raise InputError(f"must start at its sensor {r.sensor!r}", field=where)
        if r.nodes[-1] != gateway:
            raise InputError(f"must end at the gateway {gateway!r}", field=where)
        if len(set(r.nodes)) != len(r.nodes):
            twice = next(x for x in r.nodes if r.nodes.count(x) > 1)
            raise InputError(f"has a cycle: node {twice!r} appears twice", field=where)
        for a, b in r.pairs:
            if (a, b) not in mesh._hop_index:
                raise InputError(f"uses a hop {a}->{b} that is not in mesh.hops", field=where)
        if r.nodes in seen:
            raise InputError(f"repeats mesh.routes[{seen[r.nodes]}]", field=where)
        seen[r.nodes] = k
        D = mesh.slots_per_period
        if D is not None and r.length > D:
            raise InputError(f"has {r.length} hops but the slot budget is {D} per period",
                             field="mesh.slots_per_period")
    routed = {r.sensor for r in mesh.routes}
    for k, n in enumerate(mesh.nodes):
        if n.role == "sensor" and n.name not in routed:
            raise InputError(f"sensor {n.name!r} has no route to the gateway",
                             field=f"mesh.nodes[{k}]")


# ---------------------------------------------------------------------------------------------
# building and routing
# ---------------------------------------------------------------------------------------------

def make_hop(source: str, target: str, q: Any, retries: int | None = None, *,
             where: str = "mesh.hops[?]") -> Hop:
    """A :class:`Hop` from a probability given in any accepted form (exact when possible)."""
    qf, qe = probability_pair(q, f"{where}.q")
    return Hop(source, target, qf, qe, retries)


def most_reliable_route(nodes: Sequence[Node], hops: Sequence[Hop], sensor: str
                        ) -> tuple[str, ...] | None:
    """Most reliable path from ``sensor`` to the gateway (None if there is none).

    Dijkstra on w_h = −log s_h (s_h the per-period success of :meth:`Hop.period_success`;
    hops with s_h = 0 are unusable), so the path maximises Π s_h. Ties go to fewer hops, then
    to the lexicographically smallest node sequence. Paths do not pass through the gateway.
    """
    gateway = next(n.name for n in nodes if n.role == "gateway")
    out: dict[str, list[Hop]] = {}
    for h in hops:
        if h.period_success() > 0.0:
            out.setdefault(h.source, []).append(h)
    heap: list[tuple[float, int, tuple[str, ...]]] = [(0.0, 0, (sensor,))]
    done: set[str] = set()
    while heap:
        cost, length, path = heapq.heappop(heap)
        here = path[-1]
        if here in done:
            continue
        done.add(here)
        if here == gateway:
            return path
        for h in out.get(here, ()):
            if h.target not in done and h.target not in path:
                w = -math.log(h.period_success())
                heapq.heappush(heap, (cost + w, length + 1, path + (h.target,)))
    return None


def build_mesh(nodes: Iterable[Node | tuple[str, str] | Mapping[str, Any]],
               hops: Iterable[Hop | Sequence[Any] | Mapping[str, Any]],
               routes: Iterable[Route | Sequence[str]] | None = None, *,
               relay_mode: str = "aggregate", slots_per_period: int | None = None) -> Mesh:
    """Build a validated :class:`Mesh` from convenient forms.

    Parameters
    ----------
    nodes : iterable
        :class:`Node`, ``(name, role)`` or ``{"name", "role", "mode"}``.
    hops : iterable
        :class:`Hop`, ``(source, target, q[, retries])`` or ``{"source", "target", "q",
        "retries"}``; q exact when given as int, Fraction, Rational or text.
    routes : iterable, optional
        :class:`Route` or node sequences (the first node is the sensor). When None, every
        sensor gets its most reliable path and :attr:`Mesh.routing` states it.
    relay_mode : str
        ``aggregate`` (default) or ``forward``.
    slots_per_period : int, optional
        Slot budget D per period.
    """
    node_t = tuple(_node(n, f"mesh.nodes[{k}]") for k, n in enumerate(nodes))
    hop_t = tuple(_hop(h, f"mesh.hops[{k}]") for k, h in enumerate(hops))
    if routes is None:
        _check_nodes(node_t)
        _check_hops(hop_t, {n.name: n for n in node_t})
        found = []
        for k, n in enumerate(node_t):
            if n.role != "sensor":
                continue
            path = most_reliable_route(node_t, hop_t, n.name)
            if path is None:
                raise InputError(f"sensor {n.name!r} has no route to the gateway (no path of "
                                 "hops with positive success)", field=f"mesh.nodes[{k}]")
            found.append(Route(n.name, path, "most-reliable"))
        return Mesh(node_t, hop_t, tuple(found), relay_mode, slots_per_period, ROUTING_RELIABLE)
    route_t = tuple(_route(r, f"mesh.routes[{k}]") for k, r in enumerate(routes))
    return Mesh(node_t, hop_t, route_t, relay_mode, slots_per_period, ROUTING_GIVEN)


def _node(n: Any, where: str) -> Node:
    if isinstance(n, Node):
        return n
    if isinstance(n, Mapping):
        unknown = set(n) - {"name", "role", "mode"}
        if unknown:
            raise InputError("unknown key (allowed: mode, name, role)",
                             field=f"{where}.{sorted(map(str, unknown))[0][:40]}")
        return Node(n.get("name"), n.get("role"), n.get("mode"))
    if isinstance(n, (tuple, list)) and len(n) in (2, 3):
        return Node(*n)
    raise InputError("must be a Node, (name, role) or a mapping", field=where)


def _hop(h: Any, where: str) -> Hop:
    if isinstance(h, Hop):
        return h
    if isinstance(h, Mapping):
        unknown = set(h) - {"source", "target", "q", "retries"}
        if unknown:
            raise InputError("unknown key (allowed: q, retries, source, target)",
                             field=f"{where}.{sorted(map(str, unknown))[0][:40]}")
        if h.get("q") is None:
            raise InputError("is required", field=f"{where}.q")
        return make_hop(h.get("source"), h.get("target"), h["q"], h.get("retries"),
                        where=where)
    if isinstance(h, (tuple, list)) and len(h) in (3, 4):
        return make_hop(*h, where=where)
    raise InputError("must be a Hop, (source, target, q[, retries]) or a mapping", field=where)


def _route(r: Any, where: str) -> Route:
    if isinstance(r, Route):
        return r
    if isinstance(r, (tuple, list)) and r and all(isinstance(x, str) for x in r):
        return Route(r[0], tuple(r))
    raise InputError("must be a Route or a sequence of node names", field=where)
