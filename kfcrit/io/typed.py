"""Typed records: frozen dataclasses read from, written to and described by JSON.

The analysis record is a tree of frozen dataclasses. Three generic functions, driven by the
dataclasses' type hints alone, keep its three forms in step:

* :func:`to_json` — the plain JSON value (what ``--json`` prints and every view renders);
* :func:`from_json` — the typed record from JSON (strict: an unknown or missing key, or a value
  of the wrong type, is an error naming its path);
* :func:`json_schema` — the JSON Schema (draft 2020-12) of the JSON form.

Invariant: for every record ``r``, ``from_json(type(r), to_json(r)) == r`` and ``to_json(r)``
validates against ``json_schema(type(r))``. A renamed field therefore fails the schema test, the
round trip and every view that reads it, instead of hiding behind ``dict.get``.

Supported field types: ``bool``, ``int``, ``float``, ``str``, ``None``, an :class:`enum.Enum`
of strings, a nested dataclass, ``list[T]``, ``tuple[T, ...]``, ``dict[str, T]``, unions with
``None`` (``T | None``), unions of these (read as the first that fits) and :data:`JSON` (any
JSON value; the analysis record does not use it). A ``float`` field accepts an integer and keeps
it (``1`` stays ``1``, not ``1.0``), so a record's JSON form survives the round trip exactly.
"""
from __future__ import annotations

import dataclasses
import enum
import functools
import math
import types
import typing
from typing import Any, Union

JSON = Union[None, bool, int, float, str, list[Any], dict[str, Any]]  # noqa: UP007 - one object
"""Any JSON value (its schema is ``{}``)."""

SCHEMA_DIALECT = "https://json-schema.org/draft/2020-12/schema"


def opt(default: Any = None) -> Any:
    """A field that may be absent from the JSON form: written only when not ``None``.

    Used for keys that a section carries only in some cases (e.g. ``basis`` of a critical value
    that rests on coinciding bounds); the schema lists them as optional properties.
    """
    return dataclasses.field(default=default, metadata={"omit_none": True})


def internal(default_factory: Any) -> Any:
    """A field kept on the object but not in its JSON form or schema (e.g. wall-clock timings,
    which would make two runs of the same input differ)."""
    return dataclasses.field(default_factory=default_factory, metadata={"internal": True},
                             compare=False, repr=False)


class _Absent:
    """The value of an :func:`opt_key` field whose key is absent from the JSON form."""

    _instance: _Absent | None = None

    def __new__(cls) -> _Absent:
        if cls._instance is None:
            cls._instance = super().__new__(cls)
        return cls._instance

    def __bool__(self) -> bool:
        return False

    def __repr__(self) -> str:
        return "ABSENT"

    def __reduce__(self) -> str:
        return "ABSENT"


ABSENT: Any = _Absent()
"""Marks an :func:`opt_key` field whose key is absent (falsy; distinct from a ``null`` value)."""


def opt_key() -> Any:
    """A key that some records carry and others do not, whatever its value.

    Unlike :func:`opt`, a ``null`` value is kept (written as ``null``); only an absent key is
    left out of the JSON form. The attribute of an absent key is :data:`ABSENT` (falsy).
    """
    return dataclasses.field(default=ABSENT, metadata={"omit_absent": True})


def _omittable(f: dataclasses.Field) -> bool:
    return bool(f.metadata.get("omit_none") or f.metadata.get("omit_absent"))


def _omitted(f: dataclasses.Field, value: Any) -> bool:
    if f.metadata.get("omit_absent"):
        return value is ABSENT
    return bool(f.metadata.get("omit_none")) and value is None


def _public_fields(cls_or_obj: Any) -> list[dataclasses.Field]:
    return [f for f in dataclasses.fields(cls_or_obj) if not f.metadata.get("internal")]


@functools.cache
def _write_plan(cls: type) -> tuple[tuple[str, bool, bool], ...]:
    """(name, omitted when absent, omitted when None) of each public field, once per class."""
    return tuple((f.name, bool(f.metadata.get("omit_absent")), bool(f.metadata.get("omit_none")))
                 for f in _public_fields(cls))


class RecordError(ValueError):
    """A JSON value does not fit the typed record (the message names the path)."""


