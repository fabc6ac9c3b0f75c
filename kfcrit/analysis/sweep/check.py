"""``kfcrit check`` of a sweep file: the sweep file itself, then every point's system.

:func:`kfcrit.analysis.sweep.points.load_sweep` validates the sweep file (keys, parameters, value
lists, numbers) but leaves a value that a point's model refuses (a negative distance, a packet
longer than the frame allows) to that point's row, so that one bad point does not stop a long
sweep. ``kfcrit check`` promises more: a sweep file it accepts has no bad point. This module
sets each swept value, and then each point's whole assignment, in the base system and runs the
system-file validation on the result (:func:`kfcrit.analysis.spec.spec_from_mapping`, which
builds the system and the channel but analyses nothing).

Errors name the sweep file's own field: ``sweep.grid.<param>[i]`` or
``sweep.points[i].<param>`` with the value, or the point index for a combination whose values
are each valid alone but not together.
"""
from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

from kfcrit.defaults import MAX_STATES_DEFAULT
from kfcrit.errors import InputError, KfcritError
from kfcrit.io.systemfile import read_yaml

if TYPE_CHECKING:
    from kfcrit.analysis.sweep.points import SweepSpec

SWEEP_FILE_KEYS = ("name", "description", "system", "tolerance", "grid", "points", "plot")
"""Top-level keys of a sweep file (the same set as :data:`kfcrit.analysis.sweep.points.SWEEP_KEYS`)."""


def check_sweep_keys(doc: Any) -> None:
    """A sweep file's top-level keys: an unknown one (``grids:``) names the sweep field and the
    keys a sweep file takes, before anything else is read."""
    if not isinstance(doc, dict):
        raise InputError("the sweep file must be a YAML mapping (system:, grid: or points:)",
                         field="file")
    for key in doc:
        if not isinstance(key, str) or key not in SWEEP_FILE_KEYS:
            raise InputError(f"unknown key in a sweep file (allowed: "
                             f"{', '.join(SWEEP_FILE_KEYS)})", field=f"sweep.{str(key)[:60]}")
    if "system" not in doc:
        raise InputError("is required (the base system: a system file path or an inline "
                         "system mapping)", field="sweep.system")
    if ("grid" in doc) == ("points" in doc):
        raise InputError("give exactly one of grid and points", field="sweep.grid")


def _value_fields(doc: dict, parameters: tuple[str, ...],
                  points: tuple[tuple[str, ...], ...]) -> Iterator[tuple[str, str, str]]:
    """Each distinct (parameter, value text) once, with the sweep field that gave it first."""
    seen: set[tuple[str, str]] = set()
    positions: dict[str, dict[str, int]] = {}
    for index, point in enumerate(points):
        for param, text in zip(parameters, point):
            if (param, text) in seen:
                continue
            seen.add((param, text))
            if "points" in doc:
                where = f"sweep.points[{index}].{param}"
            else:
                pos = positions.setdefault(param, {})
                pos.setdefault(text, len(pos))
                where = f"sweep.grid.{param}[{pos[text]}]"
            yield param, text, where


def _refusal(doc: dict, base_dir: Path, max_states: int, *,
             channel_only: bool = False) -> KfcritError | None:
    """The error the system-file validation gives ``doc`` (None when it is valid).

    With ``channel_only`` (every swept parameter is a ``channel.…`` field) only the channel is
    validated: the rest of ``doc`` is the base system, already validated by
    :func:`~kfcrit.analysis.sweep.points.load_sweep`, and building its exact matrices again for each
    point would cost a thousand times more than the channel.
    """
    from kfcrit.analysis.spec import parse_channel, spec_from_mapping

    try:
        if channel_only:
            parse_channel(doc["channel"], "channel", base_dir)
        else:
            spec_from_mapping(doc, base_dir=base_dir, max_states=max_states)
    except KfcritError as exc:
        return exc
    return None


def check_points(spec: SweepSpec, doc: dict, *, max_states: int) -> None:
    """Validate every value, then every point, of a loaded sweep against the system-file rules.

    Parameters
    ----------
    spec : kfcrit.analysis.sweep.points.SweepSpec
        The sweep as :func:`~kfcrit.analysis.sweep.points.load_sweep` returns it.
    doc : dict
        The sweep file's document (to name ``grid`` or ``points`` fields).
    max_states : int
        The state-size cap, as for the sweep itself.

    Raises
    ------
    InputError
        The first refused value, naming ``sweep.grid.<param>[i]`` (or
        ``sweep.points[i].<param>``) and the value; or the first point whose values are each
        valid but refused together, naming the point and its assignment.
    """
    from kfcrit.analysis.sweep.points import apply_point

    channel_only = all(p.startswith("channel.") for p in spec.parameters) \
        and isinstance(spec.base_doc.get("channel"), dict)
    for param, text, where in _value_fields(doc, spec.parameters, spec.points):
        exc = _refusal(apply_point(spec.base_doc, [(param, text)]), spec.base_dir, max_states,
                       channel_only=channel_only)
        if exc is not None:
            raise InputError(f"the value {text[:40]!r} is refused by the base system: {exc}",
                             field=where) from None
    if len(spec.parameters) < 2:
        return  # each point is one value, checked above
    for index in range(len(spec.points)):
        assignment = spec.assignments(index)
        exc = _refusal(apply_point(spec.base_doc, assignment), spec.base_dir, max_states,
                       channel_only=channel_only)
        if exc is not None:
            values = ", ".join(f"{p} = {t[:40]}" for p, t in assignment)
            raise InputError(f"point {index} ({values}) is refused by the base system: {exc}",
                             field="sweep.points" if "points" in doc else "sweep.grid") from None


def check_sweep_file(path: str | Path, *, max_states: int = MAX_STATES_DEFAULT) -> SweepSpec:
    """Validate a sweep file as ``kfcrit check`` does and return its
    :class:`~kfcrit.analysis.sweep.points.SweepSpec` (nothing is analysed or written)."""
    from kfcrit.analysis.sweep.points import load_sweep

    doc, _ = read_yaml(path)
    check_sweep_keys(doc)
    spec = load_sweep(path, max_states=max_states)
    check_points(spec, doc, max_states=max_states)
    return spec
