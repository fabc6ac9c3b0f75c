"""Terminal view of the analysis record (a pure function of the typed
:class:`~kfcrit.analysis.sections.AnalysisRecord`)."""
from __future__ import annotations

import re
from typing import Any

from kfcrit.analysis.sections import AnalysisRecord
from kfcrit.io.typed import ABSENT
from kfcrit.records.covariance import AccuracyDesign, CovarianceBounds
from kfcrit.records.link import LinkBudgetRecord
from kfcrit.records.network import NetworkSection
from kfcrit.views.formatting import counted
from kfcrit.views.mesh.meshtext import mesh_lines
from kfcrit.views.text.looptext import loop_lines
from kfcrit.views.text.netmargin import (
    NETWORK_P_MEANING,
    NO_CRITICAL_VALUE,
    bottleneck_margin_text,
    burst_margin_of,
    has_no_critical_value,
    margin_text,
)
from kfcrit.views.text.tracefit import channel_fit_lines

_DECIMAL = re.compile(r"-?\d+(\.\d+)?(e[-+]?\d+)?")
_LONG_DECIMAL = re.compile(r"\d\.\d{9,}")


def _num(v: Any, digits: int = 6) -> str:
    if v is None or v is ABSENT:
        return "—"
    if isinstance(v, float):
        return f"{v:.{digits}g}"
    return str(v)


def safe_text(text: Any) -> str:
    """Text from a user's file with control characters (ESC, CR, …) shown as ``\\xNN``, so
    that a crafted name cannot rewrite the terminal."""
    return "".join(c if c.isprintable() or c == " " else f"\\x{ord(c):02x}" for c in str(text))


EXACT_TEXT_MAX = 100
"""Longest exact expression the terminal view prints in full (``--json`` always has it all)."""


def _present(v: Any) -> bool:
    """Whether a typed field holds a value (not ``None``, not an absent optional key)."""
    return v is not None and v is not ABSENT


def _exact(expression: str | None) -> str:
    """``  (= expression)`` for a quantity with an exact form; long forms point to ``--json``."""
    expr = (expression or "").strip()
    if not expr or _DECIMAL.fullmatch(expr) or _LONG_DECIMAL.search(expr):
        return ""   # a decimal (or text holding one) is the value itself, not an exact form
    if "RootOf" in expr or len(expr) > EXACT_TEXT_MAX:
        return f"  (exact form of {len(expr)} characters: see --json)"
    return f"  (= {expr})"


REVIEW_MARK = {"pass": "PASS", "fail": "FAIL", "undetermined": "UNDETERMINED"}
STATUS_MARK = {"pass": "ok ", "fail": "FAIL", "undetermined": "?  ", "not applicable": "-  "}


def review_lines(rec: AnalysisRecord) -> list[str]:
    """The review decision and its reasons (the first thing a reader sees)."""
    review = rec.review
    lines = [f"  REVIEW: {REVIEW_MARK.get(review.decision.value, '—')}"]
    for r in review.reasons:
        lines.append(f"    [{STATUS_MARK.get(r.status.value, '?  ')}] {r.check}: "
                     f"{r.detail}")
    return lines


def _value_text(value: float | None, interval: list[float | None] | None, *,
                exact: bool = False, expression: str | None = None) -> str:
    """A value with its exact form, or its interval when only bracketed."""
    if value is not None:
        return f"{value:.6g}" + (f" (= {expression})" if exact and expression and
                                 len(expression) <= 30 else "")
    if interval:
        return f"in [{_num(interval[0])}, {_num(interval[1])}]"
    return "—"


