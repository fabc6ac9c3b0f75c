"""How far the simulated means can be trusted, and the self-checks of a simulation.

The tail regime (variance of tr P finite or not, horizon settled or not) decides whether a
statistical check that misses its tolerance is a failure or only inconclusive.
"""
from __future__ import annotations

import math

import numpy as np

from kfcrit.model.channels import Channel
from kfcrit.model.system import System
from kfcrit.records.contract import VerificationCheck
from kfcrit.records.simulation import MeanBasis, SimulationReliability
from kfcrit.sim.engine import initial_covariance
from kfcrit.sim.results import ErgodicResult, SimulationResult
from kfcrit.sim.stats import finite_or_none, quiet_numerics

VARIANCE_CLAIM = (
    "claim: Var tr P < inf iff the loss factor q (1 - p i.i.d., 1 - r Gilbert-Elliott) is below "
    "(1 - p_c)^2, i.e. p > p_2 with 1 - p_2 = (1 - p_c)^2 - the q-th moment condition of "
    "Mo-Sinopoli Cor. 2 with exponent 2 (1 - p_2 = rho^-4 for non-degenerate systems, "
    "1 - p_c = rho^-2) and, by the same loss-burst argument with the growth rate of Thm 9, "
    "1 - p_2 = rho^(-4q/(q-1)) for the degenerate second-order case (docs/theory.md §4)")


def critical_upper(critical_value: float | None = None,
                   critical_bracket: tuple[float | None, float | None] | None = None,
                   upper_bound: float | None = None) -> tuple[float | None, float | None, str]:
    """(lower end, upper end, source) of what is known about p_c.

    The exact value when known; else the bracket; else [None, p_up] (p_c ≤ p_up).
    """
    if critical_value is not None:
        return float(critical_value), float(critical_value), "critical_value"
    lo, hi = critical_bracket if critical_bracket is not None else (None, None)
    if hi is not None:
        return (None if lo is None else float(lo)), float(hi), "critical_bracket"
    if upper_bound is not None:
        return (None if lo is None else float(lo)), float(upper_bound), "upper_bound (p_c <= p_up)"
    return (None if lo is None else float(lo)), None, "none"


def _loss_factor(channel: Channel) -> tuple[float | None, str | None]:
    """q = 1 − p (i.i.d.) or 1 − r (Gilbert–Elliott): the per-step probability that a loss
    burst goes on; None for a measured trace."""
    proc = channel.arrival_process()
    if proc.kind == "iid":
        return 1.0 - float(proc.p), "1 - p"
    if proc.kind == "markov":
        return 1.0 - float(proc.recovery_rate), "1 - r"
    return None, None


def tail_regime(system: System, channel: Channel, steps: int, *,
                critical_value: float | None = None,
                critical_bracket: tuple[float | None, float | None] | None = None,
                upper_bound: float | None = None) -> SimulationReliability:
    r"""How far sample means of tr P_t can be trusted at this operating point.

    * ``heavy_tailed``: a loss burst of length k has probability ∝ q^k (q = 1 − p for i.i.d.
      losses, q = 1 − r for Gilbert–Elliott) and multiplies E[P] by about (1 − p_c)^{−k}, its
      square by (1 − p_c)^{−2k}, so

      .. math:: \operatorname{Var} \operatorname{tr} P < \infty \iff q < (1 - p_c)^2,

      i.e. p > p₂ with 1 − p₂ = (1 − p_c)² (a claim, :data:`VARIANCE_CLAIM`): 1 − ρ^{−4} for
      non-degenerate systems, 1 − ρ^{−4q/(q−1)} for the degenerate second-order case. When p_c is
      only bracketed the upper end is used (it flags more operating points: conservative);
      without any information on p_c, p_c = 1 − ρ(A)^{−2} (the non-degenerate value, a lower
      bound of p_c) and the condition reads q ρ(A)⁴ ≥ 1. The sample standard deviation then
      underestimates the spread, the ±5 se tolerance is no test, and the sample mean sits below
      the true mean most of the time. ``None`` for a measured trace (no model).
    * ``settled``: tr S_T ≥ 0.95 tr S̄ for the Lyapunov recursion S_{t+1} = (1 − p) A S_t A' + Q
      from Σ0 (i.i.d. only): near p_c, (1 − p) ρ² → 1 and the mean needs far more than the
      horizon T to approach its limit, so limit bounds say nothing about E[tr P_T] yet.
    """
    rho = float(max(abs(np.linalg.eigvals(system.a)))) if system.n else 0.0
    q, q_name = _loss_factor(channel)
    _, hi, source = critical_upper(critical_value, critical_bracket, upper_bound)
    with quiet_numerics():
        # numpy power: ρ⁴ beyond float64 is inf (the heavy tail is then certain), not an error
        if q is None:
            value, basis, p2 = None, None, None
        elif hi is None:
            value, basis = float(q * np.float64(rho) ** 4), f"({q_name}) rho(A)^4"
            p2 = None
        else:
            gap = np.float64(1.0 - min(max(hi, 0.0), 1.0)) ** 2   # (1 − p_c)²
            value = float(q / gap) if gap > 0 else math.inf
            basis, p2 = f"({q_name}) / (1 - p_c)^2", float(1.0 - gap)
    heavy = None if value is None else bool(not value < 1)
    at_horizon: float | None = None
    limit: float | None = None
    settled: bool | None = None
    if channel.arrival_process().kind == "iid" and q * rho * rho < 1:
        from kfcrit.theory.covariance.bounds import lower_covariance

        S_T = lyapunov_traces(system, 1.0 - q, np.array([steps]))[0]
        with quiet_numerics():
            Sbar = lower_covariance(system.a, system.q, 1.0 - q)
        lim = float(np.trace(Sbar)) if Sbar is not None else None
        if S_T is not None and lim is not None and math.isfinite(lim):
            at_horizon, limit, settled = S_T, lim, bool(S_T >= 0.95 * lim)
    return SimulationReliability(
        variance_condition=basis,
        variance_value=finite_or_none(value) if value is not None else None,
        heavy_tailed=heavy, variance_threshold_p2=p2, variance_critical_value=hi,
        variance_critical_source=source,
        variance_basis=VARIANCE_CLAIM if q is not None else None,
        lyapunov_trace_at_horizon=at_horizon, lyapunov_trace_limit=limit, settled=settled)


