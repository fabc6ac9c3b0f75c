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

from kfcrit.version import __version__
from kfcrit.io.jsonio import jsonable
from kfcrit.model.system import System, conditioning_warnings
from kfcrit.io.systemfile import SystemSpec

CONTRACT_KEYS = ("name", "classification", "critical_value", "robust_critical_value",
                 "lower_bound", "block_lower_bound", "upper_bound", "operating_point",
                 "warnings")
DETAIL_KEYS = ("description", "system", "structure", "theory", "covariance_bounds",
               "static_gain", "phase_transition", "simulation", "invariant", "link_budget",
               "requirements", "verification", "provenance")


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
        """The record as plain JSON types, contract keys first.

        Wall-clock timings are left out (see :meth:`timings`), so that the same input and seed
        give byte-identical JSON.
        """
        out = {k: self.sections.get(k) for k in CONTRACT_KEYS}
        out.update({k: self.sections.get(k) for k in DETAIL_KEYS})
        return _split_timings(jsonable(out), "", {})

    def timings(self) -> dict[str, float]:
        """Wall-clock seconds reported by the sections, keyed by their dotted path."""
        found: dict[str, float] = {}
        _split_timings(jsonable(dict(self.sections)), "", found)
        return found


TIMING_KEYS = frozenset({"seconds", "runtime_seconds"})


def _split_timings(obj: Any, path: str, found: dict[str, float]) -> Any:
    """Copy of ``obj`` without the keys in :data:`TIMING_KEYS`; those go into ``found``."""
    if isinstance(obj, dict):
        out = {}
        for k, v in obj.items():
            if k in TIMING_KEYS and (v is None or isinstance(v, (int, float))):
                found[f"{path}.{k}".lstrip(".")] = v
            else:
                out[k] = _split_timings(v, f"{path}.{k}", found)
        return out
    if isinstance(obj, list):
        return [_split_timings(v, f"{path}[{i}]", found) for i, v in enumerate(obj)]
    return obj


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
    if sections.get("classification") == "stable":
        worst = max(pc or 0.0, robust.get("value") if robust.get("value") is not None else 0.0)
        out.update(margin=p - (pc or 0.0), margin_robust=p - worst, bracket=None,
                   verdict="mean-stable",
                   reason="ρ(A) < 1: E[P_t] is bounded for every arrival probability")
        if robust.get("value") is not None and p <= worst:
            # a system within the tolerance is unstable (or undetectable) at this p
            out.update(verdict="undetermined",
                       reason="ρ(A) < 1 as entered, but a system within the tolerance has "
                              f"critical value {worst:.6g} ≥ p (see the robust critical value)")
        return out
    if sections.get("classification") == "not-detectable":
        out.update(margin=None, margin_robust=None, bracket=None, verdict="mean-unstable",
                   diverges_for_all_p=True,
                   reason="(C, A) is not detectable: a mode with |λ| ≥ 1 is unobservable, so "
                          "the expected error covariance diverges for every arrival probability, "
                          "even p = 1 (no losses); there is no critical value, and p_up and the "
                          "covariance bounds do not apply",
                   basis="PBH detectability test (MATH §3: the theorems assume (A, C) "
                         "detectable)")
        return out
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
        out["note"] = ("p_c, p_up and the covariance bounds S̄, V̄ assume i.i.d. losses; for this "
                       "bursty channel the margin compares only the stationary arrival "
                       "probability, and the verdict follows the basis stated")
    out["verdict"] = verdict
    if spec.channel.model == "trace":
        trace_verdict(spec, out)
    return out