def design_lines(design: AccuracyDesign | None) -> list[str]:
    """The accuracy requirement as a required arrival probability, and what it asks of the
    radio (theory §11)."""
    if not _present(design):
        return []
    req = design.required_arrival_probability
    lines = [f"  accuracy requirement  {design.requirement}"]
    if req.status == "interval":
        lo, hi = req.interval
        lines.append(f"  required arrival p    [{_num(lo)}, {_num(hi)}]  (p ≤ p_S fails, "
                     "p ≥ p_V meets it)")
    else:
        lines.append(f"  required arrival p    {req.status}: {req.reason or ''}")
    radio = design.radio
    bounds = ((("max_distance_m", radio.max_distance_m), ("min_tx_power_dbm", radio.min_tx_power_dbm),
               ("max_payload_bytes", radio.max_payload_bytes),
               ("retries_needed", radio.retries_needed)) if _present(radio) else ())
    for key, bound in bounds:
        unit = bound.unit or ""
        ends = []
        for b, what in ((bound.sufficient, "meets it"), (bound.necessary, "beyond it fails")):
            text = {"unbounded": "no limit", "unreachable": "unreachable",
                    "phy-limit": f"{_num(b.value)} {unit} (the PHY's limit)"}.get(
                b.status, f"{_num(b.value)} {unit}")
            ends.append(f"{text} {what}")
        lines.append(f"    {bound.quantity or key:<19} {bound.sense}: " + "; ".join(ends))
    return lines


def network_lines(net: NetworkSection | None, bursty: bool = False) -> list[str]:
    """The sensor network: one row per node (arrival probability, critical value, margin,
    verdict with that link dead), the uniform margin and the bottleneck link (``bursty``: one
    sensor on a Markov link, whose margin is r − r_nec, theory §10)."""
    if net is None or net is ABSENT:
        return []
    lines = ["  sensor network        " + f"{counted(len(net.sensors), 'sensor')}, verdict "
             f"{(net.verdict or '—').upper()}",
             f"    {'sensor':<12} {'p_i':>9}  {'critical p_i':<24} {'margin':>19}  N−1 (link dead)"]
    for s in net.sensors:
        cv = s.critical_value
        critical = (NO_CRITICAL_VALUE if has_no_critical_value(s) else
                    _value_text(cv.value, cv.interval, exact=cv.exact, expression=cv.expression))
        # the report's margin text (an interval when p_c,i is only bracketed): one rendering
        lines.append(f"    {safe_text(s.name)[:12]:<12} "
                     f"{_num(s.arrival_probability):>9}  "
                     f"{critical:<24} "
                     f"{margin_text(s):>19}  "
                     f"{s.n_minus_1.verdict}")
    um = net.uniform_margin
    delta = (f"unbounded ({um.unbounded})" if um.unbounded else
             _value_text(um.value, um.interval))
    lines.append(f"    margin r - r_nec      {delta}  (the link's recovery rate against the "
                 "burst condition's threshold)" if bursty else
                 f"    uniform margin δ      {delta}  (every link "
                 "degraded by δ reaches the boundary)")
    bn = net.bottleneck
    if bn.name:
        lines.append(f"    bottleneck link       {safe_text(bn.name)}  (margin "
                     f"{bottleneck_margin_text(bn)})")
    return lines


