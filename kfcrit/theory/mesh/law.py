"""The exact joint law π(S) of the received sensor set of a mesh, per period (theory §13).

Hop outcomes
------------
Without a slot budget, every hop outcome in a period is an independent Bernoulli variable
with success s_h = 1 − (1 − q_h)^{k_h+1}. Which packets share a variable depends on the mode
of the hop's transmitter:

* ``aggregate``: one variable per hop — everything the node holds goes in one frame, so all
  sensors whose routes use the hop succeed or fail together on it;
* ``forward``: one variable per (hop, sensor) — every packet gets its own attempts (two routes
  of the same sensor through the same hop carry the same packet, so they share it).

A route delivers iff all its variables succeed; a sensor's packet arrives iff one of its routes
delivers (path diversity). The law is computed by **conditioning on the shared variables**
(those used by more than one route): given their outcomes, each route's remaining variables are
private, so routes are independent and sensors are independent:

.. math::

    π(S) = \\sum_{z ∈ \\{0,1\\}^{V_{sh}}} P(z) \\prod_{i ∈ S} a_i(z)
           \\prod_{i ∉ S} (1 − a_i(z)),\\qquad
    a_i(z) = 1 − \\prod_{r ∈ R_i} \\bigl(1 − [z \\text{ passes } r]\\, π_r\\bigr),

where π_r is the product of the route's private successes. Cost 2^{V_sh}·2^N; with no shared
variable this is the product law of theory §9.

Slot budget
-----------
With D slots per period (one attempt per slot, hops in route order, at most k_h + 1 attempts
on hop h when ``retries`` is set), a route of hops with successes q_1..q_L delivers with

.. math::

    P_D = \\sum_{a_1 + … + a_L ≤ D,\\ 1 ≤ a_h ≤ k_h + 1} \\prod_{h} q_h (1 − q_h)^{a_h − 1},

computed by a DP over hops on the number of slots used (:func:`slot_arrival`). For equal q and
no caps it is the negative binomial
:math:`\\sum_{t=L}^{D} \\binom{t-1}{L-1} q^L (1-q)^{t-L}`. Under a slot budget each route is
modelled as its own schedule of D slots and routes are independent (no aggregation across
routes); contention between routes for shared slots is not modelled.
"""
from __future__ import annotations

import itertools
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import numpy as np
import sympy as sp

from kfcrit.errors import InputError
from kfcrit.model.mesh import Mesh, Route

Number = float | Fraction
MAX_SHARED = 20
"""Most shared hop variables enumerated (2^MAX_SHARED outcomes)."""


@dataclass(frozen=True)
class JointLaw:
    """A law over received sets: ``probabilities[k]`` is π(S) for S = the sensors whose bit is
    set in k (bit i = ``sensors[i]``, the order of
    :func:`kfcrit.theory.links.netkernels.all_received_sets`).

    ``exact``: the entries are sympy Rationals (else floats). ``method`` says how the law
    was computed.
    """

    sensors: tuple[str, ...]
    probabilities: tuple[Any, ...]
    exact: bool
    method: str = ""

    def __post_init__(self) -> None:
        if len(self.probabilities) != 2 ** len(self.sensors):
            raise InputError(f"must have 2^{len(self.sensors)} entries", field="law")

    @property
    def size(self) -> int:
        """Number of sensors N."""
        return len(self.sensors)

    def weights(self) -> np.ndarray:
        """π as a float array of length 2^N."""
        return np.array([float(v) for v in self.probabilities])

    def as_dict(self) -> dict[frozenset[str], Any]:
        """{received set (names): π(S)}."""
        return {frozenset(self.members(k)): v for k, v in enumerate(self.probabilities)}

    def members(self, k: int) -> tuple[str, ...]:
        """Names of the sensors in cell k."""
        return tuple(s for i, s in enumerate(self.sensors) if k >> i & 1)

    def mask(self, names: Iterable[str]) -> int:
        """Bit mask of a set of sensor names."""
        out = 0
        for n in names:
            if n not in self.sensors:
                raise InputError(f"unknown sensor {str(n)[:40]!r}", field="law.sensors")
            out |= 1 << self.sensors.index(n)
        return out

    def probability_within(self, T: Iterable[str] | int) -> Any:
        """P(S ⊆ T)."""
        t = T if isinstance(T, int) else self.mask(T)
        return _sum(v for k, v in enumerate(self.probabilities) if k & ~t == 0)

    def marginal(self, sensor: str) -> Any:
        """P(sensor ∈ S)."""
        bit = 1 << self.sensors.index(sensor)
        return _sum(v for k, v in enumerate(self.probabilities) if k & bit)

    def all_lost(self) -> Any:
        """π(∅)."""
        return self.probabilities[0]

    def total(self) -> Any:
        """Σ_S π(S) (1, exactly for an exact law)."""
        return _sum(self.probabilities)


