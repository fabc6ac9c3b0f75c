"""View model of the simulation sections and the verification appendix: figure captions, the
simulation summary, the checks, tolerances, seeds and versions."""
from __future__ import annotations

import re
from typing import Any

from kfcrit.analysis.records.simulation import SimulationOperatingPoint
from kfcrit.version import __version__
from kfcrit.views import formatting as filters
from kfcrit.views.figures.record import mean_diverges, series_of, tail_of
from kfcrit.views.report.network import is_network
from kfcrit.views.report.parts import (
    as_dict,
    as_list,
    exact_claim,
    missing,
    number,
    prose,
    row,
    safe_svg,
    typed_record,
    typed_section,
)

FIGURE_CAPTIONS = {
    "phase_transition": ("Phase transition",
                         "Trace of the lower bound S̄ and the upper bound V̄ of lim E[P_t] "
                         "against the arrival probability p (traces on a log scale), with p_low, p_c, p_up "
                         "and the operating point marked. Below p_c the expected error "
                         "covariance diverges."),
    "traces": ("Simulated error traces around the critical value",
               "Mean trace of P_t over simulated loss sequences for p just below and just above "
               "the critical value (log scale). Below p_c the expected covariance diverges; a "
               "mean over finitely many paths shows it as growth or as ever larger spikes from "
               "long loss bursts (it underestimates the expectation). Above p_c it settles."),
    "operating": ("Simulated mean covariance at the operating point",
                  "Mean trace of P_t over simulated paths at the operating p, with its 95 % "
                  "confidence band, against tr S̄ and tr V̄ (Sinopoli et al., Theorems 4 and 6: "
                  "S̄ ⪯ lim E[P_t] ⪯ V̄)."),
    "cdf": ("Distribution of tr P at the operating point",
            "Empirical CDF of the error covariance trace over the simulated paths at the "
            "simulation horizon (the law of P_t converges weakly to the invariant distribution, "
            "Kar–Sinopoli–Moura, Theorem 9)."),
    "almost_sure": ("Almost-sure behaviour along one path",
                    "Largest and smallest tr P_t over the dyadic blocks t ∈ [2ᵏ, 2ᵏ⁺¹) of "
                    "one long simulated path at the operating p. What the theory says about "
                    "limsup and liminf is in the statements above; a finite path only "
                    "illustrates it: the block maxima grow with the longest loss run, which "
                    "grows like log t, so they may look flat over the blocks shown."),
    "invariant": ("Support of the invariant distribution",
                  "Support of the invariant distribution of P_t (Kar–Sinopoli–Moura, Theorem "
                  "10): it starts at the Riccati fixed point P* and has empty intervals that "
                  "carry no mass for every 0 < p < 1 (log scale). Blue: no empty interval found "
                  "at the computed resolution, so the support lies there (it is self-similar: "
                  "each blue piece holds smaller gaps)."),
}


def figure_reasons(rec: dict[str, Any]) -> dict[str, str]:
    """Why a figure may be missing, from what the record lacks (shown instead of the figure)."""
    no_channel = rec.get("operating_point") is None
    sim = as_dict(rec.get("simulation"))
    if rec.get("simulation") is None:
        sim_why = "no simulation in the record"
    elif sim.get("skipped"):
        sim_why = prose(sim.get("reason") or "simulation skipped")
    else:
        sim_why = ""
    op_why = ("the system file has no channel section, so there is no operating point"
              if no_channel else sim_why or "the simulation produced no data at the operating point")
    return {"phase_transition": "no phase-transition data in the record",
            "traces": sim_why or "the simulation produced no runs around p_c",
            "operating": op_why, "cdf": op_why, "almost_sure": op_why,
            "invariant": "the invariant-distribution analysis did not run"}


SINGLE_LINK_ONLY = "computed for single-link systems only"
HORIZON_LEVELS = (0.5, 0.9, 0.99)


def network_run(rec: Any) -> dict[str, Any]:
    """``simulation.network`` of the record: the per-sensor-arrival Monte Carlo of a sensor
    network (empty if absent)."""
    return as_dict(as_dict(as_dict(rec).get("simulation")).get("network"))