def summary(rec: AnalysisRecord) -> str:
    """A readable multi-line summary of an analysis record."""
    lines = [f"kfcrit analysis: {safe_text(rec.name)}"]
    lines.extend(review_lines(rec))
    sysd = rec.system
    lines.append(f"  states n = {sysd.n}, outputs m = {sysd.m}, "
                 f"input {'exact' if sysd.exact_input else 'floating-point'}")
    lines.append("  classification        "
                 + (rec.classification.value if rec.classification is not None else "—"))
    # a floating-point input's values are numerical even where decided on its binary rationals
    exact_input = sysd.exact_input is not False
    stacked = _present(rec.network) and len(rec.network.sensors) > 1
    if stacked:
        lines.append("  stacked system (all sensors on one link): p_c, p_low and p_up below; "
                     "each sensor's own critical value is in the network table")
    elif _present(rec.mesh):
        lines.append("  stacked system (all sensors on one link): p_c, p_low and p_up below; "
                     "the mesh is judged on its joint law of the received set (mesh section), "
                     "not by one p against this p_c")
    lines.extend(_critical_lines(rec, exact_input))
    lines.extend(_operating_lines(rec))
    lines.extend(channel_fit_lines(rec.channel_fit))
    lines.extend(network_lines(rec.network, _present(rec.network) and burst_margin_of(
        rec, rec.network)))
    lines.extend(mesh_lines(rec))
    lines.extend(loop_lines(rec.loop))
    lines.extend(design_lines(rec.design))
    lines.extend(_bounds_lines(rec))
    lines.extend(_simulation_lines(rec))
    lines.extend(_link_lines(rec))
    checks = rec.verification
    if checks:
        passed = sum(c.passed is True for c in checks)
        failed = [c.check for c in checks if c.passed is False]
        unsure = [c.check for c in checks if c.status == "inconclusive"]
        idle = sum(c.status == "not applicable" for c in checks)
        lines.append(f"  verification          {passed} of {len(checks) - idle} checks passed"
                     + (f" ({idle} not applicable)" if idle else "")
                     + (f"; inconclusive: {'; '.join(unsure)}" if unsure else "")
                     + (f"; FAILED: {'; '.join(failed)}" if failed else ""))
    for w in rec.warnings:
        lines.append(f"  warning: {w}")
    return "\n".join(lines)


def _critical_lines(rec: AnalysisRecord, exact_input: bool) -> list[str]:
    """p_c (with its reason), the robust critical value, p_low, the block bound and p_up."""
    cv = rec.critical_value
    value = cv.value if cv is not None else None
    exact = _exact(cv.expression) if cv is not None and cv.exact and exact_input else ""
    lines = [f"  critical value p_c    {_num(value, 12)}{exact}"]
    if cv is not None and cv.reason:
        lines.append(f"      {cv.reason}")
    rob = rec.robust_critical_value
    if rob is not None:
        lines.append(f"  robust critical value {_num(rob.value, 12)}  "
                     f"(tolerance {rob.tolerance})")
    lb = rec.lower_bound
    lines.append(f"  lower bound p_low     {_num(lb.value if lb is not None else None, 12)}"
                 f"{_exact(lb.expression) if lb is not None and exact_input else ''}")
    blb = rec.block_lower_bound
    if blb is not None:
        lines.append(f"  block lower bound     {_num(blb.value, 12)}"
                     f"{_exact(blb.expression) if exact_input else ''}")
    ub = rec.upper_bound
    if ub is not None and ub.status == "not applicable":
        lines.append(f"  upper bound p_up      {ub.reason or 'not applicable'}")
    elif ub is not None:
        iv = ub.interval or [None, None]
        lines.append(f"  upper bound p_up      {_num(ub.value, 12)}  in "
                     f"[{_num(iv[0], 12)}, {_num(iv[1], 12)}]"
                     f"{'  certified' if ub.certified else '  not certified'}")
    return lines


def _operating_lines(rec: AnalysisRecord) -> list[str]:
    """The operating point against p_c: p (or the bottleneck's), margins, bracket, verdict."""
    op = rec.operating_point
    if op is None:
        return []
    lines = []
    network = _present(rec.network) and _present(op.bottleneck)
    if network:
        lines.append(f"  bottleneck link p     {_num(op.arrival_probability, 12)}  "
                     f"({safe_text(op.bottleneck)})")
    else:
        lines.append(f"  operating point p     {_num(op.arrival_probability, 12)}")
    bursty = _present(op.recovery_threshold)
    if op.margin is not None:
        label = ("margin r - r_nec" if bursty else "uniform margin δ" if network
                 else "margin p - p_c")
        lines.append(f"  {label:<21} {op.margin:+.6g}")
        if _present(op.margin_to_sufficient):
            lines.append(f"  margin r - r_suf(f)   {op.margin_to_sufficient:+.6g}")
        if bursty and _present(op.iid_margin):
            lines.append(f"      (i.i.d. comparison p - p_c = {op.iid_margin:+.6g}: not "
                         "a margin for this channel)")
    if op.bracket and not (network and op.margin is not None):
        b = op.bracket
        label = "uniform margin δ in" if network else "bracket"
        lines.append(f"  {label:<21} [{_num(b[0])}, {_num(b[1])}]")
    verdict = op.verdict.value
    lines.append(f"  stability verdict     {verdict.upper()}")
    if op.reason:
        lines.append(f"      reason: {op.reason}")
    if op.iid_comparison_verdict and op.iid_comparison_verdict != verdict:
        lines.append(f"      (the i.i.d. comparison p vs p_c alone would say "
                     f"{op.iid_comparison_verdict})")
    if op.basis:
        lines.append(f"      basis: {op.basis}")
    if op.note:
        lines.append(f"      note: {op.note}")
    return lines


