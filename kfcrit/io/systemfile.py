"""System files: YAML in, an exact :class:`~kfcrit.model.system.System` plus channel out.

Numbers are read from their text, never through a binary float: the YAML loader below keeps the
source text of every int/float scalar and :func:`kfcrit.model.exprparse.number_from_text` turns it into
an exact rational. Aliases, duplicate keys and unknown keys are errors. Only the safe YAML
constructors exist (``yaml.SafeLoader`` subclass), so no tag can build a Python object.
"""
from __future__ import annotations

import gc
import hashlib
import re
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from kfcrit.errors import InputError
from kfcrit.io.channelfile import BASIC_CHANNELS, ChannelParser, channel_from_mapping
from kfcrit.io.loopfile import LoopSpec, loop_from_mapping
from kfcrit.io.safeio import read_text
from kfcrit.model.channels import Channel, check_keys, exact_probability, key_name
from kfcrit.model.continuous import SampledModel, sample
from kfcrit.model.exprparse import number_from_text
from kfcrit.model.network import Network, network_from_mapping
from kfcrit.model.system import MAX_STATES_DEFAULT, System

MAX_FILE_BYTES = 20_000_000
MAX_NESTING = 64
"""Deepest nesting of YAML collections accepted (a system file needs 3 levels)."""
MAX_NODES = 1_000_000
"""Most YAML values (scalars and collections) in a file read by :func:`read_yaml` by default."""
MATRIX_KEYS = frozenset({"A", "C", "Q", "R", "Sigma0"})
TOP_KEYS = {"name", "description", "A", "C", "Q", "R", "Sigma0", "channel", "requirements",
            "continuous", "sampling_time", "sensors", "links", "sink_position_m", "R_cross",
            "mesh", "loop"}
REQUIRED_KEYS = {"name", "C", "R"}
"""Required in every system file; the model is either ``A`` and ``Q`` (discrete time) or
``continuous: {A, Q}`` with ``sampling_time`` (:data:`CONTINUOUS_KEYS`), never both."""
CONTINUOUS_KEYS = {"A", "Q"}
SCAN_MATRIX_KEYS = MATRIX_KEYS | {"continuous", "sensors", "R_cross", "loop"}
"""Top-level keys whose lists the size guard of :func:`scan_yaml` covers."""
REQUIREMENT_KEYS = {"max_error_trace", "max_tail_probability", "max_mean_error_trace",
                    "max_cost"}


class YamlNumber(str):
    """The source text of a YAML int or float scalar (converted exactly later)."""


_BaseLoader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)  # LibYAML when available


PLAIN_YAML_NUMBER = re.compile(r"[-+]?(?:(?:0|[1-9][0-9]*)|([0-9]+\.[0-9]*(?:[eE][-+][0-9]+)?))")
"""Plain scalars that YAML 1.1 (PyYAML's safe resolver) reads as an int (``-12``) or, with a
dot (group 1), a float (``0.25``, ``-1.5e-03``)."""
_FLOAT_TAG = "tag:yaml.org,2002:float"
_INT_TAG = "tag:yaml.org,2002:int"
_NUMBER_TAGS = frozenset({_FLOAT_TAG, _INT_TAG})