def horizon_quantiles_text(levels: Any, quants: Any) -> str:
    """Quantiles of tr P at the horizon at the levels 50 %, 90 %, 99 % ("" when absent)."""
    levels, quants = as_list(levels), as_list(quants)
    if not levels or len(levels) != len(quants):
        return ""
    return ", ".join(f"{filters.pct(lv, 3)}: {filters.num(number(qv), 5)}"
                     for lv, qv in zip(levels, quants)
                     if lv in HORIZON_LEVELS and number(qv) is not None)


def network_mean_text(rec: dict[str, Any]) -> str:
    """What the network's simulation found at the horizon, in one sentence ("" without one).

    The record keeps E[tr P_t] at the last step t = steps with its 95 % band (or, when the
    network is mean-unstable, that the mean does not exist) and quantiles of tr P there.
    """
    net = network_run(rec)
    if not net:
        return ""
    head = (f"Simulated with each sensor over its own link ({filters.count(net.get('paths'))} "
            f"paths × {filters.count(net.get('steps'))} steps"
            + (f", seed {net.get('seed')}" if net.get("seed") is not None else "") + "): ")
    mt = as_dict(net.get("mean_trace"))
    if net.get("mean_exists") is False:
        body = ("E[tr P_t] diverges (the network is mean-unstable), so the sample mean "
                f"{filters.num(number(net.get('sample_mean_trace')), 5)} at t = "
                f"{filters.count(net.get('steps'))} estimates nothing")
    elif number(mt.get("mean")) is not None:
        body = (f"E[tr P_t] at t = {filters.count(net.get('steps'))} is "
                f"{filters.num(number(mt.get('mean')), 6)}, 95 % band "
                f"{filters.span(number(mt.get('lower')), number(mt.get('upper')), 5)}")
    else:
        body = "the record has no mean at the horizon"
    quant = horizon_quantiles_text(net.get("horizon_levels"), net.get("horizon_quantiles"))
    return head + body + (f"; quantiles of tr P there: {quant}" if quant else "") + "."


def network_scopes(rec: dict[str, Any]) -> dict[str, str]:
    """For a sensor network, why each single-link figure is absent, in one sentence each: the
    network record keeps its simulation's values at the horizon only (``simulation.network``),
    and the sweeps over one arrival probability p do not apply to per-sensor arrivals."""
    net = network_run(rec)
    kept = (network_mean_text(rec) + " The record keeps the network simulation's values at "
            "the horizon only, so no curve over time is drawn.") if net else \
        "The record has no simulation of the network."
    return {
        "phase_transition": "The phase transition (S̄ and V̄ against one arrival probability p) "
                            f"is {SINGLE_LINK_ONLY}: a network's arrivals are one per sensor, "
                            "and its stability region over the links' p_i, with each link's "
                            "critical value, is in section 1.",
        "traces": f"Runs just below and above the critical value are {SINGLE_LINK_ONLY}: a "
                  "network has no single critical value (each link's is in section 1).",
        "operating": kept,
        "cdf": ("The empirical distribution of tr P is kept for single-link systems only; the "
                "network record keeps its quantiles at the horizon: "
                + (horizon_quantiles_text(net.get("horizon_levels"),
                                          net.get("horizon_quantiles")) or "none") + ".")
        if net else "The record has no simulation of the network.",
        "almost_sure": f"The block maxima along one long path are {SINGLE_LINK_ONLY}.",
    }


def block_maxima_text(rec: dict[str, Any]) -> str:
    """What the plotted block maxima did, in numbers (no claim about the infinite path)."""
    blk = as_dict(as_dict(as_dict(rec.get("simulation")).get("operating_point"))
                  .get("almost_sure"))
    top = [v for v in as_list(blk.get("block_max")) if number(v) is not None]
    if len(top) < 2:
        return ""
    return (f" On this path the block maximum goes from {filters.num(top[0], 4)} in the first "
            f"block to {filters.num(top[-1], 4)} in the last ({len(top)} blocks).")


