"""Sensor networks: one plant (A, Q, Σ0) observed by N sensors, each over its own link.

Sensor i measures y^i_t = C_i x_t + v^i_t with noise covariance R_i (m_i × m_i); its packets
travel over its own channel. Stacking the sensors' rows gives one linear system (theory §9): the
rows of a received set S ⊆ {1..N} are C_S, their noise R_S. Sensor noises are independent
(block-diagonal stacked R) unless ``R_cross`` gives the full stacked covariance.

Invariant: a :class:`Network` holds exact sympy matrices (what the user wrote) and float views,
exactly like :class:`kfcrit.model.system.System`; :meth:`Network.stacked_system` is the
single :class:`System` with every row, and for one sensor it is that sensor's system.

The model layer never reads link budgets: :func:`network_from_mapping` receives the channel
parser as an argument (``channel_parser(mapping, field_prefix) -> Channel``).
"""
from __future__ import annotations

import re
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import sympy as sp

from kfcrit.errors import InputError
from kfcrit.model.exprparse import compare, parse_expression
from kfcrit.model.system import (
    MAX_STATES_DEFAULT,
    System,
    is_definite,
    sym_tolerance,
    to_float,
    to_matrix,
)

MAX_SENSORS = 256
"""Most sensors a network may have (the analysis enumerates the 2^N received sets only for
small N; beyond, one-sensor maps whose cost grows polynomially in N, docs/theory.md §15)."""
SENSOR_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_-]{0,39}")
"""Sensor names: a letter, then letters, digits, ``_`` or ``-`` (at most 40 characters), so that
a sweep path ``sensors.NAME.channel.distance_m`` is unambiguous."""
SENSOR_KEYS = {"name", "C", "R", "channel", "position_m"}
SENSOR_REQUIRED = {"name", "C", "R"}
NETWORK_KEYS = frozenset({"A", "Q", "Sigma0", "sensors", "links", "sink_position_m", "R_cross",
                          "name"})
"""Top-level keys :func:`network_from_mapping` reads (the caller checks the others)."""
SINGLE_SENSOR_KEYS = frozenset({"C", "R", "channel"})
"""Top-level keys of the single-sensor form; a file uses either these or ``sensors:``."""


def _check_symmetric(M: sp.ImmutableMatrix, Mf: np.ndarray, where: str, exact: bool) -> None:
    """Refuse an asymmetric matrix (exactly for rational entries, else with a scale-aware
    float tolerance)."""
    if np.max(np.abs(Mf - Mf.T), initial=0.0) > sym_tolerance(Mf):
        raise InputError("must be symmetric", field=where)
    if exact and all(e.is_Rational for e in M) and M != M.T:
        raise InputError("must be symmetric", field=where)


