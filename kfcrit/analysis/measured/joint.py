r"""A network whose sensors' traces were recorded together: the empirical joint law of the
received set S_t and the facts of mean stability under it (theory §13, §14).

Independent links would give P(S_t ⊆ T) = Π_{i∉T}(1 − p_i); time-aligned traces give its
empirical value, whatever the correlation (contention, shared fades). Under the empirical law
π̂ (taken i.i.d. in time) the facts are those of
:func:`kfcrit.theory.mesh.stability.law_stability`. With confidence c each necessary
constraint's probability gets a Clopper–Pearson interval at the simultaneous (Bonferroni) level
1 − (1 − c)/k over the k constraints:

.. math::

    \exists T:\ \underline P(S \subseteq T)\,\rho_T^2 \ge 1 \ \Rightarrow\ \text{unstable},
    \qquad
    \forall T:\ \overline P(S \subseteq T)\,\rho_T^2 < 1 \ \wedge\ E \ \Rightarrow\ \text{stable},

E being the exact-region proof (the necessary condition is then also sufficient). A sufficient
certificate found at π̂ alone is reported, not extended to the region.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import sympy as sp

from kfcrit.analysis import verdict as vd
from kfcrit.analysis.measured.section import (
    JointConstraintFit,
    JointLawFit,
    SensorTraceFit,
)
from kfcrit.analysis.measured.single import MeasuredFit, fit_section, real_or_none
from kfcrit.errors import InputError
from kfcrit.link.tracefit import clopper_pearson, fit_trace, joint_law, rows_to_decide
from kfcrit.model.network import Network
from kfcrit.theory.critical.compare import compare_probability
from kfcrit.theory.links.network import Constraint, necessary_constraints
from kfcrit.theory.mesh.law import JointLaw
from kfcrit.theory.mesh.stability import law_stability

MAX_LAW_CELLS_SHOWN = 256
"""The record lists π̂(S) for every S up to this many cells (8 sensors)."""


def network_traces(network: Network) -> list[np.ndarray] | None:
    """The sensors' traces when every sensor of the network has a trace channel (else None).

    Raises
    ------
    InputError
        Traces of unequal length: traces of one network are read as time-aligned (period k of
        every file is the same sampling period), so they must cover the same periods.
    """
    channels = [s.channel for s in network.sensors]
    if network.size < 2 or any(c is None or c.model != "trace" for c in channels):
        return None
    n0 = channels[0].arrivals.size
    for i, c in enumerate(channels):
        if c.arrivals.size != n0:
            raise InputError(f"has {c.arrivals.size} periods but sensor {network.names[0]!r}'s "
                             f"trace has {n0}: the traces of one network are read time-aligned "
                             "and must cover the same periods", field=f"sensors[{i}].channel.path")
    return [np.asarray(c.arrivals, dtype=bool) for c in channels]


def empirical_law(names: tuple[str, ...], counts: np.ndarray, n: int) -> JointLaw:
    """π̂(S) = counts/n as an exact law (bit i of the cell index = sensor i)."""
    return JointLaw(tuple(names), tuple(sp.Rational(int(k), int(n)) for k in counts), True,
                    "empirical (time-aligned traces)")


def _sign(prob: float, c: Constraint) -> int | None:
    """Sign of prob·ρ_T² − 1, decided exactly (None when undecidable)."""
    rho2 = c.mod2_expr if c.mod2_expr is not None else sp.Rational(c.mod2)
    try:
        return compare_probability(sp.Rational(prob) * rho2, 1)
    except ArithmeticError:
        return None


@dataclass(frozen=True)
class ConstraintEvidence:
    """One necessary constraint's row of the record and what decides it: the exact signs of
    P(S ⊆ T)·ρ_T² − 1 at the ends of the simultaneous interval (None: undecidable), the count
    of periods with S ⊆ T and the simultaneous level."""

    fit: JointConstraintFit
    sign_low: int | None
    sign_high: int | None
    count: int
    level: float


def constraint_rows(network: Network, traces: list[np.ndarray], cons: list[Constraint],
                    confidence: float) -> list[ConstraintEvidence]:
    """Each necessary constraint with its empirical probability, simultaneous interval and
    the product of marginals (independent links)."""
    level = 1.0 - (1.0 - confidence) / max(len(cons), 1)
    n = traces[0].size
    p_hat = np.array([t.mean() for t in traces])
    rows = []
    for c in cons:
        outside = [t for i, t in enumerate(traces) if i not in c.blind]
        within = ~np.any(outside, axis=0) if outside else np.ones(n, dtype=bool)
        k = int(within.sum())
        lo, hi = clopper_pearson(k, n, level)
        product = float(np.prod([1.0 - p_hat[i] for i in range(len(traces))
                                 if i not in c.blind]))
        mod2 = float(c.mod2)
        row = JointConstraintFit(
            unobservable=[network.names[i] for i in sorted(c.blind)], modulus2=mod2,
            probability=k / n, interval=[float(lo), float(hi)], product=product,
            value=k / n * mod2, value_low=lo * mod2, value_high=hi * mod2,
            product_value=product * mod2)
        rows.append(ConstraintEvidence(row, _sign(lo, c), _sign(hi, c), k, level))
    return rows


def joint_fit(network: Network, traces: list[np.ndarray], confidence: float, *,
              certify: bool = True) -> MeasuredFit:
    """The ``channel_fit`` section of a network of time-aligned traces and the verdict's
    inputs (theory §13, §14)."""
    ej = joint_law(traces, confidence)
    law = empirical_law(network.names, ej.counts, ej.n)
    ls = law_stability(network, law, certify=certify)
    cons = list(necessary_constraints(network))
    rows = constraint_rows(network, traces, cons, confidence)
    fails = [r for r in rows if r.sign_low is not None and r.sign_low >= 0]
    holds = all(r.sign_high is not None and r.sign_high < 0 for r in rows)
    binding = max(rows, key=lambda r: r.fit.value) if rows else None
    length = None
    decided = bool(fails) or (holds and bool(ls.exact_region))
    if binding is not None and not decided and (ls.exact_region or binding.fit.value >= 1):
        length = rows_to_decide(binding.fit.probability, 1.0 / binding.fit.modulus2,
                                binding.level)
    c = vd.confidence_text(confidence)
    fails_basis = holds_basis = ""
    if fails:
        f = max(fails, key=lambda r: r.fit.value_low).fit
        fails_basis = (f"the joint law of the time-aligned traces gives P(S ⊆ "
                       f"{set_text(f.unobservable)}) ≥ {f.interval[0]:.6g} (lower end "
                       f"of its simultaneous {c} interval), and that times ρ_T² = "
                       f"{f.modulus2:.6g} is {f.value_low:.6g} ≥ 1: the necessary "
                       "condition fails on the whole confidence region (theory §13)")
    if holds:
        top = max(rows, key=lambda r: r.fit.value_high).fit if rows else None
        holds_basis = ("every upper end of the simultaneous intervals keeps P(S ⊆ T)·ρ_T² < 1"
                       + (f" (largest {top.value_high:.6g})" if top else "")
                       + "; the necessary condition is also sufficient here ("
                       + ls.exact_region_reason + ")")
    inputs = vd.JointLawInputs(confidence, ls.facts, bool(fails), holds,
                               bool(ls.exact_region), fails_basis, holds_basis, length)
    any_received = np.any(traces, axis=0)
    fit = fit_trace(any_received, confidence)
    p_hat = np.array([t.mean() for t in traces])
    independent = None if not cons else all(c.factor(p_hat) < 1 for c in cons)
    covered = decided
    necessary = ls.facts.necessary
    law = JointLawFit(
        sensors=list(network.names), n=int(ej.n), confidence=float(confidence),
        p_all_lost=float(ej.p_all_lost),
        p_all_lost_interval=[float(v) for v in ej.p_all_lost_interval],
        p_all_lost_product=float(ej.p_all_lost_product),
        all_lost_ratio=real_or_none(ej.all_lost_ratio),
        law=([float(v) for v in ej.counts / ej.n]
             if ej.counts.size <= MAX_LAW_CELLS_SHOWN else []),
        constraints=[r.fit for r in rows],
        necessary=None if necessary is None else bool(necessary),
        sufficient=bool(ls.facts.sufficient), exact_region=bool(ls.exact_region),
        independent_necessary=None if independent is None else bool(independent),
        region_covered=covered, statement=_statement(covered, ls.reason))
    section = fit_section(
        fit, any_received,
        subject="at least one sensor received (the network's time-aligned traces)",
        length_to_decide=length,
        length_to_decide_basis=(
            "decided: the whole confidence region is on one side" if decided else
            "the binding constraint's probability against 1/ρ_T²" if length is not None
            else "no trace length decides at the estimated law"),
        sensors=[_sensor_row(name, t, confidence) for name, t in zip(network.names, traces)],
        joint_law=law,
        notes=["the sensors' traces are read time-aligned (period k of each is the same "
               "sampling period): the joint law of the received set replaces the product of "
               "independent links (theory §13)",
               f"the fit above is of the trace 'at least one sensor received'; the "
               f"likelihood-ratio p-value {fit.lrt_p_value:.3g} tests whether it is i.i.d. in "
               "time, as the joint-law theory assumes"])
    return MeasuredFit(section, None, inputs)


def set_text(names: list[str]) -> str:
    """A sensor set as text: ``∅`` (every packet lost) or ``{a, b}``."""
    return "{" + ", ".join(names) + "}" if names else "∅"


def _statement(covered: bool, reason: str) -> str:
    if covered:
        return "the facts hold on the whole confidence region of the joint law"
    return ("the confidence region of the joint law is not covered: only the necessary "
            "condition is bounded over it (simultaneous intervals); the point estimate's facts "
            f"are given ({reason})")


def _sensor_row(name: str, trace: np.ndarray, confidence: float) -> SensorTraceFit:
    fit = fit_trace(trace, confidence)
    return SensorTraceFit(name=name, n=int(fit.n), p_hat=float(fit.p_hat),
                          p_interval=[float(v) for v in fit.p_interval],
                          failure_rate_hat=real_or_none(fit.failure_rate_hat),
                          recovery_rate_hat=real_or_none(fit.recovery_rate_hat),
                          lrt_p_value=float(fit.lrt_p_value))


def network_confidence(network: Network) -> float:
    """The confidence of a network's joint verdict: the highest its sensors' channels ask."""
    return max(float(getattr(s.channel, "confidence", 0.95)) for s in network.sensors)


__all__ = ["MAX_LAW_CELLS_SHOWN", "ConstraintEvidence", "constraint_rows", "empirical_law", "joint_fit",
           "network_confidence", "network_traces", "set_text"]
