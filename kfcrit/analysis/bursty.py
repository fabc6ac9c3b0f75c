"""The bursty-link section of the analysis record: mean stability under Gilbert–Elliott losses.

theory §7: a loss burst lasts j steps with probability (1 − r)^{j−1} r; for a scalar system P
grows like a^{2j} during a burst, so E[P] is bounded iff (1 − r)·a² < 1. For n > 1 the same test
with a = ρ(A) is labelled as what it is (a claim for non-degenerate systems, a necessary
condition otherwise). The scalar theorem is checked with the project's one random-Riccati
simulator, :func:`kfcrit.sim.montecarlo.simulate`.
"""
from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np

from kfcrit.analysis import verdict as vd
from kfcrit.io.typed import to_json
from kfcrit.model.channels import Channel, GilbertElliott
from kfcrit.model.system import System
from kfcrit.records.bursty import (
    BurstCondition,
    BurstSimulationCheck,
    GilbertElliottSection,
    LiteratureClaim,
)
from kfcrit.sim.montecarlo import simulate
from kfcrit.theory.critical.section import critical_value
from kfcrit.theory.links.markov import burst_necessary

GE_CLAIMS: tuple[dict[str, str], ...] = (
    {"statement": "Kalman filtering with Markovian (Gilbert-Elliott) packet losses: conditions "
                  "for the stability of the peak covariance (sufficient in general, necessary "
                  "and sufficient for some classes of systems).",
     "source": "M. Huang, S. Dey, Stability of Kalman filtering with Markovian packet losses, "
               "Automatica 43(4), 2007",
     "status": "claim from the literature (not verified by kfcrit)"},
    {"statement": "For non-degenerate systems the mean error covariance is bounded iff "
                  "(1 - r) |lambda_1|^2 < 1, whatever the failure rate f; for second-order "
                  "systems the condition depends on the structure of (A, C) and reduces to the "
                  "i.i.d. critical value when f + r = 1.",
     "source": "K. You, M. Fu, L. Xie, Mean square stability for Kalman filtering with "
               "Markovian packet losses, Automatica 47(12), 2011",
     "status": "claim from the literature (not verified by kfcrit)"},
)
"""Literature results beyond the scalar case, labelled as claims (theory §7)."""

GE_SIM_PATHS = 4000
GE_SIM_MIN_LOST = 100
"""The horizon keeps about this many paths that have lost every packet since t = 0."""
GE_SIM_STEPS = (8, 400)
GE_SIM_BOUNDED_STEPS = 40
"""Least horizon when the condition holds (E[P_t] must have settled to show that it is bounded)."""
GE_GROWTH_FACTOR = 2.0
"""E[P_T] / E[P_{T/2}] above this reads as growing, below as bounded."""


def ge_horizon(a: float, failure: float, recovery: float, paths: int = GE_SIM_PATHS) -> int:
    """Horizon T of the simulation check of :func:`gilbert_elliott_section` for the scalar ``a``.

    When (1 − r)a² > 1, E[P_t] grows like ((1 − r)a²)^t through the paths that have lost every
    packet since the start; a sample of ``paths`` paths estimates it only while about
    :data:`GE_SIM_MIN_LOST` such paths remain: paths·π_loss·(1 − r)^T ≈ 100 with π_loss =
    f/(f + r). Beyond that horizon the sample mean saturates (it is a mean of a heavy-tailed
    variable) and would wrongly look bounded. When the condition holds the horizon is at least
    :data:`GE_SIM_BOUNDED_STEPS`, so that the mean has settled.
    """
    lo, hi = GE_SIM_STEPS
    if recovery >= 1:
        steps = hi
    else:
        pi_loss = failure / (failure + recovery)
        steps = int(math.floor(math.log(GE_SIM_MIN_LOST / (paths * pi_loss))
                               / math.log1p(-recovery)))
    if (1 - recovery) * a * a < 1:
        steps = max(steps, GE_SIM_BOUNDED_STEPS)
    return max(lo, min(hi, steps))