def _sum(values: Iterable[Any]) -> Any:
    out: Any = 0
    for v in values:
        out = out + v
    return out


def _to_output(values: Sequence[Number], exact: bool) -> tuple[Any, ...]:
    if exact:
        return tuple(sp.Rational(v.numerator, v.denominator) for v in values)
    return tuple(float(v) for v in values)


def product_law(sensors: Sequence[str], p: Sequence[Any]) -> JointLaw:
    """Independent links: π(S) = Π_{i∈S} p_i Π_{i∉S}(1 − p_i) (theory §9); exact when every
    p_i is a sympy Rational, Fraction or int."""
    exact = all(isinstance(v, (sp.Rational, Fraction, int)) and not isinstance(v, bool)
                for v in p)
    vals = [_num(v, exact) for v in p]
    return JointLaw(tuple(sensors), _to_output(_product_cells(vals, exact), exact), exact,
                    "product of independent links")


def _num(v: Any, exact: bool) -> Number:
    if exact:
        r = sp.Rational(v)
        return Fraction(int(r.p), int(r.q))
    return float(v)


def _product_cells(a: Sequence[Number], exact: bool) -> list[Number]:
    """Cells of the product law of marginals a (bit i = sensor i)."""
    one: Number = Fraction(1) if exact else 1.0
    cells: list[Number] = [one]
    for ai in a:
        cells = [c * (one - ai) for c in cells] + [c * ai for c in cells]
    return cells


# ---------------------------------------------------------------------------------------------
# slot budgets
# ---------------------------------------------------------------------------------------------

def slot_arrival(q: Sequence[Number], D: int, caps: Sequence[int | None] | None = None
                 ) -> Number:
    """P(the L hops of a route succeed within D slots), hops in order, one attempt per slot,
    at most ``caps[h]`` attempts on hop h (None: no cap). See the module docstring."""
    exact = all(isinstance(v, Fraction) for v in q)
    one: Number = Fraction(1) if exact else 1.0
    zero: Number = Fraction(0) if exact else 0.0
    caps = list(caps) if caps is not None else [None] * len(q)
    dist: list[Number] = [one] + [zero] * D
    for qh, cap in zip(q, caps):
        new = [zero] * (D + 1)
        top = D if cap is None else min(D, cap)
        for used, mass in enumerate(dist):
            if mass == 0:
                continue
            fail = one
            for a in range(1, top + 1):
                if used + a > D:
                    break
                new[used + a] += mass * fail * qh
                fail = fail * (one - qh)
        dist = new
    return _sum(dist)


# ---------------------------------------------------------------------------------------------
# the law of a mesh
# ---------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class _Variable:
    hop: int
    sensor: str | None       # None: one variable for every packet on the hop (aggregate)


def _probabilities(mesh: Mesh, override: Mapping[int, Any], exact: bool) -> list[Number]:
    """Per hop the per-attempt success (with overrides: dead hops 0, scaled hops σ)."""
    out: list[Number] = []
    for k, h in enumerate(mesh.hops):
        v = override.get(k, h.q_exact if exact else h.q)
        out.append(_num(v, exact))
    return out