@functools.cache
def _hints(cls: type) -> dict[str, Any]:
    """Type hints of a record class, resolved once per class (classes never change)."""
    return typing.get_type_hints(cls, include_extras=False)


def _is_optional(tp: Any) -> tuple[bool, Any]:
    """``(True, T)`` for ``T | None``; ``(False, tp)`` otherwise (decided once per type)."""
    try:
        return _optional_of(tp)
    except TypeError:  # an unhashable type annotation
        return _optional_of.__wrapped__(tp)


@functools.cache
def _optional_of(tp: Any) -> tuple[bool, Any]:
    """:func:`_is_optional`, cached (types never change)."""
    origin = typing.get_origin(tp)
    if origin in (Union, types.UnionType) and tp is not JSON:
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        if len(args) == 1 and len(typing.get_args(tp)) == 2:
            return True, args[0]
    return False, tp


# ----------------------------------------------------------------------------- to JSON

def to_json(obj: Any) -> Any:
    """The plain JSON value of a typed record (non-finite floats become ``None``).

    Dataclass fields keep their declaration order; enums become their values; tuples lists.
    """
    if isinstance(obj, enum.Enum):
        return obj.value
    if obj is None or isinstance(obj, (bool, str)):
        return obj
    if isinstance(obj, int):
        return int(obj)
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        out = {}
        for name, omit_absent, omit_none in _write_plan(type(obj)):
            value = getattr(obj, name)
            if not (value is ABSENT if omit_absent else omit_none and value is None):
                out[name] = to_json(value)
        return out
    if isinstance(obj, dict):
        return {str(k): to_json(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_json(v) for v in obj]
    raise RecordError(f"cannot write {type(obj).__name__} as JSON")


# ----------------------------------------------------------------------------- from JSON

def from_json(tp: Any, value: Any, path: str = "record") -> Any:
    """Read ``value`` (plain JSON) as type ``tp``; :class:`RecordError` names the first misfit.

    A compiled reader of ``tp`` (:func:`_reader`, built once per type) reads a value that fits;
    only a misfit is read again by the checking reader, for the message naming its path.
    """
    try:
        return _reader(tp)(value)
    except (_Misfit, RecordError, TypeError, ValueError):
        return _checked(tp, value, path)


def _checked(tp: Any, value: Any, path: str) -> Any:
    """:func:`from_json`, checking every node and naming the path of the first misfit."""
    if tp is JSON or tp is Any:
        return _check_json(value, path)
    optional, inner = _is_optional(tp)
    if value is None:
        if optional or tp is type(None) or (
                typing.get_origin(tp) in (Union, types.UnionType)
                and type(None) in typing.get_args(tp)):
            return None
        raise RecordError(f"{path}: must not be null")
    tp = inner
    origin = typing.get_origin(tp)
    if isinstance(tp, type) and dataclasses.is_dataclass(tp):
        return _dataclass_from_json(tp, value, path)
    if isinstance(tp, type) and issubclass(tp, enum.Enum):
        try:
            return tp(value)
        except ValueError:
            allowed = ", ".join(repr(m.value) for m in tp)
            raise RecordError(f"{path}: must be one of {allowed}, got {value!r}") from None
    if tp is bool:
        if not isinstance(value, bool):
            raise RecordError(f"{path}: must be true or false")
        return value
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise RecordError(f"{path}: must be an integer")
        return value
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise RecordError(f"{path}: must be a number")
        return value  # an int stays an int (a float field accepts one; its JSON form is kept)
    if tp is str:
        if not isinstance(value, str):
            raise RecordError(f"{path}: must be a string")
        return value
    if origin in (list, tuple):
        if not isinstance(value, list):
            raise RecordError(f"{path}: must be a list")
        (item,) = typing.get_args(tp)[:1]
        plain = _PLAIN_ITEMS.get(item)
        if plain is not None and all(type(v) in plain for v in value):
            return tuple(value) if origin is tuple else list(value)  # every item fits as is
        items = [_checked(item, v, f"{path}[{i}]") for i, v in enumerate(value)]
        return tuple(items) if origin is tuple else items
    if origin is dict:
        if not isinstance(value, dict):
            raise RecordError(f"{path}: must be an object")
        _, item = typing.get_args(tp)
        return {k: _checked(item, v, f"{path}.{k}") for k, v in value.items()}
    if origin in (Union, types.UnionType):
        misfits = []
        for arg in typing.get_args(tp):
            try:
                return _checked(arg, value, path)
            except RecordError as exc:
                misfits.append(str(exc))
        raise RecordError(f"{path}: fits none of {_type_name(tp)} ("
                          + "; ".join(misfits) + ")")
    raise RecordError(f"{path}: unsupported field type {tp!r}")


_PLAIN_ITEMS: typing.Mapping[Any, tuple[type, ...]] = types.MappingProxyType(
    {str: (str,), float: (float, int), int: (int,), bool: (bool,),
     float | None: (float, int, type(None)), str | None: (str, type(None))})
"""Item types whose JSON values :func:`from_json` returns unchanged, with the exact Python
types that fit them as they are (a list of these is checked in one pass, not item by item)."""


def _type_name(tp: Any) -> str:
    """``A | B | None`` with bare class names (for error messages)."""
    args = typing.get_args(tp)
    if typing.get_origin(tp) in (Union, types.UnionType):
        return " | ".join(_type_name(a) for a in args)
    if args:
        return f"{getattr(tp, '__name__', tp)}[{', '.join(_type_name(a) for a in args)}]"
    return "None" if tp is type(None) else getattr(tp, "__name__", str(tp))


def _check_json(value: Any, path: str) -> Any:
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, list):
        return [_check_json(v, f"{path}[{i}]") for i, v in enumerate(value)]
    if isinstance(value, dict):
        return {str(k): _check_json(v, f"{path}.{k}") for k, v in value.items()}
    raise RecordError(f"{path}: {type(value).__name__} is not a JSON value")