def mean_regime(system: System, channel: Channel, *, critical_value: float | None = None,
                critical_bracket: tuple[float | None, float | None] | None = None,
                upper_bound: float | None = None) -> MeanBasis:
    """Whether E[tr P_t] stays bounded at this operating point: ``exists`` True/False/None.

    i.i.d. losses (theory §3–§4): bounded iff p > p_c, so False when p ≤ p_c (or ≤ the lower end
    of its bracket), True when p > p_c (or > the upper end, or > p_up), None in between.
    Gilbert–Elliott (theory §7, §10): (1 − r) ρ(A)² ≥ 1 is necessary for divergence-freedom to
    fail for any system — False; otherwise, as a claim (the burst argument with the i.i.d.
    growth rate 1/(1 − p_c), You–Fu–Xie for non-degenerate systems), False when r ≤ p_c and
    True when r > p_c (bracket ends as above), None in between. A measured trace: None.
    """
    proc = channel.arrival_process()
    lo, hi, source = critical_upper(critical_value, critical_bracket, upper_bound)
    rho = float(max(abs(np.linalg.eigvals(system.a)))) if system.n else 0.0
    if proc.kind == "iid":
        x, name, basis = float(proc.p), "p", "theorem: E[P_t] bounded iff p > p_c (docs/theory.md §3–§4)"
    elif proc.kind == "markov":
        r = float(proc.recovery_rate)
        with quiet_numerics():
            burst = float((1.0 - r) * np.float64(rho) ** 2)
        if not burst < 1:
            return MeanBasis(exists=False, basis="theorem: (1 - r) rho(A)^2 >= 1 makes E[P_t] "
                             "unbounded for any system (docs/theory.md §10, necessary burst "
                             "condition)", value=finite_or_none(burst), critical_source=source)
        x, name = r, "r"
        basis = ("claim: E[P_t] bounded iff r > p_c (loss bursts with the i.i.d. growth rate "
                 "1/(1 - p_c); You-Fu-Xie 2011 for non-degenerate systems, docs/theory.md §7, §10)")
    else:
        return MeanBasis(exists=None, basis="a measured trace: no model", critical_source=source)
    exists = None
    if rho < 1:   # a stable plant: E[P_t] bounded even without arrivals (Lyapunov)
        exists = True
    elif lo is not None and x <= lo:
        exists = False
    elif hi is not None and x > hi:
        exists = True
    return MeanBasis(exists=exists, basis=basis, compared=name, value=x, critical_lower=lo,
                     critical_upper=hi, critical_source=source)


def lyapunov_traces(system: System, p: float, times: np.ndarray) -> list[float | None]:
    """tr S_t at the given (sorted) times, S_{t+1} = (1 − p) A S_t A' + Q, S_0 = Σ0.

    Overflow is handled explicitly: once S_t is no longer finite the remaining entries are
    None (the caller then has no lower bound to compare with).
    """
    A, Q = system.a, system.q
    S = initial_covariance(system, None)
    out: list[float | None] = []
    k, last = 0, int(times[-1]) if times.size else -1
    with quiet_numerics():
        for t in range(last + 1):
            while k < times.size and times[k] == t:
                tr = float(np.trace(S))
                out.append(tr if math.isfinite(tr) else None)
                k += 1
            if not np.all(np.isfinite(S)):
                out.extend([None] * (times.size - len(out)))
                break
            S = (1 - p) * A @ S @ A.T + Q
    return out


