"""The requirements of a system file, assessed: the tail requirement by simulation (with the
tail exponent beside it) and the accuracy requirement by the covariance bounds and the design.

The assessments are built as the typed record's sections
(:class:`~kfcrit.records.contract.RequirementsRecord`), never as dicts read back."""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace
from typing import Any

from kfcrit.analysis import verdict as vd
from kfcrit.records.contract import (
    OperatingPoint,
    PowerLawEstimate,
    RequirementAssessment,
    RequirementsRecord,
    TailAssessment,
)
from kfcrit.records.covariance import (
    AccuracyDesign,
    CovarianceBounds,
    TailSection,
    TailSimulationCheck,
)
from kfcrit.records.simulation import Exceedance, Simulation, SimulationOperatingPoint


def simulated_horizon(simulation: Simulation | None) -> SimulationOperatingPoint | None:
    """The simulation at the operating point, None when it was not run (or skipped)."""
    return (simulation.operating_point or None) if simulation is not None else None


def tail_simulation_check(tail: TailSection | None,
                          simulation: Simulation | None) -> TailSection | None:
    r"""The tail exponent against the simulation: the log–log slope of the empirical CCDF.

    .. math:: \log P(\operatorname{tr} P_T > M) \approx c - \beta \log M

    fitted by least squares on the simulated paths at the horizon over the upper tail (CCDF
    between 10/N and 0.2: at least ten paths beyond every point used). A finite horizon and N
    paths bias the slope; the comparison is evidence for the labelled claim, not a proof.
    Returns ``tail`` with the check (unchanged when there is nothing to compare).
    """
    import numpy as np

    op = simulated_horizon(simulation)
    if tail is None or op is None:
        return tail
    beta, paths, cdf = tail.exponent.value, op.paths, op.horizon.cdf
    if beta is None or not cdf.trace or not paths:
        return tail
    m = np.asarray(cdf.trace, dtype=float)
    ccdf = 1.0 - np.asarray(cdf.probability, dtype=float)
    keep = (ccdf >= 10.0 / paths) & (ccdf <= 0.2) & (m > 0) & np.isfinite(m)
    method = ("least-squares slope of log CCDF against log tr P at the horizon, CCDF in "
              "[10/N, 0.2]")
    if keep.sum() >= 4 and np.ptp(np.log(m[keep])) > 0:
        slope = float(np.polyfit(np.log(m[keep]), np.log(ccdf[keep]), 1)[0])
        check = TailSimulationCheck(
            method=method, paths=paths, horizon=op.steps, points=int(keep.sum()), slope=slope,
            exponent_estimate=-slope, relative_difference=abs(-slope - beta) / beta,
            trace_range=[float(m[keep].min()), float(m[keep].max())])
    else:
        check = TailSimulationCheck(method=method, paths=paths, horizon=op.steps,
                                    points=int(keep.sum()),
                                    note="too few simulated tail points for a slope")
    return replace(tail, simulation_check=check)


def power_law_tail(requirements: RequirementsRecord | None, tail: TailSection | None,
                   simulation: Simulation | None) -> RequirementsRecord | None:
    r"""The tail requirement read with the tail exponent beside the Monte Carlo (a claim).

    .. math:: P(\operatorname{tr} P > M) \approx P(\operatorname{tr} P > m_0)\,(M/m_0)^{-\beta}

    from the empirical CCDF at the highest level m_0 ≤ M that at least ten simulated paths
    exceed; the Wilson interval of the simulation stays the basis of the status. Returns
    ``requirements`` with the estimate added to its tail assessment (unchanged when there is
    nothing to add).
    """
    import numpy as np

    op = simulated_horizon(simulation)
    if (requirements is None or not isinstance(requirements.assessment, TailAssessment)
            or tail is None or op is None):
        return requirements
    beta, limit = tail.exponent.value, requirements.max_error_trace
    cdf, paths = op.horizon.cdf, op.paths
    if not (limit and beta and cdf.trace and paths):
        return requirements
    m = np.asarray(cdf.trace, dtype=float)
    ccdf = 1.0 - np.asarray(cdf.probability, dtype=float)
    ok = (ccdf >= 10.0 / paths) & (m <= limit) & (m > 0)
    if not ok.any():
        return requirements
    i = int(np.flatnonzero(ok)[np.argmax(m[ok])])
    estimate = PowerLawEstimate(
        value=float(ccdf[i] * (limit / m[i]) ** (-beta)), anchor_level=float(m[i]),
        anchor_probability=float(ccdf[i]), exponent=beta, label=tail.exponent.label,
        formula="P(tr P > M) ≈ P(tr P > m0) (M/m0)^(-beta)")
    return replace(requirements,
                   assessment=replace(requirements.assessment, power_law_estimate=estimate))


