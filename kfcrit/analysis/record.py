"""The analysis: one typed record that every view renders.

``analyze_system(spec)`` asks each concern for its section — the critical value
(:mod:`kfcrit.theory.critical.section`), the upper bound and covariance bounds
(:mod:`kfcrit.theory.upper.bracket`, :mod:`kfcrit.theory.covariance.bounds`), the simulation
(:mod:`kfcrit.sim`) and the link (:mod:`kfcrit.link`) — then decides, in one place
(:mod:`kfcrit.analysis.verdict`), the stability verdict at the operating point and the review
decision, and returns the typed :class:`~kfcrit.analysis.sections.AnalysisRecord`. The terminal
summary, ``--json``, the HTML, the PDF and the sweep table are all views of it; no view computes
anything.

Contract (keys always present, ``null`` where not computed)::

    schema_version, name, classification, critical_value {value, exact, expression, latex,
    reason}, robust_critical_value {value, tolerance} | null, lower_bound {value, expression},
    block_lower_bound {value, expression}, upper_bound {value, interval, certified},
    operating_point {..., verdict, basis} | null, review {decision, reasons}, warnings [...]

followed by the detail sections ``system``, ``structure``, ``theory``, ``covariance_bounds``,
``phase_transition``, ``simulation``, ``link_budget``, ``requirements``, ``verification`` and
``provenance``.
"""
from __future__ import annotations

import dataclasses
import functools
import platform
import typing
from dataclasses import dataclass, field, replace
from typing import Any

from kfcrit.analysis import verdict as vd
from kfcrit.analysis.links import bursty_channel, link_curves
from kfcrit.analysis.measured import measured_channel
from kfcrit.analysis.mesh.build import mesh_sections
from kfcrit.analysis.network import network_lower_bound, network_sections, network_simulation
from kfcrit.analysis.requirements import (
    power_law_tail,
    requirement_assessment,
    tail_simulation_check,
)
from kfcrit.analysis.sections import SCHEMA_VERSION, AnalysisRecord
from kfcrit.analysis.verification import section_value, verification
from kfcrit.defaults import DEFAULT_TOLERANCE
from kfcrit.io.systemfile import SystemSpec
from kfcrit.io.typed import ABSENT, to_json
from kfcrit.model.system import System, conditioning_warnings
from kfcrit.records.bursty import BurstCurveRecord, GilbertElliottSection
from kfcrit.records.channel import channel_record
from kfcrit.records.contract import (
    OperatingPoint,
    Provenance,
    SystemSection,
    UpperBoundRecord,
)
from kfcrit.records.covariance import (
    AccuracyDesign,
    BestStaticGain,
    CovarianceBounds,
    CovarianceSummary,
    Markers,
    PhaseTransition,
    StaticGain,
    StaticGainEstimate,
    TailSection,
)
from kfcrit.records.link import LinkBudgetRecord
from kfcrit.records.simulation import Simulation
from kfcrit.records.system import (
    AnalysisOptionsRecord,
    Matrices,
    continuous_record,
    sensor_records,
)
from kfcrit.version import __version__

DETAIL_KEYS = ("description", "system", "structure", "theory", "covariance_bounds",
               "static_gain", "phase_transition", "simulation", "invariant", "link_budget",
               "requirements", "verification", "provenance")


@dataclass(frozen=True)
class AnalysisOptions:
    """Options of one analysis (stored, not acted on, by the constructor).

    ``details`` False computes only what the verdict and the review need (the sweep's mode):
    no phase-transition curve, static gains or invariant support, covariance bounds only for an
    accuracy requirement and the simulation only for a tail requirement.

    Parameters
    ----------
    tolerance : float
        Relative perturbation size of the robust critical value (and numeric decision tolerance).
    upper_tol : float
        Width of the certified bracket of p_up.
    simulate : bool
        Run the Monte Carlo cross-check.
    quick : bool
        A draft: no robust critical value, smaller simulations.
    seed : int
        Root seed of the simulation.
    paths, steps : int, optional
        Simulation size (default: chosen from the system).
    details : bool
        Compute the sections beyond the verdict and the review.

    Attributes
    ----------
    tolerance, upper_tol, simulate, quick, seed, paths, steps, details
        As given (frozen).

    Raises
    ------
    TypeError
        An unknown option name (also from ``kfcrit.analyze(system, name=value)``).

    References
    ----------
    docs/theory.md §3 (p_up bracket), §4 (robust value), §16 (verdict and review).

    Examples
    --------
    >>> from kfcrit import AnalysisOptions
    >>> opts = AnalysisOptions(simulate=False)
    >>> opts.simulate, opts.tolerance, opts.seed
    (False, 1e-09, 0)
    >>> AnalysisOptions(nonsense=1)
    Traceback (most recent call last):
        ...
    TypeError: AnalysisOptions.__init__() got an unexpected keyword argument 'nonsense'
    """

    tolerance: float = DEFAULT_TOLERANCE
    upper_tol: float = 1e-9
    simulate: bool = True
    quick: bool = False
    seed: int = 0
    paths: int | None = None
    steps: int | None = None
    details: bool = True


@dataclass(frozen=True)
class TheorySections:
    """The sections that depend on (A, C) and the tolerances only (not on the channel).

    Computed once per system by :func:`theory_sections`; a sweep over channel parameters passes
    the same object to every :func:`analyze_system` call instead of recomputing it.
    """

    sections: dict[str, Any]
    """The typed sections by record key (``classification``, ``critical_value``, …,
    ``upper_bound``: the classes of :class:`AnalysisRecord`'s fields)."""
    warnings: tuple[str, ...]
    critical_exact: Any = None
    p_low_exact: Any = None
    structure: Any = None
    """The eigen-structure (:func:`kfcrit.theory.structure.eigen.structure_of`) the sections used."""
    upper: Any = None
    """The p_up bracket (:class:`kfcrit.theory.upper.record.UpperBound`) behind ``upper_bound``,
    passed to the covariance bounds so that p_up is computed once per system."""
    timings: dict[str, float] = field(default_factory=dict)
    """Wall-clock seconds the theory reported (kept out of the sections)."""

    @property
    def classification(self) -> str | None:
        """The classification's value (``"non-degenerate"``, …), None if not classified."""
        cls = self.sections.get("classification")
        return cls.value if cls is not None else None

    def value(self, key: str) -> float | None:
        """``value`` of the theory section ``key`` (None when the section is absent)."""
        section = self.sections.get(key)
        return section.value if section is not None else None