class ExactLoader(_BaseLoader):  # type: ignore[misc, valid-type]
    """Safe loader that keeps number text and forbids aliases and duplicate keys.

    Aliases are detected at construction: a node met a second time can only be an alias (every
    non-alias node is constructed exactly once), so the check works for the C and the pure-Python
    parser alike.
    """

    def resolve(self, kind, value, implicit):  # noqa: ANN001 - PyYAML signature
        """PyYAML's tag of a node; a plain decimal number's found by one match (matrices hold
        many): a text :data:`PLAIN_YAML_NUMBER` matches is one the safe resolver's first
        matching pattern for its first character, YAML 1.1's float or int, also matches."""
        if kind is yaml.ScalarNode and implicit[0]:
            match = PLAIN_YAML_NUMBER.fullmatch(value)
            if match is not None:
                return _FLOAT_TAG if match.group(1) else _INT_TAG
        return super().resolve(kind, value, implicit)

    def construct_object(self, node, deep=False):  # noqa: ANN001 - PyYAML signature
        if node in self.constructed_objects or node in self.recursive_objects:
            raise InputError(f"YAML aliases are not allowed (line {node.start_mark.line + 1})",
                             field="file")
        return super().construct_object(node, deep=deep)

    def construct_sequence(self, node, deep=False):  # noqa: ANN001
        """PyYAML's list of a sequence node, its number entries (a matrix row) built directly
        as :class:`YamlNumber` (what their constructor gives) and recorded as constructed, so
        that a node met again is still refused as an alias."""
        if not isinstance(node, yaml.SequenceNode):
            return super().construct_sequence(node, deep=deep)
        done = self.constructed_objects
        out = []
        for child in node.value:
            if type(child) is yaml.ScalarNode and child.tag in _NUMBER_TAGS \
                    and child not in done and child not in self.recursive_objects:
                value = done[child] = YamlNumber(child.value)
            else:
                value = self.construct_object(child, deep=deep)
            out.append(value)
        return out

    def construct_mapping(self, node, deep=False):  # noqa: ANN001
        if not isinstance(node, yaml.MappingNode):
            return super().construct_mapping(node, deep=deep)
        seen = set()
        for key_node, _ in node.value:
            if key_node.tag == "tag:yaml.org,2002:merge":
                raise InputError(f"YAML merge keys (<<) are not allowed (line "
                                 f"{key_node.start_mark.line + 1})", field="file")
            if isinstance(key_node, yaml.ScalarNode):
                if key_node.value in seen:
                    raise InputError(f"duplicate key (line {key_node.start_mark.line + 1})",
                                     field=str(key_node.value)[:40])
                seen.add(key_node.value)
        return super().construct_mapping(node, deep=deep)


def _number(loader: yaml.SafeLoader, node: yaml.Node) -> YamlNumber:
    return YamlNumber(loader.construct_scalar(node))


ExactLoader.add_constructor(_INT_TAG, _number)
ExactLoader.add_constructor(_FLOAT_TAG, _number)


_RESOLVER = yaml.resolver.Resolver()
_NULL_TAG = "tag:yaml.org,2002:null"
_MERGE_TAG = "tag:yaml.org,2002:merge"


class _Frame:
    """One open collection during :func:`scan_yaml`."""

    __slots__ = ("mapping", "path", "keys", "expect_key", "current", "count", "limit", "matrix")

    def __init__(self, mapping: bool, path: str, limit: int | None, matrix: str | None) -> None:
        self.mapping = mapping
        self.path = path
        self.keys: set[str] = set()
        self.expect_key = True
        self.current = ""
        self.count = 0
        self.limit = limit
        self.matrix = matrix


def _join(path: str, key: str) -> str:
    return f"{path}.{key}" if path else key


