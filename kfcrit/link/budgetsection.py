"""The ``link_budget`` section of the record, built as its record classes from a link budget.

A link budget (:class:`kfcrit.link.linkbudget.LinkBudget`, which imports this module: the link
is therefore taken as it is, not by its class) is read against the arrival probability its
design needs, the binding requirement of :func:`kfcrit.link.requirement.binding_requirement`:
the required SINR, received power and distance, the link margin, the shadowing outages, and
the check of the link's own margin policy (theory §11; the policy in the review, §16.3).
"""
from __future__ import annotations

import functools
import math
from typing import Any

import numpy as np

from kfcrit.io.typed import ABSENT
from kfcrit.link.fading import fading_note
from kfcrit.link.propagation import db_to_linear
from kfcrit.link.radios import CalibratedOqpsk
from kfcrit.link.requirement import BindingRequirement, binding_requirement, stability_requirement
from kfcrit.records.channel import FrameRecord
from kfcrit.records.link import (
    DesignCheck,
    LinkBudgetRecord,
    LinkState,
    LinkThreshold,
    MarginPolicy,
    Shadowing,
)


def frame_record(link: Any) -> FrameRecord:
    """The frame of ``link`` on the air: payload, overheads, PHY limit, airtime and retries.

    .. math:: L_{PSDU} = \\text{payload} + \\text{MAC overhead},\\qquad
              L_{PPDU} = H_{PHY} + L_{PSDU}
    """
    frame = link.radio.frame
    psdu = link.psdu_bytes
    return FrameRecord(
        payload_bytes=link.packet_bytes, mac_overhead_bytes=psdu - link.packet_bytes,
        psdu_bytes=psdu, phy_header_bytes=frame.phy_header_bytes,
        ppdu_bytes=psdu + frame.phy_header_bytes, max_psdu_bytes=frame.max_psdu_bytes,
        max_payload_bytes=frame.max_payload_bytes(link.mac_overhead_bytes),
        standard=frame.standard,
        per_covers=("PPDU (PHY header + MAC header + payload + FCS)"
                    if link.per_over == "ppdu" and frame.phy_header_bytes
                    else "PSDU (MAC header + payload + FCS)"),
        definition="packet_bytes is the application payload; PSDU = MAC header + payload + "
                   "FCS; PPDU = PHY header (preamble, SFD, PHR) + PSDU",
        airtime_s=frame.airtime_s(psdu), max_retries=link.max_retries,
        max_retries_allowed=frame.max_retries,
        attempts_duration_s=frame.attempts_duration_s(psdu, link.max_retries),
        retry_formula="p = 1 - PER^(k+1)", retry_assumption=_retry_assumption(link),
        per_bytes=link.per_bytes, per_over=link.per_over,
        fading_per_attempt=link.fading_per_attempt)


def _retry_assumption(link: Any) -> str:
    """How the k + 1 attempts of a period fail, in words."""
    if link.fading_per_attempt == "independent":
        shadowing = "each with its own shadowing value (p = 1 - E[PER]^(k+1))"
    elif link.fading_per_attempt == "correlated":
        shadowing = (f"given shadowing values that follow a Gauss-Markov sequence, correlated "
                     f"by rho = exp(-Delta/T_c) = {link.attempt_correlation:.4g} between "
                     f"attempts (Delta = {link.attempt_spacing_s:.4g} s, T_c = "
                     f"{link.coherence_time_s:g} s)")
    else:
        shadowing = "given the shadowing value of the period, which they share"
    return ("the k + 1 attempts fit in the sample period and fail independently, " + shadowing
            + ("; fast fading redrawn per attempt (PER averaged over it)"
               if link.fading.active else "")
            + "; acknowledgement losses cause needless retries, not lost updates; "
            "CSMA-CA backoffs are not included in attempts_duration_s")