def trace_verdict(spec: SystemSpec, op: dict[str, Any]) -> None:
    """A measured 0/1 trace decides nothing about mean stability: the theorems (Sinopoli,
    Mo–Sinopoli, MATH §3–4; Gilbert–Elliott, MATH §7) are about i.i.d. or Markov arrival
    *models*, and a finite recording is neither. The verdict is ``undetermined``; the empirical
    arrival rate, what the i.i.d. comparison would say, and a Gilbert–Elliott fit of the trace
    are kept for information."""
    from kfcrit.link.linkbudget import gilbert_elliott_fit

    fit = gilbert_elliott_fit(spec.channel.arrivals, spec.system)
    op["iid_comparison_verdict"] = op.get("verdict")
    op["verdict"] = "undetermined"
    op["note"] = ("p_c, p_up and the covariance bounds S̄, V̄ assume i.i.d. losses; the margin "
                  "compares only the empirical arrival rate of the trace with p_c")
    op["basis"] = ("measured trace: the mean-stability theorems assume i.i.d. (Sinopoli, "
                   "Mo–Sinopoli) or Gilbert–Elliott (MATH §7) arrivals, which a recorded "
                   "sequence is not; the empirical arrival rate"
                   + (" and a Gilbert–Elliott fit are" if fit.get("available") else " is")
                   + " given for information only")
    op["trace"] = {"length": int(spec.channel.arrivals.size),
                   "empirical_arrival_probability": op["arrival_probability"],
                   "gilbert_elliott_fit": fit}


def analyze(system: System | SystemSpec, options: AnalysisOptions | None = None,
            **kwargs: Any) -> Analysis:
    """Analyse a system (or a loaded system file) and return the :class:`Analysis` record.

    Parameters
    ----------
    system : System or SystemSpec
        The system, or a loaded system file (which adds channel and requirements).
    options : AnalysisOptions, optional
        Tolerances, simulation size and seed; keyword arguments override its fields.

    Notes
    -----
    The order is that of the theory: exact structure and p_c (Mo–Sinopoli), the numerical upper
    bound p_up (Sinopoli Thm 5), the covariance bounds S̄ ⪯ lim E[P_t] ⪯ V̄ at the operating point
    (Thm 4, 6), then the simulation that cross-checks them, and finally the verdict.
    """
    opts = options or AnalysisOptions()
    if kwargs:
        opts = AnalysisOptions(**{**opts.__dict__, **kwargs})
    spec = _as_spec(system)
    s = spec.system
    sec: dict[str, Any] = {k: None for k in CONTRACT_KEYS + DETAIL_KEYS}
    sec["name"] = s.name
    sec["description"] = spec.description
    sec["system"] = system_section(spec)
    sec["requirements"] = spec.requirements.to_dict()
    warnings: list[str] = conditioning_warnings(s)

    _critical_sections(spec, opts, sec, warnings)
    _upper_sections(spec, opts, sec, warnings)
    close_bracket(sec)
    sec["operating_point"] = operating_point(spec, sec)
    _bounds_sections(spec, sec, warnings)
    _simulation_sections(spec, opts, sec, warnings)
    _link_sections(spec, sec, warnings)
    sec["requirements"] = requirement_assessment(sec["requirements"], sec.get("simulation"))
    bursty_verdict(sec)
    sec["verification"] = verification(sec, warnings)
    sec["warnings"] = list(dict.fromkeys(warnings))  # de-duplicated, order kept
    sec["provenance"] = provenance(spec, opts)
    return Analysis(sections=sec)


def _critical_sections(spec: SystemSpec, opts: AnalysisOptions, sec: dict[str, Any],
                       warnings: list[str]) -> None:
    from kfcrit.theory import critical

    crit = critical.critical_section(spec.system, opts.tolerance, channel=spec.channel)
    for key in ("classification", "critical_value", "robust_critical_value", "lower_bound",
                "block_lower_bound", "structure", "theory"):
        sec[key] = crit.get(key)
    warnings.extend(crit.get("warnings") or [])


def _upper_sections(spec: SystemSpec, opts: AnalysisOptions, sec: dict[str, Any],
                    warnings: list[str]) -> None:
    from kfcrit.theory import upper

    if sec.get("classification") == "not-detectable":
        sec["upper_bound"] = not_detectable_upper()
        return
    ub = upper.upper_section(spec.system, tol=opts.upper_tol)
    sec["upper_bound"] = ub
    warnings.extend(ub.get("warnings") or [])


NOT_DETECTABLE = ("not applicable: (C, A) is not detectable, so E[P_t] diverges for every "
                  "arrival probability (even p = 1)")


def not_detectable_upper() -> dict[str, Any]:
    """The ``upper_bound`` section of an undetectable system: p_up is not defined (Sinopoli's
    Theorems 3–6 assume (A, C) detectable), so it is labelled instead of computed."""
    return {"value": None, "interval": None, "certified": False, "status": "not applicable",
            "method": None, "certificate": None, "tolerance": None, "reason": NOT_DETECTABLE,
            "warnings": []}


