"""Parameter sweeps: ``kfcrit sweep sweep.yaml`` over any system or channel parameter.

A sweep file names a base system (a system file, or an inline system mapping) and a grid (the
Cartesian product of value lists) or an explicit list of points::

    name: distance and packet size
    system: link-oqpsk-sensor.yaml          # relative to the sweep file, or an inline mapping
    tolerance: 1e-9                         # optional, for the robust critical value
    grid:                                   # first parameter varies slowest
      channel.distance_m: {start: 20, stop: 200, num: 10}      # inclusive, exact steps
      channel.packet_bytes: [20, 40, 127]
      A[0][0]: {start: 1.1, stop: 1.5, step: 0.1}
      channel.noise.bandwidth_hz: {start: 1e5, stop: 1e7, num: 5, scale: log}
    # points: [{channel.distance_m: 10, channel.tx_power_dbm: 0}, ...]   (instead of grid)
    plot: {x: channel.distance_m}           # optional; default the first parameter

A parameter is ``channel.KEY[.KEY…]`` (any channel field, nested mappings included) or a
matrix entry ``A[i][j]`` (also ``C``, ``Q``, ``R``, ``Sigma0``; an off-diagonal entry of the
symmetric Q, R, Σ0 sets both (i, j) and (j, i)). Values are kept as text and read exactly by the
system-file parser, like any system file; nothing is ever evaluated.

Each point gives one row: the critical value (or the best bound available), the arrival
probability and the margin p − p_req, and for link budgets the SINR, the required SINR, the
link margin in dB and the largest distance. Output folder (created if missing; its parent must
exist): ``sweep.csv``, ``sweep.json``, ``margin.svg``, ``margin.png`` and ``run.json`` (runner,
workers, computed/reused counts: the only file that depends on how the sweep ran), each written
atomically (temporary file, fsync, rename).

Validation before anything is written: the sweep file (parameters, values that must be numbers,
keys the channel model does not know, the size cap of :data:`MAX_POINTS`), the output folder and
the ``--scheduler`` address (connected to first). A swept value a point's model refuses (say a
negative distance) is an error *row* of that point, not of the sweep.

Invariant (resumability): every finished row is appended to ``sweep.journal.jsonl`` and fsynced
before it is counted; a row is keyed by the SHA-256 of (format, kfcrit version, base system,
tolerance, max_states, the point's assignments), and each journal line carries a check binding
it to the sweep file's bytes and to its own result (:func:`journal_check`). After an
interruption only the missing points are computed; a changed sweep file, base system or
tolerance recomputes everything, and a line that is edited, forged, torn or malformed counts as
not computed. The journal is never followed through a symbolic link.
Invariant (reproducibility): a row depends only on its key's inputs — never on the worker,
the chunking or the order of completion — and rows are written sorted by point index, so local
processes, a single process and a Dask cluster give byte-identical tables.
"""
from __future__ import annotations

import copy
import csv
import hashlib
import io
import itertools
import json
import math
import os
import re
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from decimal import Decimal
from fractions import Fraction
from pathlib import Path
from typing import Any

import sympy as sp

from kfcrit.analysis.sweep.journal import (  # noqa: F401 - re-exported for callers
    JOURNAL_NAME,
    MAX_JOURNAL_BYTES,
    MAX_POINTS,
    POINT_ERROR_CODES,
    Journal,
)
from kfcrit.analysis.sweep.rows import (  # noqa: F401 - re-exported for callers
    RESULT_COLUMNS,
    binding_requirement_of,
    loop_columns,
    requirement_of,
    row_of,
)
from kfcrit.analysis.sweep.run import (  # noqa: F401 - re-exported for callers
    ClusterLostError,
    Items,
    PointJob,
    check_scheduler,
    connect_dask,
    run_dask,
    run_processes,
    run_serial,
    terminate_pool,
)
from kfcrit.defaults import MAX_STATES_DEFAULT
from kfcrit.errors import ExitCode, InputError, KfcritError
from kfcrit.io.jsonio import jsonable
from kfcrit.io.safeio import printable
from kfcrit.version import __version__

FORMAT_VERSION = 1
MAX_NUM = 100_000
MAX_SERIES = 12
SWEEP_KEYS = {"name", "description", "system", "tolerance", "grid", "points", "plot"}
MATRICES = ("A", "C", "Q", "R", "Sigma0")
SYMMETRIC = ("Q", "R", "Sigma0")
_MATRIX_PATH = re.compile(r"^(A|C|Q|R|Sigma0)\[(\d{1,6})\]\[(\d{1,6})\]$")
_CHANNEL_PATH = re.compile(r"^channel(\.[A-Za-z_][A-Za-z0-9_]{0,63}){1,6}$")
_SENSOR_PATH = re.compile(r"^sensors\.([A-Za-z][A-Za-z0-9_-]{0,39})\.channel"
                          r"((\.[A-Za-z_][A-Za-z0-9_]{0,63}){1,6})$")
