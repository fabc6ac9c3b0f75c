"""The ``loop`` section of a system file with a closed loop (theory §12).

:func:`loop_analysis` reads the facts of :mod:`kfcrit.theory.loop` at the operating point of the
two links — the sensing link (the file's ``channel``) and the actuation link (``loop.channel``):

* the TCP-like optimal loop (acknowledged, ``zero``, no gains given, i.i.d. links): γ_c (the
  record's p_c of (A, C)), ν_c = p_up(A', B') (exact where a theorem or the single-input
  identity gives it), S and L of the control MARE and the cost J with its bounds;
* any other loop (UDP-like, ``hold``, Gilbert–Elliott or traced links, or the file's own K
  and L; defaults: steady-state Kalman and LQR gains) as a fixed linear design: the exact
  mean-square stability test ρ(Σ π_m Φ_m ⊗ Φ_m) < 1 and the Lyapunov cost;

then the critical curve in the (γ̄, ν̄) plane, the TCP-like/UDP-like comparison, the cost against
each link's arrival probability, a seeded closed-loop Monte Carlo and the actuation link budget.
The verdict words come from :mod:`kfcrit.analysis.verdict` only.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import sympy as sp

from kfcrit.analysis import verdict as vd
from kfcrit.analysis.loop.designs import (
    LoopPoint,
    TcpParts,
    comparison_rows,
    cost_curves,
    cost_summary,
    fixed_curve,
    loss_link,
    optional_float,
    tcp_cost_at,
    tcp_rectangle,
)
from kfcrit.analysis.loop.schema import (
    LoopCostCurve,
    LoopCostSummary,
    LoopCurve,
    LoopDesignRow,
    LoopGains,
    LoopLinkCheck,
    LoopSection,
    LoopSimulationSummary,
    LoopStability,
    LoopThreshold,
)
from kfcrit.io.systemfile import SystemSpec
from kfcrit.model.system import to_float
from kfcrit.records.contract import RequirementAssessment
from kfcrit.records.link import DesignCheck
from kfcrit.theory.facts import StabilityFacts
from kfcrit.theory.loop.fixed import fixed_loop
from kfcrit.theory.loop.stack import FixedDesign, fixed_design
from kfcrit.theory.loop.thresholds import LoopThresholdFact, actuation_threshold

SIM_PATHS, SIM_STEPS = 1000, 1500
"""Closed-loop Monte Carlo size of ``kfcrit analyze`` (``--quick``: a third of each)."""


@dataclass(frozen=True)
class LoopDetails:
    """The parts of the ``loop`` section computed only with details: the TCP-like/UDP-like
    comparison, the other design's curve, the cost curves and the closed-loop Monte Carlo."""

    comparison: list[LoopDesignRow]
    alternative_curve: LoopCurve | None
    cost_curves: list[LoopCostCurve]
    simulation: LoopSimulationSummary | None


def loop_threshold(th: LoopThresholdFact) -> LoopThreshold:
    """A threshold fact of :mod:`kfcrit.theory.loop.thresholds` as the record's threshold."""
    return LoopThreshold(value=optional_float(th.value), expression=th.expression,
                         exact=bool(th.exact),
                         interval=None if th.interval is None else [float(x) for x in
                                                                    th.interval],
                         basis=th.basis, certified=bool(th.certified), reason=th.reason)


def sensing_critical(sec: dict[str, Any]) -> LoopThreshold:
    r"""γ_c of the TCP-like loop: the record's p_c of (A, C) (theory §3–§4), or its bracket
    [block lower bound, p_up].

    .. math:: \gamma_c = p_c(A, C)
    """
    cls = sec["classification"].value if sec.get("classification") is not None else None
    cv = sec.get("critical_value")
    if cls == "not-detectable":
        return LoopThreshold(value=None, expression=None, exact=False, interval=None,
                             basis="none", certified=True, reason="(C, A) is not detectable")
    if cls == "stable":
        return LoopThreshold(value=0.0, expression="0", exact=True, interval=[0.0, 0.0],
                             basis="theorem", certified=True, reason="ρ(A) < 1")
    if cv is not None and cv.value is not None:
        v = float(cv.value)
        return LoopThreshold(value=v, expression=cv.expression if cv.exact else None,
                             exact=bool(cv.exact), interval=[v, v],
                             basis="theorem" if cv.exact else "numerical",
                             certified=bool(cv.exact), reason=cv.reason or "")
    ub = sec.get("upper_bound")
    blb, low = sec.get("block_lower_bound"), sec.get("lower_bound")
    lo = blb.value if blb is not None else None
    lo = lo if lo is not None else (low.value if low is not None else None) or 0.0
    hi = ((ub.interval or [None, ub.value])[1]) if ub is not None else None
    return LoopThreshold(
        value=None, expression=None, exact=False,
        interval=[float(lo), float(hi)] if hi is not None else None,
        basis="certified-interval" if ub is not None and ub.certified else "numerical",
        certified=bool(ub is not None and ub.certified),
        reason="no closed form: [block lower bound, p_up(A, C)]")