def close_bracket(sec: dict[str, Any]) -> None:
    """If p_c has no closed form but the exact block lower bound and the *certified* upper end
    of p_up lie within the upper-bound tolerance, p_c is known to that width (Thm 3: p_c ≥ every
    block value; Sinopoli Thm 3: p_c ≤ p_up). Fill ``critical_value`` accordingly (not exact)."""
    cv = sec.get("critical_value") or {}
    blb = sec.get("block_lower_bound") or {}
    ub = sec.get("upper_bound") or {}
    if cv.get("value") is not None or blb.get("value") is None or not ub.get("certified"):
        return
    hi = (ub.get("interval") or [None, None])[1]
    tol = (ub.get("tolerance") or 1e-9)
    if hi is not None and 0 <= hi - blb["value"] <= max(tol, 1e-12):
        sec["critical_value"] = {
            **cv, "value": blb["value"], "exact": False, "expression": blb.get("expression"),
            "reason": (f"{cv.get('reason', '')} The bracket closes: the block lower bound "
                       f"{blb.get('expression')} (Mo–Sinopoli Thm 3) and the certified upper end "
                       f"{hi:.12g} of p_up (Sinopoli Thm 3) differ by at most {tol:g}.").strip()}


def _bounds_sections(spec: SystemSpec, sec: dict[str, Any], warnings: list[str]) -> None:
    import numpy as np

    from kfcrit.theory import bounds

    s = spec.system
    markers = {"p_low": (sec.get("lower_bound") or {}).get("value"),
               "p_c": (sec.get("critical_value") or {}).get("value"),
               "p_up": (sec.get("upper_bound") or {}).get("value"),
               "operating": (float(spec.channel.arrival_probability)
                             if spec.channel is not None else None)}
    if sec.get("classification") == "not-detectable":
        p = markers["operating"]
        if p is not None:
            S = bounds.lower_covariance(s.a, s.q, p)
            sec["covariance_bounds"] = {
                "p": p, "lower": bounds._summary(S),
                "upper": {**bounds._summary(None), "residual": None, "method": NOT_DETECTABLE,
                          "iterations": 0},
                "ordered": None, "applicable": False, "reason": NOT_DETECTABLE}
            na = {"available": False, "reason": NOT_DETECTABLE}
            sec["static_gain"] = {"p": p, "kalman": na, "best": dict(na), "p_up": None,
                                  "p_up_interval": None}
        grid = bounds.phase_grid(markers["p_low"] or 0.0, None, bounds.phase_points(s.n))
        lower = [bounds.lower_covariance(s.a, s.q, float(p)) for p in grid]
        sec["phase_transition"] = {
            "p": [float(v) for v in grid],
            "trace_lower": [None if S is None else float(np.trace(S)) for S in lower],
            "trace_upper": [None] * len(grid), "markers": markers,
            "warnings": [f"V̄ {NOT_DETECTABLE}"]}
        return
    try:  # these recompute p_up: a solver failure there is the upper section's "undetermined"
        if markers["operating"] is not None:
            cb = bounds.covariance_bounds(s, markers["operating"])
            sec["covariance_bounds"] = cb
            warnings.extend(cb.get("warnings") or [])
            sec["static_gain"] = bounds.static_gain(s, markers["operating"])
        pt = bounds.phase_transition(s, markers)
    except (np.linalg.LinAlgError, ArithmeticError, ValueError, RuntimeError) as exc:
        warnings.append("covariance bounds and phase transition not computed: numerical "
                        f"failure ({type(exc).__name__}: {str(exc)[:120]})")
        return
    sec["phase_transition"] = pt
    if (pt.get("limits") or {}).get("stopped"):
        warnings.append(f"phase-transition curve incomplete: {pt['limits']['stopped']}")


def _simulation_sections(spec: SystemSpec, opts: AnalysisOptions, sec: dict[str, Any],
                         warnings: list[str]) -> None:
    from kfcrit.theory import invariant

    sec["invariant"] = invariant.invariant_section(spec.system)
    warnings.extend((sec["invariant"] or {}).get("warnings") or [])
    if not opts.simulate:
        sec["simulation"] = {"skipped": True, "reason": "simulation disabled (--no-simulate)"}
        return
    from kfcrit.sim.montecarlo import simulation_section

    sim = simulation_section(
        spec, critical_value=(sec.get("critical_value") or {}).get("value"),
        upper_bound=(sec.get("upper_bound") or {}).get("value"), seed=opts.seed,
        quick=opts.quick)
    sec["simulation"] = sim
    warnings.extend((sim or {}).get("warnings") or [])