def scan_yaml(text: str, *, name: str = "the file", max_depth: int = MAX_NESTING,
              max_nodes: int = MAX_NODES, matrix_keys: frozenset[str] = frozenset(),
              max_items: int | None = None) -> None:
    """Check the structure of a YAML text from its event stream, before anything is built.

    LibYAML's event parser is iterative (no recursion, no Python objects but the events), so this
    pass is safe on any input and stops at the first problem: collections nested deeper than
    ``max_depth`` (PyYAML's composer recurses, and its C version crashes on some 10^4 levels),
    more than ``max_nodes`` values, aliases, merge keys ``<<``, null, complex or duplicate keys
    (named by their full field, ``channel.arrival_probability``), and any list below a top-level
    key in ``matrix_keys`` with more than ``max_items`` entries (the state-size guard, applied
    before the file is built, so a huge matrix is refused in the time of reading ``max_items``
    entries).
    """
    stack: list[_Frame] = []
    nodes = 0
    events = yaml.parse(text, Loader=_BaseLoader)
    try:
        for event in events:
            if isinstance(event, yaml.AliasEvent):
                raise InputError(f"YAML aliases are not allowed (line "
                                 f"{event.start_mark.line + 1})", field="file")
            if isinstance(event, (yaml.SequenceEndEvent, yaml.MappingEndEvent)):
                stack.pop()
                continue
            if not isinstance(event, (yaml.ScalarEvent, yaml.SequenceStartEvent,
                                      yaml.MappingStartEvent)):
                continue
            nodes += 1
            line = event.start_mark.line + 1 if event.start_mark is not None else 0
            if nodes > max_nodes:
                raise InputError(f"{name} has more than {max_nodes} YAML values (line {line})",
                                 field="file")
            parent = stack[-1] if stack else None
            if parent is not None and parent.mapping and parent.expect_key:
                _scan_key(event, parent, line)
                continue
            path, matrix = "", None
            if parent is not None and parent.mapping:
                path, parent.expect_key = _join(parent.path, parent.current), True
                matrix = parent.current if not parent.path and parent.current in matrix_keys \
                    else parent.matrix
            elif parent is not None:
                parent.count += 1
                if parent.limit is not None and parent.count > parent.limit:
                    raise InputError(f"has more than {parent.limit} rows or columns (raise the "
                                     "limit with --max-states)", field=parent.matrix)
                path, matrix = f"{parent.path}[{parent.count - 1}]", parent.matrix
            if isinstance(event, yaml.ScalarEvent):
                continue
            if len(stack) >= max_depth:
                raise InputError(f"{name} nests YAML collections deeper than {max_depth} levels "
                                 f"(line {line})", field="file")
            is_map = isinstance(event, yaml.MappingStartEvent)
            limit = max_items if matrix is not None and not is_map else None
            stack.append(_Frame(is_map, path, limit, matrix))
    except yaml.YAMLError:
        return  # the loader reports the syntax error with its position
    finally:
        events.close()


def _scan_key(event: yaml.Event, parent: _Frame, line: int) -> None:
    where = parent.path or "top level"
    if not isinstance(event, yaml.ScalarEvent):
        raise InputError(f"mapping keys must be plain names, not collections (line {line})",
                         field=parent.path or "file")
    tag = event.tag
    if tag is None or tag == "!":
        tag = _RESOLVER.resolve(yaml.ScalarNode, event.value, event.implicit)
    if tag == _MERGE_TAG:
        raise InputError(f"YAML merge keys (<<) are not allowed (line {line})",
                         field=_join(parent.path, "<<"))
    if tag == _NULL_TAG:
        raise InputError(f"a null key (~, null or empty) at {where} (line {line})",
                         field=_join(parent.path, "<null key>"))
    key = event.value
    if key in parent.keys:
        raise InputError(f"duplicate key (line {line})", field=_join(parent.path, key[:40]))
    parent.keys.add(key)
    parent.current = key[:40]
    parent.expect_key = False


def _exact_numbers(obj: Any, where: str, depth: int = 0,
                   memo: dict[str, Any] | None = None) -> Any:
    """Replace every :class:`YamlNumber` in nested lists by an exact sympy rational.

    A matrix is at most a list of lists, so nesting deeper than two levels is an error. Each
    distinct number text is converted once (``memo``, local to the call); the entries are
    visited in order, so the first bad one is the one named.
    """
    memo = {} if memo is None else memo
    if isinstance(obj, YamlNumber):
        value = memo.get(obj)
        if value is None:
            value = memo[obj] = number_from_text(str(obj), where)
        return value
    if isinstance(obj, dict):
        raise InputError("expected a number or a matrix (list of rows), got a mapping"
                         if depth == 0 else "expected a number, got a mapping", field=where)
    if isinstance(obj, list):
        if depth >= 2:
            raise InputError("must be a matrix: a list of rows of numbers", field=where)
        out = []
        for i, v in enumerate(obj):
            value = memo.get(v) if isinstance(v, YamlNumber) else None
            out.append(value if value is not None else
                       _exact_numbers(v, f"{where}[{i}]", depth + 1, memo))
        return out
    return obj