DIVERGENT_OPERATING_CAPTION = (
    "E[tr P_t] diverges at the operating p, so there is no mean to estimate and no confidence "
    "band: the curve is the sample mean of tr P_t over the simulated paths, which is finite "
    "for finitely many paths and steps but estimates nothing. tr S̄ and tr V̄ are drawn where "
    "they exist.")


def typed_run(op: dict[str, Any]) -> SimulationOperatingPoint | None:
    """The typed operating-point run of its JSON form (``None`` when empty)."""
    return typed_section(SimulationOperatingPoint, op) if op else None


def operating_run(rec: Any) -> dict[str, Any]:
    """``simulation.operating_point`` of the record (empty if absent)."""
    return as_dict(as_dict(as_dict(rec).get("simulation")).get("operating_point"))


def figures_view(figures: dict[str, str | None],
                 rec: dict[str, Any] | None = None) -> dict[str, dict[str, Any]]:
    """Each figure with its title, caption and "not computed" message (with the reason)."""
    reasons = figure_reasons(as_dict(rec))
    # a network's absent figure is replaced by one sentence (``scope``), not an empty figure
    scopes = network_scopes(as_dict(rec)) if is_network(as_dict(rec)) else {}
    out = {}
    for key, (title, caption) in FIGURE_CAPTIONS.items():
        svg = figures.get(key) if isinstance(figures, dict) else None
        if key == "almost_sure":
            caption += block_maxima_text(as_dict(rec))
        if key == "operating" and mean_diverges(typed_run(operating_run(rec))):
            caption = DIVERGENT_OPERATING_CAPTION
        scope = scopes.get(key) if not safe_svg(svg) else None
        out[key] = {"svg": safe_svg(svg), "title": title, "caption": caption,
                    "missing": missing(title[:1].lower() + title[1:],
                                       reasons.get(key)) if not scope else scope,
                    "scope": scope}
    return out


def _last(values: Any) -> float | None:
    """The last finite entry of a list (the horizon of a simulated series)."""
    if isinstance(values, list):
        for v in reversed(values):
            if number(v) is not None:
                return v
    return None