_LINKS_PATH = re.compile(r"^links(\.[A-Za-z_][A-Za-z0-9_]{0,63}){1,6}$")
_LOOP_PATH = re.compile(r"^loop\.channel(\.[A-Za-z_][A-Za-z0-9_]{0,63}){1,6}$")
"""``loop.channel.KEY[.KEY…]``: the actuation link of a closed loop (theory §12)."""
# ---------------------------------------------------------------------------------------------
# The sweep file
# ---------------------------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class SweepSpec:
    """A validated sweep: base system document, parameters and points (value texts)."""

    name: str
    base_doc: dict[str, Any]
    base_dir: Path
    parameters: tuple[str, ...]
    points: tuple[tuple[str, ...], ...]
    tolerance: float
    tolerance_text: str
    plot_x: str
    path: str | None = None
    sha256: str | None = None
    description: str = ""
    base_path: str | None = None
    keys: tuple[str, ...] = field(default=(), repr=False)

    def assignments(self, index: int) -> list[tuple[str, str]]:
        """The (parameter, value text) pairs of point ``index``."""
        return list(zip(self.parameters, self.points[index]))


def _plain(obj: Any) -> Any:
    """YAML number texts (str subclass) → plain str, recursively; other scalars unchanged."""
    if isinstance(obj, str):
        return str(obj)
    if isinstance(obj, dict):
        return {str(k) if isinstance(k, str) else k: _plain(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_plain(v) for v in obj]
    return obj


def _exact_text(value: sp.Rational | Fraction) -> str:
    """Readable exact text of a rational: a finite decimal when there is one, else ``p/q``."""
    frac = value if isinstance(value, Fraction) else Fraction(int(value.p), int(value.q))
    q = frac.denominator
    for prime in (2, 5):
        while q % prime == 0:
            q //= prime
    if q != 1:
        return f"{frac.numerator}/{frac.denominator}"
    text = format(Decimal(frac.numerator) / Decimal(frac.denominator), "f")
    if "." in text:
        text = text.rstrip("0").rstrip(".")
    return text


def _scalar_text(value: Any, where: str) -> str:
    """A value of a list as text (numbers keep their YAML source text)."""
    if isinstance(value, bool) or value is None or isinstance(value, (dict, list)):
        raise InputError("must be a number or a string", field=where)
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, str):
        if not value.strip() or len(value) > 500:
            raise InputError("must be a non-empty string of at most 500 characters", field=where)
        return str(value)
    raise InputError(f"must be a number or a string, got {type(value).__name__}", field=where)


def _exact(value: Any, where: str) -> sp.Expr:
    from kfcrit.link.linkbudget import exact_field_number

    return exact_field_number(_scalar_text(value, where), where)


def _range_values(spec: dict, where: str, *, count_only: bool = False) -> list[str] | int:
    """``{start, stop, num}`` (inclusive linspace), ``{start, stop, step}`` or ``scale: log``.

    With ``count_only`` the range is validated and only its length returned (so that an
    enormous grid is refused before any value is generated). Values are exact: rational
    arithmetic (:class:`fractions.Fraction`) for linear ranges.
    """
    from kfcrit.model.channels import check_keys

    check_keys(spec, {"start", "stop", "num", "step", "scale"}, {"start", "stop"}, where)
    scale = spec.get("scale", "linear")
    if scale not in ("linear", "log"):
        raise InputError("must be linear or log", field=f"{where}.scale")
    if ("num" in spec) == ("step" in spec):
        raise InputError("give exactly one of num and step", field=f"{where}.num")
    start = _exact(spec["start"], f"{where}.start")
    stop = _exact(spec["stop"], f"{where}.stop")
    if not (start.is_Rational and stop.is_Rational):
        raise InputError("range ends must be plain numbers", field=f"{where}.start")
    if "num" in spec:
        num = _exact(spec["num"], f"{where}.num")
        if not num.is_Integer or not 1 <= int(num) <= MAX_NUM:
            raise InputError(f"must be an integer from 1 to {MAX_NUM}", field=f"{where}.num")
        n = int(num)
        if count_only:
            return n
        if scale == "log":
            if start <= 0 or stop <= 0:
                raise InputError("a log scale needs positive start and stop",
                                 field=f"{where}.start")
            lo, hi = math.log10(float(start)), math.log10(float(stop))
            return [repr(10 ** (lo + (hi - lo) * k / (n - 1))) if 0 < k < n - 1 else
                    _exact_text(start if k == 0 else stop) for k in range(n)] if n > 1 \
                else [_exact_text(start)]
        if n == 1:
            return [_exact_text(start)]
        a, b = Fraction(int(start.p), int(start.q)), Fraction(int(stop.p), int(stop.q))
        return [_exact_text(a + (b - a) * Fraction(k, n - 1)) for k in range(n)]
    if scale == "log":
        raise InputError("a log scale needs num, not step", field=f"{where}.scale")
    step = _exact(spec["step"], f"{where}.step")
    if not step.is_Rational or step == 0 or (stop - start) / step < 0:
        raise InputError("must be a non-zero number leading from start to stop",
                         field=f"{where}.step")
    count = int(sp.floor((stop - start) / step)) + 1
    if count > MAX_NUM:
        raise InputError(f"gives more than {MAX_NUM} values", field=f"{where}.step")
    if count_only:
        return count
    a, h = Fraction(int(start.p), int(start.q)), Fraction(int(step.p), int(step.q))
    return [_exact_text(a + k * h) for k in range(count)]