@dataclass(frozen=True, eq=False)
class Requirements:
    """Optional design requirements from the system file."""

    max_error_trace: float | None = None
    """Limit M of the tail requirement P(tr P > M) ≤ max_tail_probability."""
    max_tail_probability: float | None = None
    max_mean_error_trace: float | None = None
    """Limit L of the accuracy requirement lim E[tr P_t] ≤ L (theory §11)."""
    max_cost: float | None = None
    """Limit of the closed loop's average cost J (theory §12; a file with ``loop:``)."""

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"max_error_trace": self.max_error_trace,
                               "max_tail_probability": self.max_tail_probability}
        if self.max_mean_error_trace is not None:
            out["max_mean_error_trace"] = self.max_mean_error_trace
        if self.max_cost is not None:
            out["max_cost"] = self.max_cost
        return out

    def __bool__(self) -> bool:
        return any(v is not None for v in (self.max_error_trace, self.max_tail_probability,
                                           self.max_mean_error_trace, self.max_cost))


@dataclass(frozen=True, eq=False)
class SystemSpec:
    """Everything a system file says: the system, the channel, requirements, provenance.

    Returned by :func:`kfcrit.load_spec`; built directly to pair a :class:`~kfcrit.System` with a
    channel for :func:`kfcrit.analyze` or :func:`kfcrit.simulate`.

    Parameters
    ----------
    system : System
        The plant and sensor (for a ``sensors:`` or ``mesh:`` file the stacked system).
    channel : Channel, optional
        The link (None: no operating point, only the theory).
    requirements : Requirements
        Accuracy, tail and cost requirements of the file.
    description, path, sha256 : str
        Provenance of the file.
    continuous, network, mesh, loop : optional
        The continuous-time model, sensor network, mesh and closed loop of the file (each
        documented on its field below).

    Attributes
    ----------
    system, channel, requirements, description, path, sha256, continuous, network, mesh, loop
        As given.

    Raises
    ------
    kfcrit.errors.InputError
        Never from the constructor (it stores what it is given); :func:`kfcrit.load_spec` raises
        it for an invalid file.

    References
    ----------
    docs/theory.md §1 (the model), §9 (sensor networks), §12 (closed loops), §13 (meshes).

    Examples
    --------
    >>> from kfcrit import Bernoulli, System, SystemSpec
    >>> spec = SystemSpec(System(A=[[1.25]], C=[[1]], Q=1, R=1), Bernoulli("1/2"))
    >>> spec.channel.arrival_probability, spec.network is None
    (1/2, True)
    """

    system: System
    channel: Channel | None = None
    requirements: Requirements = field(default_factory=Requirements)
    description: str = ""
    path: str | None = None
    sha256: str | None = None
    continuous: SampledModel | None = None
    """The continuous-time model and sampling (``continuous:`` with ``sampling_time``) that
    gave ``system.A`` and ``system.Q``; None for a discrete-time file."""
    network: Network | None = None
    """The sensors of a ``sensors:`` file (each with its rows of C, its noise and its channel);
    ``system`` is then the stacked system (every sensor's rows) and ``channel`` None."""
    mesh: Any = None
    """The :class:`kfcrit.io.meshfile.MeshFile` of a ``mesh:`` file (theory §13): ``system`` is
    the stacked system of its sensors, ``network`` and ``channel`` None (the mesh is the
    channel)."""
    loop: LoopSpec | None = None
    """The closed loop of a ``loop:`` file (theory §12): B, weights, actuation link, design."""


def read_yaml(path: str | Path, *, max_bytes: int = MAX_FILE_BYTES, max_nodes: int = MAX_NODES,
              matrix_keys: frozenset[str] = frozenset(),
              max_items: int | None = None) -> tuple[Any, str]:
    """Read and parse a YAML file safely; return (document, sha256 of the bytes).

    The text is checked by :func:`scan_yaml` (nesting, size, aliases, merge, null and duplicate
    keys, matrix sizes) before the document is built.
    """
    text, digest = _read_text(path, max_bytes)
    return parse_yaml_text(text, name=Path(path).name, max_nodes=max_nodes,
                           matrix_keys=matrix_keys, max_items=max_items), digest


