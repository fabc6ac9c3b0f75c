"""View model of the channel section: the configured channel, the link budget and its design
outputs, and the Gilbert–Elliott burst condition (theory §7)."""
from __future__ import annotations

from typing import TYPE_CHECKING, Any

from markupsafe import Markup

from kfcrit.records.bursty import GilbertElliottSection
from kfcrit.records.channel import ChannelRecord
from kfcrit.records.link import LinkBudgetRecord
from kfcrit.views import formatting as filters
from kfcrit.views.figures import mathsvg
from kfcrit.views.report.parts import (
    closed_form_text,
    missing,
    number,
    prose,
    row,
    safe_svg,
    stated,
)

if TYPE_CHECKING:
    from kfcrit.analysis.sections import AnalysisRecord
    from kfcrit.records.bursty import BurstCertificateRecord
    from kfcrit.records.channel import MeshChannel, NetworkChannel
    from kfcrit.records.link import LinkState, RadioRecord

    AnyChannel = ChannelRecord | NetworkChannel | MeshChannel

CHANNEL_NAMES = {"bernoulli": "Bernoulli (i.i.d. losses)",
                 "gilbert-elliott": "Gilbert–Elliott (bursty, two-state Markov losses)",
                 "trace": "measured arrival trace", "link-budget": "radio link budget"}


def record_channel(rec: AnalysisRecord) -> AnyChannel | None:
    """The channel of the record: the operating point's, else the system file's."""
    return rec.operating_point.channel if rec.operating_point is not None else rec.system.channel


def channel_rows(channel: AnyChannel) -> list[dict[str, Any]]:
    """The configured channel as labelled rows with units (nested records flattened by hand)."""
    model = channel.model
    one = channel if isinstance(channel, ChannelRecord) else None
    expr = closed_form_text(one.arrival_probability_expression) if one else None
    p = row("arrival probability p", one.arrival_probability if one else None, "prob",
            note=f"= {filters.pretty_expr(expr)}" if expr else "")
    rows = [row("model", None, note=str(CHANNEL_NAMES.get(str(model), model)))]
    if one is not None and model == "gilbert-elliott":
        rows += [row("failure rate f = P(lost | received before)", stated(one.failure_rate),
                     "prob"),
                 row("recovery rate r = P(received | lost before)",
                     stated(one.recovery_rate), "prob"),
                 row("stationary arrival probability r / (f + r)",
                     one.arrival_probability, "prob", note=p["note"]),
                 row("mean loss-burst length 1 / r", stated(one.mean_burst_length), "num",
                     note="packets")]
    elif one is not None and model == "link-budget":
        radio, pl = stated(one.radio), stated(one.path_loss)
        max_outage = stated(one.max_outage)
        # The numbers of the budget itself (powers, SINR, p) are in the budget table.
        rows += [row("radio", radio.model if radio else None,
                     note=str(radio.source or "") if radio else ""),
                 row("path-loss model", pl.model if pl else None,
                     note=prose(pl.formula) if pl else ""),
                 row("shadowing σ", pl.shadowing_sigma_db if pl else None, "dB",
                     note=str(pl.shadowing or "") if pl else ""),
                 row("arrival probability p", one.arrival_probability, "prob",
                     note=str(stated(one.arrival_probability_basis) or "")),
                 row("margin policy", stated(one.margin_db), "dB",
                     note=f"at most {filters.pct(max_outage)} shadowing outage"
                     if number(max_outage) is not None else "")]
    elif one is not None and model == "trace":
        rows += [row("trace file", stated(one.path)),
                 row("length", stated(one.length), "count", note="packets"), p]
    else:
        rows.append(p)
    return rows