QUICK_SIMULATION_MAX_STATES = 40
"""Largest n simulated by a ``--quick`` draft (each path-step costs O(n³))."""
QUICK_ROBUST_MAX_STATES = 60
"""Largest n whose robust critical value a ``--quick`` draft computes."""
QUICK_PHASE_SECONDS = 5.0
"""Time budget of the V̄ curve in a ``--quick`` draft of a system with more than 20 states."""


def classification_of(sec: dict[str, Any]) -> str | None:
    """The classification's value (``"non-degenerate"``, …) of ``sec``, None if absent."""
    cls = sec.get("classification")
    return cls.value if cls is not None else None


def _as_spec(system: System | SystemSpec) -> SystemSpec:
    return system if isinstance(system, SystemSpec) else SystemSpec(system=system)


def system_section(spec: SystemSpec) -> SystemSection:
    """Sizes, exactness and exact matrices of the system (and how it was sampled, for a
    continuous-time file; its sensors, for a network)."""
    s = spec.system
    extra: dict[str, Any] = {}
    if spec.continuous is not None:
        extra["continuous"] = continuous_record(spec.continuous)
    if spec.network is not None:
        extra["sensors"] = sensor_records(spec.network)
        sink = spec.network.sink_position
        extra["sink_position_m"] = None if sink is None else [float(x) for x in sink]
    return SystemSection(n=s.n, m=s.m, exact_input=s.exact, matrices=Matrices(**s.matrices_text()),
                         channel=channel_record(spec.channel), **extra)


def critical_inputs(theory: TheorySections) -> vd.CriticalInputs:
    """What the verdict needs of the theory sections (exact values where known)."""
    cv = theory.sections.get("critical_value")
    low = theory.value("block_lower_bound")
    p_low = theory.value("lower_bound")
    if low is None:
        low = p_low
    return vd.CriticalInputs(
        classification=theory.classification, critical=theory.value("critical_value"),
        critical_exact=theory.critical_exact if cv is not None and cv.exact else None,
        robust=theory.value("robust_critical_value"), lower=low,
        upper=theory.value("upper_bound"), p_low=p_low, p_low_exact=theory.p_low_exact)


def bursty_part(spec: SystemSpec, link: Any) -> GilbertElliottSection | None:
    """The Gilbert–Elliott section of the operating point's link: the ``link_budget`` section
    of a Gilbert–Elliott channel, ``link_budget.bursty`` of a link budget with time-correlated
    shadowing; None otherwise."""
    if link is None or spec.channel is None:
        return None
    if spec.channel.model == "link-budget":
        return link.bursty or None if isinstance(link, LinkBudgetRecord) else None
    return link if isinstance(link, GilbertElliottSection) else None


def burst_inputs(spec: SystemSpec, link: Any) -> vd.BurstInputs | None:
    """The Gilbert–Elliott chain for the verdict, with the sufficient condition the link
    section proved (the exact scalar condition of theory §7 or a coupled certificate, §10).

    For a link budget with time-correlated shadowing the chain and its section are those of
    the shadowing's two-state approximation (``link_budget.bursty``)."""
    ge = bursty_channel(spec.channel)
    if ge is None:
        return None
    part = bursty_part(spec, link)
    cond = part.condition if part is not None else None
    sufficient, basis = None, None
    if cond is not None and cond.decides is True and cond.holds is True:
        sufficient = True
        shown = (f"{cond.value:.6g}" if cond.value != 1.0 else
                 "1 - ε (1 to float precision; below 1 exactly, as r exceeds 1 - 1/a^2)")
        basis = (f"Gilbert–Elliott condition {cond.expression} holds: (1 - r) a^2 = {shown} "
                 f"({cond.status})")
    cert = part.certificate if part is not None else None
    if sufficient is None and cert and cert.facts and cert.facts.sufficient is True:
        sufficient, basis = True, cert.basis or "coupled fixed-gain certificate"
    elif sufficient is None and cert and cert.basis:
        basis = cert.basis
    elif sufficient is None and cond is not None and cond.status:
        basis = f"the condition {cond.expression} is labelled: {cond.status}"
    return vd.BurstInputs(recovery=ge.recovery_rate, failure=ge.failure_rate,
                          sufficient=sufficient, basis=basis)


def joint_verdict(sec: dict[str, Any], joint: vd.JointLawInputs, warnings: list[str]) -> None:
    """A network of time-aligned traces: its one verdict is that of the joint law of the
    received set (theory §13, §14), stated in the operating point and the network section."""
    verdict, basis = vd.joint_law_verdict(joint)
    sec["operating_point"] = replace(sec["operating_point"], verdict=verdict, basis=basis)
    sec["network"] = replace(sec["network"], verdict=verdict.value, basis=basis)
    warnings.append("network of measured traces: the verdict uses the joint law of the "
                    "received set (`channel_fit.joint_law`); the per-sensor critical values "
                    "and the uniform margin in `network` assume independent links")