def _values(spec: Any, where: str) -> list[str]:
    if isinstance(spec, list):
        if not spec:
            raise InputError("must not be empty", field=where)
        if len(spec) > MAX_NUM:
            raise InputError(f"has more than {MAX_NUM} values", field=where)
        return [_scalar_text(v, f"{where}[{i}]") for i, v in enumerate(spec)]
    if isinstance(spec, dict):
        return _range_values(spec, where)
    return [_scalar_text(spec, where)]


def _mapping_root(doc: dict, path: str) -> tuple[Any, list[str], str]:
    """The mapping a channel-like path starts from, its keys, and what to call it.

    ``channel.K…`` → the channel; ``sensors.NAME.channel.K…`` → that sensor's channel (created
    empty when the sensor takes its link from ``links:`` alone); ``links.K…`` → the link
    defaults of a network file.
    """
    m = _SENSOR_PATH.match(path)
    if m:
        sensor = next((s for s in doc.get("sensors") or []
                       if isinstance(s, dict) and str(s.get("name")) == m.group(1)), None)
        if sensor is None:
            return None, [], f"sensor {m.group(1)!r}"
        if sensor.get("channel") is None:
            sensor["channel"] = {}
        return sensor["channel"], m.group(2).split(".")[1:], f"the channel of {m.group(1)!r}"
    head, *keys = path.split(".")
    return doc.get(head), keys, f"the base {head}"


def check_parameter(path: Any, base_doc: dict, where: str) -> str:
    """Validate a parameter path against the base system document."""
    if not isinstance(path, str):
        raise InputError("parameter names must be strings", field=where)
    m = _MATRIX_PATH.match(path)
    if m:
        name, i, j = m.group(1), int(m.group(2)), int(m.group(3))
        rows = base_doc.get(name)
        if rows is None and name == "Sigma0":
            raise InputError("the base system has no Sigma0 to change", field=where)
        if not isinstance(rows, list) or not all(isinstance(r, list) for r in rows):
            raise InputError(f"{name} in the base system must be a list of rows to sweep "
                             "an entry", field=where)
        if i >= len(rows) or j >= len(rows[i]):
            raise InputError(f"index out of range ({name} is {len(rows)}x{len(rows[0])})",
                             field=where)
        return path
    if _LOOP_PATH.match(path) and not isinstance(base_doc.get("loop"), dict):
        raise InputError("the base system has no loop: mapping", field=where)
    if (_CHANNEL_PATH.match(path) or _SENSOR_PATH.match(path) or _LINKS_PATH.match(path)
            or _LOOP_PATH.match(path)):
        node, keys, what = _mapping_root(copy.deepcopy(base_doc), path)
        if not isinstance(node, dict):
            # the fault is in the base system, not in the grid that refers to it
            raise InputError(f"the base system has no {what.replace('the base ', '')} mapping "
                             f"(needed by {where})", field="system." + path.split(".")[0])
        for key in keys[:-1]:
            node = node.get(key)
            if not isinstance(node, dict):
                raise InputError(f"{what} has no mapping {key!r}", field=where)
        return path
    raise InputError("unknown parameter: use channel.KEY[.KEY...], sensors.NAME.channel.KEY"
                     "[.KEY...], links.KEY[.KEY...], loop.channel.KEY[.KEY...] or a matrix "
                     "entry like A[0][1]",
                     field=where)


_IMMUTABLE = (str, int, float, bool, type(None))


