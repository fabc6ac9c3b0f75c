r"""One measured trace: its fits, the corners of its confidence region and what the theory
proves at each corner (theory §7, §10, §14).

The stable set is an up-set in p for i.i.d. losses and, for Gilbert–Elliott losses, an up-set
in r and a down-set in f (theory §10), so the worst corner of the region decides stability on
all of it and the best corner decides instability:

.. math::

    \text{Bernoulli: } p_{lo} \text{ (worst)},\ p_{hi} \text{ (best)};\qquad
    \text{Gilbert–Elliott: } (f_{hi}, r_{lo}) \text{ (worst)},\ (f_{lo}, r_{hi}) \text{ (best)}.

At a Gilbert–Elliott corner the necessary condition (1 − r)ρ(A)² < 1 is decided exactly
(r against 1 − 1/ρ²), and the sufficient one is the exact scalar condition (theory §7) or the
coupled fixed-gain certificate :func:`kfcrit.theory.links.markov.burst_facts` (theory §10).
This module gathers facts; :func:`kfcrit.analysis.verdict.measured_verdict` decides.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from kfcrit.analysis import verdict as vd
from kfcrit.analysis.measured.section import (
    BurstLengthHistogram,
    ChannelFitSection,
    ConfidenceRegion,
    JointLawFit,
    RegionCorner,
    SensorTraceFit,
    StabilityBoundary,
)
from kfcrit.link.tracefit import (
    ChannelFit,
    fit_trace,
    lrt_iid_vs_markov,
    rows_to_decide,
    transition_counts,
)
from kfcrit.model.system import System

CURVE_MAX_STATES = 4
"""Largest n whose sufficient curve r_suf(f) is drawn in the (f, r) plane (it costs a
certificate search per point)."""


@dataclass(frozen=True)
class MeasuredFit:
    """The ``channel_fit`` section and the verdict's inputs."""

    section: ChannelFitSection
    inputs: vd.MeasuredInputs | None
    joint: vd.JointLawInputs | None = None


def plant_spectral_radius(system: System) -> float:
    """ρ(A) in floats (for the figures and texts; decisions use the exact p_low)."""
    return float(max(abs(np.linalg.eigvals(system.a)))) if system.n else 0.0


def real_or_none(x: Any) -> float | None:
    """A statistic as a Python float; None when missing or not finite (JSON has no
    infinity)."""
    if x is None:
        return None
    f = float(x)
    return f if math.isfinite(f) else None


def burst_section(fit: ChannelFit) -> BurstLengthHistogram:
    """The burst-length histogram of a fit in the record's form (Python numbers)."""
    b = fit.bursts
    return BurstLengthHistogram(
        lengths=[int(v) for v in b.lengths], counts=[int(c) for c in b.counts],
        expected=[float(e) for e in b.expected], runs=int(b.runs), censored=int(b.censored),
        mean_length=real_or_none(b.mean_length),
        fitted_recovery_rate=real_or_none(fit.recovery_rate_hat),
        statistic=real_or_none(b.statistic), dof=None if b.dof is None else int(b.dof),
        p_value=real_or_none(b.p_value))


def fit_section(fit: ChannelFit, arrivals: Any, *, subject: str, length_to_decide: int | None,
                length_to_decide_basis: str, region: ConfidenceRegion | None = None,
                boundary: StabilityBoundary | None = None,
                sensors: list[SensorTraceFit] | None = None,
                joint_law: JointLawFit | None = None,
                notes: list[str] | None = None) -> ChannelFitSection:
    """The ``channel_fit`` section: the fit itself (theory §14) and the parts given."""
    stat, _ = lrt_iid_vs_markov(transition_counts(arrivals))
    return ChannelFitSection(
        subject=subject, model=str(fit.model), n=int(fit.n), p_hat=float(fit.p_hat),
        p_interval=[float(v) for v in fit.p_interval],
        failure_rate_hat=real_or_none(fit.failure_rate_hat),
        failure_rate_interval=[float(v) for v in fit.failure_rate_interval],
        recovery_rate_hat=real_or_none(fit.recovery_rate_hat),
        recovery_rate_interval=[float(v) for v in fit.recovery_rate_interval],
        lrt_statistic=float(stat), lrt_p_value=float(fit.lrt_p_value),
        confidence=float(fit.confidence),
        length_to_decide=None if length_to_decide is None else int(length_to_decide),
        length_to_decide_basis=length_to_decide_basis, bursts=burst_section(fit),
        region=region, boundary=boundary, sensors=sensors, joint_law=joint_law, notes=notes)