def operating_point(spec: SystemSpec, theory: TheorySections,
                    link: LinkBudgetRecord | GilbertElliottSection | None = None,
                    measured: vd.MeasuredInputs | None = None) -> OperatingPoint | None:
    """Arrival probability of the configured channel against p_c, the robust value and bracket,
    with the verdict of :func:`kfcrit.analysis.verdict.operating_verdict`."""
    if spec.channel is None:
        return None
    ch = spec.channel
    p_exact = ch.arrival_probability
    p = float(p_exact)
    crit = critical_inputs(theory)
    burst = burst_inputs(spec, link)
    verdict, basis = vd.operating_verdict(p_exact, crit, iid=bool(ch.iid), burst=burst,
                                          measured_trace=ch.model == "trace", measured=measured)
    out: dict[str, Any] = {"arrival_probability": p, "channel": ch.to_dict(), "iid": ch.iid}
    cls = theory.classification
    pc = crit.critical
    worst = max(pc if pc is not None else 0.0, crit.robust if crit.robust is not None else 0.0)
    if cls == "not-detectable":
        out.update(margin=None, margin_robust=None, bracket=None, diverges_for_all_p=True,
                   reason=vd.NOT_DETECTABLE_BASIS)
    elif cls == "stable" or pc is not None:
        out.update(margin=exact_difference(p_exact, crit.critical_exact, p - (pc or 0.0)),
                   margin_robust=p - worst, bracket=None)
        if crit.robust is None or crit.robust <= (pc or 0.0):
            out["margin_robust"] = out["margin"]
    else:
        lo = crit.lower if crit.lower is not None else 0.0
        out.update(margin=None, margin_robust=None, bracket=[lo, crit.upper],
                   margin_to_bracket=[p - lo, (p - crit.upper) if crit.upper is not None
                                      else None])
    if not ch.iid or ch.model == "trace":
        out["iid_comparison_verdict"] = vd.operating_verdict(p_exact, crit)[0].value
        out["iid_margin"] = out.get("margin")
        out["margin_basis"] = "stationary arrival probability − p_c (i.i.d. comparison only)"
        out["note"] = ("p_c, p_up and the covariance bounds S̄, V̄ assume i.i.d. losses; for this "
                       "channel the margin compares only the stationary arrival probability, "
                       "and the verdict follows the basis stated")
    if burst is not None and cls != "not-detectable":
        _burst_margin(out, burst, crit, bursty_part(spec, link))
    elif (measured is not None and measured.model == "gilbert-elliott"
          and measured.worst_burst is not None and cls != "not-detectable"):
        # a trace fitted as bursty is judged on its own boundary too, at the worst corner of
        # the confidence region (so the margin's sign agrees with a verdict held there)
        _burst_margin(out, measured.worst_burst, crit, None)
        out["margin_basis"] += (f"; at the worst corner (f_hi, r_lo) of the "
                                f"{measured.confidence:g} confidence region of the trace fit")
        out["note"] = ("the trace is fitted as a Gilbert–Elliott link: its margin is the "
                       "recovery rate against r_nec; p_c, p_up and the i.i.d. bounds S̄, V̄ "
                       "do not apply to it (the i.i.d. comparison p − p_c is kept beside it)")
    return OperatingPoint(**{**out, "channel": channel_record(ch), "verdict": verdict,
                             "basis": basis})


def _burst_margin(out: dict[str, Any], burst: vd.BurstInputs, crit: vd.CriticalInputs,
                  link: GilbertElliottSection | None) -> None:
    """The margin of a bursty link against its own boundary (theory §10): r − r_nec, with
    r_nec = max(1 − 1/ρ(A)², 0) the necessary recovery threshold (positive iff the necessary
    burst condition holds), and ``margin_to_sufficient`` r − r_suf(f) from the critical curve
    when it was computed (the margin itself where the curve's sufficient end is its necessary
    one: the scalar theorem of theory §7). The i.i.d. p − p_c stays under ``iid_margin``."""
    from kfcrit.theory.links.markov import recovery_margin

    r = burst.recovery
    r_nec = crit.p_low if crit.p_low is not None else 0.0
    margin = recovery_margin(r, crit.p_low, crit.p_low_exact)
    out["note"] = ("p_c, p_up and the i.i.d. bounds S̄, V̄ assume i.i.d. losses; this link's "
                   "margin is its recovery rate against r_nec (the i.i.d. comparison p − p_c "
                   "is kept beside it), and the verdict follows the basis stated")
    out.update(margin=margin, margin_robust=margin, bracket=None,
               margin_basis="recovery rate r − r_nec, r_nec = max(1 − 1/ρ(A)², 0) (the "
                            "necessary burst condition (1 − r)ρ(A)² < 1, theory §10)",
               recovery_threshold=r_nec)
    curve: BurstCurveRecord | None = link.critical_curve or None if link is not None else None
    if curve is not None:
        f = float(burst.failure)
        for fi, rs, rn in zip(curve.failure_rates or [], curve.sufficient_recovery or [],
                              curve.necessary_recovery or []):
            if rs is not None and abs(fi - f) <= 1e-12:
                out["margin_to_sufficient"] = margin if rs == rn else float(r) - rs
                break


def exact_difference(a: Any, b: Any, fallback: float) -> float:
    """a − b rounded once to a double when both are exact (so 9/25 + 10⁻⁴⁰ − 9/25 is 1e-40,
    not 0.0); the float ``fallback`` otherwise."""
    import sympy as sp

    if isinstance(a, sp.Basic) and isinstance(b, sp.Basic) and not (a.has(sp.Float)
                                                                    or b.has(sp.Float)):
        try:
            return float(sp.N(a - b, 30))
        except (TypeError, ValueError):
            return fallback
    return fallback


