r"""View model of the measured-trace part of the report (``channel_fit``, theory §13, §14).

The fits with their exact intervals, the model choice, the confidence region's corners and what
is proven there, the burst-length histogram against the geometric law of r̂ and, for a network
of traces, the joint law of the received set against the product of the marginals:

.. math:: \hat\pi(\emptyset) \ \text{vs}\ \prod_i (1 - \hat p_i).

Every value is the record's, formatted here so that the template only lays it out.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Any

from kfcrit.views.report.parts import figure_entry, prose, stated

if TYPE_CHECKING:
    from kfcrit.analysis.measured.section import (
        BurstLengthHistogram,
        ChannelFitSection,
        ConfidenceRegion,
        JointLawFit,
        SensorTraceFit,
    )
    from kfcrit.analysis.sections import AnalysisRecord

FACT_TEXT = {True: "holds", False: "fails", None: "undecided"}
OUTCOME_TEXT = {"holds": "mean stability is proven on the whole region",
                "fails": "the necessary condition fails on the whole region",
                "neither": "the region straddles the stability boundary: not decided"}


def _num(v: Any, digits: int = 6) -> str:
    return "—" if v is None else f"{float(v):.{digits}g}"


def _interval(iv: list[float] | None) -> str:
    return f"[{_num(iv[0])}, {_num(iv[1])}]" if iv is not None and len(iv) == 2 else "—"


def fit_rows(fit: ChannelFitSection) -> list[dict[str, str]]:
    """The estimates with their intervals, the test and the length that would decide."""
    c = _num(100 * float(fit.confidence or 0), 4)
    rows = [{"label": "trace", "value": f"{fit.n} periods",
             "note": prose(fit.subject)},
            {"label": "arrival probability p̂", "value": _num(fit.p_hat),
             "note": f"{c} % Clopper–Pearson interval {_interval(fit.p_interval)}"},
            {"label": "failure rate f̂", "value": _num(fit.failure_rate_hat),
             "note": f"interval {_interval(fit.failure_rate_interval)} (Bonferroni: "
                     f"the rectangle has confidence {c} %)"},
            {"label": "recovery rate r̂", "value": _num(fit.recovery_rate_hat),
             "note": f"interval {_interval(fit.recovery_rate_interval)}"},
            {"label": "likelihood-ratio test", "value": f"p = {_num(fit.lrt_p_value, 3)}",
             "note": f"i.i.d. against Markov losses (χ², 1 dof, statistic "
                     f"{_num(fit.lrt_statistic, 4)}): model {fit.model}"}]
    rows.append({"label": "trace length to decide",
                 "value": "—" if fit.length_to_decide is None
                 else f"{fit.length_to_decide} periods",
                 "note": prose(fit.length_to_decide_basis)})
    return rows


def corner_rows(region: ConfidenceRegion) -> list[dict[str, str]]:
    """The worst and best corners of the region with the facts proven there."""
    rows = []
    for key, c in (("worst", region.worst), ("best", region.best)):
        where = (f"p = {_num(c.arrival_probability)}"
                 if c.arrival_probability is not None else
                 f"(f, r) = ({_num(c.failure_rate)}, {_num(c.recovery_rate)})")
        rows.append({"corner": key, "where": where,
                     "necessary": FACT_TEXT.get(c.necessary, "—"),
                     "sufficient": "proven" if c.sufficient else "not proven",
                     "basis": prose(c.basis)})
    return rows


def burst_rows(bursts: BurstLengthHistogram) -> list[dict[str, str]]:
    """Observed complete loss runs per length against the geometric law's expected counts."""
    lengths, counts, expected = bursts.lengths, bursts.counts, bursts.expected
    return [{"length": str(j), "observed": str(k),
             "expected": _num(expected[i], 4) if len(expected) == len(lengths) else "—"}
            for i, (j, k) in enumerate(zip(lengths, counts))]


def joint_view(joint: JointLawFit | None) -> dict[str, Any] | None:
    """The joint law of a network's time-aligned traces against independent links."""
    if joint is None:
        return None
    rows = []
    for c in joint.constraints:
        members = [str(m) for m in c.unobservable]
        rows.append({"set": "{" + ", ".join(members) + "}" if members else "∅",
                     "probability": _num(c.probability),
                     "interval": _interval(c.interval),
                     "value": f"{_num(c.value)} in [{_num(c.value_low)}, "
                              f"{_num(c.value_high)}]",
                     "product": _num(c.product_value)})
    return {"summary": (f"{len(joint.sensors)} sensors over {joint.n} "
                        f"time-aligned periods: P(all lost) = {_num(joint.p_all_lost)} "
                        f"{_interval(joint.p_all_lost_interval)}, while independent links "
                        f"with the same marginals would give "
                        f"{_num(joint.p_all_lost_product)} (ratio "
                        f"{_num(joint.all_lost_ratio, 4)})."),
            "constraints": rows, "statement": prose(joint.statement),
            "independent": FACT_TEXT.get(joint.independent_necessary, "—")}


def fit_sensor_rows(sensors: list[SensorTraceFit]) -> list[dict[str, str]]:
    """Each sensor's own trace (its marginal)."""
    return [{"name": prose(s.name), "p": _num(s.p_hat),
             "interval": _interval(s.p_interval),
             "f": _num(s.failure_rate_hat), "r": _num(s.recovery_rate_hat),
             "lrt": _num(s.lrt_p_value, 3)} for s in sensors]


def measured_view(rec: AnalysisRecord, figures: dict[str, str | None]) -> dict[str, Any]:
    """Everything the ``_channel_fit`` partial shows (``available`` False without a trace)."""
    fit = stated(rec.channel_fit)
    if fit is None:
        return {"available": False}
    region = fit.region
    op = rec.operating_point
    bursts = fit.bursts
    figs = figures
    return {
        "available": True, "rows": fit_rows(fit),
        "verdict": op.verdict.value if op is not None else None,
        "basis": prose(op.basis) if op is not None else "",
        "region": ({"corners": corner_rows(region),
                    "outcome": OUTCOME_TEXT.get(region.outcome, "—")}
                   if region is not None else None),
        "bursts": burst_rows(bursts),
        "burst_test": (f"Pearson X² = {_num(bursts.statistic, 4)}, "
                       f"{bursts.dof} dof, p-value "
                       f"{_num(bursts.p_value, 3)}"
                       if bursts.p_value is not None else
                       "too few loss runs for a goodness-of-fit test"),
        "joint": joint_view(fit.joint_law),
        "sensors": fit_sensor_rows(fit.sensors or []),
        "notes": [prose(n) for n in fit.notes or []],
        "burst_figure": figure_entry(
            figs.get("burst_histogram"), "Loss bursts of the trace",
            "Complete loss runs (a reception on both sides) by length, against the geometric "
            "law (1 − r̂)^(j−1)·r̂ of the fitted Gilbert–Elliott chain (theory §14).",
            "burst histogram: no complete loss run in the trace"),
        "region_figure": figure_entry(
            figs.get("fit_region"), "Confidence region in the (f, r) plane",
            "The Bonferroni rectangle of the failure and recovery rates, the fit, and the "
            "stability boundary: below r = 1 − 1/ρ(A)² the burst condition (1 − r)ρ(A)² < 1 "
            "fails for every f (theory §10); above the sufficient curve the coupled certificate "
            "proves mean stability (for a scalar plant the boundary itself is exact, theory §7).",
            "confidence region: the trace has no estimable rates"),
    }


__all__ = ["burst_rows", "corner_rows", "fit_rows", "joint_view", "measured_view",
           "fit_sensor_rows"]
