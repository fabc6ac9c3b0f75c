"""Mesh files: the ``mesh:`` section of a system file (theory §13).

A mesh file gives the plant (``A``, ``Q``, optional ``Sigma0``) and one ``mesh:`` mapping::

    mesh:
      relay_mode: aggregate            # or forward (default aggregate)
      slots_per_period: 6              # optional slot budget D per route and period
      retries: 3                       # default retries k_h of every hop (default: none,
                                       # i.e. one attempt, or the slot budget's limit only)
      links: {radio: ..., ...}         # link-budget defaults of every hop (no distance_m)
      nodes:
        - {name: s1, role: sensor, C: [[1, 0]], R: 1, position_m: [40, 0]}
        - {name: r1, role: relay, position_m: [20, 0]}
        - {name: gw, role: gateway, position_m: [0, 0]}
      hops:
        - {from: s1, to: r1}                            # link budget: links + positions
        - {from: r1, to: gw, retries: 2, channel: {tx_power_dbm: 4}}
        - {from: s1, to: gw, attempt_success: 0.6}      # per-attempt success given
      routes:                          # optional: default the most reliable path per sensor
        - [s1, r1, gw]

A hop's per-attempt success q_h is ``attempt_success`` (exact) or, from a link budget, one
attempt's success 1 − PER at the hop's distance (the link-budget parser is passed in, so this io
module never imports the link layer). A hop's retries come from the hop's ``retries`` or
``mesh.retries``; ``max_retries`` inside a hop's link budget is refused (one place per number).

Every error names its field (``mesh.hops[2].to``, ``mesh.routes[0]``, ``mesh.slots_per_period``).
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import sympy as sp

from kfcrit.errors import InputError
from kfcrit.model.channels import check_keys, exact_probability
from kfcrit.model.mesh import RELAY_MODES, ROLES, Hop, Mesh, Node, Route, build_mesh
from kfcrit.model.network import Network, Sensor, euclidean_distance
from kfcrit.model.system import MAX_STATES_DEFAULT

MESH_TOP_KEYS = frozenset({"name", "description", "A", "Q", "Sigma0", "mesh", "requirements"})
"""Top-level keys a mesh file may have (the sensors' C and R are in ``mesh.nodes``)."""
MESH_KEYS = {"nodes", "hops", "routes", "relay_mode", "slots_per_period", "retries", "links"}
NODE_KEYS = {"name", "role", "C", "R", "position_m", "mode"}
HOP_KEYS = {"from", "to", "attempt_success", "retries", "channel", "distance_m"}
MAX_RETRIES = 100
"""Largest retry count of a hop."""


@dataclass(frozen=True, eq=False)
class MeshHopLink:
    """How a hop's per-attempt success was obtained: ``given`` (``attempt_success``) or from a
    link-budget ``channel`` (the parsed channel, with zero retries: one attempt) at
    ``distance_m``."""

    source: str
    channel: Any = None
    distance_m: float | None = None


@dataclass(frozen=True, eq=False)
class MeshFile:
    """A mesh file's parts: the plant and sensors (:class:`Network`, no channels: the mesh is
    the channel), the validated :class:`Mesh`, node positions and per-hop link details."""

    network: Network
    mesh: Mesh
    positions: Mapping[str, tuple[float, ...]]
    links: tuple[MeshHopLink, ...]

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON data of the nodes (name, role, mode, position)."""
        return {"nodes": [{"name": n.name, "role": n.role, "mode": n.mode,
                           "position_m": list(self.positions.get(n.name, ())) or None}
                          for n in self.mesh.nodes]}


ChannelParse = Callable[[dict[str, Any], str], Any]
"""``parse(mapping, field_prefix) -> Channel`` for link-budget mappings."""


def _position(value: Any, where: str) -> tuple[sp.Expr, ...]:
    from kfcrit.model.exprparse import parse_expression

    if not isinstance(value, list) or len(value) not in (2, 3):
        raise InputError("must be a list of 2 or 3 coordinates in metres ([x, y])", field=where)
    out = []
    for k, v in enumerate(value):
        if isinstance(v, bool) or not isinstance(v, (str, int)):
            raise InputError("must be a number", field=f"{where}[{k}]")
        out.append(parse_expression(str(v), f"{where}[{k}]"))
    return tuple(out)


def _retries(value: Any, where: str) -> int:
    text = str(value)
    if isinstance(value, bool) or not text.isdigit() or int(text) > MAX_RETRIES:
        raise InputError(f"must be an integer in 0..{MAX_RETRIES}", field=where)
    return int(text)


def _nodes(raw: Any, max_states: int) -> tuple[list[Node], list[Sensor], dict[str, Any]]:
    if not isinstance(raw, list) or not raw:
        raise InputError("must be a non-empty list of nodes (sensors, relays and one gateway)",
                         field="mesh.nodes")
    nodes, sensors, positions = [], [], {}
    for k, item in enumerate(raw):
        where = f"mesh.nodes[{k}]"
        if not isinstance(item, dict):
            raise InputError("must be a mapping (name, role, ...)", field=where)
        check_keys(item, NODE_KEYS, {"name", "role"}, where)
        role, name = item["role"], item["name"]
        if role not in ROLES:
            raise InputError(f"must be one of {', '.join(ROLES)}", field=f"{where}.role")
        if not isinstance(name, str):
            raise InputError("must be a name (a letter, then letters, digits, '_' or '-')",
                             field=f"{where}.name")
        if role == "sensor":
            for key in ("C", "R"):
                if item.get(key) is None:
                    raise InputError("is required for a sensor", field=f"{where}.{key}")
        else:
            for key in ("C", "R"):
                if key in item:
                    raise InputError(f"only sensors measure (a {role} has no {key})",
                                     field=f"{where}.{key}")
        mode = item.get("mode")
        if mode is not None and (role == "gateway" or mode not in RELAY_MODES):
            raise InputError("must be aggregate or forward (and the gateway does not "
                             "transmit)", field=f"{where}.mode")
        if item.get("position_m") is not None:
            positions[name] = _position(item["position_m"], f"{where}.position_m")
        nodes.append(Node(name, role, mode))
        if role == "sensor":
            sensors.append(Sensor(name, item["C"], item["R"], None, positions.get(name),
                                  field=where, max_states=max_states))
    return nodes, sensors, positions


def _distance(hop: dict, where: str, a: str, b: str, positions: Mapping[str, Any]) -> sp.Expr:
    if hop.get("distance_m") is not None:
        from kfcrit.model.exprparse import parse_expression

        return parse_expression(str(hop["distance_m"]), f"{where}.distance_m")
    for end, name in (("from", a), ("to", b)):
        if name not in positions:
            raise InputError(f"node {name!r} has no position_m: give the hop's distance_m",
                             field=f"{where}.{end}")
    if len(positions[a]) != len(positions[b]):
        raise InputError("the two nodes' positions have different dimensions", field=where)
    d = euclidean_distance(positions[a], positions[b])
    if d == 0:
        raise InputError(f"nodes {a!r} and {b!r} are at the same position", field=where)
    return d


def _link_hop(hop: dict, where: str, links: dict | None, positions: Mapping[str, Any],
              parse: ChannelParse) -> tuple[float, MeshHopLink]:
    """q_h = one attempt's success 1 − PER of the hop's link budget at its distance."""
    own = hop.get("channel")
    if own is not None and not isinstance(own, dict):
        raise InputError("must be a mapping of link-budget parameters", field=f"{where}.channel")
    if own is None and links is None:
        raise InputError("needs attempt_success, a link-budget channel, or mesh.links",
                         field=where)
    merged: dict[str, Any] = {"model": "link-budget", **(links or {})}
    for key, val in (own or {}).items():
        if isinstance(val, dict) and isinstance(merged.get(key), dict):
            merged[key] = {**merged[key], **val}
        else:
            merged[key] = val
    if merged.get("model") != "link-budget":
        raise InputError("a hop's channel is a link budget (or give attempt_success)",
                         field=f"{where}.channel.model")
    if "max_retries" in (own or {}):
        raise InputError("give the hop's retries (or mesh.retries), not max_retries",
                         field=f"{where}.channel.max_retries")
    if "distance_m" in (own or {}):
        hop = {**hop, "distance_m": own["distance_m"]}
    d = _distance(hop, where, hop["from"], hop["to"], positions)
    merged["distance_m"] = d
    merged["max_retries"] = 0
    channel = parse(merged, f"{where}.channel")
    q = float(channel.arrival_probability)
    return q, MeshHopLink("link-budget", channel, float(d))


def _hops(raw: Any, names: set[str], links: dict | None, default_retries: int | None,
          positions: Mapping[str, Any], parse: ChannelParse) -> tuple[list[Hop],
                                                                      list[MeshHopLink]]:
    if not isinstance(raw, list) or not raw:
        raise InputError("must be a non-empty list of hops ({from, to, ...})", field="mesh.hops")
    hops, details = [], []
    for k, hop in enumerate(raw):
        where = f"mesh.hops[{k}]"
        if not isinstance(hop, dict):
            raise InputError("must be a mapping (from, to, ...)", field=where)
        check_keys(hop, HOP_KEYS, {"from", "to"}, where)
        for end in ("from", "to"):
            if not isinstance(hop[end], str) or hop[end] not in names:
                raise InputError(f"unknown node {str(hop[end])[:40]!r}", field=f"{where}.{end}")
        retries = (_retries(hop["retries"], f"{where}.retries") if hop.get("retries") is not None
                   else default_retries)
        if hop.get("attempt_success") is not None:
            if "channel" in hop:
                raise InputError("give attempt_success or a channel, not both",
                                 field=f"{where}.attempt_success")
            p = exact_probability(hop["attempt_success"], f"{where}.attempt_success")
            exact = sp.Rational(p) if p.is_Rational else None
            hops.append(Hop(hop["from"], hop["to"], float(p), exact, retries))
            d = hop.get("distance_m")
            details.append(MeshHopLink("given", None, None if d is None else float(
                _distance(hop, where, hop["from"], hop["to"], positions))))
            continue
        q, link = _link_hop(hop, where, links, positions, parse)
        hops.append(Hop(hop["from"], hop["to"], q, None, retries))
        details.append(link)
    return hops, details


def _routes(raw: Any) -> list[Route] | None:
    if raw is None:
        return None
    if not isinstance(raw, list) or not raw:
        raise InputError("must be a list of routes, each a list of node names from the sensor "
                         "to the gateway (or leave routes out: the most reliable path)",
                         field="mesh.routes")
    out = []
    for k, r in enumerate(raw):
        if not isinstance(r, list) or len(r) < 2 or not all(isinstance(x, str) for x in r):
            raise InputError("must be a list of node names from the sensor to the gateway",
                             field=f"mesh.routes[{k}]")
        out.append(Route(r[0], tuple(r)))
    return out


def mesh_from_mapping(doc: Mapping[str, Any], parse: ChannelParse, *, name: str,
                      max_states: int = MAX_STATES_DEFAULT) -> MeshFile:
    """Build the :class:`MeshFile` of a system document with a ``mesh:`` section.

    ``doc`` holds plain values (numbers as text); ``parse`` builds a link-budget channel from a
    mapping and a field prefix. See the module docstring for the format.
    """
    for key in doc:
        if key not in MESH_TOP_KEYS:
            raise InputError("a mesh file gives the sensors' C and R in mesh.nodes (allowed: "
                             f"{', '.join(sorted(MESH_TOP_KEYS))})", field=str(key)[:40])
    for key in ("A", "Q"):
        if doc.get(key) is None:
            raise InputError("is required", field=key)
    data = doc["mesh"]
    if not isinstance(data, dict):
        raise InputError("must be a mapping (nodes, hops, routes, ...)", field="mesh")
    check_keys(data, MESH_KEYS, {"nodes", "hops"}, "mesh")
    links = data.get("links")
    if links is not None and not isinstance(links, dict):
        raise InputError("must be a mapping of link-budget defaults", field="mesh.links")
    for key in ("distance_m", "max_retries"):
        if key in (links or {}):
            raise InputError("is per hop (distance_m or positions; retries)",
                             field=f"mesh.links.{key}")
    # no retries anywhere: one attempt per period, or under a slot budget no cap but the budget
    default_retries = (_retries(data["retries"], "mesh.retries")
                       if data.get("retries") is not None else None)
    nodes, sensors, positions = _nodes(data["nodes"], max_states)
    hops, details = _hops(data["hops"], {n.name for n in nodes}, links, default_retries,
                          positions, parse)
    slots = data.get("slots_per_period")
    if slots is not None:
        text = str(slots)
        if isinstance(slots, bool) or not text.isdigit():
            raise InputError("must be a positive integer (slots per period and route)",
                             field="mesh.slots_per_period")
        slots = int(text)
    mode = data.get("relay_mode", "aggregate")
    mesh = build_mesh(nodes, hops, _routes(data.get("routes")), relay_mode=mode,
                      slots_per_period=slots)
    network = Network(doc["A"], doc["Q"], doc.get("Sigma0"), sensors, name=name,
                      max_states=max_states)
    fpos = {k: tuple(float(x) for x in v) for k, v in positions.items()}
    return MeshFile(network, mesh, fpos, tuple(details))


def mesh_schema(number: dict[str, Any], matrix: dict[str, Any]) -> dict[str, Any]:
    """JSON Schema of the ``mesh:`` section (for ``kfcrit schema system``)."""
    def obj(props: dict[str, Any], required: list[str], description: str) -> dict[str, Any]:
        return {"type": "object", "properties": props, "required": required,
                "additionalProperties": False, "description": description}

    name = {"type": "string", "pattern": "^[A-Za-z][A-Za-z0-9_-]{0,39}$"}
    count = {"type": "integer", "minimum": 0}
    position = {"type": "array", "minItems": 2, "maxItems": 3, "items": number,
                "description": "position in metres [x, y] (hop distances and the map)"}
    node = obj({"name": {**name, "description": "unique node name"},
                "role": {"enum": list(ROLES), "description": "sensor, relay or gateway (exactly "
                         "one gateway: the estimator)"},
                "C": {**matrix, "description": "a sensor's rows of C (m_i × n); sensors only"},
                "R": {**matrix, "description": "a sensor's noise covariance; sensors only"},
                "position_m": position,
                "mode": {"enum": list(RELAY_MODES), "description": "relay mode of the hops this "
                         "node transmits (default mesh.relay_mode)"}},
               ["name", "role"], "a node of the mesh")
    hop = obj({"from": {**name, "description": "transmitting node"},
               "to": {**name, "description": "receiving node"},
               "attempt_success": {**number, "description": "per-attempt success q_h in [0, 1] "
                                   "(instead of a link budget)"},
               "retries": {**count, "description": "retries k_h (default mesh.retries)"},
               "channel": {"type": "object", "description": "link-budget keys of this hop over "
                           "mesh.links (not max_retries); q_h = 1 − PER at its distance"},
               "distance_m": {**number, "description": "hop length (default: from the nodes' "
                              "position_m)"}},
              ["from", "to"], "a directed hop; q_h from attempt_success or a link budget")
    return obj({
        "nodes": {"type": "array", "minItems": 2, "items": node},
        "hops": {"type": "array", "minItems": 1, "items": hop},
        "routes": {"type": "array", "minItems": 1, "description": "node lists from a sensor to "
                   "the gateway (several per sensor: path diversity); default the most reliable "
                   "path per sensor", "items": {"type": "array", "minItems": 2, "items": name}},
        "relay_mode": {"enum": list(RELAY_MODES), "description": "aggregate (one frame per hop "
                       "and period, default) or forward (one frame per packet)"},
        "slots_per_period": {"type": "integer", "minimum": 1, "description": "slot budget D of "
                             "each route per period (one attempt per slot, hops in order)"},
        "retries": {**count, "description": "default retries of every hop (default none: one "
                    "attempt, or under a slot budget no cap but the budget)"},
        "links": {"type": "object", "description": "link-budget defaults of every hop (no "
                  "distance_m, no max_retries)"}},
        ["nodes", "hops"], "a multi-hop mesh of sensors, relays and one gateway (theory §13)")
