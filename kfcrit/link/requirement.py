r"""The binding arrival-probability requirement of a link design (theory §3, §11).

A link must deliver at least the stability requirement p_stab (p_c, its robust value, or the
upper end of the bracket when p_c is unknown). An accuracy requirement lim E[tr P] ≤ L adds the
interval [p_S, p_V] of the accuracy design (:func:`kfcrit.theory.covariance.design.required_arrival`):
p ≥ p_V meets L, p ≤ p_S fails it, between them the bounds S̄ ⪯ lim E[P] ⪯ V̄ do not decide.
The design value is the binding one,

.. math:: p_{\mathrm{design}} = \max(p_{\mathrm{stab}},\ p_V),

the least arrival probability that is *guaranteed* to meet both. When p_V binds and p_S < p_V
the true threshold is not decided: p_V is the guaranteed value, and below p_S the requirement
certainly fails. An accuracy requirement no arrival probability meets (L below the no-loss
floor) leaves no design value; one whose interval could not be computed leaves the stability
value, labelled as such.

Every consumer (the link-budget section, its policy check, the sweep columns, the views) reads
the one value computed here.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from kfcrit.io.typed import ABSENT
from kfcrit.records.link import Accuracy, RequiredArrivalDesign

ACCURACY_BASIS = "accuracy requirement (p_V, sufficient)"
"""Short basis word (sweep tables) when p_V of the accuracy design binds."""
ACCURACY_IMPOSSIBLE_BASIS = "accuracy requirement (unreachable)"
"""Short basis word (sweep tables) when no arrival probability meets the accuracy requirement."""


def stability_requirement(critical_value: float | None, robust_value: float | None,
                          bracket: tuple[float | None, float | None] | None,
                          upper_bound: float | None) -> tuple[float | None, str]:
    """The arrival probability mean stability needs, and why.

    max(p_c, robust value) when p_c is known; otherwise the upper end of the bracket (or p_up):
    exceeding it is sufficient for mean stability.
    """
    if critical_value is not None:
        if robust_value is not None and robust_value > critical_value:
            return robust_value, "robust critical value"
        return critical_value, "critical value p_c"
    high = bracket[1] if bracket and bracket[1] is not None else upper_bound
    if high is not None:
        return high, "upper end of the bracket (sufficient; p_c unknown)"
    return None, "no requirement known"


@dataclass(frozen=True)
class BindingRequirement:
    """The design's required arrival probability and its basis (see the module docstring).

    ``binding`` is ``"stability"``, ``"accuracy"`` or ``"none"``; ``fails_below`` is p_S when
    the accuracy design binds (below it the accuracy requirement certainly fails);
    ``determined`` is False when the value is only the sufficient end of an undecided interval
    or when the accuracy interval could not be computed. ``accuracy`` is None when the system
    file has no accuracy requirement (the record then holds exactly the stability fields).
    """

    value: float | None
    basis: str
    short_basis: str | None
    binding: str
    stability_value: float | None
    stability_basis: str
    accuracy: Accuracy | None = None
    fails_below: float | None = None
    determined: bool = True

    def record(self, critical_value: float | None, robust_value: float | None,
               bracket: tuple[float | None, float | None]) -> RequiredArrivalDesign:
        """``link_budget.required_arrival_probability``: the stability inputs, the design
        value and its basis, and (with an accuracy requirement) how it binds."""
        accuracy = self.accuracy is not None
        return RequiredArrivalDesign(
            critical_value=critical_value, robust_value=robust_value, bracket=list(bracket),
            design_value=self.value, basis=self.basis,
            binding=self.binding if accuracy else ABSENT,
            stability_value=self.stability_value if accuracy else ABSENT,
            stability_basis=self.stability_basis if accuracy else ABSENT,
            accuracy=self.accuracy if accuracy else ABSENT,
            fails_below=self.fails_below if accuracy else ABSENT,
            determined=self.determined if accuracy else ABSENT,
            short_basis=self.short_basis if accuracy else ABSENT)


def _accuracy_summary(accuracy: Any) -> Accuracy:
    """The accuracy design's requirement and interval as the link section states it, from the
    record's typed ``design`` section or its plain (JSON) form."""
    if isinstance(accuracy, Mapping):
        req = accuracy.get("required_arrival_probability") or {}
        return Accuracy(requirement=accuracy.get("requirement"), status=req.get("status"),
                        interval=list(req["interval"]) if req.get("interval") else None,
                        p_S_certified=(req.get("p_S") or {}).get("certified"),
                        p_V_certified=(req.get("p_V") or {}).get("certified"),
                        reason=req.get("reason"))
    req = accuracy.required_arrival_probability
    return Accuracy(requirement=accuracy.requirement, status=req.status,
                    interval=list(req.interval) if req.interval else None,
                    p_S_certified=req.p_S.certified, p_V_certified=req.p_V.certified,
                    reason=req.reason)


def binding_requirement(stability: tuple[float | None, str],
                        accuracy: Any = None) -> BindingRequirement:
    r"""The binding required arrival probability: max(p_stab, p_V).

    Parameters
    ----------
    stability : (float or None, str)
        The stability requirement and its basis (:func:`stability_requirement`).
    accuracy : AccuracyDesign or mapping, optional
        The record's ``design`` section of an accuracy requirement (typed, or its JSON form):
        ``requirement`` (its text) and ``required_arrival_probability`` {status, interval
        [p_S, p_V], p_S, p_V, reason}.

    Returns
    -------
    BindingRequirement

    Notes
    -----
    .. math:: p_{\mathrm{design}} = \max(p_{\mathrm{stab}}, p_V), \qquad
              p < p_S \Rightarrow \lim E[\operatorname{tr} P] > L.
    """
    p_stab, stab_basis = stability
    stab_short = None if p_stab is None else stab_basis
    if not accuracy:
        return BindingRequirement(p_stab, stab_basis, stab_short,
                                  "none" if p_stab is None else "stability", p_stab, stab_basis)
    summary = _accuracy_summary(accuracy)
    name = summary.requirement or "the accuracy requirement"
    status = summary.status
    if status == "impossible":
        return BindingRequirement(
            None, f"accuracy requirement {name}: no arrival probability meets it ("
            f"{summary.reason or 'L is below the no-loss floor'})", ACCURACY_IMPOSSIBLE_BASIS,
            "accuracy", p_stab, stab_basis, summary, fails_below=1.0, determined=True)
    if status != "interval" or not summary.interval:
        return BindingRequirement(
            p_stab, f"{stab_basis}; the accuracy requirement {name} is not included: its "
            f"required interval was not computed ({summary.reason or status})", stab_short,
            "none" if p_stab is None else "stability", p_stab, stab_basis, summary,
            determined=False)
    p_s, p_v = (float(v) for v in summary.interval)
    if p_stab is not None and p_stab >= p_v:
        return BindingRequirement(
            p_stab, f"{stab_basis} (binds: the accuracy requirement {name} is met from p_V = "
            f"{p_v:.6g})", stab_short, "stability", p_stab, stab_basis, summary)
    exact = p_s == p_v
    tail = ("p_S = p_V: the bounds decide it exactly" if exact else
            f"guaranteed; the bounds leave [p_S, p_V] = [{p_s:.6g}, {p_v:.6g}] undecided, "
            "at or below p_S it fails")
    return BindingRequirement(
        p_v, f"accuracy requirement {name}, sufficient end p_V ({tail})", ACCURACY_BASIS,
        "accuracy", p_stab, stab_basis, summary, fails_below=p_s, determined=exact)