def channel_summary(channel: AnyChannel) -> str:
    """One line for the verdict box: the channel's defining numbers with units."""
    model = channel.model
    one = channel if isinstance(channel, ChannelRecord) else None
    if one is not None and model == "gilbert-elliott":
        return (f"Gilbert–Elliott: failure rate {filters.prob(stated(one.failure_rate))}, "
                f"recovery rate {filters.prob(stated(one.recovery_rate))}, mean loss burst "
                f"{filters.num(stated(one.mean_burst_length), 4)} packets")
    if one is not None and model == "link-budget":
        radio = stated(one.radio)
        return (f"{(radio.model if radio else None) or 'radio'}: "
                f"{filters.unit(stated(one.tx_power_dbm), 'dBm')} at "
                f"{filters.unit(stated(one.distance_m), 'm')}, "
                f"{filters.num(stated(one.packet_bytes))}-byte packets, SINR "
                f"{filters.unit(stated(one.sinr_db), 'dB')} "
                f"({stated(one.arrival_probability_basis) or 'median link'})")
    if one is not None and model == "trace":
        return f"measured trace {stated(one.path)} ({filters.count(stated(one.length))} " \
               "packets)"
    return CHANNEL_NAMES.get(str(model), str(model or "channel"))


def link_design_view(rec: AnalysisRecord) -> dict[str, Any] | None:
    """The link-budget design outcome for the verdict box (None for other channels)."""
    lb = rec.link_budget
    if lb is None or not lb.applicable:
        return None
    if isinstance(lb, GilbertElliottSection):
        cond = lb.condition
        return {"kind": "bursty", "status": cond.holds,
                "text": f"recovery rate r = {filters.prob(lb.recovery_rate)} must exceed "
                        f"1 − 1/a² = {filters.prob(lb.required_recovery_rate)}, i.e. mean "
                        f"loss bursts of at most "
                        f"{filters.num(number(lb.max_mean_burst_length), 4)} packets "
                        f"({prose(cond.status) or 'status unknown'})"}
    dc = lb.design_check
    req = lb.required_arrival_probability
    margin = ("unbounded" if dc.margin_unbounded
              else filters.unit(stated(lb.link_margin_db), 'dB'))
    parts = [f"link margin {margin} at {filters.unit(dc.distance_m, 'm')}"]
    if dc.required_margin_db is not None:
        parts[0] += f" (policy needs {filters.unit(dc.required_margin_db, 'dB')})"
    if stated(req.accuracy) is not None:
        # an accuracy requirement may bind instead of p_c: say which value the margin is read at
        parts.insert(0, "required arrival probability "
                     + (f"{filters.prob(req.design_value)} ({prose(req.basis)})"
                        if req.design_value is not None
                        else f"unreachable ({prose(req.basis)})"))
    if lb.max_distance_unbounded:
        parts.append("no distance limit at the margin policy")
    elif stated(lb.max_distance_m) is not None:
        parts.append(f"maximum distance at the margin policy "
                     f"{filters.unit(stated(lb.max_distance_m), 'm')}")
    if dc.outage_probability is not None:
        parts.append(f"shadowing outage {filters.pct(dc.outage_probability)}"
                     + (f" (policy allows {filters.pct(dc.max_outage)})"
                        if dc.max_outage is not None else ""))
    met = dc.margin_policy_met
    if dc.outage_within_policy is False:
        met = False
    return {"kind": "link", "status": met, "text": "; ".join(parts)}


def link_chain(link: LinkState) -> list[tuple[str, Any, str]]:
    """The budget chain, transmitter to arrival probability: ``(label, value, kind)``."""
    return [("transmit power", link.tx_power_dbm, "dBm"),
            ("antenna gains", link.antenna_gain_db, "dB"),
            ("distance", link.distance_m, "m"), ("path loss (median)", link.path_loss_db, "dB"),
            ("received power (median)", link.rx_power_dbm, "dBm"),
            ("noise bandwidth", link.bandwidth_hz, "Hz"),
            ("receiver noise figure", link.noise_figure_db, "dB"),
            ("noise temperature", link.temperature_k, "K"),
            ("thermal noise floor", link.noise_floor_dbm, "dBm"),
            # no interference is a value of its own, not a missing number
            ("interference", "none" if link.interference_dbm is None else link.interference_dbm,
             "text" if link.interference_dbm is None else "dBm"),
            ("noise + interference", link.noise_plus_interference_dbm, "dBm"),
            ("SINR (median link)", link.sinr_db, "dB"),
            ("bit error rate", link.bit_error_rate, "prob"),
            ("packet size", link.packet_bytes, "bytes"),
            ("packet error rate", link.packet_error_rate, "prob"),
            ("arrival probability, median link", link.arrival_probability_nominal, "prob"),
            ("arrival probability, averaged over shadowing", link.arrival_probability_mean,
             "prob"),
            ("arrival probability used (operating p)", link.arrival_probability, "prob")]


