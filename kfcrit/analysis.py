"""The analysis record: one immutable record that every view renders.

``analyze(spec)`` asks each concern for its section — the critical value (``critical``), the upper
bound and covariance bounds (``upper``, ``bounds``), the simulation (``simulate``) and the link
budget (``linkbudget``) — and assembles them with the operating point and the verdict. The
terminal summary, ``--json``, the HTML and the PDF are all views of ``Analysis.to_dict()``; no
view computes anything.

Contract (keys always present, ``null`` where not computed)::

    name, classification, critical_value {value, exact, expression, latex, reason},
    robust_critical_value {value, tolerance} | null, lower_bound {value, expression},
    block_lower_bound {value, expression}, upper_bound {value, interval, certified},
    operating_point {...} | null, warnings [...]

followed by the detail sections ``system``, ``structure``, ``theory``, ``covariance_bounds``,
``phase_transition``, ``simulation``, ``link_budget``, ``requirements`` and ``provenance``.
"""
from __future__ import annotations

import platform
from dataclasses import dataclass, field
from typing import Any

from . import __version__
from .record import jsonable
from .system import System
from .systemfile import SystemSpec

CONTRACT_KEYS = ("name", "classification", "critical_value", "robust_critical_value",
                 "lower_bound", "block_lower_bound", "upper_bound", "operating_point",
                 "warnings")
DETAIL_KEYS = ("description", "system", "structure", "theory", "covariance_bounds",
               "phase_transition", "simulation", "link_budget", "requirements", "provenance")


@dataclass(frozen=True)
class AnalysisOptions:
    """Options of one analysis (stored, not acted on, by the constructor)."""

    tolerance: float = 1e-9
    upper_tol: float = 1e-9
    simulate: bool = True
    quick: bool = False
    seed: int = 0
    paths: int | None = None
    steps: int | None = None


@dataclass(frozen=True)
class Analysis:
    """The analysis record. Build with :func:`analyze`; read with :meth:`to_dict`."""

    sections: dict[str, Any] = field(repr=False)

    def __getitem__(self, key: str) -> Any:
        return self.sections[key]

    def to_dict(self) -> dict[str, Any]:
        """The record as plain JSON types, contract keys first."""
        out = {k: self.sections.get(k) for k in CONTRACT_KEYS}
        out.update({k: self.sections.get(k) for k in DETAIL_KEYS})
        return jsonable(out)


def _as_spec(system: System | SystemSpec) -> SystemSpec:
    return system if isinstance(system, SystemSpec) else SystemSpec(system=system)


def system_section(spec: SystemSpec) -> dict[str, Any]:
    """Sizes, exactness and exact matrices of the system."""
    s = spec.system
    return {"n": s.n, "m": s.m, "exact_input": s.exact, "matrices": s.matrices_text(),
            "channel": spec.channel.to_dict() if spec.channel is not None else None}


def operating_point(spec: SystemSpec, sections: dict[str, Any]) -> dict[str, Any] | None:
    """Arrival probability of the configured channel against p_c, the robust value and bracket.

    Verdict: ``mean-stable`` when p exceeds every value that could be the critical value
    (p_c, or the upper end of the bracket when p_c is unknown, and the robust value),
    ``mean-unstable`` when p is at or below the critical value (or the lower end of the
    bracket), ``undetermined`` inside the bracket.
    """
    if spec.channel is None:
        return None
    p = float(spec.channel.arrival_probability)
    cv = sections.get("critical_value") or {}
    robust = sections.get("robust_critical_value") or {}
    low = (sections.get("block_lower_bound") or {}).get("value")
    if low is None:
        low = (sections.get("lower_bound") or {}).get("value")
    up = (sections.get("upper_bound") or {}).get("value")
    pc = cv.get("value")
    out: dict[str, Any] = {"arrival_probability": p, "channel": spec.channel.to_dict(),
                           "iid": spec.channel.iid}
    if pc is not None:
        out["margin"] = p - pc
        worst = max(pc, robust.get("value") if robust.get("value") is not None else pc)
        out["margin_robust"] = p - worst
        if p > worst:
            verdict = "mean-stable"
        elif p <= pc:
            verdict = "mean-unstable"
        else:
            verdict = "undetermined"
        out["bracket"] = None
    else:
        out["margin"] = None
        out["margin_robust"] = None
        lo = low if low is not None else 0.0
        out["bracket"] = [lo, up]
        out["margin_to_bracket"] = [p - lo, (p - up) if up is not None else None]
        if up is not None and p > up:
            verdict = "mean-stable"
        elif p <= lo:
            verdict = "mean-unstable"
        else:
            verdict = "undetermined"
    if not spec.channel.iid:
        out["note"] = ("the mean-stability theorems assume i.i.d. losses; for a bursty channel "
                       "the verdict compares the stationary arrival probability and is indicative "
                       "only (see link_budget / theory for the Gilbert-Elliott condition)")
    out["verdict"] = verdict
    return out


def analyze(system: System | SystemSpec, options: AnalysisOptions | None = None,
            **kwargs: Any) -> Analysis:
    """Analyse a system (or a loaded system file) and return the :class:`Analysis` record.

    Parameters
    ----------
    system : System or SystemSpec
        The system, or a loaded system file (which adds channel and requirements).
    options : AnalysisOptions, optional
        Tolerances, simulation size and seed; keyword arguments override its fields.
    """
    from . import critical

    opts = options or AnalysisOptions()
    if kwargs:
        opts = AnalysisOptions(**{**opts.__dict__, **kwargs})
    spec = _as_spec(system)
    s = spec.system
    sections: dict[str, Any] = {k: None for k in CONTRACT_KEYS + DETAIL_KEYS}
    warnings: list[str] = []
    sections["name"] = s.name
    sections["description"] = spec.description
    sections["system"] = system_section(spec)
    sections["lower_bound"] = critical.lower_bound(s)
    sections["critical_value"] = {"value": None, "exact": None, "expression": None,
                                  "latex": None, "reason": "not computed yet"}
    sections["block_lower_bound"] = None
    sections["upper_bound"] = None
    sections["warnings"] = warnings
    sections["requirements"] = spec.requirements.to_dict()
    sections["operating_point"] = operating_point(spec, sections)
    sections["provenance"] = provenance(spec, opts)
    return Analysis(sections=sections)


def provenance(spec: SystemSpec, opts: AnalysisOptions) -> dict[str, Any]:
    """Versions, seed, options and the input file's SHA-256 (for the verification appendix)."""
    import importlib.metadata as md

    versions = {"kfcrit": __version__, "python": platform.python_version()}
    for pkg in ("numpy", "scipy", "sympy", "cvxpy", "clarabel", "python-flint", "matplotlib",
                "jinja2"):
        try:
            versions[pkg] = md.version(pkg)
        except md.PackageNotFoundError:
            versions[pkg] = None
    return {"versions": versions, "seed": opts.seed, "input_path": spec.path,
            "input_sha256": spec.sha256, "options": dict(opts.__dict__)}