def _bounds_lines(rec: AnalysisRecord) -> list[str]:
    cb = rec.covariance_bounds
    if cb is None:
        return []
    lo, up = cb.lower, cb.upper
    if up.computed is False or str(up.method or "").startswith("not computed"):
        return _uncomputed_upper_lines(cb)
    s_text, v_text = (_num(lo.trace) if lo.exists else '∞'), (_num(up.trace) if up.exists else '∞')
    iid = rec.operating_point is None or rec.operating_point.iid is not False
    out = [f"  lim E[P] bounds at p   tr S̄ = {s_text} ≤ tr lim E[P] ≤ tr V̄ = {v_text}" if iid
           else f"  i.i.d. comparison      tr S̄ = {s_text}, tr V̄ = {v_text}"]
    if not iid:
        out.append("      (i.i.d. bounds at the stationary arrival probability: they do not "
                   "bound E[P] for this channel)")
    mj = cb.markov_jump
    if _present(mj):
        mlo, mup = mj.lower, mj.upper
        out.append(f"  lim E[P] bursty link   {_num(mlo.trace) if mlo.exists else '∞'}"
                   f" ≤ tr lim E[P] ≤ {_num(mup.trace) if mup.exists else '∞'}"
                   "  (Markov-jump bounds valid for this Gilbert–Elliott channel, theory §10)")
    if cb.applicable is False and cb.reason and rec.operating_point is not None \
            and rec.operating_point.iid is not False:
        out.append(f"      V̄ {cb.reason}")
    return out


def _uncomputed_upper_lines(cb: CovarianceBounds) -> list[str]:
    """Bounds of lim E[P] when V̄ was not computed (a sensor network): S̄ only, at the p the
    record states with its meaning, and V̄ "not computed", never ∞."""
    lo, up = cb.lower, cb.upper
    s_text = _num(lo.trace) if lo.exists else "∞"
    out = [f"  lim E[P] bounds       tr S̄ = {s_text} ≤ tr lim E[P]  at p = {_num(cb.p)}; "
           f"tr V̄ {safe_text(up.method or 'not computed')}"]
    meaning = NETWORK_P_MEANING if up.method == "not computed for a network" else None
    if meaning:
        out.append(f"      p = {_num(cb.p)} is {safe_text(meaning)}")
    return out