def _link_sections(spec: SystemSpec, sec: dict[str, Any], warnings: list[str]) -> None:
    ch = spec.channel
    if ch is None or ch.model not in ("link-budget", "gilbert-elliott"):
        return
    from kfcrit.link import linkbudget

    if ch.model == "gilbert-elliott":
        sec["link_budget"] = linkbudget.gilbert_elliott_section(spec.system, ch)
        return
    op = sec.get("operating_point") or {}
    sec["link_budget"] = linkbudget.design_section(
        ch, critical_value=(sec.get("critical_value") or {}).get("value"),
        robust_value=(sec.get("robust_critical_value") or {}).get("value"),
        bracket=tuple(op.get("bracket") or (None, None)),
        upper_bound=(sec.get("upper_bound") or {}).get("value"))
    if isinstance(sec["link_budget"], dict):
        sec["link_budget"].setdefault("design_check", design_check(sec["link_budget"]))
    warnings.extend((sec["link_budget"] or {}).get("warnings") or [])


def design_check(lb: dict[str, Any]) -> dict[str, Any] | None:
    """The configured link against its own margin policy (read from the link-budget section).

    ``margin_policy_met``: the link margin at the configured distance is at least the policy's
    effective margin max(margin_db, σ·Φ⁻¹(1 − max_outage)) (equivalently, the distance is within
    ``max_distance_m``); ``outage_within_policy``: the per-link shadowing outage below the design
    requirement is at most ``max_outage``. Either is ``None`` when its inputs are missing.
    """
    if not lb.get("applicable"):
        return None
    policy = lb.get("margin_policy") or {}
    link = lb.get("link") or {}
    shadow = lb.get("shadowing") or {}
    margin, needed = lb.get("link_margin_db"), policy.get("effective_margin_db")
    design = (lb.get("required_arrival_probability") or {}).get("design_value")
    rows = [r for r in lb.get("thresholds") or []
            if r.get("arrival_probability") == design and r.get("outage_probability") is not None]
    outage = rows[0]["outage_probability"] if rows else shadow.get("outage_below_critical")
    max_outage = policy.get("max_outage")
    return {"link_margin_db": margin, "required_margin_db": needed,
            "margin_policy_met": (margin >= needed) if None not in (margin, needed) else None,
            "distance_m": link.get("distance_m"), "max_distance_m": lb.get("max_distance_m"),
            "outage_probability": outage, "max_outage": max_outage,
            "outage_within_policy": (outage <= max_outage)
            if None not in (outage, max_outage) else None}


def bursty_verdict(sec: dict[str, Any]) -> None:
    """For a non-i.i.d. Gilbert–Elliott channel the i.i.d. comparison p > p_c does not decide
    mean stability. The Gilbert–Elliott section (:func:`kfcrit.link.linkbudget.
    gilbert_elliott_section`) states for its condition (1 − r)a² < 1 whether it ``decides``:
    only the scalar case is a theorem (MATH §7; and ρ(A) < 1 trivially). Where it decides, the
    verdict follows the condition; where it does not (a claim from the literature, or a
    necessary condition only), the verdict is ``undetermined`` and the basis says which. An
    undetectable system stays ``mean-unstable`` whatever the channel."""
    op = sec.get("operating_point")
    lb = sec.get("link_budget") or {}
    if not op or op.get("iid") or op["channel"].get("model") != "gilbert-elliott":
        return
    if sec.get("classification") == "not-detectable":
        return
    cond = lb.get("condition") if isinstance(lb.get("condition"), dict) else {}
    iid_verdict = op.get("verdict")
    if cond.get("decides") is True and cond.get("holds") is not None:
        op["verdict"] = "mean-stable" if cond["holds"] else "mean-unstable"
        op["basis"] = (f"Gilbert–Elliott condition {cond.get('expression')}: value "
                       f"{cond.get('value'):.6g} "
                       f"{'< 1 holds' if cond['holds'] else '>= 1 fails'} "
                       f"({cond.get('status')})")
    else:
        op["verdict"] = "undetermined"
        what = cond.get("status") or "no Gilbert–Elliott condition was evaluated"
        value = cond.get("value")
        op["basis"] = ("bursty losses: no theorem in the papers decides mean stability for this "
                       f"system; the condition {cond.get('expression') or '(1 - r) a^2 < 1'}"
                       + (f" (value {value:.6g})" if isinstance(value, (int, float)) else "")
                       + f" is labelled: {what}")
    op["iid_comparison_verdict"] = iid_verdict