def tail_assessment(limit: float | None, allowed: float | None,
                    exc: Exceedance | None, steps: int | None = None) -> TailAssessment:
    """The tail requirement P(tr P > limit) ≤ allowed against the simulated exceedance.

    With k of N paths above ``limit`` and the 95 % Wilson interval [lo, hi] of the exceedance:
    ``met`` if hi ≤ allowed, ``not met`` if lo > allowed, else ``not demonstrated`` (more paths
    are needed); ``status`` None when an input is missing.
    """
    status, basis = None, None
    if limit is None or allowed is None:
        basis = "needs both max_error_trace and max_tail_probability"
    elif exc is None or exc.lower is None:
        basis = "no simulation at the operating point"
    else:
        lo, hi, est = exc.lower, exc.upper, exc.estimate
        status = "met" if hi <= allowed else "not met" if lo > allowed else "not demonstrated"
        basis = (f"P(tr P > {limit:g}) ≈ {est:.4g} at t = {steps} "
                 f"({exc.count} of {exc.total} paths; 95 % interval "
                 f"[{lo:.3g}, {hi:.3g}]) against the allowed {allowed:g}")
    return TailAssessment(status=status, basis=basis,
                          estimate=exc.estimate if exc is not None else None,
                          interval=[exc.lower, exc.upper] if exc is not None else None)


def _mean(limit: float, status: str | None, basis: str,
          interval: list[float | None] | None = None) -> RequirementAssessment:
    """The assessment of lim E[tr P] ≤ ``limit`` (``interval`` [tr S̄, tr V̄] when known)."""
    if interval is None:
        return RequirementAssessment(f"lim E[tr P] ≤ {limit:g}", status, basis)
    return RequirementAssessment(f"lim E[tr P] ≤ {limit:g}", status, basis, interval=interval)


def mean_assessment(limit: float, bounds: CovarianceBounds | None,
                    verdict: vd.Verdict | None, iid: bool = True,
                    design: AccuracyDesign | None = None) -> RequirementAssessment:
    """The accuracy requirement lim E[tr P_t] ≤ L at the operating point (theory §11).

    ``not met`` when the filter is mean-unstable (E[tr P_t] diverges) or tr S̄ > L (S̄ is a lower
    bound for every p); ``met`` when tr V̄ ≤ L (V̄ an upper bound above p_up); otherwise ``not
    demonstrated`` (L lies between the bounds).
    """
    if verdict is None:
        return _mean(limit, None, "no channel: no operating point to assess")
    if verdict is vd.Verdict.MEAN_UNSTABLE:
        return _mean(limit, "not met", "the filter is mean-unstable at the operating "
                "point: lim E[tr P_t] is infinite")
    req = design.required_arrival_probability if design is not None else None
    if req is not None and req.status == "impossible":
        return _mean(limit, "not met", "no arrival probability meets it: "
                + str(req.reason or "L is below the no-loss floor"))
    if not iid:
        return _bursty_mean_assessment(limit, bounds, verdict)
    lower = bounds.lower if bounds is not None else None
    upper = bounds.upper if bounds is not None else None
    if lower is not None and lower.exists is False:
        if verdict is vd.Verdict.MEAN_STABLE:
            return _mean(limit, "not met", "(1 − p)ρ(A)² rounds to 1 or more in double "
                    "precision at this p: the Lyapunov lower bound tr S̄ = Σ_k (1 − p)^k "
                    "tr(A^k Q A'^k) is beyond float64, far above L")
        return _mean(limit, "not met", "the Lyapunov lower bound S̄ does not exist "
                "((1 − p)ρ(A)² ≥ 1): lim E[tr P_t] is infinite")
    s_tr = lower.trace if lower is not None else None
    v_tr = upper.trace if upper is not None else None
    if s_tr is not None and s_tr > limit:
        return _mean(limit, "not met", f"tr S̄ = {s_tr:.6g} > L = {limit:g} (S̄ ⪯ lim "
                "E[P_t], Sinopoli Thm 4)", interval=[s_tr, v_tr])
    if v_tr is not None and upper.exists and v_tr <= limit \
            and verdict is vd.Verdict.MEAN_STABLE:
        return _mean(limit, "met", f"tr V̄ = {v_tr:.6g} ≤ L = {limit:g} (lim E[P_t] ⪯ V̄, "
                "Sinopoli Thm 6)", interval=[s_tr, v_tr])
    s_text = "not available" if s_tr is None else f"{s_tr:.6g}"
    v_text = "not available" if v_tr is None or not upper.exists else f"{v_tr:.6g}"
    return _mean(limit, "not demonstrated", f"L = {limit:g} is not decided by the "
            f"bounds: tr S̄ = {s_text} ≤ L and tr V̄ = {v_text}", interval=[s_tr, v_tr])