def _dataclass_from_json(cls: type, value: Any, path: str) -> Any:
    if not isinstance(value, dict):
        raise RecordError(f"{path}: must be an object")
    hints = _hints(cls)
    fields = _public_fields(cls)
    names = [f.name for f in fields]
    unknown = sorted(set(value) - set(names))
    if unknown:
        raise RecordError(f"{path}: unknown key {unknown[0]!r} (expected one of {', '.join(names)})")
    missing = [f.name for f in fields if f.name not in value and not _omittable(f)]
    if missing:
        raise RecordError(f"{path}: missing key {missing[0]!r}")
    return cls(**{n: _checked(hints[n], value[n], f"{path}.{n}") for n in names if n in value})


# ----------------------------------------------------------------------------- compiled readers

class _Misfit(Exception):
    """A value that does not fit (the checking reader then names where)."""


def _misfit(value: Any) -> Any:
    raise _Misfit


@functools.cache
def _reader(tp: Any) -> typing.Callable[[Any], Any]:
    """The reader of type ``tp``: :func:`_checked`'s rules with the type analysis done once.

    It raises :class:`_Misfit` (or :class:`RecordError`) where :func:`_checked` raises
    :class:`RecordError`, and returns the same value where it does not.
    """
    if tp is JSON or tp is Any:
        return lambda v: _check_json(v, "record")
    optional, inner = _is_optional(tp)
    none_fits = optional or tp is type(None) or (
        typing.get_origin(tp) in (Union, types.UnionType) and type(None) in typing.get_args(tp))
    read = _inner_reader(inner)
    if none_fits:
        return lambda v: None if v is None else read(v)
    return lambda v: _misfit(v) if v is None else read(v)


def _scalar(kinds: tuple[type, ...], bool_fits: bool) -> typing.Callable[[Any], Any]:
    def read(v: Any) -> Any:
        if isinstance(v, bool) and not bool_fits or not isinstance(v, kinds):
            raise _Misfit
        return v
    return read