def _simulation_lines(rec: AnalysisRecord) -> list[str]:
    sim = rec.simulation
    net = sim.network if sim is not None else None
    if _present(net):
        if net.mean_exists is False:
            return [f"  simulated E[tr P_t]   diverges (network mean-unstable); sample mean "
                    f"{_num(net.sample_mean_trace)} is not an estimate"]
        mt = net.mean_trace
        mean, lower, upper = ((mt.mean, mt.lower, mt.upper) if _present(mt)
                              else (None, None, None))
        return [f"  simulated E[tr P_t]   {_num(mean)} at t = {net.steps} "
                f"(95% CI {_num(lower)} .. {_num(upper)}; "
                f"{net.paths} paths, each sensor over its own link)"]
    op = sim.operating_point if sim is not None else None
    if not _present(op):
        return []
    mt = op.mean_trace
    out = []
    if mt.diverges:
        smt = op.sample_mean_trace
        sample = ((smt.mean if _present(smt) else None) or [None])[-1]
        out.append(f"  simulated E[tr P_t]   diverges (the mean does not exist here); the sample "
                   f"mean {_num(sample)} at t = {op.steps} is not an estimate")
    elif mt.mean:
        out.append(f"  simulated E[tr P_t]   {_num(mt.mean[-1])} at t = {op.steps} "
                   f"({op.paths} paths, seed {op.seed})")
    ex = op.exceedance
    if ex is not None:
        label = f"P(tr P > {_num(ex.level)})"
        band = (f" (95% CI {_num(ex.lower, 4)} .. {_num(ex.upper, 4)})"
                if ex.lower is not None else "")
        out.append(f"  {label:<21} {_num(ex.estimate, 4)} at t = {op.steps}" + band)
    req = rec.requirements
    ass = req.assessment if req is not None else None
    if _present(ass) and ass.status:
        out.append(f"  requirement           {ass.status.upper()}: {ass.basis}")
    div = op.divergence
    if div.diverged_paths:
        out.append(f"  diverged paths        {div.diverged_paths} of {op.paths}")
    return out


def _yes_no(v: Any, yes: str = "met", no: str = "NOT met") -> str:
    return "—" if v is None else (yes if v else no)


def _link_lines(rec: AnalysisRecord) -> list[str]:
    """Link-budget design outputs and the bursty-link condition, as the record states them."""
    lb = rec.link_budget
    if lb is None or not lb.applicable:
        return []
    if not isinstance(lb, LinkBudgetRecord):
        # a Gilbert–Elliott channel's section: its burst condition
        cond = lb.condition
        if not cond.expression:
            return []
        return [f"  bursty link           {cond.expression}: {_num(cond.value)} "
                f"({'holds' if cond.holds else 'fails'}; {cond.status})"]
    out = []
    req = lb.required_arrival_probability
    if req.design_value is not None:
        out.append(f"  required arrival p    {_num(req.design_value)}"
                   + (f"  ({req.basis})" if req.basis else ""))
    for value, label, unit in ((lb.required_sinr_db, "required SINR", " dB"),
                               (lb.required_rx_power_dbm, "required rx power", " dBm"),
                               (lb.link_margin_db, "link margin", " dB")):
        if _present(value):
            out.append(f"  {label:<21} {_num(value)}{unit}")
    if lb.max_distance_unbounded:
        out.append(f"  {'max distance':<21} unbounded at the margin policy")
    elif _present(lb.max_distance_m):
        out.append(f"  {'max distance':<21} {_num(lb.max_distance_m)} m")
    shadow = lb.shadowing
    if shadow.mean_arrival_probability is not None:
        out.append(f"  shadowing-averaged p  {_num(shadow.mean_arrival_probability)}"
                   f" (σ = {_num(shadow.sigma_db)} dB, {shadow.mode or '—'})")
    dc = lb.design_check
    margin = ("unbounded (the requirement p > 0 holds at every SINR)" if dc.margin_unbounded
              else f"{_num(dc.link_margin_db, 4)} dB")
    out.append(f"  margin policy         {_yes_no(dc.margin_policy_met)}: link margin "
               f"{margin}, policy needs "
               f"{_num(dc.required_margin_db, 4)} dB = max(margin_db, "
               "σ·Φ⁻¹(1 − max_outage))")
    if dc.outage_probability is not None:
        out.append(f"  outage probability    {_num(dc.outage_probability, 4)}"
                   + (f" (policy allows {_num(dc.max_outage, 4)}: "
                      f"{_yes_no(dc.outage_within_policy, 'within', 'EXCEEDED')})"
                      if dc.max_outage is not None else ""))
    return out