def simulation_view(rec: dict[str, Any]) -> dict[str, Any]:
    """Settings and summary numbers of the simulation as labelled rows (arrays are drawn)."""
    sim = rec.get("simulation")
    d = as_dict(sim)

    op = as_dict(d.get("operating_point"))
    budget = as_dict(d.get("budget"))
    rows: list[dict[str, Any]] = []
    if d.get("skipped"):
        return {"available": False, "tail_probability": None, "rows": [],
                "missing": missing("simulation", prose(d.get("reason") or "skipped"))}
    seed = d.get("seed") if d.get("seed") is not None else op.get("seed")
    paths = op.get("paths") if op.get("paths") is not None else \
        budget.get("paths", d.get("paths"))
    steps = op.get("steps") if op.get("steps") is not None else \
        budget.get("steps", d.get("steps"))
    net = as_dict(d.get("network"))
    if not op and net:
        rows.append(row("operating-point runs", None, note=f"{filters.count(net.get('paths'))} "
                        f"paths × {filters.count(net.get('steps'))} steps, each sensor over its "
                        f"own link" + (f", seed {seed}" if seed is not None else "")))
        mt = as_dict(net.get("mean_trace"))
        if net.get("mean_exists") is False:
            rows.append(row("simulated E[tr P_t]", None, note="diverges (the network is "
                            "mean-unstable); the sample mean estimates nothing"))
        elif number(mt.get("mean")) is not None:
            band = filters.span(number(mt.get("lower")), number(mt.get("upper")), 5)
            rows.append(row("simulated E[tr P_t] at the horizon", number(mt.get("mean")), "num",
                            note=f"t = {filters.count(net.get('steps'))}; 95 % band {band}"))
        quant = horizon_quantiles_text(net.get("horizon_levels"), net.get("horizon_quantiles"))
        if quant:
            rows.append(row("quantiles of tr P at the horizon", None, note=quant))
        if net.get("diverged_paths") is not None:
            rows.append(row("diverged paths", net.get("diverged_paths"), "count",
                            note=f"of {filters.count(net.get('paths'))}"))
    elif not op:
        rows.append(row("operating-point runs", None, note="none: the record has no operating "
                        "point (no channel in the system file)"
                        if rec.get("operating_point") is None else
                        "none: the simulation produced no data at the operating point"))
    elif paths is not None or steps is not None:
        p_op = filters.num(number(op.get("arrival_probability")), 6)
        rows.append(row("operating-point runs", None, note=f"{filters.count(paths)} paths × "
                        f"{filters.count(steps)} steps at p = {p_op}"
                        + (f", seed {seed}" if seed is not None else "")))
    if "iid" in op:
        rows.append(row("i.i.d. losses", op.get("iid"), "yesno"))
    run = typed_run(op)
    _, mean, lo, hi = series_of(run) if run else (None, None, None, None)
    cb = as_dict(rec.get("covariance_bounds"))
    s_tr = number(as_dict(cb.get("lower")).get("trace"))
    v_tr = number(as_dict(cb.get("upper")).get("trace"))
    horizon = as_dict(op.get("horizon"))
    if _last(mean) is not None:
        band = (f"95 % band {filters.span(_last(lo), _last(hi), 5)}"
                if _last(lo) is not None and _last(hi) is not None else "")
        bounds = (f"tr S̄ = {filters.num(s_tr, 5)}" if s_tr is not None else "") + \
            (f", tr V̄ = {filters.num(v_tr, 5)}" if v_tr is not None else
             (", V̄ does not exist at this p" if s_tr is not None else ""))
        when = f" t = {horizon['time']}" if horizon.get("time") else ""
        if mean_diverges(run):
            rows.append(row("sample mean of tr P_t at the horizon" + when, _last(mean), "num",
                            note="; ".join(x for x in (
                                "E[tr P_t] diverges at this p: the sample mean over finitely "
                                "many paths is finite but estimates nothing", bounds) if x)))
        else:
            rows.append(row("mean tr P_t at the horizon" + when, _last(mean), "num",
                            note="; ".join(x for x in (band, bounds) if x)))
    levels, quants = as_list(horizon.get("levels")), as_list(horizon.get("quantiles"))
    if levels and len(levels) == len(quants):
        wanted = [(lv, qv) for lv, qv in zip(levels, quants) if lv in (0.5, 0.9, 0.99)]
        if wanted:
            rows.append(row("quantiles of tr P at the horizon", None, note=", ".join(
                f"{filters.pct(lv, 3)}: {filters.num(number(qv), 5)}" for lv, qv in wanted)))
    erg = as_dict(op.get("ergodic"))
    pooled = as_dict(as_dict(erg.get("time_averages")).get("pooled_mean_trace"))
    if number(pooled.get("mean")) is not None:
        rows.append(row("time average of tr P_t (one long path per replica)", pooled.get("mean"),
                        "num", note=ergodic_note(erg, pooled)))
    div = as_dict(op.get("divergence"))
    if div.get("diverged_paths") is not None:
        rows.append(row("diverged paths", div.get("diverged_paths"), "count",
                        note=f"of {filters.count(paths)} (tr P above "
                        f"{filters.sci(number(div.get('threshold')), 3)}; "
                        f"{divergence_text(div)})"))
    bursts = as_dict(op.get("bursts"))
    if number(bursts.get("mean_length")) is not None:
        rows.append(row("loss bursts", bursts.get("mean_length"), "num",
                        note=f"mean length (channel: "
                        f"{filters.num(number(bursts.get('expected_mean_length')), 4)}); "
                        f"{filters.count(bursts.get('bursts'))} bursts, longest "
                        f"{filters.num(bursts.get('longest'))}, loss fraction "
                        f"{filters.pct(number(bursts.get('loss_fraction')))}"))
    demo = d.get("phase_demo")
    curves = as_list(as_dict(demo).get("curves")) if isinstance(demo, dict) else as_list(demo)
    if curves:
        ps = [number(as_dict(c).get("arrival_probability", as_dict(c).get("p"))) for c in curves]
        ref = as_dict(demo).get("reference_value") if isinstance(demo, dict) else None
        rows.append(row("runs around p_c", None, note=(
            f"p = {', '.join(filters.num(x, 4) for x in ps)}"
            + (f" (reference {filters.num(number(ref), 6)})" if number(ref) is not None else "")
            + (f"; {filters.count(as_dict(demo).get('paths'))} paths × "
               f"{filters.count(as_dict(demo).get('steps'))} steps each"
               if isinstance(demo, dict) and as_dict(demo).get("paths") else ""))))
    seeds = d.get("seeds")
    if seeds is not None:
        rows.append(row("random seeds", None, note=seeds_text(seeds)))
    if d.get("quick") is not None:
        rows.append(row("draft (--quick)", d.get("quick"), "yesno"))
    return {"available": isinstance(sim, dict), "missing": missing("simulation"),
            "tail_probability": tail_of(typed_record(rec)), "rows": rows}