def theory_sections(system: System, options: AnalysisOptions | None = None,
                    channel: Any = None, *,
                    upper_bound: UpperBoundRecord | None = None) -> TheorySections:
    """Critical value, its bounds and robust value, the structure, and p_up of one system.

    These depend on the system and the tolerances only; compute them once per system and pass
    them to :func:`analyze_system` (``theory=``) when only the channel changes. ``upper_bound`` is the
    ``upper_bound`` section when already known: p_up depends on (A, C) only (Q and R do not
    enter Ψ_p, theory §3), so a sweep over noise parameters computes it once. The p_up bracket
    is built as its record class (:meth:`kfcrit.theory.upper.record.UpperBound.record`); its
    wall-clock seconds go to ``timings``.
    """
    from kfcrit.theory.covariance.riccati import single_blas_thread
    from kfcrit.theory.critical import section as critical
    from kfcrit.theory.structure.eigen import structure_of
    from kfcrit.theory.upper import bracket as upper

    opts = options or AnalysisOptions()
    with single_blas_thread():   # many small dense problems: BLAS threads only wait
        structure = structure_of(system, opts.tolerance)
        crit = critical.critical_value(system, opts.tolerance, channel=channel,
                                       structure=structure, robust=not (
                                           opts.quick and system.n > QUICK_ROBUST_MAX_STATES))
    sec: dict[str, Any] = crit.sections()
    warnings = list(crit.warnings)
    ub_result = None
    timings: dict[str, float] = {"structure.seconds": round(crit.structure.seconds, 4)}
    typed = dict(sec)
    if sec.get("classification") == "not-detectable":
        typed["upper_bound"] = not_detectable_upper()
    elif upper_bound is None:
        ub_result = upper.upper_result(system, tol=opts.upper_tol, structure=structure)
        typed["upper_bound"] = ub_result.record()
        if "seconds" in ub_result.solver:
            timings["upper_bound.solver.seconds"] = ub_result.solver["seconds"]
    else:
        typed["upper_bound"] = upper_bound
    if typed["upper_bound"] is not None:
        warnings.extend(typed["upper_bound"].warnings)
    close_bracket(typed)
    value = getattr(crit, "value", None)
    lower = getattr(crit, "lower", None)
    return TheorySections(sections=typed, warnings=tuple(warnings),
                          critical_exact=getattr(value, "expr", None),
                          p_low_exact=getattr(lower, "expr", None), structure=structure,
                          upper=ub_result, timings=timings)


def analyze_system(system: System | SystemSpec, options: AnalysisOptions | None = None, *,
                   theory: TheorySections | None = None, **kwargs: Any) -> AnalysisRecord:
    """Analyse a system (or a loaded system file) and return the typed :class:`AnalysisRecord`.

    The record is built from the sections of :func:`analysis_sections` (see there for the
    parameters); it is never written out and parsed back.
    """
    opts, theory, spec = _prepared(system, options, theory, kwargs)
    timings: dict[str, float] = {}
    record = _typed_record(analysis_sections(spec, opts, theory, timings=timings), theory,
                           timings)
    return replace(record, timings=timings)


ROW_KEYS = ("classification", "critical_value", "robust_critical_value", "upper_bound",
            "block_lower_bound", "lower_bound", "link_budget", "operating_point", "network", "loop")
"""The sections a sweep row reads (:func:`kfcrit.analysis.sweep.points.row_of`), with
``review``: all that :func:`analysis_data` returns with ``lean``."""


def _prepared(system: System | SystemSpec, options: AnalysisOptions | None,
              theory: TheorySections | None, overrides: dict[str, Any]
              ) -> tuple[AnalysisOptions, TheorySections, SystemSpec]:
    """The options (``overrides`` applied), the theory sections and the system file of one
    analysis; a one-sensor network is analysed as its one link (its channel included)."""
    opts = options or AnalysisOptions()
    if overrides:
        opts = replace(opts, **overrides)
    spec = _as_spec(system)
    if spec.network is not None and spec.network.size == 1:
        spec = replace(spec, channel=spec.network.sensors[0].channel)
    if theory is None:
        theory = theory_sections(spec.system, opts, channel=spec.channel)
    return opts, theory, spec


def _typed_record(sec: dict[str, Any], theory: TheorySections,
                  timings: dict[str, float]) -> AnalysisRecord:
    """The :class:`AnalysisRecord` of the sections, every one taken as built (each is typed
    where it is made, :data:`TYPED_KEYS`); the theory's wall-clock seconds join ``timings``."""
    timings.update(theory.timings)
    return AnalysisRecord(**{f.name: sec[f.name] for f in dataclasses.fields(AnalysisRecord)
                             if f.name != "timings" and f.name in sec})


@functools.cache
def record_hints() -> dict[str, Any]:
    """The field types of :class:`AnalysisRecord` (resolved once: the class never changes)."""
    return typing.get_type_hints(AnalysisRecord)


TYPED_KEYS = frozenset(f.name for f in dataclasses.fields(AnalysisRecord)
                       if f.name != "timings")
"""The record's sections :func:`analysis_sections` builds as typed values: all of them, each
built as its class by the layer that computes it."""