# ----------------------------------------------------------------------------- i.i.d. corners

def iid_facts(p: float, crit: vd.CriticalInputs) -> tuple[bool | None, bool, str]:
    """(necessary, sufficient, basis) of mean stability at i.i.d. arrival probability ``p``:
    p above p_c (or the lower end of its bracket) is necessary, above p_c and its robust value
    (or the upper end p_up) sufficient — compared exactly with
    :func:`kfcrit.analysis.verdict.exceeds`."""
    if crit.classification == "stable" and crit.robust is None:
        return True, True, "ρ(A) < 1"
    if crit.critical is not None:
        pc = crit.critical_exact if crit.critical_exact is not None else crit.critical
        worst = max(crit.critical, crit.robust if crit.robust is not None else crit.critical)
        nec = bool(vd.exceeds(p, pc))
        suf = nec and bool(vd.exceeds(p, worst))
        return nec, suf, f"p = {p:.6g} against p_c = {crit.critical:.6g}"
    lo = crit.lower if crit.lower is not None else 0.0
    nec = bool(vd.exceeds(p, lo))
    suf = crit.upper is not None and bool(vd.exceeds(p, crit.upper))
    up = "unknown" if crit.upper is None else f"{crit.upper:.6g}"
    return nec, suf, f"p = {p:.6g} against the bracket [{lo:.6g}, {up}] of p_c"


def iid_threshold(p_hat: float, crit: vd.CriticalInputs) -> tuple[float | None, str]:
    """The value p̂'s interval must exclude for a verdict, and how it is named; None when no
    trace length decides (p̂ inside the bracket of p_c, or ρ(A) < 1)."""
    if crit.classification == "stable" and crit.robust is None:
        return None, "ρ(A) < 1: every arrival probability is stable"
    if crit.critical is not None:
        worst = max(crit.critical, crit.robust if crit.robust is not None else crit.critical)
        if p_hat > worst:
            return worst, f"p_c = {worst:.6g}"
        if p_hat <= crit.critical:
            return crit.critical, f"p_c = {crit.critical:.6g}"
        return None, "p̂ lies between p_c and its robust value"
    lo = crit.lower if crit.lower is not None else 0.0
    if crit.upper is not None and p_hat > crit.upper:
        return crit.upper, f"p_up = {crit.upper:.6g}"
    if p_hat <= lo:
        return lo, f"the lower end {lo:.6g} of the bracket of p_c"
    return None, "p̂ lies inside the bracket of p_c: a longer trace cannot decide"


# ----------------------------------------------------------------------------- GE corners

def iid_corner(p: float, crit: vd.CriticalInputs) -> RegionCorner:
    """The facts of :func:`iid_facts` at arrival probability ``p``, as a corner of the
    region."""
    nec, suf, basis = iid_facts(p, crit)
    return RegionCorner(arrival_probability=float(p), failure_rate=None, recovery_rate=None,
                        necessary=None if nec is None else bool(nec), sufficient=bool(suf),
                        basis=basis)