def threshold_below(p: Any, th: LoopThreshold, expression: Any = None) -> bool | None:
    r"""Whether threshold < p is proven (True), threshold ≥ p is (False), or neither (None),
    compared exactly (:func:`kfcrit.analysis.verdict.exceeds`).

    .. math:: [\,p > \theta\,] \text{ with } \theta \text{ exact, or against } [\theta_-, \theta_+]
    """
    if expression is not None:
        return bool(vd.exceeds(p, expression))
    if th.interval is None:
        return False          # no finite threshold: an unstable mode is unreachable/unseen
    lo, hi = th.interval
    if vd.exceeds(p, hi):
        return True
    if not vd.exceeds(p, lo):
        return False
    return None


def _exact_threshold(th: LoopThreshold) -> Any:
    """The exact threshold when a theorem gives it (a claim decides by its interval)."""
    if not th.exact or th.basis != "theorem" or th.expression is None:
        return None
    from kfcrit.model.exprparse import parse_expression

    return parse_expression(str(th.expression).replace("**", "^"), "threshold")


def tcp_facts(gamma: Any, nu: Any, sens: LoopThreshold, act: LoopThreshold) -> StabilityFacts:
    """The TCP-like loop's facts: finite cost iff γ̄ > γ_c and ν̄ > ν_c (theory §12)."""
    below = [threshold_below(gamma, sens, _exact_threshold(sens)),
             threshold_below(nu, act, _exact_threshold(act))]
    names = ("γ̄ > γ_c", "ν̄ > ν_c")
    failed = [n.replace(">", "≤") for n, b in zip(names, below) if b is False]
    if failed:
        return StabilityFacts(False, False, True, f"{' and '.join(failed)}: the TCP-like "
                              "cost is infinite (theory §12)")
    if all(b is True for b in below):
        return StabilityFacts(True, True, True, "", "γ̄ > γ_c and ν̄ > ν_c (theory §12)")
    open_ = [n for n, b in zip(names, below) if b is None]
    return StabilityFacts(True, False, False, f"{', '.join(open_)} undecided: the arrival "
                          "probability lies inside the threshold's interval")


def tcp_finite(facts: StabilityFacts) -> bool | None:
    """The fact "γ̄ > γ_c and ν̄ > ν_c": True, False, or undecided (None)."""
    if facts.necessary is False:
        return False
    return True if facts.sufficient else None


def fixed_facts(stability: Any) -> StabilityFacts:
    """A fixed design's facts: ρ(Σ π_m Φ_m ⊗ Φ_m) < 1 is necessary and sufficient."""
    text = f"ρ = {stability.rho:.6g}: {stability.status} ({stability.method})"
    if stability.holds is False:
        return StabilityFacts(False, False, True, text)
    if stability.holds is True:
        return StabilityFacts(True, True, True, text, text)
    return StabilityFacts(True, False, False, text)


def _floats(M: Any) -> np.ndarray:
    return to_float(M) if isinstance(M, sp.MatrixBase) else np.asarray(M, dtype=float)


def plant(spec: SystemSpec) -> dict[str, np.ndarray]:
    """Float matrices of the loop: A, B, C, Q, R, W, U."""
    s, lp = spec.system, spec.loop
    return {"A": s.a, "B": _floats(lp.B), "C": s.c, "Q": s.q, "R": s.r, "W": _floats(lp.W),
            "U": _floats(lp.U)}


def judged_design(spec: SystemSpec, acked: bool | None = None) -> FixedDesign:
    """The fixed design of the file (its K and L, else steady-state Kalman and LQR gains)."""
    lp = spec.loop
    m = plant(spec)
    K = None if lp.estimator_gain is None else _floats(lp.estimator_gain)
    L = None if lp.controller_gain is None else _floats(lp.controller_gain)
    return fixed_design(m["A"], m["B"], m["C"], m["Q"], m["R"], m["W"], m["U"], K=K, L=L,
                        acked=lp.acknowledged if acked is None else acked,
                        on_loss=lp.on_loss)