def analysis_sections(spec: SystemSpec, opts: AnalysisOptions, theory: TheorySections, *,
                      lean: bool = False, timings: dict[str, float] | None = None
                      ) -> dict[str, Any]:
    """The sections of one analysis, by record key.

    With ``lean`` only the sections of :data:`ROW_KEYS` and the review are computed (a sweep
    row), and those that feed neither (system text, tail exponent without a tail requirement,
    verification, provenance) are skipped: the values returned are those of the full record.

    Parameters
    ----------
    spec : SystemSpec
        The system file (a bare system has no channel or requirements).
    opts : AnalysisOptions
        Tolerances, simulation size and seed.
    theory : TheorySections
        The channel-independent sections of this system (computed once per system).
    timings : dict, optional
        Receives the wall-clock seconds the lower layers reported.

    Notes
    -----
    The order is that of the theory: exact structure and p_c (Mo–Sinopoli), the numerical upper
    bound p_up (Sinopoli Thm 5), the link, the verdict at the operating point, the covariance
    bounds S̄ ⪯ lim E[P_t] ⪯ V̄ (Thm 4, 6), the simulation that cross-checks them, the
    requirements, and finally the review decision.
    """
    timings = timings if timings is not None else {}
    s = spec.system
    sec: dict[str, Any] = {k: None for k in ("name", "operating_point", "warnings")
                           + DETAIL_KEYS}
    sec.update(theory.sections)
    sec["name"] = s.name
    sec["description"] = spec.description
    sec["system"] = None if lean else system_section(spec)
    warnings: list[str] = ([] if lean else conditioning_warnings(s)) + list(theory.warnings)

    if spec.network is None or spec.network.size == 1:
        # before the link: the link design reads the accuracy requirement's [p_S, p_V]
        _design_sections(spec, theory, sec, warnings, timings)
    _link_sections(spec, opts, sec, warnings, theory, timings)
    measured = measured_channel(spec, critical_inputs(theory), details=opts.details,
                                structure=theory.structure)
    if measured is not None:
        sec["channel_fit"] = measured.section
    if spec.network is not None and spec.network.size > 1:
        sec["network"], sec["operating_point"] = network_sections(
            spec, opts, warnings, stacked=(sec.get("critical_value"), sec.get("upper_bound")),
            timings=timings)
        if measured is not None and measured.joint is not None:
            joint_verdict(sec, measured.joint, warnings)
    hop_reasons = mesh_sections(spec, opts, sec, warnings) if spec.mesh is not None else []
    if sec.get("operating_point") is None:
        sec["operating_point"] = operating_point(spec, theory, sec.get("link_budget"),
                                                 measured.inputs if measured else None)
    estimator = sec["operating_point"]   # the estimator's verdict, before a loop joins it
    loop_reasons, loop_cost = [], None
    if spec.loop is not None:  # theory §12: operating_point.verdict becomes estimator AND loop
        from kfcrit.analysis.loop.section import loop_analysis

        sec["loop"], loop_reasons, loop_cost = loop_analysis(spec, opts, sec, warnings)
    vd.stamp_operating_verdict(sec)
    if spec.network is not None and spec.network.size == 1:
        op1 = sec["operating_point"]
        sec["network"], _ = network_sections(spec, opts, warnings,
                                             single=(op1.verdict, op1.basis or ""),
                                             timings=timings)
    reqs = spec.requirements
    if not lean or getattr(reqs, "max_error_trace", None) is not None:
        _tail_section(spec, theory, sec, timings)
    if spec.network is not None and spec.network.size > 1:
        fit = sec.get("channel_fit")
        joint = fit.joint_law if fit is not None else None
        sec["covariance_bounds"] = network_lower_bound(
            spec.network, joint.p_all_lost if joint is not None else None,
            p_low_exact=theory.p_low_exact)
    elif spec.mesh is None and (opts.details
                                or getattr(reqs, "max_mean_error_trace", None) is not None):
        _bounds_sections(spec, sec, warnings, timings, curves=opts.details, quick=opts.quick,
                         upper=theory.upper)
    tail = reqs.max_error_trace is not None and reqs.max_tail_probability is not None
    if spec.network is not None and spec.network.size > 1:
        if opts.simulate and opts.details and not (opts.quick and s.n >
                                                   QUICK_SIMULATION_MAX_STATES):
            sec["simulation"] = network_simulation(spec, opts, sec["operating_point"])
        else:
            sec["simulation"] = Simulation(skipped=True, reason="simulation disabled")
    elif spec.mesh is not None:
        pass  # mesh_sections simulated over the hop outcomes
    elif opts.quick and s.n > QUICK_SIMULATION_MAX_STATES and not tail:
        sec["simulation"] = Simulation(skipped=True, reason=(
            f"--quick draft of a system with n = {s.n} > {QUICK_SIMULATION_MAX_STATES} states: "
            "the Monte Carlo cross-check is left out (run without --quick for it); the verdict "
            "rests on the theory"))
    elif opts.details or tail:
        _simulation_sections(spec, opts, sec, warnings, timings, estimator)
    if sec.get("tail") is not None:
        sec["tail"] = tail_simulation_check(sec["tail"], sec.get("simulation"))
    requirements = requirement_assessment(reqs.to_dict() if reqs else None,
                                          sec.get("simulation"), sec.get("covariance_bounds"),
                                          sec.get("operating_point"), sec.get("design"))
    if loop_cost is not None and requirements is not None:
        requirements = replace(requirements,
                               assessments=[*requirements.assessments, loop_cost])
    sec["requirements"] = power_law_tail(requirements, sec.get("tail"), sec.get("simulation"))
    sec["verification"] = [] if lean else verification(sec, warnings)
    op = sec.get("operating_point")
    lb = sec.get("link_budget")
    net = sec.get("network")
    sensor_links = [vd.link_reasons(row.link.design_check if row.link else None, row.name)
                    for row in (net.sensors if net else [])]
    review = vd.review(op.verdict if op else None, op.basis if op else None,
                       requirements.assessments if requirements is not None else (),
                       lb.design_check if isinstance(lb, LinkBudgetRecord) else None,
                       extra=[r for rs in sensor_links for r in rs] + hop_reasons
                       + loop_reasons)
    ub = sec.get("upper_bound")
    if not op and ub is not None and ub.status == "undetermined":
        review = vd.review(None, None, (), None, extra=[vd.Reason(
            "upper bound p_up", vd.CheckStatus.UNDETERMINED,
            "the p_up bracket could not be narrowed to the tolerance")])
    sec["review"] = review
    sec["warnings"] = list(dict.fromkeys(warnings))  # de-duplicated, order kept
    sec["schema_version"] = SCHEMA_VERSION
    if not lean:
        sec["provenance"] = provenance(spec, opts)
    return sec