def _period_success(mesh: Mesh, q: Sequence[Number], exact: bool) -> list[Number]:
    one: Number = Fraction(1) if exact else 1.0
    return [one - (one - qh) ** h.attempts for qh, h in zip(q, mesh.hops)]


def _route_variables(mesh: Mesh, route: Route) -> tuple[_Variable, ...]:
    out = []
    for k in mesh.route_hops(route):
        shared = mesh.mode_of(mesh.hops[k].source) == "aggregate"
        out.append(_Variable(k, None if shared else route.sensor))
    return tuple(out)


def _is_exact(mesh: Mesh, override: Mapping[int, Any]) -> bool:
    for k, h in enumerate(mesh.hops):
        v = override.get(k, h.q_exact)
        if v is None or not isinstance(v, (sp.Rational, Fraction, int)) or isinstance(v, bool):
            return False
    return True


def mesh_law(mesh: Mesh, *, dead_hops: Iterable[int] = (),
             override: Mapping[int, Any] | None = None) -> JointLaw:
    r"""The exact law π(S) of the received set of ``mesh`` (see the module docstring).

    Sensors behind a shared (aggregating) relay lose their packets together, so π(S) is not a
    product of marginals; with one shared variable Z (the relay hop's outcome)

    .. math::

        \pi(S) = \sum_z P(Z = z) \prod_{i \in S} p_i(z) \prod_{i \notin S} (1 - p_i(z)).

    Parameters
    ----------
    mesh : Mesh
        The mesh (:func:`kfcrit.model.mesh.build_mesh`).
    dead_hops : iterable of int
        Hops (indices into ``mesh.hops``) that never succeed (an N − 1 case); an index outside
        ``mesh.hops`` has no effect.
    override : mapping, optional
        Per-attempt success of some hops replacing q_h (for sensitivity analyses).

    Returns
    -------
    JointLaw
        Sympy Rationals when every q_h (and override) is exact, floats otherwise; the
        probabilities are indexed by the bit mask of the received set (bit k: sensor k).

    Raises
    ------
    kfcrit.errors.InputError
        Not for a validated mesh: the mesh's own errors are raised by ``build_mesh``.

    References
    ----------
    Gupta, Dana, Hespanha, Murray & Hassibi (2009) for routes and relays; docs/theory.md §13
    (routes, aggregating relays, joint laws) and §15.5 (conditionally independent links).

    Examples
    --------
    >>> from fractions import Fraction
    >>> from kfcrit.model.mesh import build_mesh
    >>> mesh = build_mesh([("s1", "sensor"), ("s2", "sensor"), ("r", "relay"), ("g", "gateway")],
    ...                   [("s1", "r", Fraction(9, 10)), ("s2", "r", Fraction(9, 10)),
    ...                    ("r", "g", Fraction(4, 5))])
    >>> from kfcrit.theory.mesh.law import mesh_law
    >>> law = mesh_law(mesh)
    >>> law.probabilities              # ∅, {s1}, {s2}, {s1, s2}
    (26/125, 9/125, 9/125, 81/125)
    >>> mesh_law(mesh, dead_hops=[2]).all_lost()   # the relay's uplink is dead
    1
    """
    over: dict[int, Any] = dict(override or {})
    for k in dead_hops:
        over[int(k)] = 0
    exact = _is_exact(mesh, over)
    q = _probabilities(mesh, over, exact)
    sensors = mesh.sensors
    if mesh.slots_per_period is not None:
        cells = _slot_law(mesh, q, exact)
        how = (f"slot budget D = {mesh.slots_per_period}: each route its own schedule, "
               "routes independent")
    else:
        cells, shared = _hop_law(mesh, _period_success(mesh, q, exact), exact)
        how = (f"hop outcomes, conditioning on {shared} shared variable(s) "
               f"({mesh.relay_mode} relays by default)")
    return JointLaw(sensors, _to_output(cells, exact), exact, how)