def is_tcp_optimal(spec: SystemSpec) -> bool:
    """The optimal TCP-like loop applies: acknowledged, zero on loss, no fixed gains, and
    i.i.d. (Bernoulli-type) links on both sides (theory §12)."""
    lp = spec.loop
    return (lp.acknowledged and lp.on_loss == "zero" and not lp.fixed
            and all(ch.iid and ch.model != "trace" for ch in (spec.channel, lp.channel)))


def loop_analysis(spec: SystemSpec, opts: Any, sec: dict[str, Any], warnings: list[str]
                  ) -> tuple[LoopSection, list[vd.Reason], RequirementAssessment | None]:
    """The ``loop`` section, the review's loop reasons and the cost requirement's assessment.

    Also sets ``operating_point.verdict`` to the rule of
    :func:`kfcrit.analysis.verdict.loop_operating_verdict` (estimator AND loop). The judged
    design's facts make a :class:`~kfcrit.analysis.loop.designs.LoopPoint` that the designs,
    curves and Monte Carlo of :mod:`kfcrit.analysis.loop.designs` read; :func:`loop_record`
    builds the section from the parts.
    """
    lp = spec.loop
    m = plant(spec)
    gamma_x, nu_x = spec.channel.arrival_probability, lp.channel.arrival_probability
    gamma, nu = float(gamma_x), float(nu_x)
    s_link, s_note = loss_link(spec.channel)
    a_link, a_note = loss_link(lp.channel)
    notes = [n for n in (s_note, a_note) if n]
    sens = sensing_critical(sec)
    act = loop_threshold(actuation_threshold(spec.system.A, lp.B, lp.W, lp.U,
                                             tol=max(opts.upper_tol, 1e-9)))
    design = None
    tcp_parts: TcpParts | None = None
    stability, gains, control_gain, critical_curve = None, None, None, None
    if is_tcp_optimal(spec):
        facts = tcp_facts(gamma_x, nu_x, sens, act)
        tcp_parts = tcp_cost_at(m, spec.system, gamma, nu, finite=tcp_finite(facts),
                                seed=opts.seed, quick=opts.quick or not opts.details)
        point = LoopPoint("tcp-optimal", gamma, nu, sens, act, cost_summary(tcp_parts.cost))
        control_gain = tcp_parts.L
        critical_curve = tcp_rectangle(sens, act)
    else:
        try:
            design = judged_design(spec)
        except (ValueError, np.linalg.LinAlgError) as exc:
            return _no_design(spec, sec, exc, sens, act, notes, warnings)
        res = fixed_loop(design, s_link, a_link)
        facts = fixed_facts(res.stability)
        rho = float(res.stability.rho)
        stability = LoopStability(
            status=res.stability.status,
            holds=None if res.stability.holds is None else bool(res.stability.holds),
            spectral_radius=rho, method=res.stability.method,
            dimension=int(res.stability.dimension))
        point = LoopPoint("fixed", gamma, nu, sens, act, cost_summary(res.cost), rho)
        gains = LoopGains(estimator_gain=design.K.tolist(), controller_gain=design.L.tolist(),
                          source="the file's estimator_gain and controller_gain" if lp.fixed
                          else "steady-state Kalman gain and LQR gain (defaults)")
        notes.append("the fixed design's matrices are judged as binary floats (each taken as "
                     "the rational it is)")
        if opts.details:
            critical_curve = fixed_curve(design, "this design", quick=opts.quick)
    if _trace_link(spec):
        facts = StabilityFacts(True, False, False, "measured trace: the theorems are about "
                               "arrival models; the loop is judged at the empirical rate for "
                               "information only")
    verdict, basis = vd.loop_verdict(facts)
    if verdict is vd.LoopVerdict.UNDETERMINED and facts.necessary_basis:
        basis = facts.necessary_basis
    details = (_details(spec, opts, point, design, tcp_parts, s_link, a_link, m, warnings)
               if opts.details else None)
    link, check = actuation_link(spec, point, design, details.comparison if details else [],
                                 warnings)
    joint = _join_operating_point(sec, verdict, basis)
    section = loop_record(spec, point, verdict, basis, joint, notes, stability=stability,
                          gains=gains, control_gain=control_gain,
                          critical_curve=critical_curve, details=details,
                          actuation_link=link)
    return section, vd.loop_reasons(verdict, basis, check), cost_assessment(spec, point.cost)


def _join_operating_point(sec: dict[str, Any], verdict: vd.LoopVerdict, basis: str
                          ) -> vd.Verdict:
    """Set ``operating_point`` to the estimator's verdict AND the loop's; return the joint
    verdict (:func:`kfcrit.analysis.verdict.loop_operating_verdict`)."""
    op = sec["operating_point"]
    joint, why = vd.loop_operating_verdict((op.verdict, op.basis or ""), (verdict, basis))
    sec["operating_point"] = replace(op, verdict=joint, basis=why)
    return joint