def link_state(link: Any) -> LinkState:
    """The configured link, step by step, at its median SINR.

    .. math:: P_r = P_t + G - PL(d),\\qquad \\mathrm{SINR} = P_r - (N \\oplus I),\\qquad
              p = 1 - \\mathrm{PER}^{k+1}
    """
    sinr = link.sinr_db
    log_arrival = link.median_log_arrival
    # without fading the PER is −expm1 of the same log(1 − PER) (Radio.per); with fading
    # it is the averaged PER, which log(1 − PER) was computed from
    per = (float(link.attempt_per(sinr)) if link.fading.active
           else float(-np.expm1(log_arrival)))
    noise = link.noise
    return LinkState(
        tx_power_dbm=link.tx_power_dbm, antenna_gain_db=link.antenna_gain_db,
        distance_m=link.distance_m, packet_bytes=link.packet_bytes,
        psdu_bytes=link.psdu_bytes, per_bytes=link.per_bytes, max_retries=link.max_retries,
        path_loss_db=link.path_loss_db, rx_power_dbm=link.rx_power_dbm,
        noise_floor_dbm=noise.floor_dbm, bandwidth_hz=noise.bandwidth_hz,
        noise_figure_db=noise.noise_figure_db, temperature_k=noise.temperature_k,
        interference_dbm=noise.interference_dbm, noise_plus_interference_dbm=noise.total_dbm,
        sinr_db=sinr, sinr_linear=_finite(float(db_to_linear(sinr))),
        bit_error_rate=link.median_ber, packet_error_rate=per,
        attempt_arrival_probability=float(np.exp(log_arrival)),
        arrival_probability_nominal=link.median_nominal_arrival,
        arrival_probability_mean=link.median_mean_arrival,
        arrival_probability=link.arrival_value)


def _finite(x: float) -> float | None:
    """``x``, or None when it is not finite (JSON holds no infinity)."""
    return x if math.isfinite(x) else None


def threshold_record(link: Any, label: str, p: float, outage: Any = None) -> LinkThreshold:
    """Required SINR / received power / distance and the link margin for one requirement p.

    ``outage`` is the link's :meth:`~kfcrit.link.linkbudget.LinkBudget.outage_probability`, or
    a memo of it. The distance keeps the policy's margin m:

    .. math:: PL(d_{max}) = P_t + G - (N \\oplus I) - m - s(p)
    """
    outage = outage or link.outage_probability
    if p >= 1.0:
        return _unreachable(label, p, 1.0)
    try:
        s_req = link.required_sinr_db(p)
    except ValueError:
        return _unreachable(label, p, None)
    out = outage(p)
    if s_req is None:
        return LinkThreshold(label=label, arrival_probability=p, required_sinr_db=None,
                             required_rx_power_dbm=None, link_margin_db=None,
                             max_distance_m=None, max_distance_unbounded=True,
                             outage_probability=out, reachable=True)
    d = link.max_distance_m(s_req, link.effective_margin_db)
    return LinkThreshold(label=label, arrival_probability=p, required_sinr_db=s_req,
                         required_rx_power_dbm=s_req + link.noise.total_dbm,
                         link_margin_db=link.sinr_db - s_req, max_distance_m=d,
                         max_distance_unbounded=d is None, outage_probability=out,
                         reachable=True)


def _unreachable(label: str, p: float, outage: float | None) -> LinkThreshold:
    """The row of a requirement no SINR reaches."""
    return LinkThreshold(label=label, arrival_probability=p, required_sinr_db=None,
                         required_rx_power_dbm=None, link_margin_db=None, max_distance_m=None,
                         max_distance_unbounded=False, outage_probability=outage,
                         reachable=False)


def frame_notes(link: Any, frame: FrameRecord) -> list[str]:
    """What the frame and the radio model of ``link`` assume, in words for the record."""
    head = frame.phy_header_bytes
    if link.per_over == "ppdu" and head:
        covers = (f"the PPDU of {frame.per_bytes} bytes (PHY header {head} bytes + PSDU "
                  f"{frame.psdu_bytes} bytes, MAC header and FCS "
                  f"{frame.mac_overhead_bytes} bytes added), as ns-3 counts it; per_over = psdu "
                  f"excludes the header")
    else:
        covers = (f"the PSDU of {frame.psdu_bytes} bytes (MAC header and FCS "
                  f"{frame.mac_overhead_bytes} bytes added)"
                  + (f"; the PHY header ({head} bytes) counts in the airtime only"
                     if head else ""))
    notes = [f"packet_bytes = {frame.payload_bytes} is the application payload; the packet "
             f"error rate covers {covers}"]
    if link.max_retries:
        notes.append(f"{link.max_retries} MAC retries: p = 1 - PER^{link.max_retries + 1}"
                     " within the sample period " + (
                         "(each attempt draws its own shadowing value: p = 1 - E[PER]^"
                         f"{link.max_retries + 1})" if link.independent_attempts else
                         "(attempts independent given the period's shadowing value, which "
                         "they share)"))
    note = fading_note(link.fading)
    if note:
        notes.append(note)
    if isinstance(link.radio, CalibratedOqpsk) and (link.noise.noise_figure_db or 0) > 0:
        notes.append("the radio's implementation loss is calibrated from its datasheet "
                     "sensitivity and already contains the receiver noise figure; the noise "
                     f"figure of {link.noise.noise_figure_db:g} dB given under noise is "
                     "counted in addition")
    return notes