@dataclass(frozen=True, eq=False)
class Sensor:
    """One sensor: output rows ``C`` (m_i × n), noise ``R`` (m_i × m_i), its channel.

    Parameters
    ----------
    name : str
        Unique name (letters, digits, ``_``, ``-``; starts with a letter).
    C : array_like
        Output matrix; its column count is checked by :class:`Network`.
    R : array_like
        Noise covariance (symmetric positive definite); a scalar means that scalar times I.
    channel : Channel, optional
        The sensor's link (any channel model); None when only the plant is analysed.
    position : tuple of sympy numbers, optional
        Position in metres (for maps and link distances).
    field : str, optional
        Prefix of error messages (``sensors[1]``).
    """

    name: str
    C: sp.ImmutableMatrix
    R: sp.ImmutableMatrix
    channel: Any
    position: tuple[sp.Expr, ...] | None
    exact: bool
    c: np.ndarray = field(repr=False)
    r: np.ndarray = field(repr=False)

    def __init__(self, name: str, C: Any, R: Any, channel: Any = None,
                 position: Iterable[Any] | None = None, *, field: str | None = None,
                 max_states: int = MAX_STATES_DEFAULT) -> None:
        where = field or f"sensors[{name!s:.40}]"
        if not isinstance(name, str) or not SENSOR_NAME.fullmatch(name):
            raise InputError("must start with a letter and use only letters, digits, '_' or "
                             "'-' (at most 40 characters)", field=f"{where}.name")
        C_, ec = to_matrix(C, f"{where}.C", max_size=max_states)
        m = C_.shape[0]
        R_, er = to_matrix(R, f"{where}.R", allow_scalar_identity=m, max_size=max_states)
        if R_.shape != (m, m):
            raise InputError(f"must be {m}x{m} (C has {m} rows), got {R_.shape[0]}x{R_.shape[1]}",
                             field=f"{where}.R")
        rf = to_float(R_)
        _check_symmetric(R_, rf, f"{where}.R", er)
        if not is_definite(R_, rf, er, strict=True):
            raise InputError("must be symmetric positive definite", field=f"{where}.R")
        pos = None
        if position is not None:
            pos = tuple(position)
        set_ = object.__setattr__
        set_(self, "name", name)
        set_(self, "C", C_)
        set_(self, "R", R_)
        set_(self, "channel", channel)
        set_(self, "position", pos)
        set_(self, "exact", bool(ec and er))
        cf = to_float(C_)
        for arr in (cf, rf):
            arr.setflags(write=False)
        set_(self, "c", cf)
        set_(self, "r", rf)

    @property
    def m(self) -> int:
        """Number of output rows."""
        return self.C.shape[0]


def _block_diagonal(blocks: list[sp.ImmutableMatrix]) -> sp.ImmutableMatrix:
    return sp.ImmutableMatrix(sp.diag(*blocks)) if len(blocks) > 1 else blocks[0]