def _bursty_mean_assessment(limit: float, bounds: CovarianceBounds | None,
                            verdict: vd.Verdict) -> RequirementAssessment:
    """The accuracy requirement over a channel that is not i.i.d. (theory §10).

    The i.i.d. bounds S̄, V̄ at the stationary arrival probability do not bound E[P_t] there;
    only the Markov-jump bounds of a Gilbert–Elliott chain (``covariance_bounds.markov_jump``,
    :func:`kfcrit.theory.links.burstcov.markov_jump_bounds`) decide: ``met`` if the upper bound
    is ≤ L (and the verdict is mean-stable), ``not met`` if the lower bound is > L, otherwise
    ``not demonstrated`` (and always for channels without a chain, e.g. a measured trace)."""
    mj = bounds.markov_jump if bounds is not None else None
    if not mj:
        return _mean(limit, "not demonstrated", f"L = {limit:g} is not decided: the "
                "i.i.d. bounds S̄, V̄ do not bound E[P_t] for a channel with memory, and no "
                "bound valid for this channel is available")
    lo, hi = mj.lower.trace, mj.upper.trace
    if lo is not None and lo > limit:
        return _mean(limit, "not met", f"Markov-jump lower bound lim E[tr P_t] ≥ "
                f"{lo:.6g} > L = {limit:g} (losses-only recursion over the Gilbert–Elliott "
                "chain, theory §10)", interval=[lo, hi])
    if hi is not None and hi <= limit and verdict is vd.Verdict.MEAN_STABLE:
        return _mean(limit, "met", f"Markov-jump upper bound lim E[tr P_t] ≤ {hi:.6g} "
                f"≤ L = {limit:g} (fixed-gain second-moment recursion over the Gilbert–Elliott "
                "chain, theory §10)", interval=[lo, hi])
    lo_text = "not available" if lo is None else f"{lo:.6g}"
    hi_text = "not available" if hi is None else f"{hi:.6g}"
    return _mean(limit, "not demonstrated", f"L = {limit:g} is not decided by the "
            f"Markov-jump bounds of the Gilbert–Elliott chain: lower {lo_text} ≤ L, upper "
            f"{hi_text} (theory §10)", interval=[lo, hi])


def requirement_assessment(requirements: Mapping[str, float | None] | None,
                           simulation: Simulation | None,
                           bounds: CovarianceBounds | None = None,
                           op: OperatingPoint | None = None,
                           design: AccuracyDesign | None = None) -> RequirementsRecord | None:
    """The system file's requirements (their values by key), each assessed (``assessments``, in
    file order; the tail requirement's assessment also as ``assessment`` for scripts written
    against schema 1). None without requirements."""
    if not requirements:
        return None
    items: list[RequirementAssessment] = []
    limit, allowed = requirements.get("max_error_trace"), requirements.get("max_tail_probability")
    extra: dict[str, Any] = {k: requirements[k] for k in ("max_mean_error_trace", "max_cost")
                             if k in requirements}
    if limit is not None or allowed is not None:
        op = simulated_horizon(simulation)
        tail = tail_assessment(limit, allowed, op.exceedance if op is not None else None,
                               op.steps if op is not None else None)
        extra["assessment"] = tail
        name = (f"P(tr P > {limit:g}) ≤ {allowed:g}" if None not in (limit, allowed)
                else "tail requirement (incomplete)")
        items.append(RequirementAssessment(name, tail.status, tail.basis, estimate=tail.estimate,
                                           interval=tail.interval))
    mean_limit = requirements.get("max_mean_error_trace")
    if mean_limit is not None:
        items.append(mean_assessment(mean_limit, bounds, op.verdict if op else None,
                                     op.iid if op else True, design))
    return RequirementsRecord(limit, allowed, assessments=items, **extra)
