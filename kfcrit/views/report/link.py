"""View model of the channel section: the configured channel, the link budget and its design
outputs, and the Gilbert–Elliott burst condition (theory §7)."""
from __future__ import annotations

from typing import Any

from markupsafe import Markup

from kfcrit.views import formatting as filters
from kfcrit.views.figures import mathsvg
from kfcrit.views.report.parts import (
    as_dict,
    as_list,
    closed_form_text,
    missing,
    number,
    prose,
    row,
    safe_svg,
)

CHANNEL_NAMES = {"bernoulli": "Bernoulli (i.i.d. losses)",
                 "gilbert-elliott": "Gilbert–Elliott (bursty, two-state Markov losses)",
                 "trace": "measured arrival trace", "link-budget": "radio link budget"}


def channel_rows(channel: dict[str, Any]) -> list[dict[str, Any]]:
    """The configured channel as labelled rows with units (nested mappings flattened by hand)."""
    model = channel.get("model")
    p = row("arrival probability p", channel.get("arrival_probability"), "prob",
            note=f"= {filters.pretty_expr(closed_form_text(channel['arrival_probability_expression']))}"
            if closed_form_text(channel.get("arrival_probability_expression")) else "")
    rows = [row("model", None, note=str(CHANNEL_NAMES.get(str(model), model)))]
    if model == "gilbert-elliott":
        rows += [row("failure rate f = P(lost | received before)", channel.get("failure_rate"),
                     "prob"),
                 row("recovery rate r = P(received | lost before)",
                     channel.get("recovery_rate"), "prob"),
                 row("stationary arrival probability r / (f + r)",
                     channel.get("arrival_probability"), "prob", note=p["note"]),
                 row("mean loss-burst length 1 / r", channel.get("mean_burst_length"), "num",
                     note="packets")]
    elif model == "link-budget":
        radio = as_dict(channel.get("radio"))
        pl = as_dict(channel.get("path_loss"))
        # The numbers of the budget itself (powers, SINR, p) are in the budget table.
        rows += [row("radio", radio.get("model"), note=str(radio.get("source") or "")),
                 row("path-loss model", pl.get("model"), note=prose(pl.get("formula"))),
                 row("shadowing σ", pl.get("shadowing_sigma_db"), "dB",
                     note=str(pl.get("shadowing") or "")),
                 row("arrival probability p", channel.get("arrival_probability"), "prob",
                     note=str(channel.get("arrival_probability_basis") or "")),
                 row("margin policy", channel.get("margin_db"), "dB",
                     note=f"at most {filters.pct(channel.get('max_outage'))} shadowing outage"
                     if number(channel.get("max_outage")) is not None else "")]
    elif model == "trace":
        rows += [row("trace file", channel.get("path")),
                 row("length", channel.get("length"), "count", note="packets"), p]
    else:
        rows.append(p)
    return rows


def channel_summary(channel: dict[str, Any]) -> str:
    """One line for the verdict box: the channel's defining numbers with units."""
    model = channel.get("model")
    if model == "gilbert-elliott":
        return (f"Gilbert–Elliott: failure rate {filters.prob(channel.get('failure_rate'))}, "
                f"recovery rate {filters.prob(channel.get('recovery_rate'))}, mean loss burst "
                f"{filters.num(channel.get('mean_burst_length'), 4)} packets")
    if model == "link-budget":
        radio = as_dict(channel.get("radio")).get("model") or "radio"
        return (f"{radio}: {filters.unit(channel.get('tx_power_dbm'), 'dBm')} at "
                f"{filters.unit(channel.get('distance_m'), 'm')}, "
                f"{filters.num(channel.get('packet_bytes'))}-byte packets, SINR "
                f"{filters.unit(channel.get('sinr_db'), 'dB')} "
                f"({channel.get('arrival_probability_basis') or 'median link'})")
    if model == "trace":
        return f"measured trace {channel.get('path')} ({filters.count(channel.get('length'))} " \
               "packets)"
    return CHANNEL_NAMES.get(str(model), str(model or "channel"))