def _inner_reader(tp: Any) -> typing.Callable[[Any], Any]:
    """The reader of a non-``None`` value of ``tp`` (``None`` handled by :func:`_reader`)."""
    origin = typing.get_origin(tp)
    if isinstance(tp, type) and dataclasses.is_dataclass(tp):
        return _dataclass_reader(tp)
    if isinstance(tp, type) and issubclass(tp, enum.Enum):
        return tp
    if tp is bool:
        return _scalar((bool,), True)
    if tp is int:
        return _scalar((int,), False)
    if tp is float:
        return _scalar((int, float), False)
    if tp is str:
        return _scalar((str,), True)
    if origin in (list, tuple):
        item = _reader(typing.get_args(tp)[0])
        plain = _PLAIN_ITEMS.get(typing.get_args(tp)[0])
        as_tuple = origin is tuple

        def read_list(v: Any) -> Any:
            if not isinstance(v, list):
                raise _Misfit
            if plain is not None and all(type(x) in plain for x in v):
                return tuple(v) if as_tuple else list(v)  # every item fits as is
            items = [item(x) for x in v]
            return tuple(items) if as_tuple else items
        return read_list
    if origin is dict:
        value_reader = _reader(typing.get_args(tp)[1])

        def read_dict(v: Any) -> Any:
            if not isinstance(v, dict):
                raise _Misfit
            return {k: value_reader(x) for k, x in v.items()}
        return read_dict
    if origin in (Union, types.UnionType):
        readers = [_reader(a) if a is not type(None) else _misfit for a in typing.get_args(tp)]

        def read_union(v: Any) -> Any:
            for r in readers:
                try:
                    return r(v)
                except (_Misfit, RecordError, ValueError):   # ValueError: an enum's misfit
                    continue
            raise _Misfit
        return read_union
    return _misfit


def _dataclass_reader(cls: type) -> typing.Callable[[Any], Any]:
    hints = _hints(cls)
    fields = _public_fields(cls)
    names = frozenset(f.name for f in fields)
    required = [f.name for f in fields if not _omittable(f)]
    # readers are looked up at call time: a class may refer to itself (a tree of sections)
    plan = [(f.name, hints[f.name]) for f in fields]

    def read(v: Any) -> Any:
        if not isinstance(v, dict) or not v.keys() <= names:
            raise _Misfit
        for n in required:
            if n not in v:
                raise _Misfit
        return cls(**{n: _reader(t)(v[n]) for n, t in plan if n in v})
    return read


# ----------------------------------------------------------------------------- JSON Schema

def json_schema(cls: type, *, title: str | None = None) -> dict[str, Any]:
    """JSON Schema (draft 2020-12) of the JSON form of dataclass ``cls``.

    Every dataclass becomes a ``$defs`` entry (objects with all fields required and no other
    keys); enums become ``enum`` lists; :data:`JSON` fields accept any value.
    """
    defs: dict[str, Any] = {}
    root = _schema_of(cls, defs)
    out = {"$schema": SCHEMA_DIALECT, "title": title or cls.__name__, **root, "$defs": defs}
    return out


def _schema_of(tp: Any, defs: dict[str, Any]) -> dict[str, Any]:
    if tp is JSON or tp is Any:
        return {}
    optional, inner = _is_optional(tp)
    if optional:
        return {"anyOf": [_schema_of(inner, defs), {"type": "null"}]}
    origin = typing.get_origin(tp)
    if isinstance(tp, type) and dataclasses.is_dataclass(tp):
        name = tp.__name__
        if name not in defs:
            defs[name] = {}  # placeholder: recursion-safe
            hints = _hints(tp)
            fields = _public_fields(tp)
            doc = (tp.__doc__ or "").strip().split("\n")[0]
            defs[name] = {"type": "object", "description": doc,
                          "properties": {f.name: _schema_of(hints[f.name], defs) for f in fields},
                          "required": [f.name for f in fields if not _omittable(f)],
                          "additionalProperties": False}
        return {"$ref": f"#/$defs/{name}"}
    if isinstance(tp, type) and issubclass(tp, enum.Enum):
        return {"enum": [m.value for m in tp]}
    if tp is bool:
        return {"type": "boolean"}
    if tp is int:
        return {"type": "integer"}
    if tp is float:
        return {"type": "number"}
    if tp is str:
        return {"type": "string"}
    if tp is type(None):
        return {"type": "null"}
    if origin in (list, tuple):
        return {"type": "array", "items": _schema_of(typing.get_args(tp)[0], defs)}
    if origin is dict:
        return {"type": "object", "additionalProperties": _schema_of(typing.get_args(tp)[1], defs)}
    if origin in (Union, types.UnionType):
        return {"anyOf": [_schema_of(a, defs) for a in typing.get_args(tp)]}
    raise RecordError(f"unsupported field type {tp!r}")