def _simulated_mean_between_bounds(cb: dict[str, Any],
                                   sim_op: dict[str, Any]) -> dict[str, Any] | None:
    """Sinopoli Thm 4/6 cross-check: the simulated E[tr P_t] at the horizon lies in
    [tr S̄, tr V̄] up to its confidence band (and a 5 % allowance for the finite horizon).

    A miss is ``inconclusive`` (``passed`` None, with the reason), not a failure, when the
    simulation section says the comparison is not valid at this operating point
    (``reliability``): the variance of tr P is infinite (heavy tails, just above p_c) or the
    Lyapunov lower bound itself has not settled within the horizon (the limit bounds then do
    not yet apply to E[tr P_T]).
    """
    lower, upper = cb.get("lower") or {}, cb.get("upper") or {}
    mt = sim_op.get("mean_trace") or {}
    if not (lower.get("exists") and upper.get("exists") and mt.get("mean")):
        return None
    if sim_op.get("iid") is False:  # S̄ and V̄ are bounds for i.i.d. losses only
        return None
    if (sim_op.get("divergence") or {}).get("diverged_paths"):
        return None
    mean, lo, hi = mt["mean"][-1], (mt.get("lower") or mt["mean"])[-1], \
        (mt.get("upper") or mt["mean"])[-1]
    if None in (mean, lo, hi):
        return None
    ok = hi >= 0.95 * lower["trace"] and lo <= 1.05 * upper["trace"]
    out = {"check": "simulation: E[tr P_t] at the horizon within [tr S̄, tr V̄] (Thm 4, 6)",
           "passed": bool(ok), "status": "passed" if ok else "failed",
           "detail": f"{lower['trace']:.6g} ≤ {mean:.6g} (band {lo:.6g}–{hi:.6g}) ≤ "
                     f"{upper['trace']:.6g}"}
    rel = sim_op.get("reliability") or {}
    if not ok:
        reasons = []
        if rel.get("heavy_tailed"):
            reasons.append(f"{rel.get('variance_condition')} = {rel.get('variance_value'):.4g}"
                           " >= 1: the variance of tr P diverges (heavy tails just above p_c), "
                           "so the sample mean is unreliable")
        if rel.get("settled") is False:
            reasons.append(f"the Lyapunov bound has not settled within the horizon (tr S_T = "
                           f"{rel.get('lyapunov_trace_at_horizon'):.4g} < 0.95 tr S̄ = "
                           f"{0.95 * rel.get('lyapunov_trace_limit'):.4g})")
        if reasons:
            out.update(passed=None, status="inconclusive", reason="; ".join(reasons))
    return out