def link_design_view(rec: dict[str, Any]) -> dict[str, Any] | None:
    """The link-budget design outcome for the verdict box (None for other channels)."""
    lb = as_dict(rec.get("link_budget"))
    if not lb.get("applicable"):
        return None
    if "condition" in lb:   # Gilbert–Elliott
        cond = as_dict(lb.get("condition"))
        return {"kind": "bursty", "status": cond.get("holds"),
                "text": f"recovery rate r = {filters.prob(lb.get('recovery_rate'))} must exceed "
                        f"1 − 1/a² = {filters.prob(lb.get('required_recovery_rate'))}, i.e. mean "
                        f"loss bursts of at most "
                        f"{filters.num(number(lb.get('max_mean_burst_length')), 4)} packets "
                        f"({prose(cond.get('status')) or 'status unknown'})"}
    dc = as_dict(lb.get("design_check"))
    req = as_dict(lb.get("required_arrival_probability"))
    parts = [f"link margin {filters.unit(lb.get('link_margin_db'), 'dB')} at "
             f"{filters.unit(dc.get('distance_m'), 'm')}"]
    if dc.get("required_margin_db") is not None:
        parts[0] += f" (policy needs {filters.unit(dc.get('required_margin_db'), 'dB')})"
    if req.get("accuracy") is not None:
        # an accuracy requirement may bind instead of p_c: say which value the margin is read at
        parts.insert(0, "required arrival probability "
                     + (f"{filters.prob(req.get('design_value'))} ({prose(req.get('basis'))})"
                        if req.get("design_value") is not None
                        else f"unreachable ({prose(req.get('basis'))})"))
    if lb.get("max_distance_unbounded"):
        parts.append("no distance limit at the margin policy")
    elif lb.get("max_distance_m") is not None:
        parts.append(f"maximum distance at the margin policy "
                     f"{filters.unit(lb.get('max_distance_m'), 'm')}")
    if dc.get("outage_probability") is not None:
        parts.append(f"shadowing outage {filters.pct(dc.get('outage_probability'))}"
                     + (f" (policy allows {filters.pct(dc.get('max_outage'))})"
                        if dc.get("max_outage") is not None else ""))
    met = dc.get("margin_policy_met")
    if dc.get("outage_within_policy") is False:
        met = False
    return {"kind": "link", "status": met, "text": "; ".join(parts)}



LINK_CHAIN = (("transmit power", "tx_power_dbm", "dBm"), ("antenna gains", "antenna_gain_db", "dB"),
              ("distance", "distance_m", "m"), ("path loss (median)", "path_loss_db", "dB"),
              ("received power (median)", "rx_power_dbm", "dBm"),
              ("noise bandwidth", "bandwidth_hz", "Hz"),
              ("receiver noise figure", "noise_figure_db", "dB"),
              ("noise temperature", "temperature_k", "K"),
              ("thermal noise floor", "noise_floor_dbm", "dBm"),
              ("interference", "interference_dbm", "dBm"),
              ("noise + interference", "noise_plus_interference_dbm", "dBm"),
              ("SINR (median link)", "sinr_db", "dB"),
              ("bit error rate", "bit_error_rate", "prob"),
              ("packet size", "packet_bytes", "bytes"),
              ("packet error rate", "packet_error_rate", "prob"),
              ("arrival probability, median link", "arrival_probability_nominal", "prob"),
              ("arrival probability, averaged over shadowing", "arrival_probability_mean",
               "prob"),
              ("arrival probability used (operating p)", "arrival_probability", "prob"))