def copy_doc(obj: Any) -> Any:
    """A deep copy of a system document: mappings and lists copied, plain scalars shared (they
    are immutable), anything else by :func:`copy.deepcopy` (several times faster than
    ``deepcopy`` of the whole document, which keeps a memo of every node)."""
    if isinstance(obj, dict):
        return {k: copy_doc(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [copy_doc(v) for v in obj]
    if isinstance(obj, _IMMUTABLE):
        return obj
    return copy.deepcopy(obj)


def apply_point(base_doc: dict, assignments: Iterable[tuple[str, str]]) -> dict:
    """A copy of the base document with the point's values set (as text)."""
    doc = copy_doc(base_doc)
    for path, text in assignments:
        m = _MATRIX_PATH.match(path)
        if m:
            name, i, j = m.group(1), int(m.group(2)), int(m.group(3))
            doc[name][i][j] = text
            if name in SYMMETRIC and i != j and j < len(doc[name]) and i < len(doc[name][j]):
                doc[name][j][i] = text
            continue
        node, keys, _ = _mapping_root(doc, path)
        for key in keys[:-1]:
            node = node[key]
        node[keys[-1]] = text
    return doc


def point_key(spec_base: dict, tolerance_text: str, max_states: int,
              assignments: Iterable[tuple[str, str]]) -> str:
    """SHA-256 key of one point's inputs (see the resumability invariant)."""
    blob = json.dumps({"format": FORMAT_VERSION, "kfcrit": __version__, "system": spec_base,
                       "tolerance": tolerance_text, "max_states": max_states,
                       "point": [list(a) for a in assignments]},
                      sort_keys=True, ensure_ascii=True, separators=(",", ":"))
    return hashlib.sha256(blob.encode()).hexdigest()


def _load_base(system: Any, sweep_dir: Path) -> tuple[dict, Path, str | None]:
    from kfcrit.io.systemfile import read_yaml

    if isinstance(system, dict):
        return _plain(system), sweep_dir, None
    if isinstance(system, str) and system.strip():
        path = Path(system)
        if not path.is_absolute():
            path = sweep_dir / path
        try:
            doc, _ = read_yaml(path)
        except InputError as exc:
            raise InputError(f"base system file: {exc}", field="system") from None
        if not isinstance(doc, dict):
            raise InputError("the base system file must be a YAML mapping", field="system")
        return _plain(doc), path.resolve().parent, str(path)
    raise InputError("must be a system file path or an inline system mapping", field="system")


def load_sweep(path: str | Path, *, max_states: int = MAX_STATES_DEFAULT) -> SweepSpec:
    """Read and validate a sweep file (every error is one line naming the field)."""
    from kfcrit.io.systemfile import read_yaml
    from kfcrit.model.channels import check_keys

    doc, digest = read_yaml(path)
    if not isinstance(doc, dict):
        raise InputError("the sweep file must be a YAML mapping (system:, grid: or points:)",
                         field="file")
    check_keys(doc, SWEEP_KEYS, {"system"}, "sweep")
    if ("grid" in doc) == ("points" in doc):
        raise InputError("give exactly one of grid and points", field="sweep.grid")
    sweep_dir = Path(path).resolve().parent
    base_doc, base_dir, base_path = _load_base(doc["system"], sweep_dir)
    _validate_base(base_doc, base_dir, max_states)
    tol_text = _scalar_text(doc.get("tolerance", "1e-9"), "sweep.tolerance")
    tol = _exact(tol_text, "sweep.tolerance")
    if not (0 <= tol <= sp.Rational(1, 10)):
        raise InputError("must be in [0, 0.1]", field="sweep.tolerance")
    if "grid" in doc:
        parameters, points = _grid(doc["grid"], base_doc)
        where = [f"sweep.grid.{p}" for p in parameters]
    else:
        parameters, points = _points(doc["points"], base_doc)
        where = [f"sweep.points[0].{p}" for p in parameters]
    if not parameters:
        raise InputError("needs at least one parameter", field="sweep.grid")
    _check_values(doc, parameters, points, base_doc)
    _check_unknown_keys(parameters, points[0], where, base_doc, base_dir)
    cache: dict[str, bool] = {}
    plot_x = next((p for col, p in enumerate(parameters)  # default: the first numeric one
                   if all(_is_number_text(pt[col], cache) for pt in points)), parameters[0])
    if doc.get("plot") is not None:
        plot = doc["plot"]
        if not isinstance(plot, dict):
            raise InputError("must be a mapping like {x: channel.distance_m}", field="sweep.plot")
        check_keys(plot, {"x"}, set(), "sweep.plot")
        if "x" in plot:
            if plot["x"] not in parameters:
                raise InputError("must be one of the swept parameters", field="sweep.plot.x")
            plot_x = str(plot["x"])
    name = doc.get("name") or Path(path).stem
    description = doc.get("description") or ""
    for key, value in (("name", name), ("description", description)):
        if not isinstance(value, str):
            raise InputError("must be a string", field=f"sweep.{key}")
    keys = tuple(point_key(base_doc, tol_text, max_states, zip(parameters, pt))
                 for pt in points)
    return SweepSpec(name=name[:200], base_doc=base_doc, base_dir=base_dir,
                     parameters=tuple(parameters), points=tuple(points),
                     tolerance=float(tol), tolerance_text=tol_text, plot_x=plot_x,
                     path=str(path), sha256=digest, description=description[:2000],
                     base_path=base_path, keys=keys)


def _base_value(base_doc: dict, path: str) -> Any:
    """The base document's value at a parameter path (None when absent)."""
    m = _MATRIX_PATH.match(path)
    if m:
        return None
    node, keys, _ = _mapping_root(copy.deepcopy(base_doc), path)
    for key in keys:
        if not isinstance(node, dict):
            return None
        node = node.get(key)
    return node


def _is_number_text(text: str, cache: dict[str, bool]) -> bool:
    from kfcrit.link.fields import parsed_text

    if text not in cache:
        try:
            cache[text] = bool(parsed_text(text).is_number)
        except KfcritError:
            cache[text] = False
    return cache[text]


def _check_values(doc: dict, parameters: list[str], points: list[tuple[str, ...]],
                  base_doc: dict) -> None:
    """Every swept value must be a number, except for a field whose base value is a word.

    A channel field such as ``radio`` or ``path_loss.shadowing`` holds a name in the base system
    (``bpsk``, ``per-link``): sweeping names there is allowed, and a wrong name is an error of
    that point. Anywhere else a value that is not a number is an error of the sweep file.
    """
    cache: dict[str, bool] = {}
    for col, path in enumerate(parameters):
        base = _base_value(base_doc, path)
        if isinstance(base, str) and not _is_number_text(base, cache):
            continue
        seen: set[str] = set()
        for index, point in enumerate(points):
            text = point[col]
            if text in seen:
                continue
            seen.add(text)
            if not _is_number_text(text, cache):
                where = (f"sweep.points[{index}].{path}" if "points" in doc else
                         f"sweep.grid.{path}[{_grid_position(doc['grid'][path], text)}]")
                raise InputError(f"must be a number, got {text[:40]!r}", field=where)


def _grid_position(spec: Any, text: str) -> int:
    """Position of ``text`` in a grid's value list (0 for a single value)."""
    if isinstance(spec, list):
        for i, v in enumerate(spec):
            if isinstance(v, str) and str(v) == text:
                return i
    return 0


def _check_unknown_keys(parameters: list[str], first: tuple[str, ...], where: list[str],
                        base_doc: dict, base_dir: Path) -> None:
    """A channel parameter absent from the base system must be a key its model accepts.

    Each such parameter is set alone (to its first value) in the base system; if the channel
    model then refuses the key itself (``unknown key``), the sweep file names an unknown
    parameter. Other errors (a value out of range) stay errors of the points that have them.
    """
    from kfcrit.analysis.spec import parse_channel, spec_from_mapping

    for path, text, where_ in zip(parameters, first, where):
        if _MATRIX_PATH.match(path) or _base_value(base_doc, path) is not None:
            continue
        doc = apply_point(base_doc, [(path, text)])
        try:
            if _CHANNEL_PATH.match(path):
                parse_channel(doc["channel"], "channel", base_dir)
            else:
                spec_from_mapping(doc, base_dir=base_dir)
        except InputError as exc:
            if "unknown key" in str(exc) and (exc.field == path or (exc.field or "").endswith(
                    "." + path.rsplit(".", 1)[-1])):
                raise InputError(f"unknown parameter: {str(exc)[len(path) + 2:]}",
                                 field=where_) from None


def _validate_base(base_doc: dict, base_dir: Path, max_states: int) -> None:
    from kfcrit.analysis.spec import spec_from_mapping

    try:
        spec_from_mapping(base_doc, base_dir=base_dir, max_states=max_states)
    except KfcritError as exc:
        raise InputError(f"base system: {exc}", field="system") from None


def _grid(grid: Any, base_doc: dict) -> tuple[list[str], list[tuple[str, ...]]]:
    if not isinstance(grid, dict) or not grid:
        raise InputError("must be a non-empty mapping of parameter: values", field="sweep.grid")
    params = []
    total = 1
    for path, spec in grid.items():  # first validate and count: refuse before generating
        where = f"sweep.grid.{path}"
        params.append(check_parameter(path, base_doc, where))
        total *= (_range_values(spec, where, count_only=True) if isinstance(spec, dict)
                  else len(_values(spec, where)))
        if total > MAX_POINTS:
            raise InputError(f"the grid has more than {MAX_POINTS} points", field="sweep.grid")
    lists = [_values(spec, f"sweep.grid.{path}") for path, spec in grid.items()]
    return params, [tuple(p) for p in itertools.product(*lists)]


def _points(points: Any, base_doc: dict) -> tuple[list[str], list[tuple[str, ...]]]:
    if not isinstance(points, list) or not points:
        raise InputError("must be a non-empty list of mappings", field="sweep.points")
    if len(points) > MAX_POINTS:
        raise InputError(f"has more than {MAX_POINTS} points", field="sweep.points")
    first = points[0]
    if not isinstance(first, dict) or not first:
        raise InputError("must be a non-empty mapping", field="sweep.points[0]")
    params = [check_parameter(p, base_doc, f"sweep.points[0].{p}") for p in first]
    out = []
    for i, pt in enumerate(points):
        if not isinstance(pt, dict) or set(pt) != set(first):
            raise InputError(f"every point must set the same parameters ({', '.join(params)})",
                             field=f"sweep.points[{i}]")
        out.append(tuple(_scalar_text(pt[p], f"sweep.points[{i}].{p}") for p in params))
    return params, out


# ---------------------------------------------------------------------------------------------
# One point
# ---------------------------------------------------------------------------------------------


def point_options(tolerance: float) -> Any:
    """The analysis options of a sweep point: those of ``kfcrit analyze`` (same tolerances,
    seed and simulation size), computing only what the verdict and the review need."""
    from kfcrit.analysis.record import AnalysisOptions

    return AnalysisOptions(tolerance=tolerance, details=False)


def point_spec(doc: dict, base_dir: Path, max_states: int, memo: dict[str, Any],
               key: str | None = None) -> Any:
    """The spec of one point's document, re-using the parsed system of an earlier point.

    A single-system document whose parts other than ``channel`` equal those of a document
    parsed before (same JSON text) differs from it only in the channel: the earlier spec
    (validated in full) gets this point's channel, parsed by the same parser as
    :func:`kfcrit.analysis.spec.spec_from_mapping`. Anything else is parsed in full. The
    result never depends on ``memo`` (the reproducibility invariant). ``key`` is the memo key
    of ``doc`` (:func:`system_keys`) when the caller has it.
    """
    from dataclasses import replace

    from kfcrit.analysis.spec import parse_channel, spec_from_mapping
    from kfcrit.io.systemfile import plain_data as plain_yaml

    if "sensors" in doc or doc.get("channel") is None:
        return spec_from_mapping(doc, base_dir=base_dir, max_states=max_states)
    if key is None:
        key = system_keys(doc, max_states, 0.0, None)[0]
    base = memo.get(key)
    if base is None:
        spec = spec_from_mapping(doc, base_dir=base_dir, max_states=max_states)
        memo[key] = spec
        return spec
    return replace(base, channel=parse_channel(plain_yaml(doc["channel"]), "channel", base_dir))


def system_keys(doc: dict, max_states: int, tolerance: float,
                upper_tol: float | None) -> tuple[str, str, str]:
    """The memo keys of a point's document: its parsed system (everything but the channel),
    its channel-independent theory (matrices, channel model, tolerance) and its p_up (A, C)."""
    pkey = "spec:" + json.dumps([{k: v for k, v in doc.items() if k != "channel"}, max_states],
                                sort_keys=True, default=str)
    skey = json.dumps([{k: doc.get(k) for k in MATRICES}, max_states, tolerance,
                       (doc.get("channel") or {}).get("model")],
                      sort_keys=True, default=str)
    ukey = json.dumps(["upper", doc.get("A"), doc.get("C"), upper_tol],
                      sort_keys=True, default=str)
    return pkey, skey, ukey


def channel_only(assignments: Iterable[tuple[str, str]]) -> bool:
    """Whether a point changes only channel fields other than ``channel.model`` (its keys of
    :func:`system_keys` are then those of the base document)."""
    return all(path.startswith("channel.") and path != "channel.model"
               for path, _ in assignments)


POINT_FAULTS = (KfcritError, ValueError, ArithmeticError)
"""What a point may raise: an error row of that point (anything else stops the sweep)."""


@dataclass(frozen=True)
class ParsedPoint:
    """A point's parsed system and its memo keys (:func:`parse_point`)."""

    spec: Any
    options: Any
    keys: tuple[str, str, str]


def parse_point(base_doc: dict, base_dir: str, tolerance: float, max_states: int,
                assignments: list[tuple[str, str]], theories: dict[str, Any],
                base_keys: tuple[str, str, str] | None = None) -> ParsedPoint:
    """The point's system (memoised by :func:`point_spec`), options and memo keys; raises
    what the point's document makes the parser raise."""
    doc = apply_point(base_doc, assignments)
    opts = point_options(tolerance)
    keys = (base_keys if base_keys is not None and channel_only(assignments)
            else system_keys(doc, max_states, tolerance, opts.upper_tol))
    return ParsedPoint(point_spec(doc, Path(base_dir), max_states, theories, keys[0]), opts,
                       keys)


def evaluate_point(base_doc: dict, base_dir: str, tolerance: float, max_states: int,
                   assignments: list[tuple[str, str]],
                   theories: dict[str, Any] | None = None,
                   base_keys: tuple[str, str, str] | None = None,
                   parsed: ParsedPoint | Exception | None = None) -> dict[str, Any]:
    """The result columns of one point (``status`` ``error`` with a one-line message on error).

    The point is analysed by :func:`kfcrit.analysis.record.analyze_system` with
    :func:`point_options`, so its verdict and review decision are those of ``kfcrit analyze``
    on the same file. ``theories`` memoises the channel-independent sections per system within
    one chunk of work (passed in, never module state); ``base_keys`` are the
    :func:`system_keys` of ``base_doc`` (read for points that change only channel fields).
    ``parsed`` is the point's :func:`parse_point` (or what it raised) when the caller parsed
    it already.
    """
    from kfcrit.analysis.record import analysis_data, theory_sections

    row: dict[str, Any] = dict.fromkeys(RESULT_COLUMNS)
    theories = {} if theories is None else theories
    try:
        if isinstance(parsed, Exception):
            raise parsed
        if parsed is None:
            parsed = parse_point(base_doc, base_dir, tolerance, max_states, assignments,
                                 theories, base_keys)
        spec, opts, (_, skey, ukey) = parsed.spec, parsed.options, parsed.keys
        if skey not in theories:
            theory = theory_sections(spec.system, opts, channel=spec.channel,
                                     upper_bound=theories.get(ukey))
            theories[skey] = theory
            theories.setdefault(ukey, theory.sections["upper_bound"])
        record, _ = analysis_data(spec, opts, theory=theories[skey], lean=True)
        row.update(row_of(record))
    except KfcritError as exc:
        row.update(status="error", error=printable(str(exc))[:300],
                   error_code=int(exc.exit_code))
    except (ValueError, ArithmeticError) as exc:
        row.update(status="error", error=f"{type(exc).__name__}: {printable(str(exc))[:250]}",
                   error_code=int(ExitCode.INCONCLUSIVE))
    return jsonable(row)


def evaluate_chunk(base_doc: dict, base_dir: str, tolerance: float, max_states: int,
                   items: list[tuple[int, str, list[tuple[str, str]]]],
                   theories: dict[str, Any] | None = None
                   ) -> list[tuple[int, str, dict[str, Any]]]:
    """Evaluate a chunk of points (the unit of work sent to a process or a Dask worker).

    ``theories`` memoises the channel-independent sections per system across the chunks one
    caller evaluates (a serial run passes one dict for the whole run; a worker gets a fresh one
    per chunk); results never depend on it. The chunk's points are parsed first and their
    links' arrival values computed together (:func:`kfcrit.link.linkbudget.warm_links`, the
    same bits as one by one), then each point is evaluated.
    """
    from kfcrit.link.linkbudget import warm_links

    theories = {} if theories is None else theories
    try:
        base_keys: tuple[str, str, str] | None = system_keys(
            base_doc, max_states, tolerance, point_options(tolerance).upper_tol)
    except (TypeError, ValueError):  # a malformed document: each point reports its own error
        base_keys = None
    parsed: list[ParsedPoint | Exception] = []
    for _, _, assignments in items:
        try:
            parsed.append(parse_point(base_doc, base_dir, tolerance, max_states, assignments,
                                      theories, base_keys))
        except POINT_FAULTS as exc:
            parsed.append(exc)
    warm_links(p.spec.channel for p in parsed if isinstance(p, ParsedPoint))
    return [(index, key, evaluate_point(base_doc, base_dir, tolerance, max_states, assignments,
                                        theories, base_keys, parsed=pre))
            for (index, key, assignments), pre in zip(items, parsed)]


# ---------------------------------------------------------------------------------------------
# Outputs
# ---------------------------------------------------------------------------------------------

def _param_value(text: str) -> Any:
    """A parameter's value for the table: an int for an integer (``packet_bytes: 20`` stays
    20), a float for any other number, else the text (texts parsed once per process:
    :func:`kfcrit.link.fields.parsed_text`, as when the sweep file was read)."""
    from kfcrit.link.fields import parsed_text

    try:
        value = parsed_text(text)
        if value.is_Integer:
            return int(value)
        return float(sp.N(value, 17))
    except (KfcritError, TypeError, ValueError):
        return text


def assemble_rows(spec: SweepSpec, results: dict[str, dict[str, Any]]) -> list[dict[str, Any]]:
    """The table: one row per point, sorted by index, fixed columns."""
    cache: dict[str, Any] = {}
    rows = []
    for index, (pt, key) in enumerate(zip(spec.points, spec.keys)):
        row: dict[str, Any] = {"index": index, "key": key[:16]}
        for param, text in zip(spec.parameters, pt):
            if text not in cache:
                cache[text] = _param_value(text)
            row[param] = cache[text]
        res = results[key]
        row.update({c: res.get(c) for c in RESULT_COLUMNS})
        rows.append(row)
    return rows


def table_csv(spec: SweepSpec, rows: list[dict[str, Any]]) -> str:
    """CSV text: header, then one line per point (floats in repr, None as empty)."""
    columns = ["index", "key", *spec.parameters, *RESULT_COLUMNS]
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(columns)
    for row in rows:
        writer.writerow(["" if row[c] is None else (repr(row[c]) if isinstance(row[c], float)
                                                    else csv_cell(row[c])) for c in columns])
    return buf.getvalue()


FORMULA_PREFIXES = ("=", "+", "-", "@", "\t", "\r")
"""First characters that make a spreadsheet read a cell as a formula (OWASP CSV injection)."""


def csv_cell(value: Any) -> Any:
    """A text cell made inert for spreadsheets: one starting with = + - @ tab or CR gets a
    leading single quote (OWASP CSV injection rule); numbers are left as they are."""
    if isinstance(value, str) and value.startswith(FORMULA_PREFIXES):
        return "'" + value
    return value


# ---------------------------------------------------------------------------------------------
# Driver
# ---------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class SweepResult:
    """What a sweep run did: the table, and how many points it computed or reused."""

    rows: list[dict[str, Any]]
    computed: int
    reused: int
    errors: int
    exit_code: int
    output: str
    files: dict[str, str]
    runner: str = "local"
    workers: int = 1

    def to_dict(self) -> dict[str, Any]:
        return {"computed": self.computed, "reused": self.reused, "errors": self.errors,
                "exit_code": self.exit_code, "output": self.output, "files": self.files,
                "points": len(self.rows)}


def run_sweep(spec: SweepSpec, output: str | Path, *, scheduler: str | None = None,
              workers: int | None = None, max_states: int = MAX_STATES_DEFAULT,
              progress: Callable[[int, int], tuple[Callable[[int], None], Callable[[], None]]]
              | None = None, journal: bool = True) -> SweepResult:
    """Run (or resume) a sweep, journalling each finished point in the folder ``output``.

    Returns the table (rows sorted by point index); the files are written by
    :func:`kfcrit.api.sweepfiles.write_outputs` (or by the caller). ``progress(total, done)`` may
    return an ``(advance, stop)`` pair of callbacks. ``workers`` must be a whole number ≥ 1
    (or None: one per core). With ``journal`` False nothing is written: the output folder is
    neither created nor read, and every point is computed.
    """
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int)
                                or workers < 1):
        raise InputError(f"must be a whole number ≥ 1, got {workers!r}", field="workers")
    if not journal:
        return _run_unjournalled(spec, scheduler=scheduler, workers=workers,
                                 max_states=max_states)
    out = Path(output)
    if out.exists() and not out.is_dir():
        raise InputError(f"{str(out)[:80]!r} exists and is not a folder", field="--output")
    if not out.exists() and not out.resolve().parent.is_dir():
        raise InputError(f"the folder {str(out.resolve().parent)[:80]!r} that should hold the "
                         "output folder does not exist", field="--output")
    client = connect_dask(scheduler) if scheduler else None
    try:
        out.mkdir(exist_ok=True)
        if not os.access(out, os.W_OK | os.X_OK):
            raise PermissionError
    except OSError:
        if client is not None:
            client.close()
        raise InputError(f"cannot create or write the output folder {str(out)[:80]!r}",
                         field="--output") from None
    journal = Journal(out / JOURNAL_NAME, spec.sha256 or "", RESULT_COLUMNS)
    try:
        known = journal.load()
    except BaseException:
        if client is not None:
            client.close()
        raise
    pending: Items = []
    seen: set[str] = set()
    for index, key in enumerate(spec.keys):
        if key not in known and key not in seen:
            seen.add(key)
            pending.append((index, key, spec.assignments(index)))
    reused = len(spec.keys) - len(pending)
    workers = workers or os.cpu_count() or 1
    job = PointJob(evaluate=evaluate_chunk, base_doc=spec.base_doc, base_dir=str(spec.base_dir),
                   tolerance=spec.tolerance, max_states=max_states)
    if client is not None:
        batches = run_dask(job, pending, client, scheduler or "")
    elif workers == 1 or len(pending) <= 8:
        batches = run_serial(job, pending)
    else:
        batches = run_processes(job, pending, workers)
    try:
        # after the runner started its pool (forked workers must not inherit the bar's thread)
        advance, stop = progress(len(spec.keys), reused) if progress else (lambda n: None,
                                                                           lambda: None)
        try:
            for batch in batches:
                journal.append([(key, res) for _, key, res in batch])
                for _, key, res in batch:
                    known[key] = res
                advance(len(batch))
        finally:
            stop()
    finally:
        batches.close()  # release workers / the Dask client at once, also on an interrupt
    rows = assemble_rows(spec, known)
    errors = [r for r in rows if r["status"] != "ok"]
    # a point's code is one of _POINT_ERROR_CODES (valid_result refuses any other in the
    # journal): no journal line can make a finished sweep exit 130 or 141
    codes = [known[k]["error_code"] if known[k].get("error_code") in POINT_ERROR_CODES
             else int(ExitCode.BAD_INPUT) for k in spec.keys if known[k].get("status") != "ok"]
    exit_code = max(codes) if codes else int(ExitCode.OK)
    return SweepResult(rows=rows, computed=len(pending), reused=reused, errors=len(errors),
                       exit_code=exit_code, output=str(out), files={},
                       runner="dask" if scheduler else "local", workers=workers)