def divergence_text(div: dict[str, Any]) -> str:
    """What happened to the paths that crossed the divergence threshold, as the record says.

    Paths continued in scaled form (``continued``) keep true values; censored paths (held at
    the threshold, the older rule) enter the means as the threshold, so the means are lower
    bounds; ``mean_is_lower_bound`` (censoring or a path frozen after a numerical failure)
    says so either way.
    """
    lower = bool(div.get("mean_is_lower_bound"))
    if div.get("continued"):
        text = "such paths are continued in scaled form, so the statistics are true values"
        return text + ("; some paths were frozen after a numerical failure, so means are "
                       "lower bounds" if lower else "")
    if div.get("diverged_paths") or lower:
        return "censored at the threshold; means are lower bounds"
    return ("a diverged path would be censored at the threshold, making the means lower "
            "bounds; none did")


ERGODIC_MIN_REPLICAS = 10
ERGODIC_MAX_SPREAD = 3.0


def ergodic_unreliable(erg: dict[str, Any], pooled: dict[str, Any]) -> str:
    """Why the time-average interval cannot be trusted ("" when nothing is wrong with it).

    tr P_t ≥ 0, so a 95 % interval reaching below zero, or replica means that differ by more
    than a factor :data:`ERGODIC_MAX_SPREAD` with fewer than :data:`ERGODIC_MIN_REPLICAS`
    replicas, mean the normal approximation behind it does not hold (few replicas, heavy tail).
    """
    reasons = []
    lower = number(pooled.get("lower"))
    if lower is not None and lower < 0:
        reasons.append("its normal approximation reached below 0 (clamped there: tr P ≥ 0)")
    means = [v for v in as_list(as_dict(erg.get("time_averages")).get("replica_mean_trace"))
             if number(v) is not None and v > 0]
    replicas = number(erg.get("replicas"))
    spread = max(means) / min(means) if len(means) >= 2 else None
    if spread is not None and spread > ERGODIC_MAX_SPREAD and \
            (replicas is None or replicas < ERGODIC_MIN_REPLICAS):
        reasons.append(f"the {filters.count(replicas) if replicas else len(means)} replica means "
                       f"range over {filters.num(min(means), 4)} – {filters.num(max(means), 4)} "
                       "(a heavy tail)")
    return "; ".join(reasons)


def ergodic_note(erg: dict[str, Any], pooled: dict[str, Any]) -> str:
    """The time-average row's note: its 95 % interval clamped at 0, the replicas, and a caution
    when the interval is unreliable (:func:`ergodic_unreliable`)."""
    lower, upper = number(pooled.get("lower")), number(pooled.get("upper"))
    if lower is not None:
        lower = max(lower, 0.0)
    note = (f"95 % interval {filters.span(lower, upper, 5)}; "
            f"{filters.count(erg.get('replicas'))} replicas × "
            f"{filters.count(erg.get('steps'))} steps, burn-in "
            f"{filters.count(erg.get('burn_in'))}")
    why = ergodic_unreliable(erg, pooled)
    if why:
        note += f". Interval unreliable: {why}; run more replicas (full mode) before using it"
    return note