THRESHOLD_LABELS = {"critical_value": "critical value p_c",
                    "robust_critical_value": "robust critical value",
                    "bracket_low": "lower end of the p_c bracket",
                    "bracket_high": "upper end of the p_c bracket",
                    "upper_bound": "upper bound p_up", "design": "design requirement",
                    "accuracy_necessary": "accuracy requirement p_S (at or below: fails)",
                    "accuracy_sufficient": "accuracy requirement p_V (guarantees it)"}


def link_budget_view(lb: dict[str, Any]) -> dict[str, Any]:
    """A link-budget section: the budget chain, the design outputs and the threshold table."""
    link = as_dict(lb.get("link"))
    policy = as_dict(lb.get("margin_policy"))
    req = as_dict(lb.get("required_arrival_probability"))
    shadow = as_dict(lb.get("shadowing"))
    dc = as_dict(lb.get("design_check"))
    chain = [row(label, "none", "text") if key == "interference_dbm" and link.get(key) is None
             else row(label, link.get(key), kind)
             for label, key, kind in LINK_CHAIN if key in link]
    distance = link.get("distance_m")
    design = [
        row("required arrival probability", req.get("design_value"), "prob",
            note=prose(req.get("basis"))),
        row("required SINR", lb.get("required_sinr_db"), "dB",
            note="smallest SINR whose packet arrival probability exceeds the requirement"),
        row("required received power", lb.get("required_rx_power_dbm"), "dBm"),
        row("link margin at the configured distance", lb.get("link_margin_db"), "dB",
            note=(f"policy needs ≥ {filters.unit(dc.get('required_margin_db'), 'dB')}"
                  if dc.get("required_margin_db") is not None else ""),
            status=dc.get("margin_policy_met")),
        row("effective margin of the policy", policy.get("effective_margin_db"), "dB",
            note=f"max({filters.unit(policy.get('margin_db'), 'dB')}, σ·Φ⁻¹(1 − "
                 f"{filters.pct(policy.get('max_outage'))}))"
            if policy.get("max_outage") is not None else
            f"margin {filters.unit(policy.get('margin_db'), 'dB')}"),
        row("maximum distance at the margin policy",
            "unbounded" if lb.get("max_distance_unbounded") else lb.get("max_distance_m"),
            "text" if lb.get("max_distance_unbounded") else "m",
            note=f"configured distance {filters.unit(distance, 'm')}"
            if distance is not None else "",
            status=dc.get("margin_policy_met")),
        row("mean-stable at the configured distance (median link)",
            lb.get("mean_stable_at_distance"), "yesno", status=lb.get("mean_stable_at_distance")),
        row("shadowing", shadow.get("sigma_db"), "dB", note=f"σ, {shadow.get('mode')} "
            "(per-link: drawn once per deployed link; per-packet: i.i.d. per packet)"
            if shadow.get("mode") else "σ"),
        row("shadowing outage P(p_link ≤ design requirement)", dc.get("outage_probability",
            shadow.get("outage_below_critical")), "pct",
            note=f"policy allows {filters.pct(dc.get('max_outage'))}"
            if dc.get("max_outage") is not None else "",
            status=dc.get("outage_within_policy")),
        row("shadowing outage P(p_link ≤ p_up)", shadow.get("outage_below_upper"), "pct"),
        row("mean arrival probability over shadowing", shadow.get("mean_arrival_probability"),
            "prob"),
    ]
    thresholds = [{"label": THRESHOLD_LABELS.get(str(as_dict(t).get("label")),
                                                 filters.key_label(as_dict(t).get("label"))),
                   **{k: as_dict(t).get(k) for k in (
                       "arrival_probability", "required_sinr_db", "required_rx_power_dbm",
                       "link_margin_db", "max_distance_m", "max_distance_unbounded",
                       "outage_probability", "reachable")}}
                  for t in as_list(lb.get("thresholds"))]
    radio = as_dict(lb.get("radio"))
    half = (len(chain) + 1) // 2
    return {"chain": chain, "chain_columns": [chain[:half], chain[half:]],
            "design": design, "thresholds": thresholds,
            "radio": radio.get("model"), "radio_formula": prose(radio.get("formula")) or None,
            "radio_svg": radio_formula_svg(radio),
            "radio_source": radio.get("source"), "policy_rule": prose(policy.get("rule")),
            "notes": [prose(n) for n in as_list(lb.get("notes"))],
            "warnings": [prose(w) for w in as_list(lb.get("warnings"))]}


