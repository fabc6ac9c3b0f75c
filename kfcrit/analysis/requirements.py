"""The requirements of a system file, assessed: the tail requirement by simulation (with the
tail exponent beside it) and the accuracy requirement by the covariance bounds and the design."""
from __future__ import annotations

from typing import Any

from kfcrit.analysis import verdict as vd


def tail_simulation_check(sec: dict[str, Any]) -> None:
    r"""The tail exponent against the simulation: the log–log slope of the empirical CCDF.

    .. math:: \log P(\operatorname{tr} P_T > M) \approx c - \beta \log M

    fitted by least squares on the simulated paths at the horizon over the upper tail (CCDF
    between 10/N and 0.2: at least ten paths beyond every point used). A finite horizon and N
    paths bias the slope; the comparison is evidence for the labelled claim, not a proof.
    """
    import numpy as np

    tail = (sec.get("tail") or {}).get("exponent") or {}
    op = (sec.get("simulation") or {}).get("operating_point") or {}
    cdf = (op.get("horizon") or {}).get("cdf") or {}
    beta, paths = tail.get("value"), op.get("paths")
    if beta is None or not cdf.get("trace") or not paths:
        return
    m = np.asarray(cdf["trace"], dtype=float)
    ccdf = 1.0 - np.asarray(cdf["probability"], dtype=float)
    keep = (ccdf >= 10.0 / paths) & (ccdf <= 0.2) & (m > 0) & np.isfinite(m)
    check: dict[str, Any] = {"method": "least-squares slope of log CCDF against log tr P at "
                             "the horizon, CCDF in [10/N, 0.2]", "paths": paths,
                             "horizon": op.get("steps"), "points": int(keep.sum())}
    if keep.sum() >= 4 and np.ptp(np.log(m[keep])) > 0:
        slope = float(np.polyfit(np.log(m[keep]), np.log(ccdf[keep]), 1)[0])
        check.update(slope=slope, exponent_estimate=-slope,
                     relative_difference=abs(-slope - beta) / beta,
                     trace_range=[float(m[keep].min()), float(m[keep].max())])
    else:
        check["note"] = "too few simulated tail points for a slope"
    sec["tail"]["simulation_check"] = check


def power_law_tail(sec: dict[str, Any]) -> None:
    r"""The tail requirement read with the tail exponent beside the Monte Carlo (a claim).

    .. math:: P(\operatorname{tr} P > M) \approx P(\operatorname{tr} P > m_0)\,(M/m_0)^{-\beta}

    from the empirical CCDF at the highest level m_0 ≤ M that at least ten simulated paths
    exceed; the Wilson interval of the simulation stays the basis of the status.
    """
    import numpy as np

    req = sec.get("requirements") or {}
    tail = (sec.get("tail") or {}).get("exponent") or {}
    limit, beta = req.get("max_error_trace"), tail.get("value")
    op = (sec.get("simulation") or {}).get("operating_point") or {}
    cdf = (op.get("horizon") or {}).get("cdf") or {}
    paths = op.get("paths")
    if not (req.get("assessment") and limit and beta and cdf.get("trace") and paths):
        return
    m = np.asarray(cdf["trace"], dtype=float)
    ccdf = 1.0 - np.asarray(cdf["probability"], dtype=float)
    ok = (ccdf >= 10.0 / paths) & (m <= limit) & (m > 0)
    if not ok.any():
        return
    i = int(np.flatnonzero(ok)[np.argmax(m[ok])])
    estimate = float(ccdf[i] * (limit / m[i]) ** (-beta))
    req["assessment"]["power_law_estimate"] = {
        "value": estimate, "anchor_level": float(m[i]), "anchor_probability": float(ccdf[i]),
        "exponent": beta, "label": tail.get("label"),
        "formula": "P(tr P > M) ≈ P(tr P > m0) (M/m0)^(-beta)"}