_SPAWN_RULE = re.compile(r"SeedSequence\(seed, spawn_key=\((\d+), (\w+)\)\)")
SEED_UNITS = {"i": "path", "j": "replica", "k": "run"}


def seed_rule_text(rule: Any) -> str:
    """A seed rule of the record in words: ``SeedSequence(seed, spawn_key=(0, i))`` reads
    "stream (0, i) of the base seed for path i" (NumPy's ``SeedSequence.spawn`` keys)."""
    def words(m: re.Match[str]) -> str:
        unit = SEED_UNITS.get(m.group(2), "index")
        return f"stream ({m.group(1)}, {m.group(2)}) of the base seed for {unit} {m.group(2)}"

    return _SPAWN_RULE.sub(words, filters.text(rule))


def seeds_text(seeds: Any) -> str:
    """The simulation's seeds in words (a mapping of stream names to seeds or seed rules)."""
    if isinstance(seeds, dict):
        parts = []
        for k, v in seeds.items():
            label = filters.key_label(k)
            if isinstance(v, dict):
                inner = ", ".join(f"{filters.key_label(a)}: {seed_rule_text(b)}"
                                  for a, b in v.items())
                parts.append(f"{label} ({inner})")
            else:
                parts.append(f"{label}: {seed_rule_text(v)}")
        return "; ".join(parts) if parts else filters.DASH
    return seed_rule_text(seeds)



OPTION_LABELS = {"tolerance": ("decision tolerance (floating-point input)", "sci"),
                 "upper_tol": ("upper-bound tolerance", "sci"),
                 "simulate": ("simulation run", "yesno"),
                 "quick": ("draft mode (--quick)", "yesno"),
                 "seed": ("base random seed", "num"), "paths": ("simulated paths", "count"),
                 "steps": ("simulated steps", "count")}


def _solver_text(solver: Any) -> str:
    """Upper-bound solver statistics in words (a mapping of counters), or its name."""
    if not isinstance(solver, dict):
        return filters.text(solver)
    parts = []
    for k, v in solver.items():
        if isinstance(v, str) and " " in v:   # a sentence of its own ("output compressed: …")
            parts.append(prose(v))
            continue
        label = filters.key_label(k)
        parts.append(f"{label} {filters.sci(v, 3) if isinstance(v, float) else filters.text(v)}")
    return ", ".join(parts) if parts else filters.DASH


_EXP_FLOAT = re.compile(r"-?\d+\.\d+e[-+]?\d+")
_LONG_FLOAT = re.compile(r"(?<![\w.])-?\d+\.\d{7,}(?![\w.])")
_ZERO_FLOAT = re.compile(r"(?<![\w.])-?0\.0+(?![\w.])")
# Check names of the record reworded where their words mislead (diverged paths are censored at
# the threshold and enter the means, which are then lower bounds: nothing is left out).
CHECK_WORDING = {"divergence flagged, not propagated":
                 "diverged paths censored at the threshold, means then lower bounds"}


def check_name(name: Any) -> str:
    """A verification check's name for the appendix (Unicode mathematics, truthful wording)."""
    text = str(name or "")
    for old, new in CHECK_WORDING.items():
        text = text.replace(old, new)
    return prose(text)


def _detail_text(detail: Any) -> str:
    """A check's detail as text; a literal ``None`` left by the record reads as an em dash and
    full-precision exponent floats (``4.261669270870999e-16``) read as ``4.26 × 10⁻¹⁶``."""
    if detail is None:
        return ""
    out = filters.text(detail).replace("None", filters.DASH)
    out = _EXP_FLOAT.sub(lambda m: filters.sci(float(m.group(0)), 3), out)
    out = _LONG_FLOAT.sub(lambda m: filters.num(float(m.group(0)), 8), out)
    return prose(_ZERO_FLOAT.sub("0", out))


CHECK_STATUS = {"passed": ("pass", "passed"), "failed": ("fail", "failed"),
                "inconclusive": ("undetermined", "inconclusive"),
                "not applicable": ("none", "not applicable")}