def _read_text(path: str | Path, max_bytes: int = MAX_FILE_BYTES) -> tuple[str, str]:
    """The UTF-8 text of a file (a regular file, size-capped: :func:`kfcrit.io.safeio.read_text`)
    and the SHA-256 of its bytes."""
    text, data = read_text(path, field="file", max_bytes=max_bytes)
    digest = hashlib.sha256(data).hexdigest()
    if not text.strip():
        raise InputError("is empty", field="file")
    return text, digest


def parse_yaml_text(text: str, *, name: str = "file", max_nodes: int = MAX_NODES,
                    matrix_keys: frozenset[str] = frozenset(),
                    max_items: int | None = None) -> Any:
    """Check (:func:`scan_yaml`) and parse a YAML text with the exact, safe loader."""
    scan_yaml(text, name=repr(name[:60]), max_nodes=max_nodes, matrix_keys=matrix_keys,
              max_items=max_items)
    try:
        doc = yaml.load(text, Loader=ExactLoader)  # noqa: S506 - SafeLoader subclass
    except InputError:
        raise
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark is not None else ""
        problem = getattr(exc, "problem", None) or "invalid YAML"
        raise InputError(f"{name[:60]!r} is not valid YAML{where}: {problem}",
                         field="file") from None
    except RecursionError:
        raise InputError("YAML nesting is too deep", field="file") from None
    return doc


def _positive_number(v: Any, field: str) -> float:
    """A positive finite number from a YAML number, a Python number or an exact expression."""
    from kfcrit.model.exprparse import parse_expression

    if isinstance(v, bool) or v is None:
        raise InputError("must be a number", field=field)
    if isinstance(v, YamlNumber):
        val = number_from_text(str(v), field)
    elif isinstance(v, (int, float)):
        val = number_from_text(repr(v), field)
    elif isinstance(v, str):
        val = parse_expression(v, field)
    else:
        raise InputError("must be a number", field=field)
    out = float(val)
    if not out > 0 or out == float("inf"):
        raise InputError("must be a positive finite number", field=field)
    return out


def _requirements(data: Any) -> Requirements:
    if not isinstance(data, dict):
        raise InputError("must be a mapping", field="requirements")
    check_keys(data, REQUIREMENT_KEYS, set(), "requirements")
    out: dict[str, float] = {}
    for key in ("max_error_trace", "max_mean_error_trace", "max_cost"):
        if key in data:
            out[key] = _positive_number(data[key], f"requirements.{key}")
    if "max_tail_probability" in data:
        v = data["max_tail_probability"]
        v = str(v) if isinstance(v, YamlNumber) else v
        out["max_tail_probability"] = float(exact_probability(
            v, "requirements.max_tail_probability"))
    return Requirements(**out)