def analysis_data(system: System | SystemSpec, options: AnalysisOptions | None = None, *,
                  theory: TheorySections | None = None, lean: bool = False, **kwargs: Any
                  ) -> tuple[dict[str, Any], dict[str, float]]:
    """The record's plain JSON form and the sections' wall-clock seconds.

    With ``lean`` only the sections of :data:`ROW_KEYS` and the review (what a sweep row reads)
    are computed and returned; the values are those of the full record. Parameters as for
    :func:`analysis_sections`.
    """
    opts, theory, spec = _prepared(system, options, theory, kwargs)
    timings: dict[str, float] = {}
    sec = analysis_sections(spec, opts, theory, lean=lean, timings=timings)
    if lean:
        data = _json_sections({k: sec.get(k) for k in ROW_KEYS}, theory, timings)
        data["review"] = review_json(sec["review"])
        return data, timings
    return _typed_record(sec, theory, timings).to_dict(), timings


def _json_sections(sec: dict[str, Any], theory: TheorySections,
                   timings: dict[str, float]) -> dict[str, Any]:
    """The plain JSON form of the sections (without ``review``), the theory's wall-clock seconds
    joined to ``timings``; a theory section's JSON form is computed once per :class:`TheorySections`
    (a sweep shares it across points; callers must not mutate it)."""
    memo: dict[str, Any] | None = theory.__dict__.get("_json_memo")
    if memo is None:
        memo = {}
        object.__setattr__(theory, "_json_memo", memo)
    timings.update(theory.timings)
    out: dict[str, Any] = {}
    for k, v in sec.items():
        key = str(k)
        if k == "review":
            continue
        if k in theory.sections and v is theory.sections[k]:
            if key not in memo:
                memo[key] = to_json(v)
            out[key] = memo[key]
        else:
            out[key] = to_json(v)
    return out


def review_json(review: vd.Review) -> dict[str, Any]:
    """The plain JSON form of a :class:`~kfcrit.analysis.verdict.Review`."""
    return {"decision": review.decision.value,
            "reasons": [{"check": r.check, "status": r.status.value, "detail": r.detail}
                        for r in review.reasons]}


NOT_DETECTABLE = ("not applicable: (C, A) is not detectable, so E[P_t] diverges for every "
                  "arrival probability (even p = 1)")


def not_detectable_upper() -> UpperBoundRecord:
    """The ``upper_bound`` section of an undetectable system: p_up is not defined (Sinopoli's
    Theorems 3–6 assume (A, C) detectable), so it is labelled instead of computed."""
    return UpperBoundRecord(value=None, interval=None, certified=False, status="not applicable",
                            method=None, certificate=None, warnings=[], tolerance=None,
                            reason=NOT_DETECTABLE)


def close_bracket(sections: dict[str, Any]) -> None:
    """If p_c has no closed form but the exact block lower bound and the *certified* upper end
    of p_up lie within the upper-bound tolerance, p_c is known to that width (Thm 3: p_c ≥ every
    block value; Sinopoli Thm 3: p_c ≤ p_up). Replace the typed ``critical_value`` accordingly
    (not exact)."""
    cv = sections.get("critical_value")
    blb = sections.get("block_lower_bound")
    ub = sections.get("upper_bound")
    if (cv is None or cv.value is not None or blb is None or blb.value is None or ub is None
            or not ub.certified):
        return
    hi = (ub.interval or [None, None])[1]
    tol = ub.tolerance or 1e-9
    if hi is not None and 0 <= hi - blb.value <= max(tol, 1e-12):
        sections["critical_value"] = replace(
            cv, value=blb.value, exact=False, expression=blb.expression,
            reason=(f"{cv.reason} The bracket closes: the block lower bound {blb.expression} "
                    f"(Mo–Sinopoli Thm 3) and the certified upper end {hi:.12g} of p_up "
                    f"(Sinopoli Thm 3) differ by at most {tol:g}.").strip())


def _bounds_sections(spec: SystemSpec, sec: dict[str, Any], warnings: list[str],
                     timings: dict[str, float], *, curves: bool = True, quick: bool = False,
                     upper: Any = None) -> None:
    """Covariance bounds at the operating point; with ``curves`` also the static gains and the
    phase-transition curves tr S̄(p), tr V̄(p)."""
    import numpy as np

    from kfcrit.theory.covariance import bounds

    s = spec.system
    markers = Markers(p_low=section_value(sec, "lower_bound"),
                      p_c=section_value(sec, "critical_value"),
                      p_up=section_value(sec, "upper_bound"),
                      operating=(float(spec.channel.arrival_probability)
                                 if spec.channel is not None else None))
    if classification_of(sec) == "not-detectable":
        p = markers.operating
        if p is not None:
            sec["covariance_bounds"] = not_detectable_bounds(s, p)
            sec["static_gain"] = StaticGain(
                p=p, kalman=StaticGainEstimate(available=False, reason=NOT_DETECTABLE),
                best=BestStaticGain(available=False, reason=NOT_DETECTABLE), p_up=None,
                p_up_interval=None)
        if not curves:
            return
        grid = bounds.phase_grid(markers.p_low or 0.0, None, bounds.phase_points(s.n))
        lower = [bounds.lower_covariance(s.a, s.q, float(p)) for p in grid]
        sec["phase_transition"] = PhaseTransition(
            p=[float(v) for v in grid],
            trace_lower=[None if S is None else float(np.trace(S)) for S in lower],
            trace_upper=[None] * len(grid), markers=markers,
            warnings=[f"V̄ {NOT_DETECTABLE}"])
        return
    from kfcrit.theory.covariance.riccati import single_blas_thread

    try:  # these recompute p_up: a solver failure there is the upper section's "undetermined"
        with single_blas_thread():
            pt = _bounds_and_curves(spec, s, sec, markers, warnings, curves, quick, upper)
    except (np.linalg.LinAlgError, ArithmeticError, ValueError, RuntimeError) as exc:
        warnings.append("covariance bounds and phase transition not computed: numerical "
                        f"failure ({type(exc).__name__}: {str(exc)[:120]})")
        return
    if pt is None:
        return
    sec["phase_transition"] = pt
    if pt.limits and pt.limits.stopped:
        warnings.append(f"phase-transition curve incomplete: {pt.limits.stopped}")