def _section_notes(link: Any, frame: FrameRecord) -> list[str]:
    """The notes of the section: what the shadowing mode means, then the frame's."""
    notes = []
    if link.sigma_db > 0 and not link.per_packet_shadowing:
        notes.append("per-link shadowing: the arrival probability is the median link's; a "
                     "deployed link falls below a requirement with the outage probability")
    if link.per_packet_shadowing and not link.time_correlated:
        notes.append("per-packet shadowing: arrivals are i.i.d. with the shadowing-averaged "
                     "probability; outage probabilities describe per-link shadowing and are "
                     "given for comparison")
    if link.time_correlated:
        notes.append("time-correlated shadowing: arrivals are bursty (Gilbert-Elliott "
                     "approximation, see gilbert_elliott); the i.i.d. requirements p_c, p_up "
                     "below do not decide mean stability for this channel")
    notes.extend(frame_notes(link, frame))
    if link.path_loss.model == "log-distance" \
            and link.distance_m < link.path_loss.reference_distance_m:
        notes.append("the distance is below the reference distance of the log-distance model")
    return notes


def policy_check(need: BindingRequirement, design: LinkThreshold | None,
                 thresholds: list[LinkThreshold], policy: MarginPolicy, shadowing: Shadowing,
                 distance_m: float) -> DesignCheck:
    """The configured link against its own margin policy, at the binding requirement.

    ``margin_policy_met``: the link margin at the configured distance is at least the policy's
    effective margin max(margin_db, σ·Φ⁻¹(1 − max_outage)) (equivalently, the distance is within
    the section's ``max_distance_m``); ``outage_within_policy``: the per-link shadowing outage
    below the design requirement (``design``'s row; the threshold row of the same arrival
    probability, else the outage below p_c) is at most ``max_outage``. Either is ``None`` when
    its inputs are missing.

    With an accuracy requirement the check also states ``design_value``, ``basis`` and
    ``requirement_reachable``: False when no arrival probability, or none the radio reaches at
    any SINR, meets the binding requirement (the policy then fails: no margin exists). When the
    requirement is p = 0 (p_c = 0: every arrival probability above 0 keeps the filter
    mean-stable) the margin is unbounded: ``margin_unbounded`` True and the policy met.
    """
    margin = design.link_margin_db if design else None
    max_distance = design.max_distance_m if design else None
    unbounded = bool(design.max_distance_unbounded) if design else False
    needed, max_outage, p = policy.effective_margin_db, policy.max_outage, need.value
    rows = [r for r in thresholds
            if r.arrival_probability == p and r.outage_probability is not None]
    outage = rows[0].outage_probability if rows else shadowing.outage_below_critical
    met = (margin >= needed) if None not in (margin, needed) else None
    margin_unbounded = (margin is None and needed is not None and unbounded
                        and p is not None and p <= 0)
    if margin_unbounded:   # every SINR gives p > 0: the margin over the requirement is unbounded
        met = True
    within = (outage <= max_outage) if None not in (outage, max_outage) else None
    if need.accuracy is None:
        return DesignCheck(link_margin_db=margin, required_margin_db=needed,
                           margin_policy_met=met, distance_m=distance_m,
                           max_distance_m=max_distance, outage_probability=outage,
                           max_outage=max_outage, outage_within_policy=within,
                           margin_unbounded=True if margin_unbounded else ABSENT)
    reachable = not (p is None and need.binding == "accuracy") and not (
        p is not None and margin is None and not unbounded)
    if not reachable:
        met, outage = False, 1.0
        within = False if max_outage is not None else None
    return DesignCheck(link_margin_db=margin, required_margin_db=needed, margin_policy_met=met,
                       distance_m=distance_m, max_distance_m=max_distance,
                       outage_probability=outage, max_outage=max_outage,
                       outage_within_policy=within, design_value=p, basis=need.basis,
                       requirement_reachable=reachable,
                       margin_unbounded=True if margin_unbounded else ABSENT)