def verification(sec: dict[str, Any], warnings: list[str] | None = None
                 ) -> list[dict[str, Any]]:
    """The checks the record relies on, each with its outcome (for the report's appendix).

    Every entry is ``{check, passed (True/False/None), status, detail}`` with ``status`` one of
    passed / failed / inconclusive (a Monte Carlo cross-check whose tolerance is not valid at
    this operating point; ``reason`` says why and a warning is added) / not applicable; nothing
    here recomputes a result, it reads what the sections measured.
    """
    warnings = warnings if warnings is not None else []
    checks: list[dict[str, Any]] = []
    ub = sec.get("upper_bound") or {}
    if ub and ub.get("status") != "not applicable":
        cert = ub.get("certificate") or {}
        checks.append({"check": "upper-bound certificate X ≻ g_p(X), X ≻ 0 (exact re-check)",
                       "passed": True if ub.get("certified") else None,
                       "detail": cert.get("verified_by") or cert.get("kind") or ub.get("status")})
    cb = sec.get("covariance_bounds") or {}
    if cb:
        checks.append({"check": "covariance bounds ordered: S̄ ⪯ V̄",
                       "passed": cb.get("ordered"),
                       "detail": f"MARE residual {((cb.get('upper') or {}).get('residual'))}"})
    sim = sec.get("simulation") or {}
    for c in sim.get("checks") or []:
        checks.append(c)
    between = _simulated_mean_between_bounds(cb, sim.get("operating_point") or {})
    if between is not None:
        checks.append(between)
        if between["status"] == "inconclusive":
            warnings.append(f"Monte Carlo check inconclusive: {between['check']} "
                            f"({between['reason']})")
    pcv = (sec.get("critical_value") or {}).get("value")
    lb = (sec.get("lower_bound") or {}).get("value")
    up = ub.get("value") if ub else None
    if pcv is not None and lb is not None:
        ok = lb <= pcv + 1e-12 and (up is None or pcv <= up + max(ub.get("tolerance") or 0,
                                                                     1e-9))
        checks.append({"check": "ordering p_low ≤ p_c ≤ p_up", "passed": bool(ok),
                       "detail": f"{lb:.12g} ≤ {pcv:.12g} ≤ {up if up is None else f'{up:.12g}'}"})
    status = {True: "passed", False: "failed", None: "not applicable"}
    return [{**c, "status": c.get("status") or status[c.get("passed")]} for c in checks]


def requirement_assessment(requirements: dict[str, Any] | None,
                           simulation: dict[str, Any] | None) -> dict[str, Any] | None:
    """The system file's tail requirement against the simulated exceedance at the horizon.

    With k of N paths above ``max_error_trace`` and the 95 % Wilson interval [lo, hi] of
    P(tr P > max_error_trace): ``met`` if hi ≤ max_tail_probability, ``not met`` if
    lo > max_tail_probability, else ``not demonstrated`` (the interval contains the allowed
    probability: more paths are needed). ``status`` is None when an input is missing.
    """
    if not requirements:
        return requirements
    out = dict(requirements)
    limit, allowed = out.get("max_error_trace"), out.get("max_tail_probability")
    op = (simulation or {}).get("operating_point") or {}
    exc = op.get("exceedance") or {}
    status, basis = None, None
    if limit is None or allowed is None:
        basis = "needs both max_error_trace and max_tail_probability"
    elif not exc or exc.get("lower") is None:
        basis = "no simulation at the operating point"
    else:
        lo, hi, est = exc["lower"], exc["upper"], exc.get("estimate")
        if hi <= allowed:
            status = "met"
        elif lo > allowed:
            status = "not met"
        else:
            status = "not demonstrated"
        basis = (f"P(tr P > {limit:g}) ≈ {est:.4g} at t = {op.get('steps')} "
                 f"({exc.get('count')} of {exc.get('total')} paths; 95 % interval "
                 f"[{lo:.3g}, {hi:.3g}]) against the allowed {allowed:g}")
    out["assessment"] = {"status": status, "basis": basis,
                         "estimate": exc.get("estimate"), "interval":
                         [exc.get("lower"), exc.get("upper")] if exc else None}
    return out


def exit_code(record: dict[str, Any]) -> int:
    """The documented exit code of an analysis record (README, "Exit codes").

    1 when a verification check failed (``passed`` False; an *inconclusive* Monte Carlo
    cross-check is a warning, not a failure); 3 when the result is undetermined — the
    operating-point verdict is ``undetermined`` (a bracket around the operating point, or no
    theorem for the channel: a measured trace, a bursty channel outside the scalar
    Gilbert–Elliott theorem), or, with no operating point, the upper bound could not be decided
    (an undecided p_up bracket that does not contain the operating point does not change a
    decided verdict; the record still says ``undetermined`` for p_up); else 0, whatever the verdict
    (``mean-unstable`` is a result, not an error). ``kfcrit.cli.main.exit_code_of`` should return
    this.
    """
    if any(c.get("passed") is False for c in record.get("verification") or []):
        return 1
    op = record.get("operating_point") or {}
    if op.get("verdict") == "undetermined":
        return 3
    if not op.get("verdict") and (record.get("upper_bound") or {}).get("status") == "undetermined":
        return 3
    return 0


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