def check_view(check: Any) -> dict[str, Any]:
    """One verification check of the record as a table row: name, badge and detail.

    The badge follows ``passed`` (True: passed, False: failed) and, when that is ``None``, the
    check's ``status`` word (inconclusive, not applicable); a passed check is never red.
    """
    c = as_dict(check)
    passed = c.get("passed")
    if passed is True:
        css, label = CHECK_STATUS["passed"]
    elif passed is False:
        css, label = CHECK_STATUS["failed"]
    else:
        word = str(c.get("status") or "not applicable")
        css, label = CHECK_STATUS.get(word, ("none", word))
    return {"name": check_name(c.get("check")), "css": css, "label": label,
            "detail": _detail_text(c.get("detail"))}


def appendix_view(rec: dict[str, Any]) -> dict[str, Any]:
    """Verification appendix: certificates and cross-checks, tolerances, versions, seeds, hash."""
    ub = as_dict(rec.get("upper_bound"))
    cv = as_dict(rec.get("critical_value"))
    rob = as_dict(rec.get("robust_critical_value"))
    prov = as_dict(rec.get("provenance"))
    sim = as_dict(rec.get("simulation"))
    st = as_dict(rec.get("structure"))
    checks = [check_view(c) for c in as_list(rec.get("verification"))]
    # how p_c was decided is information, not a check: "numerical" is never shown as a failure
    claim = exact_claim(rec, cv)
    checks.append({"name": "critical value decided exactly",
                   "css": "pass" if claim else "none",
                   "label": {True: "exact", False: "numerical"}.get(claim, "not computed"),
                   "detail": prose(cv.get("reason"))})
    opts = as_dict(prov.get("options"))
    stol = as_dict(st.get("tolerances"))
    tolerances = [
        row("robust-value tolerance (relative)", rob.get("tolerance", opts.get("tolerance")),
            "sci"),
        row("upper-bound tolerance", ub.get("tolerance", opts.get("upper_tol")), "sci"),
        row("upper-bound method", ub.get("method")),
        row("upper-bound solver", None, note=_solver_text(ub.get("solver"))),
    ]
    if stol:
        tolerances.append(row("structure analysis", None, note=", ".join(
            x for x in (("exact arithmetic" if stol.get("exact") else "floating point")
                        if "exact" in stol else "",
                        f"time budget {filters.num(stol.get('time_budget_seconds'))} s"
                        if stol.get("time_budget_seconds") is not None else "",
                        f"at most {filters.num(stol.get('max_states'))} states for exact work"
                        if stol.get("max_states") is not None else "") if x)))
    seeds = sim.get("seeds") if sim.get("seeds") is not None else prov.get("seed")
    versions = dict(as_dict(prov.get("versions")))
    if versions.get("kfcrit") != __version__:
        versions["kfcrit (report)"] = __version__
    versions.update({name: v for name, v in report_versions().items()
                     if name not in versions and name.lower() not in versions})
    options = [row(OPTION_LABELS.get(k, (filters.key_label(k), "text"))[0], v,
                   OPTION_LABELS.get(k, ("", "text"))[1],
                   note="default for the mode" if v is None and k in ("paths", "steps") else "")
               for k, v in opts.items()]
    return {"checks": checks, "tolerances": tolerances,
            "upper_warnings": [prose(w) for w in as_list(ub.get("warnings"))],
            "versions": [row(str(k), v if v is not None else "not installed")
                         for k, v in versions.items()],
            "seeds": seeds_text(seeds),
            "sha256": prov.get("input_sha256"), "input_path": prov.get("input_path"),
            "options": options}


REPORT_PACKAGES = ("weasyprint", "PyYAML", "numba", "mpmath")


def report_versions() -> dict[str, str | None]:
    """Versions of the packages behind the report and the analysis that the record's
    provenance may not list (``None``: not installed), read from the installed metadata."""
    from importlib import metadata

    out: dict[str, str | None] = {}
    for name in REPORT_PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    return out