IID_COMPARISON = ("an i.i.d. comparison only: S̄ and V̄ are the bounds of i.i.d. losses at the "
                  "stationary arrival probability and do not bound lim E[P_t] for this channel "
                  "with memory (whether they exist says nothing of its mean stability; the "
                  "Markov-jump bounds of a Gilbert–Elliott chain do bound it, theory §10)")
"""``covariance_bounds.reason`` for a channel that is not i.i.d. (``applicable`` False)."""


def not_detectable_bounds(s: System, p: float) -> CovarianceBounds:
    """The covariance bounds of an undetectable system at ``p``: the Lyapunov lower bound S̄
    (theory §3) and no V̄ (E[P_t] diverges for every p)."""
    from kfcrit.theory.covariance import bounds

    lower = bounds.covariance_summary(bounds.lower_covariance(s.a, s.q, p))
    upper = replace(bounds.covariance_summary(None), residual=None, method=NOT_DETECTABLE,
                    iterations=0)
    return CovarianceBounds(p=p, lower=lower, upper=upper, ordered=None, applicable=False,
                            reason=NOT_DETECTABLE)


def _bounds_and_curves(spec: SystemSpec, s: System, sec: dict[str, Any], markers: Markers,
                       warnings: list[str], curves: bool, quick: bool,
                       upper: Any) -> PhaseTransition | None:
    """Covariance bounds at the operating point (and static gains) into ``sec``; the
    phase-transition curve returned (None without ``curves``)."""
    from kfcrit.theory.covariance import bounds

    if markers.operating is not None:
        cb = bounds.covariance_bounds_record(s, markers.operating, upper=upper)
        if spec.channel is not None and spec.channel.model == "gilbert-elliott":
            from kfcrit.theory.links.burstcov import markov_jump_bounds
            from kfcrit.theory.links.markov import burst_necessary

            ge = spec.channel
            cb = replace(cb, markov_jump=markov_jump_bounds(
                s, float(ge.failure_rate), float(ge.recovery_rate),
                necessary_holds=burst_necessary(s, ge.recovery_rate).holds).record())
        cb = replace(cb, lower=_lower_exists_exactly(cb.lower, spec.channel, sec),
                     upper=_upper_exists_exactly(cb.upper, spec.channel, sec))
        if spec.channel is not None and not spec.channel.iid:
            cb = replace(cb, applicable=False, reason=IID_COMPARISON)
        sec["covariance_bounds"] = cb
        warnings.extend(cb.warnings or [])
        if curves:
            sec["static_gain"] = bounds.static_gain(s, markers.operating, upper=upper)
    if not curves:
        return None
    if quick and s.n > bounds.LARGE_STATES:   # iteration budgets, stated in the curve
        return bounds.phase_transition(s, markers, points=bounds.LARGE_QUICK_PHASE_POINTS,
                                       time_budget=QUICK_PHASE_SECONDS, upper=upper,
                                       iteration_budget=bounds.LARGE_QUICK_PHASE_ITERATIONS)
    if quick and s.n > 20:
        return bounds.phase_transition(s, markers, points=40, time_budget=QUICK_PHASE_SECONDS,
                                       upper=upper)
    return bounds.phase_transition(s, markers, upper=upper)


def _lower_exists_exactly(lower: CovarianceSummary, channel: Any,
                          sec: dict[str, Any]) -> CovarianceSummary:
    r"""S̄ exists iff p > p_low (Sinopoli Thm 3, 4), decided on the exact p and p_low: a
    float p that rounds onto p_low (p = 9/25 + 10⁻⁴⁰) finds no bounded S̄ in float64, yet S̄
    exists, beyond float64.

    .. math::  \exists\,\bar S \iff p > p_{low} = 1 - 1/\rho(A)^2
    """
    from kfcrit.theory.covariance.bounds import lower_exists_exactly

    if channel is None or not channel.iid:
        return lower
    return lower_exists_exactly(lower, channel.arrival_probability,
                                getattr(sec.get("lower_bound"), "expression", None))


def _upper_exists_exactly(upper: CovarianceSummary, channel: Any,
                          sec: dict[str, Any]) -> CovarianceSummary:
    r"""V̄ exists for p > p_up (Sinopoli Thm 5, 6), decided on the exact p where p_up is
    known exactly (``method`` "exact": C invertible or p_up = p_low proven): a float p that
    rounds onto p_up finds no V̄ in float64, yet it exists, beyond float64.

    .. math::  p > p_{up} \Rightarrow \exists\,\bar V = g_p(\bar V)
    """
    ub = sec.get("upper_bound")
    if upper.exists is not False or channel is None or not channel.iid \
            or getattr(ub, "method", None) != "exact":
        return upper
    expr = getattr(getattr(ub, "lower_evidence", None), "expression", None)
    if expr is None or not vd.exceeds(channel.arrival_probability, expr):
        return upper
    return replace(upper, exists=True, beyond_float64=True,
                   method="none in float64: p > p_up exactly, but p rounds onto p_up")


