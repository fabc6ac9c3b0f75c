"""Markdown reference of the file formats, generated from their JSON Schemas (so it cannot
drift from what the readers accept)."""
from __future__ import annotations

from typing import Any


def _resolve(node: dict[str, Any], defs: dict[str, Any]) -> dict[str, Any]:
    while "$ref" in node:
        node = {**defs[node["$ref"].rsplit("/", 1)[1]],
                **{k: v for k, v in node.items() if k != "$ref"}}
    return node


def _type_text(node: dict[str, Any], defs: dict[str, Any]) -> str:
    ref = node.get("$ref", "")
    if ref.endswith("/number"):
        return "number or exact expression"
    if ref.endswith("/integer"):
        return "integer"
    if ref.endswith("/matrix"):
        return "matrix (rows of numbers/expressions) or scalar"
    node = _resolve(node, defs)
    if "const" in node:
        return f"`{node['const']}`"
    if "enum" in node:
        return " \\| ".join(f"`{v}`" for v in node["enum"])
    if "type" in node:
        t = node["type"]
        if t == "array":
            return f"list of {_type_text(node.get('items', {}), defs)}"
        return {"object": "mapping", "string": "text", "integer": "integer",
                "number": "number", "boolean": "true/false"}.get(t, str(t))
    if "anyOf" in node:
        return " or ".join(_type_text(n, defs) for n in node["anyOf"])
    if "oneOf" in node:
        return "mapping: one of the channel models below (by `model`)"
    return "any"


SHALLOW_PREFIXES = ("links.",)
"""Mappings listed one level deep: their keys are the link-budget channel's, whose nested keys
the ``channel`` table of ``model: link-budget`` lists in full."""


def _values_text(node: dict[str, Any], defs: dict[str, Any]) -> str:
    """The forms a sweep grid's values take (list, one value, range mapping)."""
    forms = []
    for alt in node.get("anyOf", []):
        alt = _resolve(alt, defs) if "$ref" in alt and not alt["$ref"].endswith("/number") \
            else alt
        if alt.get("type") == "array":
            forms.append(f"list of {_type_text(alt.get('items', {}), defs)}")
        elif alt.get("type") == "object":
            forms.append("range (mapping)")
        else:
            forms.append(f"one {_type_text(alt, defs)}")
    return ", ".join(forms) or _type_text(node, defs)


def _rows(obj: dict[str, Any], defs: dict[str, Any], prefix: str,
          out: list[tuple[str, str, bool, str]]) -> None:
    obj = _resolve(obj, defs)
    required = set(obj.get("required", []))
    for key, node in (obj.get("properties") or {}).items():
        path = f"{prefix}{key}"
        desc = node.get("description") or _resolve(node, defs).get("description") or ""
        if prefix.startswith(SHALLOW_PREFIXES):
            out.append((path, _type_text(node, defs), key in required,
                        f"as `channel.{key}` of a link-budget channel (below)"))
            continue
        out.append((path, _type_text(node, defs), key in required, desc))
        inner = _resolve(node, defs)
        if inner.get("type") == "object" and inner.get("properties") and "$ref" in node \
                and not node["$ref"].endswith(("/channel",)):
            _rows(inner, defs, f"{path}.", out)
        elif inner.get("type") == "object" and inner.get("properties") and "$ref" not in node:
            _rows(inner, defs, f"{path}.", out)
        elif inner.get("type") == "array" and "$ref" in inner.get("items", {}):
            item = _resolve(inner["items"], defs)
            if item.get("properties"):
                _rows(item, defs, f"{path}[].", out)
        elif any(_resolve(alt, defs).get("properties") for alt in inner.get("anyOf", [])
                 if "$ref" in alt):
            # a name or a mapping (``radio``): the mapping's keys
            for alt in inner["anyOf"]:
                if "$ref" in alt and _resolve(alt, defs).get("properties"):
                    _rows(_resolve(alt, defs), defs, f"{path}.", out)
        elif inner.get("type") == "object" and isinstance(inner.get("additionalProperties"),
                                                          dict):
            values = inner["additionalProperties"]
            out.append((f"{path}.PARAMETER", _values_text(values, defs), False,
                        values.get("description", "")))
            for alt in values.get("anyOf", []):
                if alt.get("type") == "object" and alt.get("properties"):
                    _rows(alt, defs, f"{path}.PARAMETER.", out)


def _table(rows: list[tuple[str, str, bool, str]]) -> list[str]:
    lines = ["| key | value | required | meaning |", "| --- | --- | --- | --- |"]
    for path, kind, req, desc in rows:
        lines.append(f"| `{path}` | {kind} | {'yes' if req else ''} | {desc} |")
    return lines


def reference_markdown(system: dict[str, Any], sweep: dict[str, Any]) -> str:
    """The key reference of system files (with every channel model) and sweep files."""
    defs = system["$defs"]
    out = ["# kfcrit file reference", "",
           "Generated by `kfcrit schema --markdown` from the JSON Schemas that `kfcrit schema "
           "system` and `kfcrit schema sweep` print (a test keeps this file equal to the "
           "generator's output). Numbers are read exactly from their text; strings hold exact "
           "expressions (`\"sqrt(2)/2\"`, `\"2*cos(pi/5)\"`).", "", "## System files", ""]
    rows: list[tuple[str, str, bool, str]] = []
    _rows(system, defs, "", rows)
    out += _table(rows)
    for name, title in (("bernoulli", "bernoulli"), ("gilbert_elliott", "gilbert-elliott"),
                        ("trace", "trace"), ("link_budget", "link-budget")):
        out += ["", f"### `channel` with `model: {title}`", "",
                defs[name].get("description", ""), ""]
        crow: list[tuple[str, str, bool, str]] = []
        _rows(defs[name], defs, "channel.", crow)
        out += _table(crow)
    out += ["", "## Sweep files", ""]
    srows: list[tuple[str, str, bool, str]] = []
    _rows(sweep, sweep["$defs"], "", srows)
    out += _table(srows)
    return "\n".join(out) + "\n"