def _run_unjournalled(spec: SweepSpec, *, scheduler: str | None, workers: int | None,
                      max_states: int) -> SweepResult:
    """Every point computed in memory, nothing written (``run_sweep(..., journal=False)``)."""
    client = connect_dask(scheduler) if scheduler else None
    pending: Items = []
    seen: set[str] = set()
    for index, key in enumerate(spec.keys):
        if key not in seen:
            seen.add(key)
            pending.append((index, key, spec.assignments(index)))
    workers = workers or os.cpu_count() or 1
    job = PointJob(evaluate=evaluate_chunk, base_doc=spec.base_doc, base_dir=str(spec.base_dir),
                   tolerance=spec.tolerance, max_states=max_states)
    if client is not None:
        batches = run_dask(job, pending, client, scheduler or "")
    elif workers == 1 or len(pending) <= 8:
        batches = run_serial(job, pending)
    else:
        batches = run_processes(job, pending, workers)
    known: dict[str, dict[str, Any]] = {}
    try:
        for batch in batches:
            for _, key, res in batch:
                known[key] = res
    finally:
        batches.close()
    rows = assemble_rows(spec, known)
    errors = [r for r in rows if r["status"] != "ok"]
    codes = [known[k]["error_code"] if known[k].get("error_code") in POINT_ERROR_CODES
             else int(ExitCode.BAD_INPUT) for k in spec.keys if known[k].get("status") != "ok"]
    return SweepResult(rows=rows, computed=len(pending), reused=0, errors=len(errors),
                       exit_code=max(codes) if codes else int(ExitCode.OK), output="",
                       files={}, runner="dask" if scheduler else "local", workers=workers)