def loop_record(spec: SystemSpec, point: LoopPoint, verdict: vd.LoopVerdict, basis: str,
                operating_verdict: vd.Verdict, notes: list[str], *,
                stability: LoopStability | None = None, gains: LoopGains | None = None,
                control_gain: list[list[float]] | None = None,
                critical_curve: LoopCurve | None = None, details: LoopDetails | None = None,
                actuation_link: LoopLinkCheck | None = None) -> LoopSection:
    """The ``loop`` section, field by field, from the operating point of the judged design and
    the parts computed beside it (None or empty where not computed)."""
    lp = spec.loop
    return LoopSection(
        acknowledged=bool(lp.acknowledged), on_loss=lp.on_loss, design=point.design,
        sensing_arrival_probability=point.gamma, actuation_arrival_probability=point.nu,
        sensing_iid=bool(spec.channel.iid), actuation_iid=bool(lp.channel.iid),
        actuation_model=lp.channel.model,
        sensing_critical=point.sensing, actuation_critical=point.actuation,
        verdict=verdict, basis=basis, operating_verdict=operating_verdict,
        spectral_radius=optional_float(point.spectral_radius), stability=stability,
        cost=point.cost, critical_curve=critical_curve,
        alternative_curve=details.alternative_curve if details is not None else None,
        comparison=list(details.comparison) if details is not None else [],
        cost_curves=list(details.cost_curves) if details is not None else [],
        simulation=details.simulation if details is not None else None,
        actuation_link=actuation_link, gains=gains, control_gain=control_gain,
        notes=list(notes))


def _trace_link(spec: SystemSpec) -> bool:
    return "trace" in (spec.channel.model, spec.loop.channel.model)


def _no_design(spec: SystemSpec, sec: dict[str, Any], exc: Exception, sens: LoopThreshold,
               act: LoopThreshold, notes: list[str], warnings: list[str]
               ) -> tuple[LoopSection, list[vd.Reason], RequirementAssessment | None]:
    """No default gains exist (a Riccati equation has no stabilising solution): the loop is
    mean-square unstable when (A, B) is not stabilisable (ν_c does not exist), else
    undetermined."""
    warnings.append(f"closed loop: the default design could not be formed ({exc})")
    unstab = act.basis == "none"
    facts = StabilityFacts(False, False, True, "(A, B) is not stabilisable: no controller "
                           "bounds the state") if unstab else StabilityFacts(
        True, False, False, f"no default design: {exc}")
    verdict, basis = vd.loop_verdict(facts)
    if not unstab:
        basis = facts.necessary_basis
    cost = LoopCostSummary(value=None, lower=None, upper=None,
                           finite=False if unstab else None, method="none", error=None,
                           reason=str(exc))
    point = LoopPoint("fixed", float(spec.channel.arrival_probability),
                      float(spec.loop.channel.arrival_probability), sens, act, cost)
    joint = _join_operating_point(sec, verdict, basis)
    return (loop_record(spec, point, verdict, basis, joint, notes),
            vd.loop_reasons(verdict, basis, None), cost_assessment(spec, cost))


def _details(spec: SystemSpec, opts: Any, point: LoopPoint, design: FixedDesign | None,
             tcp_parts: TcpParts | None, s_link: Any, a_link: Any,
             m: dict[str, np.ndarray], warnings: list[str]) -> LoopDetails:
    """The comparison, the cost curves, the other design's curve and the Monte Carlo (what
    was computed before a failure is kept, with a warning)."""
    rows: list[LoopDesignRow] = []
    alternative: LoopCurve | None = None
    curves: list[LoopCostCurve] = []
    try:
        finite = tcp_finite(tcp_facts(spec.channel.arrival_probability,
                                      spec.loop.channel.arrival_probability,
                                      point.sensing, point.actuation))
        rows, udp = comparison_rows(spec, m, point, design, tcp_parts, s_link, a_link,
                                    judged_design, tcp_finite=finite, quick=opts.quick,
                                    seed=opts.seed)
        if point.design == "tcp-optimal" and udp is not None:
            alternative = fixed_curve(udp, "UDP-like (Kalman + LQR)", quick=opts.quick)
        elif spec.loop.on_loss == "zero":
            alternative = tcp_rectangle(point.sensing, point.actuation)
        curves = cost_curves(spec, m, point, design, tcp_parts, udp, quick=opts.quick,
                             seed=opts.seed)
    except (ValueError, np.linalg.LinAlgError, ArithmeticError) as exc:
        warnings.append(f"closed loop: comparison or cost curves not computed ({exc})")
    simulation = None
    if opts.simulate:
        from kfcrit.analysis.loop.designs import loop_monte_carlo

        simulation = loop_monte_carlo(point, design, m, s_link, a_link, seed=opts.seed,
                                      quick=opts.quick,
                                      L=tcp_parts.L if tcp_parts is not None else None)
    return LoopDetails(rows, alternative, curves, simulation)


