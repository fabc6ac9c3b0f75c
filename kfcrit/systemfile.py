"""System files: YAML in, an exact :class:`~kfcrit.system.System` plus channel out.

Numbers are read from their text, never through a binary float: the YAML loader below keeps the
source text of every int/float scalar and :func:`kfcrit.exprparse.number_from_text` turns it into
an exact rational. Aliases, duplicate keys and unknown keys are errors. Only the safe YAML
constructors exist (``yaml.SafeLoader`` subclass), so no tag can build a Python object.
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from .channels import Channel, channel_from_mapping, check_keys, exact_probability
from .errors import InputError
from .exprparse import number_from_text
from .system import MAX_STATES_DEFAULT, System

MAX_FILE_BYTES = 20_000_000
TOP_KEYS = {"name", "description", "A", "C", "Q", "R", "Sigma0", "channel", "requirements"}
REQUIRED_KEYS = {"name", "A", "C", "Q", "R"}
REQUIREMENT_KEYS = {"max_error_trace", "max_tail_probability"}


class YamlNumber(str):
    """The source text of a YAML int or float scalar (converted exactly later)."""


_BaseLoader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)  # LibYAML when available


class _ExactLoader(_BaseLoader):  # type: ignore[misc, valid-type]
    """Safe loader that keeps number text and forbids aliases and duplicate keys.

    Aliases are detected at construction: a node met a second time can only be an alias (every
    non-alias node is constructed exactly once), so the check works for the C and the pure-Python
    parser alike.
    """

    def construct_object(self, node, deep=False):  # noqa: ANN001 - PyYAML signature
        if node in self.constructed_objects or node in self.recursive_objects:
            raise InputError(f"YAML aliases are not allowed (line {node.start_mark.line + 1})",
                             field="file")
        return super().construct_object(node, deep=deep)

    def construct_mapping(self, node, deep=False):  # noqa: ANN001
        if not isinstance(node, yaml.MappingNode):
            return super().construct_mapping(node, deep=deep)
        seen = set()
        for key_node, _ in node.value:
            if isinstance(key_node, yaml.ScalarNode):
                if key_node.value in seen:
                    raise InputError(f"duplicate key (line {key_node.start_mark.line + 1})",
                                     field=str(key_node.value)[:40])
                seen.add(key_node.value)
        return super().construct_mapping(node, deep=deep)


def _number(loader: yaml.SafeLoader, node: yaml.Node) -> YamlNumber:
    return YamlNumber(loader.construct_scalar(node))


_ExactLoader.add_constructor("tag:yaml.org,2002:int", _number)
_ExactLoader.add_constructor("tag:yaml.org,2002:float", _number)


def _exact_numbers(obj: Any, where: str, depth: int = 0) -> Any:
    """Replace every :class:`YamlNumber` in nested lists by an exact sympy rational.

    A matrix is at most a list of lists, so nesting deeper than two levels is an error.
    """
    if isinstance(obj, YamlNumber):
        return number_from_text(str(obj), where)
    if isinstance(obj, list):
        if depth >= 2:
            raise InputError("must be a matrix: a list of rows of numbers", field=where)
        return [_exact_numbers(v, f"{where}[{i}]", depth + 1) for i, v in enumerate(obj)]
    return obj


@dataclass(frozen=True, eq=False)
class Requirements:
    """Optional design requirements from the system file."""

    max_error_trace: float | None = None
    max_tail_probability: float | None = None

    def to_dict(self) -> dict[str, Any]:
        return {"max_error_trace": self.max_error_trace,
                "max_tail_probability": self.max_tail_probability}


@dataclass(frozen=True, eq=False)
class SystemSpec:
    """Everything a system file says: the system, the channel, requirements, provenance."""

    system: System
    channel: Channel | None = None
    requirements: Requirements = field(default_factory=Requirements)
    description: str = ""
    path: str | None = None
    sha256: str | None = None


def read_yaml(path: str | Path, *, max_bytes: int = MAX_FILE_BYTES) -> tuple[Any, str]:
    """Read and parse a YAML file safely; return (document, sha256 of the bytes)."""
    p = Path(path)
    try:
        if p.is_dir():
            raise InputError(f"{str(p)[:80]!r} is a directory", field="file")
        size = p.stat().st_size
    except OSError:
        raise InputError(f"cannot read {str(p)[:80]!r} (no such file or not readable)",
                         field="file") from None
    if size > max_bytes:
        raise InputError(f"is larger than {max_bytes} bytes", field="file")
    try:
        data = p.read_bytes()
    except OSError:
        raise InputError(f"cannot read {str(p)[:80]!r}", field="file") from None
    digest = hashlib.sha256(data).hexdigest()
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        raise InputError("is not valid UTF-8 text", field="file") from None
    if not text.strip():
        raise InputError("is empty", field="file")
    try:
        doc = yaml.load(text, Loader=_ExactLoader)  # noqa: S506 - SafeLoader subclass
    except InputError:
        raise
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark is not None else ""
        problem = getattr(exc, "problem", None) or "invalid YAML"
        raise InputError(f"not valid YAML{where}: {problem}", field="file") from None
    except RecursionError:
        raise InputError("YAML nesting is too deep", field="file") from None
    return doc, digest


def _requirements(data: Any) -> Requirements:
    if not isinstance(data, dict):
        raise InputError("must be a mapping", field="requirements")
    check_keys(data, REQUIREMENT_KEYS, set(), "requirements")
    out: dict[str, float] = {}
    if "max_error_trace" in data:
        v = data["max_error_trace"]
        if not isinstance(v, YamlNumber):
            raise InputError("must be a number", field="requirements.max_error_trace")
        val = number_from_text(str(v), "requirements.max_error_trace")
        if val <= 0:
            raise InputError("must be positive", field="requirements.max_error_trace")
        out["max_error_trace"] = float(val)
    if "max_tail_probability" in data:
        v = data["max_tail_probability"]
        v = str(v) if isinstance(v, YamlNumber) else v
        out["max_tail_probability"] = float(exact_probability(
            v, "requirements.max_tail_probability"))
    return Requirements(**out)


def _plain(obj: Any) -> Any:
    """YamlNumber → its text, recursively (for channel mappings read by other modules)."""
    if isinstance(obj, YamlNumber):
        return str(obj)
    if isinstance(obj, dict):
        return {k: _plain(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_plain(v) for v in obj]
    return obj


def spec_from_mapping(doc: Any, *, base_dir: Path | None = None,
                      max_states: int = MAX_STATES_DEFAULT) -> SystemSpec:
    """Validate a parsed system document and build the :class:`SystemSpec`."""
    if not isinstance(doc, dict):
        raise InputError("the file must be a YAML mapping (name:, A:, C:, Q:, R:, ...)",
                         field="file")
    for key in doc:
        if not isinstance(key, str) or key not in TOP_KEYS:
            raise InputError(f"unknown key (allowed: {', '.join(sorted(TOP_KEYS))})",
                             field=str(key)[:40])
    for key in sorted(REQUIRED_KEYS):
        if key not in doc or doc[key] is None:
            raise InputError("is required", field=key)
    name = doc["name"]
    if not isinstance(name, (str, YamlNumber)) or not str(name).strip():
        raise InputError("must be a non-empty string", field="name")
    description = doc.get("description") or ""
    if not isinstance(description, str):
        raise InputError("must be a string", field="description")
    mats = {k: _exact_numbers(doc[k], k) for k in ("A", "C", "Q", "R", "Sigma0") if k in doc}
    system = System(mats["A"], mats["C"], mats["Q"], mats["R"], mats.get("Sigma0"),
                    name=str(name)[:200], max_states=max_states)
    channel = (channel_from_mapping(_plain(doc["channel"]), "channel", base_dir)
               if doc.get("channel") is not None else None)
    reqs = _requirements(doc["requirements"]) if doc.get("requirements") is not None \
        else Requirements()
    return SystemSpec(system=system, channel=channel, requirements=reqs,
                      description=description[:2000])


def load_spec(path: str | Path, *, max_states: int = MAX_STATES_DEFAULT) -> SystemSpec:
    """Load a system file: the system, its channel, requirements and provenance (SHA-256)."""
    doc, digest = read_yaml(path)
    spec = spec_from_mapping(doc, base_dir=Path(path).resolve().parent, max_states=max_states)
    return SystemSpec(system=spec.system, channel=spec.channel, requirements=spec.requirements,
                      description=spec.description, path=str(path), sha256=digest)


def load_system(path: str | Path, *, max_states: int = MAX_STATES_DEFAULT) -> System:
    """Load only the :class:`System` of a system file."""
    return load_spec(path, max_states=max_states).system