# Typeset forms of the radio models' BER formulas (the record carries them as ASCII text).
RADIO_LATEX = {
    "ieee802154-oqpsk-2450": (r"\mathrm{BER} = \frac{8}{15}\cdot\frac{1}{16}\sum_{k=2}^{16}"
                              r"(-1)^k \binom{16}{k}\,"
                              r"\exp\left(20\,\mathrm{SINR}\,\left(\frac{1}{k} - 1\right)\right)"),
    "bpsk": (r"\mathrm{BER} = Q\left(\sqrt{2E_b/N_0}\right) = "
             r"\frac{1}{2}\,\mathrm{erfc}\left(\sqrt{E_b/N_0}\right),\quad "
             r"E_b/N_0 = \mathrm{SINR}\cdot 10^{G/10}"),
}


def radio_formula_svg(radio: dict[str, Any]) -> Markup | None:
    """The radio model's BER formula typeset as SVG (``None``: shown as text instead)."""
    latex = RADIO_LATEX.get(str(radio.get("model")))
    return safe_svg(mathsvg.latex_svg(latex, fontsize=10.5, label=str(radio.get("formula") or "")
                                  or None)) if latex and radio.get("formula") else None


def bursty_view(lb: dict[str, Any]) -> dict[str, Any]:
    """A Gilbert–Elliott section: the burst condition (theory §7), its status and the claims."""
    cond = as_dict(lb.get("condition"))
    sim = as_dict(lb.get("simulation"))
    rows = [
        row("failure rate f", lb.get("failure_rate"), "prob", note="P(lost | received before)"),
        row("recovery rate r", lb.get("recovery_rate"), "prob", note="P(received | lost before)"),
        row("stationary arrival probability r/(f + r)", lb.get("stationary_arrival_probability"),
            "prob"),
        row("mean loss-burst length 1/r", lb.get("mean_burst_length"), "num", note="packets"),
        row("spectral radius ρ(A) = a", lb.get("spectral_radius"), "num"),
        row(f"burst condition {filters.pretty_text(cond.get('expression'))}", cond.get("value"),
            "num", note=("holds" if cond.get("holds") else "fails" if cond.get("holds") is False
                         else "not decided") + (f"; {prose(cond.get('status'))}"
                                                if cond.get("status") else ""),
            status=cond.get("holds")),
        row("required recovery rate 1 − 1/a²", lb.get("required_recovery_rate"), "prob",
            note="r must exceed this (f does not enter)"),
        row("longest admissible mean loss burst", lb.get("max_mean_burst_length"), "num",
            note="packets"),
    ]
    if sim:
        ratio = number(sim.get("growth_ratio"))
        consistent = lb.get("simulation_consistent")
        reading = "" if ratio is None else ("; reads as growing (bounded below 2)" if ratio >= 2
                                            else "; reads as bounded (below 2)")
        verdict = ("; agrees with the burst condition" if consistent else
                   "; DISAGREES with the burst condition" if consistent is False else "")
        rows.append(row("simulated growth of mean P (last / second quarter)",
                        sim.get("growth_ratio"), "num",
                        note=f"{filters.count(sim.get('paths'))} paths × "
                             f"{filters.count(sim.get('steps'))} steps, seed "
                             f"{filters.num(sim.get('seed'))}{reading}{verdict}"
                             + ("; capped" if sim.get("capped") else ""),
                        status=consistent))
    else:
        rows.append(row("simulation of the bursty channel", None,
                        note="not run: the dedicated simulation covers scalar systems only"))
    rows += certificate_rows(as_dict(lb.get("certificate")))
    claims = [{"statement": prose(as_dict(c).get("statement")),
               "source": str(as_dict(c).get("source") or ""),
               "status": str(as_dict(c).get("status") or "")} for c in as_list(lb.get("claims"))]
    return {"rows": rows, "claims": claims}