def actuation_link(spec: SystemSpec, point: LoopPoint, design: FixedDesign | None,
                   comparison: list[LoopDesignRow], warnings: list[str]
                   ) -> tuple[LoopLinkCheck | None, DesignCheck | None]:
    """The actuation link budget against its margin policy, read against the arrival
    probability the loop needs there: ν_c (TCP-like) or the design's critical ν̄ at the
    operating γ̄ (the upper end of its bracket, from the ``comparison`` row of this design)."""
    ch = spec.loop.channel
    from kfcrit.link.budgetsection import link_budget_record
    from kfcrit.link.linkbudget import LinkBudget

    if ch.model != "link-budget" or not isinstance(ch, LinkBudget):
        return None, None
    need, bracket, basis = _required_nu(point, design, comparison)
    try:
        lb = link_budget_record(ch, critical_value=need, robust_value=None, bracket=bracket,
                                upper_bound=None)
    except (ValueError, ArithmeticError) as exc:
        warnings.append(f"actuation link budget not computed: {exc}")
        return None, None
    check = lb.design_check
    if not check:
        return None, None
    summary = LoopLinkCheck(
        required_arrival_probability=lb.required_arrival_probability.design_value,
        required_basis=basis, arrival_probability=point.nu,
        link_margin_db=check.link_margin_db, required_margin_db=check.required_margin_db,
        margin_policy_met=check.margin_policy_met, distance_m=check.distance_m,
        max_distance_m=check.max_distance_m, outage_probability=check.outage_probability,
        max_outage=check.max_outage, outage_within_policy=check.outage_within_policy,
        sinr_db=lb.link.sinr_db, radio=lb.radio.model)
    return summary, check


def _required_nu(point: LoopPoint, design: FixedDesign | None,
                 comparison: list[LoopDesignRow]
                 ) -> tuple[float | None, tuple[float | None, float | None], str]:
    if point.design == "tcp-optimal" or design is None:
        act = point.actuation
        if act.exact and act.value is not None:
            return act.value, (None, None), "ν_c of the TCP-like loop"
        iv = act.interval or [None, None]
        return None, (iv[0], iv[1]), "the bracket of ν_c"
    row = next((r for r in comparison if r.design == "this design"), None)
    iv = row.critical_nu_interval if row is not None else None
    if iv:
        return None, (iv[0], iv[1]), "the design's critical ν̄ at the operating γ̄"
    return None, (None, None), "the design's critical ν̄ (not found)"


def cost_assessment(spec: SystemSpec, c: LoopCostSummary) -> RequirementAssessment | None:
    r"""The cost requirement J ≤ max_cost: met when the upper bound (or the Monte Carlo value
    plus three standard errors) is within it, not met when the lower bound (or the value minus
    three standard errors) exceeds it or J is infinite, else not demonstrated.

    .. math:: J_{up} \le J_{max} \Rightarrow \text{met}, \qquad J_{low} > J_{max}
              \Rightarrow \text{not met}
    """
    limit = spec.requirements.max_cost
    if limit is None:
        return None
    value, lo, hi, err = c.value, c.lower, c.upper, c.error or 0.0
    name = f"closed-loop cost J ≤ {limit:g}"
    interval = [lo, hi] if lo is not None or hi is not None else None

    def assessed(status: str, basis: str) -> RequirementAssessment:
        return RequirementAssessment(name, status, basis, estimate=value, interval=interval)

    if c.finite is False:
        return assessed("not met", "J is infinite (the loop is not "
                "mean-square stable at the operating point)")
    if hi is not None and hi <= limit:
        return assessed("met", f"upper bound {hi:.6g} ≤ {limit:g}")
    if lo is not None and lo > limit:
        return assessed("not met", f"lower bound {lo:.6g} > {limit:g}")
    if value is not None and err and value + 3 * err <= limit:
        return assessed("met", f"J = {value:.6g} ± {err:.2g} (3 standard "
                f"errors within {limit:g})")
    if value is not None and value - 3 * err > limit:
        return assessed("not met", f"J = {value:.6g} > {limit:g}")
    return assessed("not demonstrated", "the cost's bounds straddle the "
            "limit" if value is not None else "the cost is not known")