def burst_corner(system: System, crit: vd.CriticalInputs, f: float, r: float, *,
                 sufficient: bool, structure: Any = None
                 ) -> tuple[vd.BurstInputs, RegionCorner]:
    r"""The facts at one corner (f, r) of the Gilbert–Elliott rectangle.

    Necessary: (1 − r)ρ² < 1 ⇔ r > 1 − 1/ρ² = p_low (exactly). With ``sufficient`` the
    sufficient condition is sought: for a scalar plant the exact condition of theory §7
    ((1 − r)a² < 1 is also sufficient), else the coupled certificate of theory §10.
    """
    def corner(nec: bool | None, suf: bool, basis: str) -> RegionCorner:
        return RegionCorner(arrival_probability=None, failure_rate=float(f),
                            recovery_rate=float(r), necessary=nec, sufficient=suf, basis=basis)

    p_low = crit.p_low_exact if crit.p_low_exact is not None else crit.p_low
    if crit.classification == "stable" and crit.robust is None:
        return vd.BurstInputs(r, f, True, "ρ(A) < 1"), corner(True, True, "ρ(A) < 1")
    nec = True if not crit.p_low else bool(vd.exceeds(r, p_low))
    basis = (f"(1 − r)·ρ(A)² = {(1.0 - r) / (1.0 - crit.p_low):.6g}" if crit.p_low and
             crit.p_low < 1 else "(1 − r)·ρ(A)² < 1")
    suf, why = False, None
    if nec and sufficient:
        if system.n == 1:
            suf, why = True, (f"scalar plant: (1 − r)·a² < 1 at r = {r:.6g} is necessary and "
                              "sufficient (theory §7)")
        else:
            from kfcrit.theory.links import markov

            facts = markov.burst_facts(system, f, r, structure=structure,
                                       classification=crit.classification)
            suf, why = bool(facts.facts.sufficient), facts.basis
    return (vd.BurstInputs(r, f, True if suf else None, why),
            corner(bool(nec), bool(suf), why or basis))


def _outcome(worst: RegionCorner, best: RegionCorner) -> str:
    if worst.sufficient:
        return "holds"
    if best.necessary is False:
        return "fails"
    return "neither"


def ge_length(fit: ChannelFit, crit: vd.CriticalInputs, n_states: int) -> tuple[int | None, str]:
    """Trace length at which the interval of r̂ would exclude the burst boundary 1 − 1/ρ²."""
    if crit.classification == "stable" and crit.robust is None:
        return None, "ρ(A) < 1: every channel is stable"
    if not crit.p_low or fit.recovery_rate_hat is None:
        return None, "the recovery rate is not estimable from this trace"
    f, r = fit.failure_rate_hat, fit.recovery_rate_hat
    if f is None or f == 0:
        return None, "no loss started in the trace"
    m = rows_to_decide(r, crit.p_low, 1.0 - (1.0 - fit.confidence) / 2.0)
    extra = "" if n_states == 1 else "; the certificate's curve may need more"
    if m is None:
        return None, f"r̂ = 1 − 1/ρ² = {crit.p_low:.6g}"
    return 1 + int(np.ceil(m * (f + r) / f)), f"r against 1 − 1/ρ(A)² = {crit.p_low:.6g}{extra}"


# ----------------------------------------------------------------------------- boundary

def boundary_section(system: System, crit: vd.CriticalInputs, fit: ChannelFit, *,
                     curve: bool, structure: Any = None) -> StabilityBoundary:
    """The stability boundary of the (f, r) plane: r = 1 − 1/ρ² and, for small vector plants,
    the sufficient curve of the coupled certificate (theory §10)."""
    rho = plant_spectral_radius(system)
    nec = crit.p_low if crit.p_low else (max(0.0, 1.0 - 1.0 / rho ** 2) if rho > 1 else None)

    def boundary(note: str, failure_rates: Any = (), sufficient: Any = ()
                 ) -> StabilityBoundary:
        return StabilityBoundary(spectral_radius=real_or_none(rho),
                                 necessary_recovery=real_or_none(nec),
                                 failure_rates=[float(v) for v in failure_rates],
                                 sufficient_recovery=[real_or_none(v) for v in sufficient],
                                 note=note)

    if nec is None:
        return boundary("ρ(A) ≤ 1: no burst boundary")
    if system.n == 1:
        return boundary("scalar plant: (1 − r)a² < 1 is necessary and sufficient (theory §7)")
    if not curve or system.n > CURVE_MAX_STATES:
        return boundary("sufficient curve not computed (only for plants of at most "
                        f"{CURVE_MAX_STATES} states with a Gilbert–Elliott fit)")
    from kfcrit.theory.links import markov

    hi = fit.failure_rate_interval[1]
    grid = sorted({round(k / 6, 6) for k in range(1, 7)} | {round(min(max(hi, 1e-3), 1.0), 6)})
    cc = markov.burst_critical_curve(system, failure_rates=grid, tol=1e-2, structure=structure)
    return boundary("sufficient curve: least r with a coupled fixed-gain certificate (width "
                    "1e-2, theory §10)", cc.failure_rates, cc.sufficient_recovery)