UNBOUNDED_MARGIN = ("the requirement is p > 0 (p_c = 0), which every SINR meets, so any "
                    "margin policy is met")
"""Note of the link-margin row when the margin is unbounded (``design_check.margin_unbounded``)."""


THRESHOLD_LABELS = {"critical_value": "critical value p_c",
                    "robust_critical_value": "robust critical value",
                    "bracket_low": "lower end of the p_c bracket",
                    "bracket_high": "upper end of the p_c bracket",
                    "upper_bound": "upper bound p_up", "design": "design requirement",
                    "accuracy_necessary": "accuracy requirement p_S (at or below: fails)",
                    "accuracy_sufficient": "accuracy requirement p_V (guarantees it)"}


def link_budget_view(lb: LinkBudgetRecord) -> dict[str, Any]:
    """A link-budget section: the budget chain, the design outputs and the threshold table."""
    policy = lb.margin_policy
    req = lb.required_arrival_probability
    shadow = lb.shadowing
    dc = lb.design_check
    chain = [row(label, value, kind) for label, value, kind in link_chain(lb.link)]
    distance = lb.link.distance_m
    design = [
        row("required arrival probability", req.design_value, "prob",
            note=prose(req.basis)),
        row("required SINR", stated(lb.required_sinr_db), "dB",
            note="smallest SINR whose packet arrival probability exceeds the requirement"),
        row("required received power", stated(lb.required_rx_power_dbm), "dBm"),
        row("link margin at the configured distance", stated(lb.link_margin_db), "dB",
            note=(f"policy needs ≥ {filters.unit(dc.required_margin_db, 'dB')}"
                  if dc.required_margin_db is not None else ""),
            status=dc.margin_policy_met) if not dc.margin_unbounded else
        row("link margin at the configured distance", "unbounded", "text",
            note=UNBOUNDED_MARGIN, status=True),
        row("effective margin of the policy", policy.effective_margin_db, "dB",
            note=f"max({filters.unit(policy.margin_db, 'dB')}, σ·Φ⁻¹(1 − "
                 f"{filters.pct(policy.max_outage)}))"
            if policy.max_outage is not None else
            f"margin {filters.unit(policy.margin_db, 'dB')}"),
        row("maximum distance at the margin policy",
            "unbounded" if lb.max_distance_unbounded else stated(lb.max_distance_m),
            "text" if lb.max_distance_unbounded else "m",
            note=f"configured distance {filters.unit(distance, 'm')}"
            if distance is not None else "",
            status=dc.margin_policy_met),
        row("mean-stable at the configured distance (median link)",
            lb.mean_stable_at_distance, "yesno", status=lb.mean_stable_at_distance),
        row("shadowing", shadow.sigma_db, "dB", note=f"σ, {shadow.mode} "
            "(per-link: drawn once per deployed link; per-packet: i.i.d. per packet)"
            if shadow.mode else "σ"),
        row("shadowing outage P(p_link ≤ design requirement)", dc.outage_probability, "pct",
            note=f"policy allows {filters.pct(dc.max_outage)}"
            if dc.max_outage is not None else "",
            status=dc.outage_within_policy),
        row("shadowing outage P(p_link ≤ p_up)", shadow.outage_below_upper, "pct"),
        row("mean arrival probability over shadowing", shadow.mean_arrival_probability,
            "prob"),
    ]
    thresholds = [{"label": THRESHOLD_LABELS.get(t.label, filters.key_label(t.label)),
                   "arrival_probability": t.arrival_probability,
                   "required_sinr_db": t.required_sinr_db,
                   "required_rx_power_dbm": t.required_rx_power_dbm,
                   "link_margin_db": t.link_margin_db, "max_distance_m": t.max_distance_m,
                   "max_distance_unbounded": t.max_distance_unbounded,
                   "outage_probability": t.outage_probability, "reachable": t.reachable}
                  for t in lb.thresholds]
    radio = lb.radio
    half = (len(chain) + 1) // 2
    return {"chain": chain, "chain_columns": [chain[:half], chain[half:]],
            "design": design, "thresholds": thresholds,
            "radio": radio.model, "radio_formula": prose(radio.formula) or None,
            "radio_svg": radio_formula_svg(radio),
            "radio_source": radio.source, "policy_rule": prose(policy.rule),
            "notes": [prose(n) for n in lb.notes],
            "warnings": [prose(w) for w in lb.warnings]}