def certificate_rows(cert: dict[str, Any]) -> list[dict[str, Any]]:
    """The burst verdict for any system (theory §10): the necessary burst condition, the coupled
    fixed-gain certificate and the literature's claim, as the record states them."""
    if not cert:
        return []
    verdict = cert.get("verdict")
    rows = [row("burst verdict (docs/theory.md §10)", str(verdict).replace("-", " ") if verdict else None,
                note=prose(cert.get("basis")),
                status={"mean-stable": True, "mean-unstable": False}.get(str(verdict)))]
    nec = as_dict(cert.get("necessary"))
    if nec:
        rows.append(row("necessary burst condition (1 − r)·ρ(A)² < 1", nec.get("value"), "num",
                        note=("holds" if nec.get("holds") else "fails")
                        + (f"; {prose(nec.get('how'))}" if nec.get("how") else ""),
                        status=nec.get("holds")))
    coupled = as_dict(cert.get("certificate"))
    if coupled:
        rows.append(row("coupled fixed-gain certificate", coupled.get("spectral_radius"), "num",
                        note=("proven" if coupled.get("certified") else "not proven")
                        + " (spectral radius of the second-moment recursion, < 1 proves "
                        "E[P_t] bounded)"
                        + (f"; gain: {prose(coupled.get('gain_origin'))}"
                           if coupled.get("gain_origin") else ""),
                        status=coupled.get("certified")))
    else:
        rows.append(row("coupled fixed-gain certificate", None,
                        note="none in the record (not needed when the necessary condition "
                             "fails, or none was found)"))
    claim = as_dict(cert.get("claim"))
    if claim:
        rows.append(row("literature claim (not proven here)", None,
                        note=f"{prose(claim.get('statement'))}; if true the verdict would be "
                             f"{str(claim.get('verdict_if_true') or '?').replace('-', ' ')}"))
    return rows


def channel_view(rec: dict[str, Any]) -> dict[str, Any]:
    """The channel section: the configured channel, and its link budget or bursty analysis."""
    op = as_dict(rec.get("operating_point"))
    channel = as_dict(op.get("channel")) or as_dict(as_dict(rec.get("system")).get("channel"))
    lb = rec.get("link_budget")
    lbd = as_dict(lb)
    model = channel.get("model")
    view: dict[str, Any] = {
        "available": bool(channel), "model": model,
        "title": CHANNEL_NAMES.get(str(model), str(model or "")),
        "missing": missing("channel", "the system file has no channel section; add one "
                            "(bernoulli, gilbert-elliott, trace or link-budget) to get an "
                            "operating point and a verdict"),
        "rows": channel_rows(channel) if channel else [],
        "link": None, "bursty": None, "explanation": ""}
    if model == "link-budget":
        if lbd.get("applicable"):
            view["link"] = link_budget_view(lbd)
        else:
            view["explanation"] = missing("link budget", prose(lbd.get("reason") or
                                                              "no link-budget section"))
    elif model == "gilbert-elliott":
        if lbd.get("applicable"):
            view["bursty"] = bursty_view(lbd)
            view["rows"] = view["rows"][:1]   # the bursty table below has the rates
        else:
            view["explanation"] = missing("bursty-link analysis", prose(lbd.get("reason") or
                                                                        "no section"))
    elif channel:
        view["explanation"] = ("The arrival probability is given directly, so there is no link "
                               "budget to design; use channel model link-budget to derive p "
                               "from a radio link, or gilbert-elliott for bursty losses.")
    return view