def link_budget_record(link: Any, *, critical_value: float | None,
                       robust_value: float | None,
                       bracket: tuple[float | None, float | None] | None,
                       upper_bound: float | None, accuracy: Any = None) -> LinkBudgetRecord:
    """The ``link_budget`` section of a link budget (without its curves and bursty part).

    The design value is the binding requirement of :func:`kfcrit.link.requirement.
    binding_requirement`: max(p_stab, p_V) with an accuracy requirement, p_stab otherwise; the
    required SINR, link margin, maximum distance and outage are read against it.

    Parameters
    ----------
    link : LinkBudget
        The configured link (:class:`kfcrit.link.linkbudget.LinkBudget`).
    critical_value, robust_value : float or None
        p_c and the robust critical value (None when unknown).
    bracket : (float or None, float or None)
        Lower and upper ends bracketing p_c when it is unknown.
    upper_bound : float or None
        p_up.
    accuracy : AccuracyDesign or mapping, optional
        The record's ``design`` section of an accuracy requirement (``requirement`` and
        ``required_arrival_probability`` with the interval [p_S, p_V]); None without one.

    Returns
    -------
    LinkBudgetRecord
        With ``thresholds`` (one row per known requirement), the shadowing outages below p_c
        and p_up, the margin policy and its check.
    """
    bracket = tuple(bracket) if bracket is not None else (None, None)
    need = binding_requirement(
        stability_requirement(critical_value, robust_value, bracket, upper_bound), accuracy)
    # the design value repeats one of the thresholds, and the shadowing outages two of them:
    # each requirement p is worked out once
    outage = functools.lru_cache(maxsize=None)(link.outage_probability)
    computed: dict[tuple[float, float], LinkThreshold] = {}

    def threshold(label: str, p: float) -> LinkThreshold:
        key = (p, math.copysign(1.0, p))
        if key not in computed:
            computed[key] = threshold_record(link, label, p, outage)
        row = computed[key]
        return LinkThreshold(
            label=label, arrival_probability=p, required_sinr_db=row.required_sinr_db,
            required_rx_power_dbm=row.required_rx_power_dbm, link_margin_db=row.link_margin_db,
            max_distance_m=row.max_distance_m, max_distance_unbounded=row.max_distance_unbounded,
            outage_probability=row.outage_probability, reachable=row.reachable)

    rows = []
    for label, value in (("critical_value", critical_value), ("robust_critical_value",
                                                              robust_value),
                         ("bracket_low", bracket[0] if critical_value is None else None),
                         ("bracket_high", bracket[1] if critical_value is None else None),
                         ("upper_bound", upper_bound)):
        if value is not None:
            rows.append(threshold(label, float(value)))
    if need.accuracy is not None and need.accuracy.interval:
        p_s, p_v = need.accuracy.interval
        rows.append(threshold("accuracy_necessary", float(p_s)))
        rows.append(threshold("accuracy_sufficient", float(p_v)))
    design = threshold("design", need.value) if need.value is not None else None
    frame = frame_record(link)
    chain = link.shadowing_markov() if link.time_correlated else None
    policy = MarginPolicy(
        margin_db=link.margin_db, max_outage=link.max_outage,
        effective_margin_db=link.effective_margin_db,
        rule=("keep margin_db dB of SINR above the requirement (per-packet shadowing is "
              "averaged into the arrival probability)"
              if link.per_packet_shadowing and not link.time_correlated else
              "keep max(margin_db, sigma * Phi^-1(1 - max_outage)) dB of SINR above the "
              "requirement"))
    shadowing = Shadowing(
        sigma_db=link.sigma_db, mode=link.path_loss.shadowing,
        mean_arrival_probability=link.median_mean_arrival,
        outage_below_critical=(outage(float(critical_value))
                               if critical_value is not None else None),
        outage_below_upper=outage(float(upper_bound)) if upper_bound is not None else None)
    return LinkBudgetRecord(
        applicable=True, radio=link.radio.record(), link=link_state(link),
        margin_policy=policy,
        required_arrival_probability=need.record(critical_value, robust_value, bracket),
        max_distance_unbounded=bool(design.max_distance_unbounded) if design else False,
        mean_stable_at_distance=(link.arrival_value > need.stability_value)
        if need.stability_value is not None else None,
        shadowing=shadowing, thresholds=rows, notes=_section_notes(link, frame),
        design_check=policy_check(need, design, rows, policy, shadowing, link.distance_m),
        warnings=[] if chain is None else [
            "time-correlated shadowing makes the losses bursty (Gilbert-Elliott f = "
            f"{chain.failure_rate:.4g}, r = {chain.recovery_rate:.4g}): comparing the "
            "stationary arrival probability with the i.i.d. p_c does not decide mean "
            "stability; the burst condition (1 - r) rho(A)^2 < 1 is necessary "
            "(docs/theory.md §10)"],
        frame=frame, required_sinr_db=design.required_sinr_db if design else None,
        required_rx_power_dbm=design.required_rx_power_dbm if design else None,
        link_margin_db=design.link_margin_db if design else None,
        max_distance_m=design.max_distance_m if design else None,
        gilbert_elliott=chain.record() if chain is not None else None)