def _simulation_sections(spec: SystemSpec, opts: AnalysisOptions, sec: dict[str, Any],
                         warnings: list[str], timings: dict[str, float],
                         estimator: OperatingPoint | None = None) -> None:
    from kfcrit.theory.covariance import invariant

    inv = invariant.invariant_section(spec.system)
    sec["invariant"] = inv
    warnings.extend((inv.warnings or []) if inv is not None else [])
    if not opts.simulate:
        sec["simulation"] = Simulation(skipped=True,
                                       reason="simulation disabled (--no-simulate)")
        return
    from time import perf_counter

    from kfcrit.sim.montecarlo import simulation_section

    pc = section_value(sec, "critical_value")
    robust = section_value(sec, "robust_critical_value")
    op = sec.get("operating_point")
    bracket = None if spec.network is not None or op is None else op.bracket
    if pc is not None and robust is not None and robust > pc:
        # a system within the tolerance is worse: judge the mean's existence conservatively
        pc, bracket = None, [pc, robust]
    t0 = perf_counter()
    sim = simulation_section(
        spec, critical_value=pc, upper_bound=section_value(sec, "upper_bound"),
        seed=opts.seed, quick=opts.quick,
        critical_bracket=tuple(bracket) if bracket and None not in bracket else None,
        mean_decision=_mean_decision(estimator))
    timings["simulation.runtime_seconds"] = perf_counter() - t0
    sec["simulation"] = sim
    warnings.extend(sim.warnings)


def _mean_decision(estimator: OperatingPoint | None) -> tuple[bool | None, str] | None:
    """(exists, basis) of E[P_t] at the operating point as the estimator's verdict decides
    it (exists None when the verdict is undetermined), or None without an operating point."""
    if estimator is None:
        return None
    return vd.mean_bounded(estimator.verdict), estimator.basis


def _link_sections(spec: SystemSpec, opts: AnalysisOptions, sec: dict[str, Any],
                   warnings: list[str], theory: TheorySections,
                   timings: dict[str, float]) -> None:
    ch = spec.channel
    if ch is None or ch.model not in ("link-budget", "gilbert-elliott"):
        return
    from kfcrit.analysis.bursty import bursty_link_section
    from kfcrit.link.budgetsection import link_budget_record

    if ch.model == "gilbert-elliott":
        sec["link_budget"] = bursty_link_section(spec, opts, theory, ch, timings)
        return
    blb = section_value(sec, "block_lower_bound")
    low = blb if blb is not None else section_value(sec, "lower_bound")
    bracket = (None, None) if section_value(sec, "critical_value") is not None or \
        classification_of(sec) in ("stable", "not-detectable") else \
        (low if low is not None else 0.0, section_value(sec, "upper_bound"))
    lb = link_budget_record(
        ch, critical_value=section_value(sec, "critical_value"),
        robust_value=section_value(sec, "robust_critical_value"),
        bracket=bracket, upper_bound=section_value(sec, "upper_bound"),
        accuracy=sec.get("design"))
    typed: dict[str, Any] = {}
    if opts.details:
        typed["curves"] = link_curves(ch, sec, spec, lb.required_sinr_db)
    ge = bursty_channel(ch)
    if ge is not None:
        typed["bursty"] = bursty_link_section(spec, opts, theory, ge, timings,
                                              "link_budget.bursty")
    lb = replace(lb, **typed)
    sec["link_budget"] = lb
    warnings.extend(lb.warnings or [])


def _design_sections(spec: SystemSpec, theory: TheorySections, sec: dict[str, Any],
                     warnings: list[str], timings: dict[str, float]) -> None:
    """The accuracy requirement turned into a required arrival probability [p_S, p_V] (theory
    §11) and, for a link budget, into the radio: distance, transmit power, payload, retries."""
    level = getattr(spec.requirements, "max_mean_error_trace", None)
    if level is None or classification_of(sec) == "not-detectable":
        return
    from kfcrit.theory.covariance.design import required_arrival

    req = required_arrival(spec.system, level, structure=theory.structure).record()
    radio: Any = ABSENT
    ch = spec.channel
    if ch is not None and ch.model == "link-budget" and req.status == "interval":
        from kfcrit.link.design import link_design

        p_s, p_v = req.interval
        try:
            radio = link_design(ch, p_s, p_v).record()
        except (ValueError, ArithmeticError) as exc:
            warnings.append(f"link design for the accuracy requirement not computed: {exc}")
    sec["design"] = AccuracyDesign(requirement=f"lim E[tr P] ≤ {level:g}",
                                   required_arrival_probability=req, radio=radio)


def _tail_section(spec: SystemSpec, theory: TheorySections, sec: dict[str, Any],
                  timings: dict[str, float]) -> None:
    """The power-law tail exponent of tr P at the operating point (a labelled claim)."""
    if spec.channel is None or not spec.channel.iid or spec.channel.model == "trace":
        return
    from kfcrit.theory.covariance.tails import tail_exponent

    sec["tail"] = TailSection(exponent=tail_exponent(
        spec.system, spec.channel.arrival_probability,
        classification=theory.classification, structure=theory.structure))


@functools.lru_cache(maxsize=1)
def _versions() -> tuple[tuple[str, str | None], ...]:
    """Package versions, read once per process (reading package metadata costs milliseconds,
    and it cannot change while the process runs)."""
    import importlib.metadata as md

    versions: list[tuple[str, str | None]] = [("kfcrit", __version__),
                                              ("python", platform.python_version())]
    for pkg in ("numpy", "scipy", "sympy", "cvxpy", "clarabel", "python-flint", "matplotlib",
                "jinja2"):
        try:
            versions.append((pkg, md.version(pkg)))
        except md.PackageNotFoundError:
            versions.append((pkg, None))
    return tuple(versions)


def provenance(spec: SystemSpec, opts: AnalysisOptions) -> Provenance:
    """Versions, seed, options and the input file's SHA-256 (for the verification appendix)."""
    return Provenance(versions=dict(_versions()), seed=opts.seed, input_path=spec.path,
                      input_sha256=spec.sha256, options=AnalysisOptionsRecord(**opts.__dict__))


exit_code = vd.exit_code
"""The documented exit code of a record's JSON form (:func:`kfcrit.analysis.verdict.exit_code`)."""