def route_arrival(mesh: Mesh, route: Route, q: Sequence[Number] | None = None) -> Number:
    """Probability that one route delivers (independent hops; the slot DP with a budget)."""
    exact = q is None and mesh.exact
    if q is None:
        q = _probabilities(mesh, {}, exact)
    idx = mesh.route_hops(route)
    if mesh.slots_per_period is not None:
        return slot_arrival([q[k] for k in idx], mesh.slots_per_period,
                            [mesh.hops[k].retries if mesh.hops[k].retries is None
                             else mesh.hops[k].retries + 1 for k in idx])
    s = _period_success(mesh, q, isinstance(q[0], Fraction) if q else exact)
    out: Number = Fraction(1) if s and isinstance(s[0], Fraction) else 1.0
    for k in idx:
        out = out * s[k]
    return out


def _slot_law(mesh: Mesh, q: Sequence[Number], exact: bool) -> list[Number]:
    one: Number = Fraction(1) if exact else 1.0
    marg = []
    for s in mesh.sensors:
        miss = one
        for r in mesh.routes_of(s):
            miss = miss * (one - route_arrival(mesh, r, q))
        marg.append(one - miss)
    return _product_cells(marg, exact)


def _hop_law(mesh: Mesh, s: Sequence[Number], exact: bool) -> tuple[list[Number], int]:
    """Cells of π by conditioning on the variables used by more than one route."""
    one: Number = Fraction(1) if exact else 1.0
    zero: Number = Fraction(0) if exact else 0.0
    routes = [(r.sensor, _route_variables(mesh, r)) for r in mesh.routes]
    uses: dict[_Variable, int] = {}
    for _, vs in routes:
        for v in set(vs):
            uses[v] = uses.get(v, 0) + 1
    shared = sorted((v for v, c in uses.items() if c > 1),
                    key=lambda v: (v.hop, v.sensor or ""))
    if len(shared) > MAX_SHARED:
        raise InputError(f"has {len(shared)} hop variables shared by several routes; at most "
                         f"{MAX_SHARED} are enumerated", field="mesh.routes")
    pos = {v: j for j, v in enumerate(shared)}
    private = []
    for sensor, vs in routes:
        prod = one
        for v in set(vs):
            if v not in pos:
                prod = prod * s[v.hop]
        private.append((mesh.sensors.index(sensor), [pos[v] for v in set(vs) if v in pos], prod))
    N = len(mesh.sensors)
    total = [zero] * (2 ** N)
    for z in itertools.product((True, False), repeat=len(shared)):
        pz = one
        for v, ok in zip(shared, z):
            pz = pz * (s[v.hop] if ok else one - s[v.hop])
        if pz == 0:
            continue
        miss = [one] * N
        for i, need, prod in private:
            if all(z[j] for j in need):
                miss[i] = miss[i] * (one - prod)
        cells = _product_cells([one - m for m in miss], exact)
        total = [t + pz * c for t, c in zip(total, cells)]
    return total, len(shared)


def hop_outcome_variables(mesh: Mesh) -> tuple[tuple[int, str | None], ...]:
    """The independent hop variables of the law, as (hop index, sensor or None), in a fixed
    order (for simulation: sample each with its per-period success)."""
    seen: dict[tuple[int, str | None], None] = {}
    for r in mesh.routes:
        for v in _route_variables(mesh, r):
            seen[(v.hop, v.sensor)] = None
    return tuple(seen)


def received_from_outcomes(mesh: Mesh, outcome: Mapping[tuple[int, str | None], bool]
                           ) -> frozenset[str]:
    """The received set given the outcome of every hop variable (no slot budget)."""
    got = set()
    for r in mesh.routes:
        if all(outcome[(v.hop, v.sensor)] for v in _route_variables(mesh, r)):
            got.add(r.sensor)
    return frozenset(got)