# Typeset forms of the radio models' BER formulas (the record carries them as ASCII text).
RADIO_LATEX = {
    "ieee802154-oqpsk-2450": (r"\mathrm{BER} = \frac{8}{15}\cdot\frac{1}{16}\sum_{k=2}^{16}"
                              r"(-1)^k \binom{16}{k}\,"
                              r"\exp\left(20\,\mathrm{SINR}\,\left(\frac{1}{k} - 1\right)\right)"),
    "bpsk": (r"\mathrm{BER} = Q\left(\sqrt{2E_b/N_0}\right) = "
             r"\frac{1}{2}\,\mathrm{erfc}\left(\sqrt{E_b/N_0}\right),\quad "
             r"E_b/N_0 = \mathrm{SINR}\cdot 10^{G/10}"),
}


def radio_formula_svg(radio: RadioRecord) -> Markup | None:
    """The radio model's BER formula typeset as SVG (``None``: shown as text instead)."""
    latex = RADIO_LATEX.get(radio.model)
    return safe_svg(mathsvg.latex_svg(latex, fontsize=10.5, label=radio.formula or None)) \
        if latex and radio.formula else None


def bursty_view(lb: GilbertElliottSection) -> dict[str, Any]:
    """A Gilbert–Elliott section: the burst condition (theory §7), its status and the claims."""
    cond = lb.condition
    sim = lb.simulation
    rows = [
        row("failure rate f", lb.failure_rate, "prob", note="P(lost | received before)"),
        row("recovery rate r", lb.recovery_rate, "prob", note="P(received | lost before)"),
        row("stationary arrival probability r/(f + r)", lb.stationary_arrival_probability,
            "prob"),
        row("mean loss-burst length 1/r", lb.mean_burst_length, "num", note="packets"),
        row("spectral radius ρ(A) = a", lb.spectral_radius, "num"),
        row(f"burst condition {filters.pretty_text(cond.expression)}", cond.value,
            "num", note=("holds" if cond.holds else "fails" if cond.holds is False
                         else "not decided") + (f"; {prose(cond.status)}"
                                                if cond.status else ""),
            status=cond.holds),
        row("required recovery rate 1 − 1/a²", lb.required_recovery_rate, "prob",
            note="r must exceed this (f does not enter)"),
        row("longest admissible mean loss burst", lb.max_mean_burst_length, "num",
            note="packets"),
    ]
    if sim is not None:
        ratio = number(sim.growth_ratio)
        consistent = lb.simulation_consistent
        reading = "" if ratio is None else ("; reads as growing (bounded below 2)" if ratio >= 2
                                            else "; reads as bounded (below 2)")
        verdict = ("; agrees with the burst condition" if consistent else
                   "; DISAGREES with the burst condition" if consistent is False else "")
        rows.append(row("simulated growth of mean P (last / second quarter)",
                        sim.growth_ratio, "num",
                        note=f"{filters.count(sim.paths)} paths × "
                             f"{filters.count(sim.steps)} steps, seed "
                             f"{filters.num(sim.seed)}{reading}{verdict}"
                             + ("; capped" if sim.capped else ""),
                        status=consistent))
    else:
        rows.append(row("simulation of the bursty channel", None,
                        note="not run: the dedicated simulation covers scalar systems only"))
    rows += certificate_rows(stated(lb.certificate))
    claims = [{"statement": prose(c.statement), "source": c.source, "status": c.status}
              for c in lb.claims]
    return {"rows": rows, "claims": claims}


