"""The verification appendix of the record: every check the analysis relies on, with its
outcome, read from the typed sections (nothing here recomputes a result)."""
from __future__ import annotations

from typing import Any

from kfcrit.analysis.requirements import simulated_horizon
from kfcrit.io.typed import ABSENT
from kfcrit.records.contract import VerificationCheck
from kfcrit.records.covariance import CovarianceBounds
from kfcrit.records.simulation import SimulationOperatingPoint


def _simulated_mean_between_bounds(cb: CovarianceBounds | None,
                                   sim_op: SimulationOperatingPoint | None
                                   ) -> VerificationCheck | None:
    """Sinopoli Thm 4/6 cross-check: the simulated E[tr P_t] at the horizon lies in
    [tr S̄, tr V̄] up to its confidence band (and a 5 % allowance for the finite horizon).

    A miss is ``inconclusive`` (``passed`` None, with the reason), not a failure, when the
    simulation section says the comparison is not valid at this operating point
    (``reliability``): the variance of tr P is infinite (heavy tails, just above p_c) or the
    Lyapunov lower bound itself has not settled within the horizon (the limit bounds then do
    not yet apply to E[tr P_T]).
    """
    if cb is None or sim_op is None:
        return None
    lower, upper, mt = cb.lower, cb.upper, sim_op.mean_trace
    if not (lower.exists and upper.exists and mt.mean) or None in (lower.trace, upper.trace):
        return None   # a bound that exists beyond float64 has no trace to compare with
    if sim_op.iid is False:  # S̄ and V̄ are bounds for i.i.d. losses only
        return None
    if sim_op.divergence.diverged_paths:
        return None
    mean, lo, hi = mt.mean[-1], (mt.lower or mt.mean)[-1], (mt.upper or mt.mean)[-1]
    if None in (mean, lo, hi):
        return None
    ok = hi >= 0.95 * lower.trace and lo <= 1.05 * upper.trace
    check = "simulation: E[tr P_t] at the horizon within [tr S̄, tr V̄] (Thm 4, 6)"
    detail = (f"{lower.trace:.6g} ≤ {mean:.6g} (band {lo:.6g}–{hi:.6g}) ≤ "
              f"{upper.trace:.6g}")
    rel = sim_op.reliability
    reasons = []
    if not ok and rel.heavy_tailed:
        reasons.append(f"{rel.variance_condition} = {rel.variance_value:.4g} >= 1: the variance "
                       "of tr P diverges (heavy tails just above p_c), so the sample mean is "
                       "unreliable")
    if not ok and rel.settled is False:
        reasons.append(f"the Lyapunov bound has not settled within the horizon (tr S_T = "
                       f"{rel.lyapunov_trace_at_horizon:.4g} < 0.95 tr S̄ = "
                       f"{0.95 * rel.lyapunov_trace_limit:.4g})")
    if reasons:
        return VerificationCheck(check, None, "inconclusive", detail=detail,
                                 reason="; ".join(reasons))
    return VerificationCheck(check, bool(ok), "passed" if ok else "failed", detail=detail)


def or_none(value: Any) -> Any:
    """``value``, or None for the :data:`~kfcrit.io.typed.ABSENT` of an absent key."""
    return None if value is ABSENT else value


STATUS_OF_PASSED = {True: "passed", False: "failed", None: "not applicable"}
"""A check's status from its outcome (unless it states its own, e.g. ``inconclusive``)."""


def verification(sec: dict[str, Any], warnings: list[str] | None = None
                 ) -> list[VerificationCheck]:
    """The checks the record relies on, each with its outcome (for the report's appendix).

    Every entry has ``check``, ``passed`` (True/False/None), ``status`` (passed / failed /
    inconclusive — a Monte Carlo cross-check whose tolerance is not valid at this operating
    point; ``reason`` says why and a warning is added — / not applicable) and ``detail``;
    nothing here recomputes a result, it reads what the sections measured.
    """
    warnings = warnings if warnings is not None else []
    checks: list[VerificationCheck] = []

    def add(check: str, passed: bool | None, detail: str | None) -> None:
        checks.append(VerificationCheck(check, passed, STATUS_OF_PASSED[passed], detail=detail))

    ub = sec.get("upper_bound")
    if ub is not None and ub.status != "not applicable":
        cert = ub.certificate
        detail = (cert.verified_by or cert.kind) if cert is not None else None
        add("upper-bound certificate X ≻ g_p(X), X ≻ 0 (exact re-check)",
            True if ub.certified else None, detail or ub.status)
    cb = sec.get("covariance_bounds")
    if cb is not None:
        add("covariance bounds ordered: S̄ ⪯ V̄", or_none(cb.ordered),
            f"MARE residual {or_none(cb.upper.residual)}")
        checks.extend(_enclosure_check(cb.upper))
    sim = sec.get("simulation")
    checks.extend((sim.checks or []) if sim is not None else [])
    between = _simulated_mean_between_bounds(cb, simulated_horizon(sim))
    if between is not None:
        checks.append(between)
        if between.status == "inconclusive":
            warnings.append(f"Monte Carlo check inconclusive: {between.check} "
                            f"({between.reason})")
    pcv = section_value(sec, "critical_value")
    lb = section_value(sec, "lower_bound")
    up = ub.value if ub is not None else None
    if pcv is not None and lb is not None:
        ok = lb <= pcv + 1e-12 and (up is None or pcv <= up + max(ub.tolerance or 0, 1e-9))
        add("ordering p_low ≤ p_c ≤ p_up", bool(ok),
            f"{lb:.12g} ≤ {pcv:.12g} ≤ {up if up is None else f'{up:.12g}'}")
    if sec.get("loop") is not None:
        from kfcrit.analysis.loop.designs import loop_check

        check = loop_check(sec["loop"])
        if check is not None:
            checks.append(check)
            if check.status == "inconclusive":
                warnings.append(f"Monte Carlo check inconclusive: {check.check} "
                                f"({check.reason})")
    return checks


def _enclosure_check(upper: Any) -> list[VerificationCheck]:
    """The verified enclosure of V̄ (theory §3), when the bounds attempted one."""
    if upper.certified is ABSENT:
        return []
    check = "V̄ enclosed: (1 − ε)V ⪯ V̄ ⪯ (1 + ε)V (verified float64, theory §3)"
    if upper.certified:
        enc = upper.certificate
        return [VerificationCheck(check, True, "passed", detail=(
            f"ε = {enc.relative_width:g}, tr V̄ in "
            f"[{enc.trace_interval[0]:.10g}, {enc.trace_interval[1]:.10g}]"))]
    return [VerificationCheck(check, None, "inconclusive", detail="no enclosure proven",
                              reason="the solver's V̄ could not be enclosed (Q singular, or V̄ "
                                     "not converged); it rests on its residual")]


def section_value(sec: dict[str, Any], key: str) -> float | None:
    """``value`` of the typed section ``key`` of ``sec`` (None when absent)."""
    section = sec.get(key)
    return section.value if section is not None else None