def ge_simulation_check(system: System, channel: GilbertElliott, *, paths: int = GE_SIM_PATHS,
                        steps: int | None = None, seed: int = 0) -> dict[str, Any]:
    """Sample means of tr P at T/2 and T under the Gilbert–Elliott channel, and their ratio.

    Runs :func:`kfcrit.sim.montecarlo.simulate` (P_0 = Σ0, the chain started in its stationary
    law). The ratio E[P_T]/E[P_{T/2}] is near 1 when E[P_t] is bounded and about
    ((1 − r)a²)^{T/2} when it grows (T from :func:`ge_horizon` unless given). The ratio is
    formed from the log10 means, so it stays finite where the means overflow float64.

    Returns
    -------
    dict
        ``paths, steps, seed, horizon_rule, mean_half, mean_end, growth_ratio,
        expected_growth_if_unbounded, capped`` (``capped``: a mean exceeded float64 and is
        given as inf; the ratio is still exact).
    """
    f = float(channel.failure_rate)
    r = float(channel.recovery_rate)
    a = float(max(abs(np.linalg.eigvals(system.a))))
    if steps is None:
        steps = ge_horizon(a, f, r, paths)
    res = simulate(system, paths=paths, steps=steps, seed=seed, channel=channel,
                   horizon_samples=steps + 1, track_lambda_max=False)
    times = list(res.times)
    i_half, i_end = times.index(steps // 2), times.index(steps)
    log_mean = (res.log10_mean_trace if res.log10_mean_trace is not None
                else np.log10(res.mean_trace))
    half, end = float(res.mean_trace[i_half]), float(res.mean_trace[i_end])
    ratio = float(10.0 ** (log_mean[i_end] - log_mean[i_half]))
    value = (1 - r) * a * a
    return {"paths": paths, "steps": steps, "seed": seed,
            "horizon_rule": f"about {GE_SIM_MIN_LOST} paths lose every packet up to T "
                            f"(T in [{GE_SIM_STEPS[0]}, {GE_SIM_STEPS[1]}], at least "
                            f"{GE_SIM_BOUNDED_STEPS} when the condition holds)",
            "mean_half": half, "mean_end": end,
            "growth_ratio": ratio if math.isfinite(ratio) else None,
            "expected_growth_if_unbounded": (float(value ** (steps - steps // 2))
                                             if value > 1 else None),
            "capped": not (math.isfinite(half) and math.isfinite(end)),
            "simulator": "kfcrit.sim.montecarlo.simulate"}


def simulation_record(sim: dict[str, Any]) -> BurstSimulationCheck:
    """The record of :func:`ge_simulation_check`'s result (non-finite means are None)."""
    return BurstSimulationCheck(
        paths=int(sim["paths"]), steps=int(sim["steps"]), seed=int(sim["seed"]),
        horizon_rule=sim["horizon_rule"], mean_half=_finite(sim["mean_half"]),
        mean_end=_finite(sim["mean_end"]), growth_ratio=_finite(sim["growth_ratio"]),
        expected_growth_if_unbounded=_finite(sim["expected_growth_if_unbounded"]),
        capped=bool(sim["capped"]), simulator=sim["simulator"])


def _finite(x: float | None) -> float | None:
    """A finite float, else None (the record holds no NaN or infinity)."""
    return None if x is None or not math.isfinite(x) else float(x)


def ge_condition_status(system: Any, classification: str, c_nonzero: bool) -> tuple[str, bool]:
    """(label of the condition, whether it is a theorem that decides mean stability)."""
    if classification == "stable":
        return ("theorem: rho(A) < 1, so E[P_t] is bounded for every loss process "
                "(the condition holds trivially)", True)
    if classification == "not-detectable":
        return ("not applicable: (C, A) is not detectable, E[P_t] diverges for every loss "
                "process", False)
    if system.n == 1 and c_nonzero:
        return ("theorem (scalar case, docs/theory.md §7: a loss burst lasts j steps with probability "
                "(1 - r)^(j-1) r and multiplies P by about a^(2j))", True)
    if classification == "non-degenerate":
        return ("claim: necessary and sufficient for non-degenerate systems (You-Fu-Xie 2011, "
                "see claims); not verified by kfcrit", False)
    return (f"necessary condition only (claim, loss-burst argument of docs/theory.md §7 applied to "
            f"lambda_1); no sufficient condition is implemented for a {classification} system "
            "(You-Fu-Xie 2011 give structure-dependent conditions for second-order systems)",
            False)


def _condition_holds(system: Any, recovery_rate: Any, value: float) -> bool:
    r"""(1 − r)ρ(A)² < 1, decided exactly where r and ρ(A)² are exact
    (:func:`kfcrit.theory.links.markov.burst_necessary`); the float ``value`` only when the
    exact decision is out of reach.

    .. math::  (1 - r)\,\rho(A)^2 < 1
    """
    holds = burst_necessary(system, recovery_rate).holds
    return bool(value < 1) if holds is None else bool(holds)


def gilbert_elliott_section(system: Any, channel: Channel, *, seed: int = 0,
                            simulate: bool = True,
                            classification: str | None = None) -> dict[str, Any]:
    """The JSON form of :func:`gilbert_elliott_record` (``{"applicable": False, "reason"}``
    for a channel that is not a :class:`GilbertElliott` model)."""
    if not isinstance(channel, GilbertElliott):
        return {"applicable": False, "reason": "the channel is not a Gilbert-Elliott model"}
    return to_json(gilbert_elliott_record(system, channel, seed=seed, simulate=simulate,
                                          classification=classification))


def gilbert_elliott_record(system: Any, channel: GilbertElliott, *, seed: int = 0,
                           simulate: bool = True,
                           classification: str | None = None) -> GilbertElliottSection:
    """Mean stability under Gilbert–Elliott losses (theory §7).

    Scalar case (theorem): losses arrive in bursts of length j with probability
    (1 − r)^{j−1} r, and P grows like a^{2j} during a burst (while after an arrival it is at most
    R/c²), so E[P] is bounded iff (1 − r)·a² < 1, i.e. the recovery rate r exceeds 1 − 1/a²
    (the i.i.d. critical value; f does not enter). It is checked by :func:`ge_simulation_check`
(the project's random-Riccati simulator, :func:`kfcrit.sim.montecarlo.simulate`).
    For n > 1 the same test with a = ρ(A) is labelled as what it is: a claim from the literature
    for non-degenerate systems, a necessary condition only otherwise.

    Parameters
    ----------
    system : System
        The system.
    channel : GilbertElliott
        The configured bursty channel.
    seed : int
        Seed of the simulation check.
    simulate : bool
        Run the simulation check (scalar case only).

    Returns
    -------
    GilbertElliottSection
        ``applicable, failure_rate, recovery_rate, stationary_arrival_probability,
        mean_burst_length, spectral_radius, classification, condition {expression, value, holds,
        status, decides}, required_recovery_rate, max_mean_burst_length, simulation | null,
        simulation_consistent | null, simulation_note, claims`` (the certificate and the
        critical curve are added by the analysis, :func:`kfcrit.analysis.record.bursty_link_section`).
    """
    f = float(channel.failure_rate)
    r = float(channel.recovery_rate)
    a = float(max(abs(np.linalg.eigvals(system.a))))
    value = (1 - r) * a * a
    if classification is None:
        classification = critical_value(system).classification
    scalar = system.n == 1
    c_nonzero = bool(np.any(system.c != 0))
    status, decides = ge_condition_status(system, classification, c_nonzero)
    r_min = max(0.0, 1 - 1 / (a * a)) if a > 0 else 0.0
    out: dict[str, Any] = {"simulation": None, "simulation_consistent": None,
                           "simulation_note": None}
    # the scalar theorem, and the literature's claim for non-degenerate vector systems, are both
    # checked by simulation (small systems: each path-step costs O(n³))
    claim = classification == "non-degenerate" and system.n <= 6
    if simulate and (scalar and decides or claim) and classification != "stable":
        sim = ge_simulation_check(system, channel, seed=seed)
        out["simulation"] = simulation_record(sim)
        expected = sim["expected_growth_if_unbounded"]
        if abs(value - 1) < 0.15:
            out["simulation_note"] = ("(1 - r) a^2 is within 0.15 of 1: a simulation of this "
                                      "size cannot tell bounded from growing; not compared")
        elif value > 1 and (expected is None or expected < 2 * GE_GROWTH_FACTOR):
            out["simulation_note"] = ("the horizon a simulation can resolve is too short for "
                                      "the predicted growth to show; not compared")
        elif sim["growth_ratio"] is not None:
            out["simulation_consistent"] = (sim["growth_ratio"] < GE_GROWTH_FACTOR) == \
                (value < 1)
            reading = "bounded" if sim["growth_ratio"] < GE_GROWTH_FACTOR else "growing"
            out["simulation_note"] = (f"E[P_T]/E[P_T/2] = {sim['growth_ratio']:.4g} at T = "
                                      f"{sim['steps']}; read as {reading} (threshold "
                                      f"{GE_GROWTH_FACTOR:g})")
    return GilbertElliottSection(
        applicable=True, failure_rate=f, recovery_rate=r,
        stationary_arrival_probability=r / (f + r), mean_burst_length=1 / r, spectral_radius=a,
        classification=classification,
        condition=BurstCondition(expression="(1 - r) a^2 < 1", value=_finite(value),
                                 holds=_condition_holds(system, channel.recovery_rate, value),
                                 status=status, decides=decides),
        required_recovery_rate=r_min, max_mean_burst_length=(1 / r_min) if r_min > 0 else None,
        claims=[LiteratureClaim(statement=c["statement"], source=c["source"],
                                status=c["status"]) for c in GE_CLAIMS], **out)


def bursty_link_section(spec: Any, opts: Any, theory: Any, ge: GilbertElliott,
                        timings: dict[str, float] | None = None,
                        path: str = "link_budget") -> GilbertElliottSection:
    """The Gilbert–Elliott section of a bursty chain: the conditions of theory §7 (scalar) and
    §10 (any system: the necessary burst condition and the coupled fixed-gain certificate,
    :func:`kfcrit.theory.links.markov.burst_facts`) and, with ``details``, the critical curve in the
    (failure rate, recovery rate) plane. ``theory`` is the system's
    :class:`~kfcrit.analysis.record.TheorySections`, ``opts`` the analysis options; the
    theory builds the certificate and the curve as their records (their wall-clock seconds go
    into ``timings``)."""
    from kfcrit.theory.links import markov

    s = spec.system
    cls = theory.classification
    out = gilbert_elliott_record(s, ge, seed=opts.seed, simulate=opts.details,
                                 classification=cls)
    if cls == "not-detectable":
        return out
    bv = markov.burst_facts(s, ge.failure_rate, ge.recovery_rate, structure=theory.structure,
                            classification=cls)
    claim = (None if bv.claim is None else
             (vd.Verdict.MEAN_STABLE if bv.claim["stable_if_true"] else
              vd.Verdict.MEAN_UNSTABLE).value)
    out = replace(out, certificate=bv.record(vd.verdict_of(bv.facts)[0].value, claim))
    if timings is not None and bv.certificate is not None:
        timings[f"{path}.certificate.certificate.seconds"] = bv.certificate.seconds
    if opts.details and s.n <= 12 and cls != "stable":
        points = 5 if opts.quick else 9
        grid = sorted({round(k / points, 12) for k in range(1, points + 1)}
                      | {0.01, float(ge.failure_rate)})
        curve = markov.burst_critical_curve(
            s, failure_rates=grid, tol=1e-2 if opts.quick else 1e-3,
            operating=(float(ge.failure_rate), float(ge.recovery_rate)),
            structure=theory.structure)
        out = replace(out, critical_curve=curve.record())
        if timings is not None:
            timings[f"{path}.critical_curve.seconds"] = curve.seconds
    return out