# ----------------------------------------------------------------------------- the section

def trace_fit(system: System, arrivals: Any, confidence: float, crit: vd.CriticalInputs, *,
              details: bool = True, structure: Any = None) -> MeasuredFit:
    """Fit a single trace channel and gather the facts at the corners of its region."""
    fit = fit_trace(arrivals, confidence)
    if fit.model == "bernoulli":
        lo, hi = fit.p_interval
        worst, best = iid_corner(lo, crit), iid_corner(hi, crit)
        threshold, text = iid_threshold(fit.p_hat, crit)
        length = None if threshold is None else rows_to_decide(fit.p_hat, threshold,
                                                               fit.confidence)
        inputs = vd.MeasuredInputs("bernoulli", fit.confidence, worst_p=lo, best_p=hi,
                                   length_to_decide=length, threshold_text=text)
    else:
        (f_lo, f_hi), (r_lo, r_hi) = fit.failure_rate_interval, fit.recovery_rate_interval
        w_in, worst = burst_corner(system, crit, f_hi, r_lo, sufficient=True,
                                   structure=structure)
        b_in, best = burst_corner(system, crit, f_lo, r_hi, sufficient=system.n == 1,
                                  structure=structure)
        length, text = ge_length(fit, crit, system.n)
        inputs = vd.MeasuredInputs("gilbert-elliott", fit.confidence, worst_burst=w_in,
                                   best_burst=b_in, length_to_decide=length,
                                   threshold_text=text)
    outcome = _outcome(worst, best)
    decided = outcome != "neither"  # a decided region needs no longer trace
    section = fit_section(
        fit, arrivals, subject="the channel's trace",
        length_to_decide=None if decided else inputs.length_to_decide,
        length_to_decide_basis=("decided: the whole confidence region is on one side"
                                if decided else inputs.threshold_text),
        region=ConfidenceRegion(model=str(fit.model), confidence=float(fit.confidence),
                                worst=worst, best=best, outcome=outcome),
        boundary=boundary_section(system, crit, fit, structure=structure,
                                  curve=details and fit.model == "gilbert-elliott"),
        notes=model_notes(fit))
    return MeasuredFit(section, inputs)


def model_notes(fit: ChannelFit) -> list[str]:
    """What the reader should know about the model choice."""
    out = [f"model chosen by the likelihood-ratio test at level {1 - fit.confidence:.3g}: "
           f"p-value {fit.lrt_p_value:.3g} → {fit.model}"]
    b = fit.bursts
    if b.p_value is not None and b.p_value < 1 - fit.confidence:
        out.append(f"the burst lengths do not fit the geometric law of r̂ (X² p-value "
                   f"{b.p_value:.3g}): losses may have more memory than a two-state chain, "
                   "and the verdict rests on the two-state model")
    return out


__all__ = ["CURVE_MAX_STATES", "MeasuredFit", "boundary_section", "burst_corner",
           "burst_section", "fit_section", "ge_length", "iid_corner", "iid_facts",
           "iid_threshold", "model_notes", "plant_spectral_radius", "real_or_none", "trace_fit"]
