"""How far the simulated means can be trusted, and the self-checks of a simulation.

The tail regime (variance of tr P finite or not, horizon settled or not) decides whether a
statistical check that misses its tolerance is a failure or only inconclusive.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from kfcrit.model.channels import Channel
from kfcrit.model.system import System
from kfcrit.sim.engine import initial_covariance
from kfcrit.sim.results import ErgodicResult, SimulationResult
from kfcrit.sim.stats import finite_or_none, quiet_numerics


def tail_regime(system: System, channel: Channel, steps: int) -> dict[str, Any]:
    """How far sample means of tr P_t can be trusted at this operating point.

    * ``heavy_tailed``: a loss burst of length k has probability ∝ q^k (q = 1 − p for i.i.d.
      losses, q = 1 − r for Gilbert–Elliott) and multiplies P by about ρ(A)^{2k}, so
      E[(tr P)²] ≥ c Σ_k (q ρ⁴)^k: when q ρ(A)⁴ ≥ 1 the variance of tr P diverges (Mo–Sinopoli
      Cor. 2 with exponent 2 gives the same threshold for non-degenerate systems). The sample
      standard deviation then underestimates the spread, the ±5 se tolerance is no test, and
      the sample mean sits below the true mean most of the time. This happens for every p just
      above p_c (q ρ² < 1 ≤ q ρ⁴). ``None`` for a measured trace (no model).
    * ``settled``: tr S_T ≥ 0.95 tr S̄ for the Lyapunov recursion S_{t+1} = (1 − p) A S_t A' + Q
      from Σ0 (i.i.d. only): near p_c, (1 − p) ρ² → 1 and the mean needs far more than the
      horizon T to approach its limit, so limit bounds say nothing about E[tr P_T] yet.
    """
    rho = float(max(abs(np.linalg.eigvals(system.a)))) if system.n else 0.0
    proc = channel.arrival_process()
    if proc.kind == "iid":
        q, basis = 1.0 - float(proc.p), "(1 - p) rho(A)^4"
    elif proc.kind == "markov":
        q, basis = 1.0 - float(proc.recovery_rate), "(1 - r) rho(A)^4"
    else:
        q, basis = None, None
    with quiet_numerics():
        # numpy power: ρ⁴ beyond float64 is inf (the heavy tail is then certain), not an error
        value = None if q is None else float(q * np.float64(rho) ** 4)
    out: dict[str, Any] = {
        "variance_condition": basis,
        "variance_value": finite_or_none(value) if value is not None else None,
        "heavy_tailed": None if value is None else bool(not value < 1),
        "lyapunov_trace_at_horizon": None, "lyapunov_trace_limit": None, "settled": None}
    if proc.kind == "iid" and q * rho * rho < 1:
        from kfcrit.theory.bounds import lower_covariance

        S_T = lyapunov_traces(system, 1.0 - q, np.array([steps]))[0]
        with quiet_numerics():
            Sbar = lower_covariance(system.a, system.q, 1.0 - q)
        lim = float(np.trace(Sbar)) if Sbar is not None else None
        if S_T is not None and lim is not None and math.isfinite(lim):
            out.update(lyapunov_trace_at_horizon=S_T, lyapunov_trace_limit=lim,
                       settled=bool(S_T >= 0.95 * lim))
    return out


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
           status: str | None = None) -> dict[str, Any]:
    """One verification entry; ``status`` is passed / failed / inconclusive / not applicable."""
    st = status or {True: "passed", False: "failed", None: "not applicable"}[passed]
    out = {"check": check, "passed": passed, "status": st, "detail": detail}
    if reason:
        out["reason"] = reason
    return out


def simulation_checks(system: System, channel: Channel, res: SimulationResult,
                      erg: ErgodicResult, regime: dict[str, Any] | None = None
                      ) -> list[dict[str, Any]]:
    """Self-checks of the operating-point simulation: ``{check, passed, status, detail}``.

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
    out: list[dict[str, Any]] = []
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
        elif regime.get("heavy_tailed") or res.failed_paths:
            why = (f"{res.failed_paths} paths were frozen after a numerical failure, so "
                   "the simulated means are approximate" if res.failed_paths else
                   f"{regime['variance_condition']} = {regime['variance_value']:.4g} >= 1: the "
                   "variance of tr P diverges (heavy tails just above p_c), so the sample mean "
                   "and its standard error are unreliable at this horizon")
            out.append(_check(name, None, detail, reason=why, status="inconclusive"))
        else:
            out.append(_check(name, False, detail))
    return out