def _check(check: str, passed: bool | None, detail: str, *, reason: str | None = None,
           status: str | None = None) -> VerificationCheck:
    """One verification entry; ``status`` is passed / failed / inconclusive / not applicable."""
    st = status or {True: "passed", False: "failed", None: "not applicable"}[passed]
    if reason:
        return VerificationCheck(check, passed, st, detail=detail, reason=reason)
    return VerificationCheck(check, passed, st, detail=detail)


def simulation_checks(system: System, channel: Channel, res: SimulationResult,
                      erg: ErgodicResult, regime: SimulationReliability | None = None
                      ) -> list[VerificationCheck]:
    """Self-checks of the operating-point simulation (``check, passed, status, detail``).

    * every statistic is finite (divergence is flagged, never NaN/inf);
    * the mean loss-burst length matches the channel (1/r Gilbert–Elliott, 1/p i.i.d.) within
      5 standard errors of a geometric law (variance (1 − q)/q²);
    * i.i.d. channels with (1 − p) ρ(A)² < 1: E[tr P_t] ≥ tr S_t − 5 se at every sample time,
      S_{t+1} = (1 − p) A S_t A' + Q, S_0 = Σ0 (Sinopoli Lemma 1(f), by induction).

    A statistical check that misses its tolerance where the tolerance is not valid — heavy
    tails (see :func:`tail_regime`: just above p_c the variance of tr P is infinite) or paths
    censored at the divergence threshold (the means are then lower bounds) — is
    ``inconclusive`` (``passed`` None, with the reason), not failed: near p_c the simulated mean
    need not settle within any affordable horizon.
    """
    regime = regime if regime is not None else tail_regime(system, channel, res.steps)
    out: list[VerificationCheck] = []
    # plain values may exceed float64 (then inf, with a finite log10 beside them); never NaN
    plain = [res.mean_trace, res.std_trace, res.horizon_traces]
    logs = [a for a in (res.log10_mean_trace, res.horizon_log10_traces) if a is not None]
    ok = (all(not np.isnan(a).any() for a in plain) and all(np.isfinite(a).all() for a in logs)
          and all(np.isfinite(a).all() for a in (erg.sums, erg.burst_trace)))
    out.append(_check("simulation: all statistics finite or given as log10 (divergence "
                      "flagged, not propagated)", bool(ok),
                      f"{res.diverged_paths} of {res.paths} paths crossed the divergence "
                      "threshold (continued in scaled form)"))
    bursts = int(erg.burst_count[:, 1:].sum())
    if erg.expected_mean_burst is not None and bursts >= 30:
        q = 1.0 / erg.expected_mean_burst
        mean = float(erg.losses.sum() / bursts)
        se = math.sqrt((1 - q) / (q * q) / bursts)
        out.append(_check("simulation: mean loss-burst length matches the channel",
                          bool(abs(mean - erg.expected_mean_burst) <= 5 * se + 1e-12),
                          f"{mean:.4g} vs {erg.expected_mean_burst:.4g} "
                          f"(5 se = {5 * se:.2g}, {bursts} bursts)"))
    p = float(channel.arrival_probability)
    rho = float(max(abs(np.linalg.eigvals(system.a))))
    if channel.iid and (1 - p) * rho * rho < 1:
        name = "simulation: E[tr P_t] >= Lyapunov lower bound tr S_t (Lemma 1)"
        lower = lyapunov_traces(system, p, res.times)
        later = [k for k in range(res.times.size) if res.times[k] > 0]  # t = 0: equal
        if any(lower[k] is None for k in later):
            out.append(_check(name, None, "the Lyapunov recursion overflowed float64",
                              reason="tr S_t is not representable", status="inconclusive"))
            return out
        lo = np.array([lower[k] for k in later], dtype=float)
        se = res.std_trace[later] / math.sqrt(res.paths)
        with quiet_numerics():
            z = (res.mean_trace[later] - lo) / np.maximum(se, 1e-300)
        zmin = float(np.min(z)) if z.size else 0.0
        detail = (f"min over t of (mean − bound)/se = {max(min(zmin, 1e6), -1e6):.3g} "
                  "(>= −5 required)")
        if zmin >= -5:
            out.append(_check(name, True, detail))
        elif regime.heavy_tailed or res.failed_paths:
            why = (f"{res.failed_paths} paths were frozen after a numerical failure, so "
                   "the simulated means are approximate" if res.failed_paths else
                   f"{regime.variance_condition} = {_ratio_text(regime.variance_value)} >= 1: the "
                   "variance of tr P diverges (heavy tails just above p_c), so the sample mean "
                   "and its standard error are unreliable at this horizon")
            out.append(_check(name, None, detail, reason=why, status="inconclusive"))
        else:
            out.append(_check(name, False, detail))
    return out


def _ratio_text(value: float | None) -> str:
    """A variance ratio as text; None stands for an unbounded ratio (the upper end of p_c's
    bracket is 1), which is ≥ 1 all the same."""
    return "∞" if value is None else f"{value:.4g}"