def plain_data(obj: Any) -> Any:
    """YamlNumber → its text, recursively (for channel mappings read by other modules)."""
    if isinstance(obj, YamlNumber):
        return str(obj)
    if isinstance(obj, dict):
        return {k: plain_data(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [plain_data(v) for v in obj]
    return obj


def _raw_shape(value: Any, name: str, max_states: int) -> tuple[int, int] | None:
    """Shape of a raw (unconverted) matrix: None for a scalar; errors name the matrix."""
    if isinstance(value, dict):
        raise InputError("expected a number or a matrix (list of rows), got a mapping",
                         field=name)
    if not isinstance(value, (list, tuple)):
        return None
    if len(value) == 0:
        raise InputError("must be a non-empty matrix", field=name)
    if not all(isinstance(r, (list, tuple)) for r in value):
        raise InputError("must be a list of rows (e.g. [[1, 0], [0, 1]])", field=name)
    ncols = len(value[0])
    if len(value) > max_states or ncols > max_states:
        raise InputError(f"has more than {max_states} rows or columns (raise the limit with "
                         "--max-states)", field=name)
    if ncols == 0:
        raise InputError("has an empty row", field=name)
    for i, row in enumerate(value):
        if len(row) != ncols:
            raise InputError(f"row {i} has {len(row)} entries, row 0 has {ncols}", field=name)
    return len(value), ncols


def _check_shapes(doc: dict, max_states: int) -> None:
    """The dimension checks of :class:`System`, on the raw lists (cheap: no entry is read).

    In a continuous-time file the state matrix and noise are ``continuous.A``, ``continuous.Q``.
    """
    shapes = {k: _raw_shape(doc[k], k, max_states) for k in sorted(MATRIX_KEYS) if k in doc}
    a_name = "A"
    if "continuous" in doc:
        a_name = "continuous.A"
        for key in ("A", "Q"):
            shapes[key] = _raw_shape(doc["continuous"][key], f"continuous.{key}", max_states)
    a = shapes["A"] or (1, 1)
    n = a[0]
    if a != (n, n):
        raise InputError(f"must be square, got {a[0]}x{a[1]}", field=a_name)
    c = shapes["C"] or (1, 1)
    if c[1] != n:
        raise InputError(f"must have {n} columns (the size of A), got {c[1]}", field="C")
    for key, size in (("Q", n), ("R", c[0]), ("Sigma0", n)):
        shape = shapes.get(key)
        if shape is not None and shape != (size, size):
            name = "continuous.Q" if key == "Q" and "continuous" in doc else key
            raise InputError(f"must be {size}x{size}, got {shape[0]}x{shape[1]}", field=name)


def _check_model_form(doc: dict) -> None:
    """Either ``A`` and ``Q`` or ``continuous: {A, Q}`` with ``sampling_time``, not both."""
    if "continuous" in doc or "sampling_time" in doc:
        for key in ("A", "Q"):
            if key in doc:
                raise InputError("give either A and Q (discrete time) or continuous: with "
                                 "sampling_time, not both", field=key)
        for key in ("continuous", "sampling_time"):
            if doc.get(key) is None:
                raise InputError("is required with "
                                 + ("sampling_time" if key == "continuous" else "continuous:"),
                                 field=key)
        data = doc["continuous"]
        if not isinstance(data, dict):
            raise InputError("must be a mapping with A and Q (the continuous-time state matrix "
                             "and noise spectral density)", field="continuous")
        check_keys(data, CONTINUOUS_KEYS, CONTINUOUS_KEYS, "continuous")
        for key in ("A", "Q"):
            if data[key] is None:
                raise InputError("is required", field=f"continuous.{key}")
        if isinstance(doc["sampling_time"], (list, dict)):
            raise InputError("must be a number (seconds)", field="sampling_time")
        return
    for key in ("A", "Q"):
        if doc.get(key) is None:
            raise InputError("is required (or continuous: with sampling_time)", field=key)


def _sampled(doc: dict) -> SampledModel | None:
    """The sampled continuous-time model of a file (:func:`kfcrit.model.continuous.sample`)."""
    if "continuous" not in doc:
        return None
    data = doc["continuous"]
    return sample(_exact_numbers(data["A"], "continuous.A"),
                  _exact_numbers(data["Q"], "continuous.Q"),
                  _exact_numbers(doc["sampling_time"], "sampling_time"))


RECORD_MARKERS = ("schema_version", "review")
"""Top-level keys every record saved by ``kfcrit analyze --json`` has and no system file has."""
SWEEP_ONLY_KEYS = ("system", "grid", "points")
"""Top-level keys of a sweep file that no system file has."""


def is_saved_record(doc: Any) -> bool:
    """Whether a parsed document is an analysis record saved by ``kfcrit analyze --json``."""
    return isinstance(doc, dict) and all(k in doc for k in RECORD_MARKERS)


def is_sweep_document(doc: Any) -> bool:
    """Whether a parsed document is a sweep file rather than a system file.

    A sweep file names its base ``system:`` (no system file has that key); ``grid:`` or
    ``points:`` without any matrix also mark one, so that a sweep file whose ``system:`` key is
    misspelled is still reported as a sweep file.
    """
    if not isinstance(doc, dict):
        return False
    return "system" in doc or (any(k in doc for k in SWEEP_ONLY_KEYS)
                               and not any(k in doc for k in MATRIX_KEYS | {"continuous"}))


def wrong_kind_error(doc: Any, path: str | Path | None = None) -> InputError | None:
    """The one-line error for a saved record or a sweep file given where a system file is
    expected (None for anything else)."""
    import shlex

    name = shlex.quote(str(path)) if path is not None else "FILE"
    if is_saved_record(doc):
        return InputError(f"this is a saved analysis record (kfcrit analyze --json), not a system "
                          f"file; render it with 'kfcrit report {name} -o review.html'",
                          field="file")
    if is_sweep_document(doc):
        return InputError(f"this is a sweep file, not a system file; validate it with 'kfcrit "
                          f"check {name}' and run it with 'kfcrit sweep {name}'", field="file")
    return None


def _json_record(text: str) -> Any:
    """The JSON document ``text`` holds when it looks like a saved record (else None): such a
    record is recognised before the YAML reader's size guards, sized for system files, see it."""
    if text.lstrip("\ufeff \t\r\n")[:1] != "{":
        return None
    import json

    try:
        doc = json.loads(text.lstrip("\ufeff"))
    except (ValueError, RecursionError):
        return None
    return doc if is_saved_record(doc) else None


def read_system_mapping(doc: Any, *, base_dir: Path | None = None,
                      max_states: int = MAX_STATES_DEFAULT,
                      channels: Mapping[str, ChannelParser] = BASIC_CHANNELS) -> SystemSpec:
    """Validate a parsed system document and build the :class:`SystemSpec`.

    ``channels`` maps each channel ``model`` to its parser (the analysis layer adds the models
    of higher layers, e.g. link budgets).
    """
    if not isinstance(doc, dict):
        raise InputError("the file must be a YAML mapping (name:, A:, C:, Q:, R:, ...)",
                         field="file")
    wrong = wrong_kind_error(doc)
    if wrong is not None:
        raise wrong
    for key in doc:
        if not isinstance(key, str) or key not in TOP_KEYS:
            raise InputError(f"unknown key (allowed: {', '.join(sorted(TOP_KEYS))})",
                             field=key_name(key))
    if "sensors" in doc:
        return _network_spec(doc, base_dir, max_states, channels)
    if "mesh" in doc:
        return _mesh_spec(doc, base_dir, max_states, channels)
    for key in sorted(REQUIRED_KEYS):
        if key not in doc or doc[key] is None:
            raise InputError("is required", field=key)
    name, description = _name_and_description(doc)
    _check_model_form(doc)
    _check_shapes(doc, max_states)  # on the raw structure, before any exact conversion
    mats = {k: _exact_numbers(doc[k], k) for k in ("A", "C", "Q", "R", "Sigma0") if k in doc}
    sampled = _sampled(doc)
    if sampled is not None:
        mats["A"], mats["Q"] = (sampled.A, sampled.Q) if sampled.exact \
            else (sampled.float_a(), sampled.float_q())
    system = System(mats["A"], mats["C"], mats["Q"], mats["R"], mats.get("Sigma0"),
                    name=name, max_states=max_states)
    channel = (channel_from_mapping(plain_data(doc["channel"]), "channel", base_dir,
                                    parsers=channels)
               if doc.get("channel") is not None else None)
    reqs = _requirements(doc["requirements"]) if doc.get("requirements") is not None \
        else Requirements()
    loop = None if doc.get("loop") is None else loop_from_mapping(
        doc["loop"], system.n, system.m, convert=_exact_numbers,
        parse_channel=lambda d, prefix: channel_from_mapping(plain_data(d), prefix, base_dir,
                                                             parsers=channels))
    if loop is not None and channel is None:
        raise InputError("is required with loop: (the sensing link)", field="channel")
    if reqs.max_cost is not None and loop is None:
        raise InputError("needs a loop: section (the cost is the closed loop's)",
                         field="requirements.max_cost")
    return SystemSpec(system=system, channel=channel, requirements=reqs,
                      description=description, continuous=sampled, loop=loop)


def _name_and_description(doc: dict) -> tuple[str, str]:
    if doc.get("name") is None:
        raise InputError("is required", field="name")
    name = doc["name"]
    if not isinstance(name, (str, YamlNumber)) or not str(name).strip():
        raise InputError("must be a non-empty string", field="name")
    description = doc.get("description") or ""
    if not isinstance(description, str):
        raise InputError("must be a string", field="description")
    return str(name)[:200], description[:2000]


def _network_spec(doc: dict, base_dir: Path | None, max_states: int,
                  channels: Mapping[str, ChannelParser]) -> SystemSpec:
    """The spec of a ``sensors:`` file (theory §9): the network and its stacked system."""
    name, description = _name_and_description(doc)
    for key in ("continuous", "sampling_time"):
        if key in doc:
            raise InputError("a sensors: file gives A and Q in discrete time", field=key)
    if "loop" in doc:
        raise InputError("a closed loop has one sensing link (channel:), not sensors:",
                         field="loop")

    def parse(mapping: dict, prefix: str) -> Channel:
        return channel_from_mapping(plain_data(mapping), prefix, base_dir, parsers=channels)

    plain = {k: (plain_data(v) if k in ("sensors", "links") else v) for k, v in doc.items()}
    network = network_from_mapping(plain, parse, name=name, max_states=max_states)
    reqs = _requirements(doc["requirements"]) if doc.get("requirements") is not None \
        else Requirements()
    return SystemSpec(system=network.stacked_system(), channel=None, requirements=reqs,
                      description=description, network=network)


def _mesh_spec(doc: dict, base_dir: Path | None, max_states: int,
               channels: Mapping[str, ChannelParser]) -> SystemSpec:
    """The spec of a ``mesh:`` file (theory §13, :mod:`kfcrit.io.meshfile`)."""
    from kfcrit.io.meshfile import mesh_from_mapping

    name, description = _name_and_description(doc)

    def parse(mapping: dict, prefix: str) -> Channel:
        return channel_from_mapping(mapping, prefix, base_dir, parsers=channels)

    plain = {k: (plain_data(v) if k == "mesh" else v) for k, v in doc.items()}
    mesh = mesh_from_mapping(plain, parse, name=name, max_states=max_states)
    reqs = _requirements(doc["requirements"]) if doc.get("requirements") is not None \
        else Requirements()
    return SystemSpec(system=mesh.network.stacked_system(), requirements=reqs,
                      description=description, mesh=mesh)


def max_nodes_for(max_states: int) -> int:
    """The YAML value budget of a system file: five full matrices of the largest size, plus
    room for the rest (so a file is refused before it is built, not after)."""
    return 5 * max_states * max_states + 10_000




@contextmanager
def paused_gc() -> Iterator[None]:
    """Python's cyclic garbage collector off inside the block (restored after).

    Reading a big file creates objects by the hundred thousand (YAML nodes, number texts,
    sympy rationals) and no reference cycles: each collection the allocations trigger would
    traverse all of them again (measured: half the time of reading a 400-state file).
    """
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


def read_system_file(path: str | Path, *, max_states: int = MAX_STATES_DEFAULT,
              channels: Mapping[str, ChannelParser] = BASIC_CHANNELS) -> SystemSpec:
    """Load a system file: the system, its channel, requirements and provenance (SHA-256).

    The structure is checked before the document is built (:func:`scan_yaml` with the
    state-size guard ``max_states``); then the shapes, then the exact entries.
    """
    text, digest = _read_text(path)
    wrong = wrong_kind_error(_json_record(text), path)
    if wrong is not None:
        raise wrong
    with paused_gc():
        doc = parse_yaml_text(text, name=Path(path).name, max_nodes=max_nodes_for(max_states),
                              matrix_keys=SCAN_MATRIX_KEYS, max_items=max_states)
        wrong = wrong_kind_error(doc, path)
        if wrong is not None:
            raise wrong
        spec = read_system_mapping(doc, base_dir=Path(path).resolve().parent,
                                   max_states=max_states, channels=channels)
    out = SystemSpec(system=spec.system, channel=spec.channel, requirements=spec.requirements,
                     description=spec.description, path=str(path), sha256=digest,
                     continuous=spec.continuous, network=spec.network, mesh=spec.mesh,
                     loop=spec.loop)
    return out


def read_system(path: str | Path, *, max_states: int = MAX_STATES_DEFAULT) -> System:
    """Load only the :class:`System` of a system file."""
    return read_system_file(path, max_states=max_states).system