def certificate_rows(cert: BurstCertificateRecord | None) -> list[dict[str, Any]]:
    """The burst verdict for any system (theory §10): the necessary burst condition, the coupled
    fixed-gain certificate and the literature's claim, as the record states them."""
    if cert is None:
        return []
    verdict = cert.verdict
    rows = [row("burst verdict (docs/theory.md §10)", verdict.replace("-", " ") if verdict else None,
                note=prose(cert.basis),
                status={"mean-stable": True, "mean-unstable": False}.get(verdict))]
    nec = cert.necessary
    rows.append(row("necessary burst condition (1 − r)·ρ(A)² < 1", nec.value, "num",
                    note=("holds" if nec.holds else "fails")
                    + (f"; {prose(nec.how)}" if nec.how else ""),
                    status=nec.holds))
    coupled = cert.certificate
    if coupled is not None:
        rows.append(row("coupled fixed-gain certificate", coupled.spectral_radius, "num",
                        note=("proven" if coupled.certified else "not proven")
                        + " (spectral radius of the second-moment recursion, < 1 proves "
                        "E[P_t] bounded)"
                        + (f"; gain: {prose(coupled.gain_origin)}"
                           if coupled.gain_origin else ""),
                        status=coupled.certified))
    else:
        rows.append(row("coupled fixed-gain certificate", None,
                        note="none in the record (not needed when the necessary condition "
                             "fails, or none was found)"))
    claim = cert.claim
    if claim is not None:
        rows.append(row("literature claim (not proven here)", None,
                        note=f"{prose(claim.statement)}; if true the verdict would be "
                             f"{(claim.verdict_if_true or '?').replace('-', ' ')}"))
    return rows


def channel_view(rec: AnalysisRecord) -> dict[str, Any]:
    """The channel section: the configured channel, and its link budget or bursty analysis."""
    channel = record_channel(rec)
    lb = rec.link_budget
    model = channel.model if channel is not None else None
    view: dict[str, Any] = {
        "available": channel is not None, "model": model,
        "title": CHANNEL_NAMES.get(str(model), str(model or "")),
        "missing": missing("channel", "the system file has no channel section; add one "
                            "(bernoulli, gilbert-elliott, trace or link-budget) to get an "
                            "operating point and a verdict"),
        "rows": channel_rows(channel) if channel is not None else [],
        "link": None, "bursty": None, "explanation": ""}
    if model == "link-budget":
        if isinstance(lb, LinkBudgetRecord) and lb.applicable:
            view["link"] = link_budget_view(lb)
        else:
            view["explanation"] = missing("link budget", "no link-budget section")
    elif model == "gilbert-elliott":
        if isinstance(lb, GilbertElliottSection) and lb.applicable:
            view["bursty"] = bursty_view(lb)
            view["rows"] = view["rows"][:1]   # the bursty table below has the rates
        else:
            view["explanation"] = missing("bursty-link analysis", "no section")
    elif channel is not None:
        view["explanation"] = ("The arrival probability is given directly, so there is no link "
                               "budget to design; use channel model link-budget to derive p "
                               "from a radio link, or gilbert-elliott for bursty losses.")
    return view