@dataclass(frozen=True, eq=False)
class Network:
    """A plant x_{t+1} = A x_t + w_t, w ~ N(0, Q), x_0 ~ N(·, Σ0) observed by ``sensors``.

    Parameters
    ----------
    A, Q : array_like
        Plant matrices (as for :class:`System`; ``Q`` may be a scalar).
    Sigma0 : array_like, optional
        Initial covariance (default identity).
    sensors : sequence of Sensor
        At least one; names unique; every ``C`` has n columns.
    R_cross : array_like, optional
        The full stacked noise covariance (Σ m_i square, sensors in order) when sensor noises
        are correlated; its diagonal blocks must equal the sensors' ``R``. Default: the
        block-diagonal matrix of the sensors' ``R``.
    name : str, optional
        Label for reports.
    """

    A: sp.ImmutableMatrix
    Q: sp.ImmutableMatrix
    Sigma0: sp.ImmutableMatrix
    sensors: tuple[Sensor, ...]
    R_cross: sp.ImmutableMatrix | None
    name: str
    sink_position: tuple[sp.Expr, ...] | None
    _stacked: System = field(repr=False)

    def __init__(self, A: Any, Q: Any, Sigma0: Any = None, sensors: Iterable[Sensor] = (),
                 R_cross: Any = None, name: str | None = None,
                 sink_position: Iterable[Any] | None = None,
                 max_states: int = MAX_STATES_DEFAULT) -> None:
        sensors = tuple(sensors)
        if not sensors:
            raise InputError("must list at least one sensor", field="sensors")
        if len(sensors) > MAX_SENSORS:
            raise InputError(f"has {len(sensors)} sensors; at most {MAX_SENSORS} are supported",
                             field="sensors")
        A_, _ = to_matrix(A, "A", max_size=max_states)
        n = A_.shape[0]
        if A_.shape != (n, n):
            raise InputError(f"must be square, got {A_.shape[0]}x{A_.shape[1]}", field="A")
        seen: dict[str, int] = {}
        for k, s in enumerate(sensors):
            if not isinstance(s, Sensor):
                raise InputError("must be a Sensor", field=f"sensors[{k}]")
            if s.C.shape[1] != n:
                raise InputError(f"must have {n} columns (the size of A), got {s.C.shape[1]}",
                                 field=f"sensors[{k}].C")
            if s.name in seen:
                raise InputError(f"duplicate sensor name {s.name!r} (also sensors[{seen[s.name]}])",
                                 field=f"sensors[{k}].name")
            seen[s.name] = k
        C_ = sp.ImmutableMatrix(sp.Matrix.vstack(*[s.C for s in sensors]))
        m = C_.shape[0]
        if R_cross is None:
            R_, rc = _block_diagonal([s.R for s in sensors]), None
        else:
            rc, _ = to_matrix(R_cross, "R_cross", max_size=max_states)
            if rc.shape != (m, m):
                raise InputError(f"must be {m}x{m} (all sensors' rows), got "
                                 f"{rc.shape[0]}x{rc.shape[1]}", field="R_cross")
            start = 0
            for k, s in enumerate(sensors):
                block = rc[start:start + s.m, start:start + s.m]
                if any(compare(block[i, j], s.R[i, j], "R_cross") != 0
                       for i in range(s.m) for j in range(s.m)):
                    raise InputError(f"diagonal block of sensor {s.name!r} (rows {start}.."
                                     f"{start + s.m - 1}) must equal sensors[{k}].R",
                                     field="R_cross")
                start += s.m
            R_ = rc
        # the stacked System validates Q, Sigma0 and the stacked R (symmetric, definite); the
        # stacked R is R_cross when given, so its errors name R_cross, not R
        try:
            stacked = System(A_, C_, Q, R_, Sigma0, name=name, max_states=max_states)
        except InputError as exc:
            if rc is None or exc.field is None or not (exc.field == "R"
                                                       or exc.field.startswith("R[")):
                raise
            message = str(exc)[len(exc.field) + 2:]
            raise type(exc)(message, field="R_cross" + exc.field[1:]) from None
        set_ = object.__setattr__
        set_(self, "A", stacked.A)
        set_(self, "Q", stacked.Q)
        set_(self, "Sigma0", stacked.Sigma0)
        set_(self, "sensors", sensors)
        set_(self, "R_cross", rc)
        set_(self, "name", stacked.name)
        set_(self, "sink_position", tuple(sink_position) if sink_position is not None else None)
        set_(self, "_stacked", stacked)

    # -- sizes and views ------------------------------------------------------------------------
    @property
    def n(self) -> int:
        """State dimension."""
        return self.A.shape[0]

    @property
    def size(self) -> int:
        """Number of sensors N."""
        return len(self.sensors)

    @property
    def names(self) -> tuple[str, ...]:
        """Sensor names in order."""
        return tuple(s.name for s in self.sensors)

    @property
    def exact(self) -> bool:
        """Every entry came from exact input."""
        return self._stacked.exact

    def row_slices(self) -> tuple[slice, ...]:
        """Rows of each sensor in the stacked C."""
        out, start = [], 0
        for s in self.sensors:
            out.append(slice(start, start + s.m))
            start += s.m
        return tuple(out)

    def index(self, sensor: int | str) -> int:
        """Position of a sensor given by index or name."""
        if isinstance(sensor, str):
            if sensor not in self.names:
                raise InputError(f"unknown sensor {sensor[:40]!r} (sensors: "
                                 f"{', '.join(self.names)})", field="sensor")
            return self.names.index(sensor)
        if isinstance(sensor, (int, np.integer)) and not isinstance(sensor, bool) \
                and 0 <= int(sensor) < self.size:
            return int(sensor)
        raise InputError(f"must be a sensor name or an index in 0..{self.size - 1}",
                         field="sensor")

    def stacked_system(self) -> System:
        """The :class:`System` with every sensor's rows (C stacked in order, R stacked)."""
        return self._stacked

    def received_system(self, S: Iterable[int | str]) -> System:
        """The :class:`System` of the rows of the received set ``S`` (names or indices).

        R_S is the submatrix of the stacked R on those rows (theory §9).
        """
        idx = sorted({self.index(s) for s in S})
        if not idx:
            raise InputError("a received set must contain at least one sensor", field="S")
        sl = self.row_slices()
        rows = [r for i in idx for r in range(sl[i].start, sl[i].stop)]
        st = self._stacked
        C = st.C.extract(rows, list(range(self.n)))
        R = st.R.extract(rows, rows)
        label = f"{st.name} [{', '.join(self.names[i] for i in idx)}]"
        return System(st.A, C, st.Q, R, st.Sigma0, name=label)

    def arrival_probabilities(self) -> tuple[sp.Expr | None, ...]:
        """Each sensor's stationary arrival probability (exact where the channel is), or None
        for a sensor without a channel."""
        return tuple(s.channel.arrival_probability if s.channel is not None else None
                     for s in self.sensors)

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON data: the sensors with exact matrix text and channels."""
        def text(M: sp.MatrixBase) -> list[list[str]]:
            return [[sp.sstr(e) for e in M.row(i)] for i in range(M.shape[0])]
        return {"n": self.n, "sensors": [
            {"name": s.name, "m": s.m, "C": text(s.C), "R": text(s.R),
             "channel": s.channel.to_dict() if s.channel is not None else None,
             "position_m": [float(x) for x in s.position] if s.position is not None else None}
            for s in self.sensors],
            "sink_position_m": ([float(x) for x in self.sink_position]
                                if self.sink_position is not None else None),
            "correlated_noise": self.R_cross is not None}


# ---------------------------------------------------------------------------------------------
# system-file form
# ---------------------------------------------------------------------------------------------

def _position(value: Any, where: str) -> tuple[sp.Expr, ...]:
    """An exact position [x, y] or [x, y, z] in metres."""
    if not isinstance(value, (list, tuple)) or len(value) not in (2, 3):
        raise InputError("must be a list of 2 or 3 coordinates in metres ([x, y])", field=where)
    out = []
    for k, v in enumerate(value):
        if isinstance(v, bool) or not isinstance(v, (str, int)):
            raise InputError("must be a number", field=f"{where}[{k}]")
        out.append(parse_expression(str(v), f"{where}[{k}]"))
    return tuple(out)


def euclidean_distance(a: tuple[sp.Expr, ...], b: tuple[sp.Expr, ...]) -> sp.Expr:
    """Exact Euclidean distance √(Σ (a_k − b_k)²) (a sympy number)."""
    return sp.sqrt(sum(((x - y) ** 2 for x, y in zip(a, b)), sp.Integer(0)))


def _merge(defaults: Mapping[str, Any], own: Mapping[str, Any]) -> dict[str, Any]:
    """``own`` over ``defaults``; nested mappings (``path_loss``, ``noise``) merge key by key."""
    out = dict(defaults)
    for key, val in own.items():
        if isinstance(val, dict) and isinstance(out.get(key), dict):
            out[key] = _merge(out[key], val)
        else:
            out[key] = val
    return out


def _channel_mapping(raw: Mapping[str, Any], where: str, links: Mapping[str, Any] | None,
                     position: tuple[sp.Expr, ...] | None,
                     sink: tuple[sp.Expr, ...] | None) -> dict[str, Any] | None:
    """The channel mapping of one sensor: ``links`` defaults merged, distance from positions."""
    chan = raw.get("channel")
    if chan is None and links is None:
        return None
    if chan is None:
        chan = {}
    if not isinstance(chan, dict):
        raise InputError("must be a mapping with a 'model' key", field=f"{where}.channel")
    if links is not None and chan.get("model", "link-budget") == "link-budget":
        chan = _merge({"model": "link-budget", **links}, chan)
    if position is not None and chan.get("model") == "link-budget":
        if "distance_m" in chan and "distance_m" in (raw.get("channel") or {}):
            raise InputError("give distance_m or position_m, not both",
                             field=f"{where}.channel.distance_m")
        if sink is None:
            raise InputError("is required when sensors give position_m",
                             field="sink_position_m")
        if len(sink) != len(position):
            raise InputError(f"has {len(position)} coordinates, sink_position_m has {len(sink)}",
                             field=f"{where}.position_m")
        d = euclidean_distance(position, sink)
        if d == 0:
            raise InputError("coincides with sink_position_m (distance 0)",
                             field=f"{where}.position_m")
        chan = {**chan, "distance_m": d}
    return chan


def network_from_mapping(doc: Mapping[str, Any],
                         channel_parser: Callable[[dict[str, Any], str], Any], *,
                         name: str | None = None,
                         max_states: int = MAX_STATES_DEFAULT) -> Network:
    """Build a :class:`Network` from the ``sensors:`` form of a system file.

    Reads the keys :data:`NETWORK_KEYS` of ``doc`` (the caller checks the other top-level
    keys): ``A``, ``Q``, ``Sigma0``, ``sensors`` (a list of mappings with ``name``, ``C``,
    ``R``, optional ``channel`` and ``position_m``), optional ``links`` (defaults merged into
    every link-budget channel, nested mappings key by key; a sensor without ``channel`` gets a
    link-budget channel from ``links`` alone), ``sink_position_m`` (with ``position_m``, the
    channel's ``distance_m`` is the exact Euclidean distance √(Σ (x_k − s_k)²), a sympy number)
    and ``R_cross``.

    Numbers may be YAML number text (kept as strings) or exact expressions; every number is
    read by :mod:`kfcrit.model.exprparse`, never ``eval``.

    Parameters
    ----------
    doc : mapping
        The parsed system document.
    channel_parser : callable
        ``channel_parser(mapping, field_prefix) -> Channel``; the prefix is
        ``sensors[i].channel``.
    """
    if not isinstance(doc, Mapping):
        raise InputError("the file must be a YAML mapping", field="file")
    both = sorted(SINGLE_SENSOR_KEYS & set(doc))
    if both:
        raise InputError(f"give either sensors: or top-level {', '.join(both)} (one sensor), "
                         "not both", field=both[0])
    for key in ("A", "Q", "sensors"):
        if doc.get(key) is None:
            raise InputError("is required", field=key)
    raw_sensors = doc["sensors"]
    if not isinstance(raw_sensors, list) or not raw_sensors:
        raise InputError("must be a non-empty list of sensors (name, C, R, channel)",
                         field="sensors")
    if len(raw_sensors) > MAX_SENSORS:
        raise InputError(f"has {len(raw_sensors)} sensors; at most {MAX_SENSORS} are supported",
                         field="sensors")
    links = doc.get("links")
    if links is not None and not isinstance(links, dict):
        raise InputError("must be a mapping of link-budget defaults", field="links")
    if links is not None and "distance_m" in links:
        raise InputError("distances are per sensor (distance_m or position_m)",
                         field="links.distance_m")
    sink = (_position(doc["sink_position_m"], "sink_position_m")
            if doc.get("sink_position_m") is not None else None)
    sensors = []
    for k, raw in enumerate(raw_sensors):
        where = f"sensors[{k}]"
        if not isinstance(raw, dict):
            raise InputError("must be a mapping (name, C, R, channel)", field=where)
        for key in raw:
            if key not in SENSOR_KEYS:
                raise InputError(f"unknown key (allowed: {', '.join(sorted(SENSOR_KEYS))})",
                                 field=f"{where}.{str(key)[:40]}")
        for key in sorted(SENSOR_REQUIRED):
            if raw.get(key) is None:
                raise InputError("is required", field=f"{where}.{key}")
        sname = raw["name"]
        if not isinstance(sname, str):
            raise InputError("must be a name (a letter, then letters, digits, '_' or '-')",
                             field=f"{where}.name")
        position = (_position(raw["position_m"], f"{where}.position_m")
                    if raw.get("position_m") is not None else None)
        chan_map = _channel_mapping(raw, where, links, position, sink)
        channel = (channel_parser(chan_map, f"{where}.channel")
                   if chan_map is not None else None)
        sensors.append(Sensor(str(sname), raw["C"], raw["R"], channel, position, field=where,
                              max_states=max_states))
    label = name if name is not None else doc.get("name")
    return Network(doc["A"], doc["Q"], doc.get("Sigma0"), sensors, R_cross=doc.get("R_cross"),
                   name=str(label)[:200] if label is not None else None, sink_position=sink,
                   max_states=max_states)