def tail_assessment(limit: float | None, allowed: float | None,
                    simulation: dict[str, Any] | None) -> dict[str, Any]:
    """The tail requirement P(tr P > limit) ≤ allowed against the simulated exceedance.

    With k of N paths above ``limit`` and the 95 % Wilson interval [lo, hi] of the exceedance:
    ``met`` if hi ≤ allowed, ``not met`` if lo > allowed, else ``not demonstrated`` (more paths
    are needed); ``status`` None when an input is missing.
    """
    op = (simulation or {}).get("operating_point") or {}
    exc = op.get("exceedance") or {}
    status, basis = None, None
    if limit is None or allowed is None:
        basis = "needs both max_error_trace and max_tail_probability"
    elif not exc or exc.get("lower") is None:
        basis = "no simulation at the operating point"
    else:
        lo, hi, est = exc["lower"], exc["upper"], exc.get("estimate")
        status = "met" if hi <= allowed else "not met" if lo > allowed else "not demonstrated"
        basis = (f"P(tr P > {limit:g}) ≈ {est:.4g} at t = {op.get('steps')} "
                 f"({exc.get('count')} of {exc.get('total')} paths; 95 % interval "
                 f"[{lo:.3g}, {hi:.3g}]) against the allowed {allowed:g}")
    return {"status": status, "basis": basis, "estimate": exc.get("estimate"),
            "interval": [exc.get("lower"), exc.get("upper")] if exc else None}


def mean_assessment(limit: float, bounds: dict[str, Any] | None,
                    op: dict[str, Any] | None,
                    design: dict[str, Any] | None = None) -> dict[str, Any]:
    """The accuracy requirement lim E[tr P_t] ≤ L at the operating point (theory §11).

    ``not met`` when the filter is mean-unstable (E[tr P_t] diverges) or tr S̄ > L (S̄ is a lower
    bound for every p); ``met`` when tr V̄ ≤ L (V̄ an upper bound above p_up); otherwise ``not
    demonstrated`` (L lies between the bounds).
    """
    verdict = (op or {}).get("verdict")
    if verdict is None:
        return {"status": None, "basis": "no channel: no operating point to assess"}
    if verdict == vd.Verdict.MEAN_UNSTABLE.value:
        return {"status": "not met", "basis": "the filter is mean-unstable at the operating "
                "point: lim E[tr P_t] is infinite"}
    req = (design or {}).get("required_arrival_probability") or {}
    if req.get("status") == "impossible":
        return {"status": "not met", "basis": "no arrival probability meets it: "
                + str(req.get("reason") or "L is below the no-loss floor")}
    if (op or {}).get("iid") is False:
        return _bursty_mean_assessment(limit, bounds, verdict)
    lower = (bounds or {}).get("lower") or {}
    upper = (bounds or {}).get("upper") or {}
    if bounds and lower.get("exists") is False:
        if verdict == vd.Verdict.MEAN_STABLE.value:
            return {"status": "not met", "basis": "(1 − p)ρ(A)² rounds to 1 or more in double "
                    "precision at this p: the Lyapunov lower bound tr S̄ = Σ_k (1 − p)^k "
                    "tr(A^k Q A'^k) is beyond float64, far above L"}
        return {"status": "not met", "basis": "the Lyapunov lower bound S̄ does not exist "
                "((1 − p)ρ(A)² ≥ 1): lim E[tr P_t] is infinite"}
    s_tr, v_tr = lower.get("trace"), upper.get("trace")
    if s_tr is not None and s_tr > limit:
        return {"status": "not met", "basis": f"tr S̄ = {s_tr:.6g} > L = {limit:g} (S̄ ⪯ lim "
                "E[P_t], Sinopoli Thm 4)", "interval": [s_tr, v_tr]}
    if v_tr is not None and upper.get("exists") and v_tr <= limit \
            and verdict == vd.Verdict.MEAN_STABLE.value:
        return {"status": "met", "basis": f"tr V̄ = {v_tr:.6g} ≤ L = {limit:g} (lim E[P_t] ⪯ V̄, "
                "Sinopoli Thm 6)", "interval": [s_tr, v_tr]}
    s_text = "not available" if s_tr is None else f"{s_tr:.6g}"
    v_text = "not available" if v_tr is None or not upper.get("exists") else f"{v_tr:.6g}"
    return {"status": "not demonstrated", "basis": f"L = {limit:g} is not decided by the "
            f"bounds: tr S̄ = {s_text} ≤ L and tr V̄ = {v_text}", "interval": [s_tr, v_tr]}


