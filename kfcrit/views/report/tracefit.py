r"""View model of the measured-trace part of the report (``channel_fit``, theory §13, §14).

The fits with their exact intervals, the model choice, the confidence region's corners and what
is proven there, the burst-length histogram against the geometric law of r̂ and, for a network
of traces, the joint law of the received set against the product of the marginals:

.. math:: \hat\pi(\emptyset) \ \text{vs}\ \prod_i (1 - \hat p_i).

Every value is the record's, formatted here so that the template only lays it out.
"""
from __future__ import annotations

from typing import Any

from kfcrit.views.report.parts import as_dict, as_list, figure_entry, prose

FACT_TEXT = {True: "holds", False: "fails", None: "undecided"}
OUTCOME_TEXT = {"holds": "mean stability is proven on the whole region",
                "fails": "the necessary condition fails on the whole region",
                "neither": "the region straddles the stability boundary: not decided"}


def _num(v: Any, digits: int = 6) -> str:
    return "—" if v is None else f"{float(v):.{digits}g}"


def _interval(iv: Any) -> str:
    iv = as_list(iv)
    return f"[{_num(iv[0])}, {_num(iv[1])}]" if len(iv) == 2 else "—"


def fit_rows(fit: dict[str, Any]) -> list[dict[str, str]]:
    """The estimates with their intervals, the test and the length that would decide."""
    c = _num(100 * float(fit.get("confidence") or 0), 4)
    rows = [{"label": "trace", "value": f"{fit.get('n')} periods",
             "note": prose(fit.get("subject"))},
            {"label": "arrival probability p̂", "value": _num(fit.get("p_hat")),
             "note": f"{c} % Clopper–Pearson interval {_interval(fit.get('p_interval'))}"},
            {"label": "failure rate f̂", "value": _num(fit.get("failure_rate_hat")),
             "note": f"interval {_interval(fit.get('failure_rate_interval'))} (Bonferroni: "
                     f"the rectangle has confidence {c} %)"},
            {"label": "recovery rate r̂", "value": _num(fit.get("recovery_rate_hat")),
             "note": f"interval {_interval(fit.get('recovery_rate_interval'))}"},
            {"label": "likelihood-ratio test", "value": f"p = {_num(fit.get('lrt_p_value'), 3)}",
             "note": f"i.i.d. against Markov losses (χ², 1 dof, statistic "
                     f"{_num(fit.get('lrt_statistic'), 4)}): model {fit.get('model')}"}]
    rows.append({"label": "trace length to decide",
                 "value": "—" if fit.get("length_to_decide") is None
                 else f"{fit['length_to_decide']} periods",
                 "note": prose(fit.get("length_to_decide_basis"))})
    return rows


def corner_rows(region: dict[str, Any]) -> list[dict[str, str]]:
    """The worst and best corners of the region with the facts proven there."""
    rows = []
    for key in ("worst", "best"):
        c = as_dict(region.get(key))
        where = (f"p = {_num(c.get('arrival_probability'))}"
                 if c.get("arrival_probability") is not None else
                 f"(f, r) = ({_num(c.get('failure_rate'))}, {_num(c.get('recovery_rate'))})")
        rows.append({"corner": key, "where": where,
                     "necessary": FACT_TEXT.get(c.get("necessary"), "—"),
                     "sufficient": "proven" if c.get("sufficient") else "not proven",
                     "basis": prose(c.get("basis"))})
    return rows


def burst_rows(bursts: dict[str, Any]) -> list[dict[str, str]]:
    """Observed complete loss runs per length against the geometric law's expected counts."""
    lengths, counts = as_list(bursts.get("lengths")), as_list(bursts.get("counts"))
    expected = as_list(bursts.get("expected"))
    return [{"length": str(j), "observed": str(k),
             "expected": _num(expected[i], 4) if len(expected) == len(lengths) else "—"}
            for i, (j, k) in enumerate(zip(lengths, counts))]


def joint_view(joint: dict[str, Any]) -> dict[str, Any] | None:
    """The joint law of a network's time-aligned traces against independent links."""
    if not joint:
        return None
    rows = []
    for c in as_list(joint.get("constraints")):
        c = as_dict(c)
        members = [str(m) for m in as_list(c.get("unobservable"))]
        rows.append({"set": "{" + ", ".join(members) + "}" if members else "∅",
                     "probability": _num(c.get("probability")),
                     "interval": _interval(c.get("interval")),
                     "value": f"{_num(c.get('value'))} in [{_num(c.get('value_low'))}, "
                              f"{_num(c.get('value_high'))}]",
                     "product": _num(c.get("product_value"))})
    return {"summary": (f"{len(as_list(joint.get('sensors')))} sensors over {joint.get('n')} "
                        f"time-aligned periods: P(all lost) = {_num(joint.get('p_all_lost'))} "
                        f"{_interval(joint.get('p_all_lost_interval'))}, while independent links "
                        f"with the same marginals would give "
                        f"{_num(joint.get('p_all_lost_product'))} (ratio "
                        f"{_num(joint.get('all_lost_ratio'), 4)})."),
            "constraints": rows, "statement": prose(joint.get("statement")),
            "independent": FACT_TEXT.get(joint.get("independent_necessary"), "—")}


def fit_sensor_rows(sensors: list[Any]) -> list[dict[str, str]]:
    """Each sensor's own trace (its marginal)."""
    return [{"name": prose(s.get("name")), "p": _num(s.get("p_hat")),
             "interval": _interval(s.get("p_interval")),
             "f": _num(s.get("failure_rate_hat")), "r": _num(s.get("recovery_rate_hat")),
             "lrt": _num(s.get("lrt_p_value"), 3)} for s in map(as_dict, sensors)]


def measured_view(rec: dict[str, Any], figures: dict[str, str | None]) -> dict[str, Any]:
    """Everything the ``_channel_fit`` partial shows (``available`` False without a trace)."""
    fit = as_dict(as_dict(rec).get("channel_fit"))
    if not fit:
        return {"available": False}
    region = as_dict(fit.get("region"))
    op = as_dict(rec.get("operating_point"))
    figs = as_dict(figures)
    return {
        "available": True, "rows": fit_rows(fit),
        "verdict": op.get("verdict"), "basis": prose(op.get("basis")),
        "region": ({"corners": corner_rows(region),
                    "outcome": OUTCOME_TEXT.get(str(region.get("outcome")), "—")}
                   if region else None),
        "bursts": burst_rows(as_dict(fit.get("bursts"))),
        "burst_test": (f"Pearson X² = {_num(as_dict(fit.get('bursts')).get('statistic'), 4)}, "
                       f"{as_dict(fit.get('bursts')).get('dof')} dof, p-value "
                       f"{_num(as_dict(fit.get('bursts')).get('p_value'), 3)}"
                       if as_dict(fit.get("bursts")).get("p_value") is not None else
                       "too few loss runs for a goodness-of-fit test"),
        "joint": joint_view(as_dict(fit.get("joint_law"))),
        "sensors": fit_sensor_rows(as_list(fit.get("sensors"))),
        "notes": [prose(n) for n in as_list(fit.get("notes"))],
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