def _bursty_mean_assessment(limit: float, bounds: dict[str, Any] | None,
                            verdict: str) -> dict[str, Any]:
    """The accuracy requirement over a channel that is not i.i.d. (theory §10).

    The i.i.d. bounds S̄, V̄ at the stationary arrival probability do not bound E[P_t] there;
    only the Markov-jump bounds of a Gilbert–Elliott chain (``covariance_bounds.markov_jump``,
    :func:`kfcrit.theory.links.burstcov.markov_jump_bounds`) decide: ``met`` if the upper bound
    is ≤ L (and the verdict is mean-stable), ``not met`` if the lower bound is > L, otherwise
    ``not demonstrated`` (and always for channels without a chain, e.g. a measured trace)."""
    mj = (bounds or {}).get("markov_jump")
    if not isinstance(mj, dict):
        return {"status": "not demonstrated", "basis": f"L = {limit:g} is not decided: the "
                "i.i.d. bounds S̄, V̄ do not bound E[P_t] for a channel with memory, and no "
                "bound valid for this channel is available"}
    lo = (mj.get("lower") or {}).get("trace")
    hi = (mj.get("upper") or {}).get("trace")
    if lo is not None and lo > limit:
        return {"status": "not met", "basis": f"Markov-jump lower bound lim E[tr P_t] ≥ "
                f"{lo:.6g} > L = {limit:g} (losses-only recursion over the Gilbert–Elliott "
                "chain, theory §10)", "interval": [lo, hi]}
    if hi is not None and hi <= limit and verdict == vd.Verdict.MEAN_STABLE.value:
        return {"status": "met", "basis": f"Markov-jump upper bound lim E[tr P_t] ≤ {hi:.6g} "
                f"≤ L = {limit:g} (fixed-gain second-moment recursion over the Gilbert–Elliott "
                "chain, theory §10)", "interval": [lo, hi]}
    lo_text = "not available" if lo is None else f"{lo:.6g}"
    hi_text = "not available" if hi is None else f"{hi:.6g}"
    return {"status": "not demonstrated", "basis": f"L = {limit:g} is not decided by the "
            f"Markov-jump bounds of the Gilbert–Elliott chain: lower {lo_text} ≤ L, upper "
            f"{hi_text} (theory §10)", "interval": [lo, hi]}


def requirement_assessment(requirements: dict[str, Any] | None,
                           simulation: dict[str, Any] | None,
                           bounds: dict[str, Any] | None = None,
                           op: dict[str, Any] | None = None,
                           design: dict[str, Any] | None = None) -> dict[str, Any] | None:
    """The system file's requirements, each assessed (``assessments``, in file order; the tail
    requirement's assessment also as ``assessment`` for scripts written against schema 1)."""
    if not requirements:
        return requirements
    out = dict(requirements)
    items = []
    limit, allowed = out.get("max_error_trace"), out.get("max_tail_probability")
    if limit is not None or allowed is not None:
        tail = tail_assessment(limit, allowed, simulation)
        out["assessment"] = tail
        name = (f"P(tr P > {limit:g}) ≤ {allowed:g}" if None not in (limit, allowed)
                else "tail requirement (incomplete)")
        items.append({"requirement": name, **tail})
    mean_limit = out.get("max_mean_error_trace")
    if mean_limit is not None:
        items.append({"requirement": f"lim E[tr P] ≤ {mean_limit:g}",
                      **mean_assessment(mean_limit, bounds, op, design)})
    out["assessments"] = items
    return out
