"""View model of the simulation sections and the verification appendix: figure captions, the
simulation summary, the checks, tolerances, seeds and versions."""
from __future__ import annotations

import dataclasses
import re
from typing import TYPE_CHECKING, Any

from kfcrit.version import __version__
from kfcrit.views import formatting as filters
from kfcrit.views.figures.record import mean_diverges, series_of, tail_of
from kfcrit.views.report.network import is_network
from kfcrit.views.report.parts import (
    exact_claim,
    missing,
    number,
    prose,
    row,
    safe_svg,
    stated,
    stated_fields,
)

if TYPE_CHECKING:
    from kfcrit.analysis.sections import AnalysisRecord, VerificationCheck
    from kfcrit.records.simulation import (
        ErgodicAverages,
        NetworkSimulation,
        PooledMeanTrace,
        SimulationDivergence,
        SimulationOperatingPoint,
        SimulationSeeds,
        UpperSolver,
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


def figure_reasons(rec: AnalysisRecord) -> dict[str, str]:
    """Why a figure may be missing, from what the record lacks (shown instead of the figure)."""
    no_channel = rec.operating_point is None
    sim = rec.simulation
    if sim is None:
        sim_why = "no simulation in the record"
    elif stated(sim.skipped):
        sim_why = prose(stated(sim.reason) or "simulation skipped")
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


def network_run(rec: AnalysisRecord) -> NetworkSimulation | None:
    """``simulation.network`` of the record: the per-sensor-arrival Monte Carlo of a sensor
    network (``None`` if absent)."""
    return stated(rec.simulation.network) if rec.simulation is not None else None


def horizon_quantiles_text(levels: list[float | None] | None,
                           quants: list[float | None] | None) -> str:
    """Quantiles of tr P at the horizon at the levels 50 %, 90 %, 99 % ("" when absent)."""
    levels, quants = levels or [], quants or []
    if not levels or len(levels) != len(quants):
        return ""
    return ", ".join(f"{filters.pct(lv, 3)}: {filters.num(number(qv), 5)}"
                     for lv, qv in zip(levels, quants)
                     if lv in HORIZON_LEVELS and number(qv) is not None)


def network_quantiles_text(net: NetworkSimulation) -> str:
    """The network simulation's quantiles of tr P at the horizon (:func:`horizon_quantiles_text`)."""
    return horizon_quantiles_text(stated(net.horizon_levels), stated(net.horizon_quantiles))


def network_mean_text(rec: AnalysisRecord) -> str:
    """What the network's simulation found at the horizon, in one sentence ("" without one).

    The record keeps E[tr P_t] at the last step t = steps with its 95 % band (or, when the
    network is mean-unstable, that the mean does not exist) and quantiles of tr P there.
    """
    net = network_run(rec)
    if net is None:
        return ""
    head = (f"Simulated with each sensor over its own link ({filters.count(net.paths)} "
            f"paths × {filters.count(net.steps)} steps"
            + (f", seed {net.seed}" if net.seed is not None else "") + "): ")
    mt = stated(net.mean_trace)
    if net.mean_exists is False:
        body = ("E[tr P_t] diverges (the network is mean-unstable), so the sample mean "
                f"{filters.num(number(stated(net.sample_mean_trace)), 5)} at t = "
                f"{filters.count(net.steps)} estimates nothing")
    elif mt is not None and number(mt.mean) is not None:
        body = (f"E[tr P_t] at t = {filters.count(net.steps)} is "
                f"{filters.num(number(mt.mean), 6)}, 95 % band "
                f"{filters.span(number(mt.lower), number(mt.upper), 5)}")
    else:
        body = "the record has no mean at the horizon"
    quant = network_quantiles_text(net)
    return head + body + (f"; quantiles of tr P there: {quant}" if quant else "") + "."


def network_scopes(rec: AnalysisRecord) -> dict[str, str]:
    """For a sensor network, why each single-link figure is absent, in one sentence each: the
    network record keeps its simulation's values at the horizon only (``simulation.network``),
    and the sweeps over one arrival probability p do not apply to per-sensor arrivals."""
    net = network_run(rec)
    kept = (network_mean_text(rec) + " The record keeps the network simulation's values at "
            "the horizon only, so no curve over time is drawn.") if net is not None else \
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
                + (network_quantiles_text(net) or "none") + ".")
        if net is not None else "The record has no simulation of the network.",
        "almost_sure": f"The block maxima along one long path are {SINGLE_LINK_ONLY}.",
    }


def block_maxima_text(rec: AnalysisRecord) -> str:
    """What the plotted block maxima did, in numbers (no claim about the infinite path)."""
    run = operating_run(rec)
    top = [v for v in (run.almost_sure.block_max if run is not None else [])
           if number(v) is not None]
    if len(top) < 2:
        return ""
    return (f" On this path the block maximum goes from {filters.num(top[0], 4)} in the first "
            f"block to {filters.num(top[-1], 4)} in the last ({len(top)} blocks).")


DIVERGENT_OPERATING_CAPTION = (
    "E[tr P_t] diverges at the operating p, so there is no mean to estimate and no confidence "
    "band: the curve is the sample mean of tr P_t over the simulated paths, which is finite "
    "for finitely many paths and steps but estimates nothing. tr S̄ and tr V̄ are drawn where "
    "they exist.")


def operating_run(rec: AnalysisRecord) -> SimulationOperatingPoint | None:
    """``simulation.operating_point`` of the record (``None`` if absent)."""
    return stated(rec.simulation.operating_point) if rec.simulation is not None else None


def figures_view(figures: dict[str, str | None],
                 rec: AnalysisRecord) -> dict[str, dict[str, Any]]:
    """Each figure with its title, caption and "not computed" message (with the reason)."""
    reasons = figure_reasons(rec)
    # a network's absent figure is replaced by one sentence (``scope``), not an empty figure
    scopes = network_scopes(rec) if is_network(rec) else {}
    out = {}
    for key, (title, caption) in FIGURE_CAPTIONS.items():
        svg = figures.get(key)
        if key == "almost_sure":
            caption += block_maxima_text(rec)
        if key == "operating" and mean_diverges(operating_run(rec)):
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


def network_run_rows(net: NetworkSimulation, seed: int | None) -> list[dict[str, Any]]:
    """The simulation rows of a sensor network (its Monte Carlo keeps values at the horizon)."""
    rows = [row("operating-point runs", None, note=f"{filters.count(net.paths)} "
                f"paths × {filters.count(net.steps)} steps, each sensor over its "
                f"own link" + (f", seed {seed}" if seed is not None else ""))]
    mt = stated(net.mean_trace)
    if net.mean_exists is False:
        rows.append(row("simulated E[tr P_t]", None, note="diverges (the network is "
                        "mean-unstable); the sample mean estimates nothing"))
    elif mt is not None and number(mt.mean) is not None:
        band = filters.span(number(mt.lower), number(mt.upper), 5)
        rows.append(row("simulated E[tr P_t] at the horizon", number(mt.mean), "num",
                        note=f"t = {filters.count(net.steps)}; 95 % band {band}"))
    quant = network_quantiles_text(net)
    if quant:
        rows.append(row("quantiles of tr P at the horizon", None, note=quant))
    if stated(net.diverged_paths) is not None:
        rows.append(row("diverged paths", net.diverged_paths, "count",
                        note=f"of {filters.count(net.paths)}"))
    return rows


def operating_rows(rec: AnalysisRecord, run: SimulationOperatingPoint,
                   paths: int | None) -> list[dict[str, Any]]:
    """The rows of the operating point's runs: the mean at the horizon against tr S̄ and tr V̄,
    its quantiles, the time average, the diverged paths and the loss bursts."""
    rows = [row("i.i.d. losses", run.iid, "yesno")]
    _, mean, lo, hi = series_of(run)
    cb = rec.covariance_bounds
    s_tr = number(cb.lower.trace) if cb is not None else None
    v_tr = number(cb.upper.trace) if cb is not None else None
    horizon = run.horizon
    if _last(mean) is not None:
        band = (f"95 % band {filters.span(_last(lo), _last(hi), 5)}"
                if _last(lo) is not None and _last(hi) is not None else "")
        bounds = (f"tr S̄ = {filters.num(s_tr, 5)}" if s_tr is not None else "") + \
            (f", tr V̄ = {filters.num(v_tr, 5)}" if v_tr is not None else
             (", V̄ does not exist at this p" if s_tr is not None else ""))
        when = f" t = {horizon.time}" if horizon.time else ""
        if mean_diverges(run):
            rows.append(row("sample mean of tr P_t at the horizon" + when, _last(mean), "num",
                            note="; ".join(x for x in (
                                "E[tr P_t] diverges at this p: the sample mean over finitely "
                                "many paths is finite but estimates nothing", bounds) if x)))
        else:
            rows.append(row("mean tr P_t at the horizon" + when, _last(mean), "num",
                            note="; ".join(x for x in (band, bounds) if x)))
    levels, quants = horizon.levels, horizon.quantiles
    if levels and len(levels) == len(quants):
        wanted = [(lv, qv) for lv, qv in zip(levels, quants) if lv in (0.5, 0.9, 0.99)]
        if wanted:
            rows.append(row("quantiles of tr P at the horizon", None, note=", ".join(
                f"{filters.pct(lv, 3)}: {filters.num(number(qv), 5)}" for lv, qv in wanted)))
    erg = run.ergodic
    pooled = erg.time_averages.pooled_mean_trace
    if number(pooled.mean) is not None:
        rows.append(row("time average of tr P_t (one long path per replica)", pooled.mean,
                        "num", note=ergodic_note(erg, pooled)))
    div = run.divergence
    rows.append(row("diverged paths", div.diverged_paths, "count",
                    note=f"of {filters.count(paths)} (tr P above "
                    f"{filters.sci(number(div.threshold), 3)}; "
                    f"{divergence_text(div)})"))
    bursts = run.bursts
    if number(bursts.mean_length) is not None:
        rows.append(row("loss bursts", bursts.mean_length, "num",
                        note=f"mean length (channel: "
                        f"{filters.num(number(bursts.expected_mean_length), 4)}); "
                        f"{filters.count(bursts.bursts)} bursts, longest "
                        f"{filters.num(bursts.longest)}, loss fraction "
                        f"{filters.pct(number(bursts.loss_fraction))}"))
    return rows


def simulation_view(rec: AnalysisRecord) -> dict[str, Any]:
    """Settings and summary numbers of the simulation as labelled rows (arrays are drawn)."""
    sim = rec.simulation
    if sim is not None and stated(sim.skipped):
        return {"available": False, "tail_probability": None, "rows": [],
                "missing": missing("simulation", prose(stated(sim.reason) or "skipped"))}
    run = operating_run(rec)
    budget = stated(sim.budget) if sim is not None else None
    seed = stated(sim.seed) if sim is not None else None
    if seed is None and run is not None:
        seed = run.seed
    paths = run.paths if run is not None else budget.paths if budget is not None else None
    steps = run.steps if run is not None else budget.steps if budget is not None else None
    net = network_run(rec)
    rows: list[dict[str, Any]] = []
    if run is None and net is not None:
        rows += network_run_rows(net, seed)
    elif run is None:
        rows.append(row("operating-point runs", None, note="none: the record has no operating "
                        "point (no channel in the system file)"
                        if rec.operating_point is None else
                        "none: the simulation produced no data at the operating point"))
    else:
        p_op = filters.num(number(run.arrival_probability), 6)
        rows.append(row("operating-point runs", None, note=f"{filters.count(paths)} paths × "
                        f"{filters.count(steps)} steps at p = {p_op}"
                        + (f", seed {seed}" if seed is not None else "")))
        rows += operating_rows(rec, run, paths)
    demo = stated(sim.phase_demo) if sim is not None else None
    if demo is not None and demo.curves:
        ps = [number(c.arrival_probability) for c in demo.curves]
        ref = demo.reference_value
        rows.append(row("runs around p_c", None, note=(
            f"p = {', '.join(filters.num(x, 4) for x in ps)}"
            + (f" (reference {filters.num(number(ref), 6)})" if number(ref) is not None else "")
            + (f"; {filters.count(demo.paths)} paths × "
               f"{filters.count(demo.steps)} steps each" if demo.paths else ""))))
    seeds = stated(sim.seeds) if sim is not None else None
    if seeds is not None:
        rows.append(row("random seeds", None, note=seeds_text(seeds)))
    quick = stated(sim.quick) if sim is not None else None
    if quick is not None:
        rows.append(row("draft (--quick)", quick, "yesno"))
    return {"available": sim is not None, "missing": missing("simulation"),
            "tail_probability": tail_of(rec), "rows": rows}


def divergence_text(div: SimulationDivergence) -> str:
    """What happened to the paths that crossed the divergence threshold, as the record says.

    Paths continued in scaled form (``continued``) keep true values; censored paths (held at
    the threshold, the older rule) enter the means as the threshold, so the means are lower
    bounds; ``mean_is_lower_bound`` (censoring or a path frozen after a numerical failure)
    says so either way.
    """
    lower = bool(div.mean_is_lower_bound)
    if div.continued:
        text = "such paths are continued in scaled form, so the statistics are true values"
        return text + ("; some paths were frozen after a numerical failure, so means are "
                       "lower bounds" if lower else "")
    if div.diverged_paths or lower:
        return "censored at the threshold; means are lower bounds"
    return ("a diverged path would be censored at the threshold, making the means lower "
            "bounds; none did")


ERGODIC_MIN_REPLICAS = 10
ERGODIC_MAX_SPREAD = 3.0


def ergodic_unreliable(erg: ErgodicAverages, pooled: PooledMeanTrace) -> str:
    """Why the time-average interval cannot be trusted ("" when nothing is wrong with it).

    tr P_t ≥ 0, so a 95 % interval reaching below zero, or replica means that differ by more
    than a factor :data:`ERGODIC_MAX_SPREAD` with fewer than :data:`ERGODIC_MIN_REPLICAS`
    replicas, mean the normal approximation behind it does not hold (few replicas, heavy tail).
    """
    reasons = []
    lower = number(pooled.lower)
    if lower is not None and lower < 0:
        reasons.append("its normal approximation reached below 0 (clamped there: tr P ≥ 0)")
    means = [v for v in erg.time_averages.replica_mean_trace if number(v) is not None and v > 0]
    replicas = number(erg.replicas)
    spread = max(means) / min(means) if len(means) >= 2 else None
    if spread is not None and spread > ERGODIC_MAX_SPREAD and \
            (replicas is None or replicas < ERGODIC_MIN_REPLICAS):
        reasons.append(f"the {filters.count(replicas) if replicas else len(means)} replica means "
                       f"range over {filters.num(min(means), 4)} – {filters.num(max(means), 4)} "
                       "(a heavy tail)")
    return "; ".join(reasons)


def ergodic_note(erg: ErgodicAverages, pooled: PooledMeanTrace) -> str:
    """The time-average row's note: its 95 % interval clamped at 0, the replicas, and a caution
    when the interval is unreliable (:func:`ergodic_unreliable`)."""
    lower, upper = number(pooled.lower), number(pooled.upper)
    if lower is not None:
        lower = max(lower, 0.0)
    note = (f"95 % interval {filters.span(lower, upper, 5)}; "
            f"{filters.count(erg.replicas)} replicas × "
            f"{filters.count(erg.steps)} steps, burn-in "
            f"{filters.count(erg.burn_in)}")
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


def seeds_text(seeds: SimulationSeeds | int) -> str:
    """The simulation's seeds in words (its streams, each a seed or a seed rule), or the base
    seed alone."""
    if not dataclasses.is_dataclass(seeds):
        return seed_rule_text(seeds)
    parts = []
    for k, v in stated_fields(seeds):
        label = filters.key_label(k)
        if dataclasses.is_dataclass(v):
            inner = ", ".join(f"{filters.key_label(a)}: {seed_rule_text(b)}"
                              for a, b in stated_fields(v))
            parts.append(f"{label} ({inner})")
        else:
            parts.append(f"{label}: {seed_rule_text(v)}")
    return "; ".join(parts) if parts else filters.DASH


OPTION_LABELS = {"tolerance": ("decision tolerance (floating-point input)", "sci"),
                 "upper_tol": ("upper-bound tolerance", "sci"),
                 "simulate": ("simulation run", "yesno"),
                 "quick": ("draft mode (--quick)", "yesno"),
                 "seed": ("base random seed", "num"), "paths": ("simulated paths", "count"),
                 "steps": ("simulated steps", "count")}


def _solver_text(solver: UpperSolver | None) -> str:
    """Upper-bound solver statistics in words (its counters and notes), or a dash."""
    if solver is None:
        return filters.text(solver)
    parts = []
    for k, v in stated_fields(solver):
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


def check_view(check: VerificationCheck) -> dict[str, Any]:
    """One verification check of the record as a table row: name, badge and detail.

    The badge follows ``passed`` (True: passed, False: failed) and, when that is ``None``, the
    check's ``status`` word (inconclusive, not applicable); a passed check is never red.
    """
    passed = check.passed
    if passed is True:
        css, label = CHECK_STATUS["passed"]
    elif passed is False:
        css, label = CHECK_STATUS["failed"]
    else:
        word = check.status or "not applicable"
        css, label = CHECK_STATUS.get(word, ("none", word))
    return {"name": check_name(check.check), "css": css, "label": label,
            "detail": _detail_text(stated(check.detail))}


def structure_tolerance_text(rec: AnalysisRecord) -> str | None:
    """The structure analysis's arithmetic, time budget and state limit in words (``None``
    when the record states none of them)."""
    stol = rec.structure.tolerances if rec.structure is not None else None
    if stol is None or not stated_fields(stol):
        return None
    exact = stated(stol.exact)
    budget, states = stated(stol.time_budget_seconds), stated(stol.max_states)
    return ", ".join(
        x for x in (("exact arithmetic" if exact else "floating point")
                    if exact is not None else "",
                    f"time budget {filters.num(budget)} s" if budget is not None else "",
                    f"at most {filters.num(states)} states for exact work"
                    if states is not None else "") if x)


def appendix_view(rec: AnalysisRecord) -> dict[str, Any]:
    """Verification appendix: certificates and cross-checks, tolerances, versions, seeds, hash."""
    ub = rec.upper_bound
    cv = rec.critical_value
    rob = rec.robust_critical_value
    prov = rec.provenance
    sim = rec.simulation
    checks = [check_view(c) for c in rec.verification]
    # how p_c was decided is information, not a check: "numerical" is never shown as a failure
    claim = exact_claim(rec, cv)
    checks.append({"name": "critical value decided exactly",
                   "css": "pass" if claim else "none",
                   "label": {True: "exact", False: "numerical"}.get(claim, "not computed"),
                   "detail": prose(cv.reason if cv is not None else None)})
    opts = prov.options
    tolerances = [
        row("robust-value tolerance (relative)",
            rob.tolerance if rob is not None else opts.tolerance, "sci"),
        row("upper-bound tolerance", ub.tolerance if ub is not None else opts.upper_tol, "sci"),
        row("upper-bound method", ub.method if ub is not None else None),
        row("upper-bound solver", None,
            note=_solver_text(stated(ub.solver) if ub is not None else None)),
    ]
    structure = structure_tolerance_text(rec)
    if structure is not None:
        tolerances.append(row("structure analysis", None, note=structure))
    sim_seeds = stated(sim.seeds) if sim is not None else None
    seeds = sim_seeds if sim_seeds is not None else prov.seed
    versions = dict(prov.versions)
    if versions.get("kfcrit") != __version__:
        versions["kfcrit (report)"] = __version__
    versions.update({name: v for name, v in report_versions().items()
                     if name not in versions and name.lower() not in versions})
    options = [row(OPTION_LABELS.get(k, (filters.key_label(k), "text"))[0], v,
                   OPTION_LABELS.get(k, ("", "text"))[1],
                   note="default for the mode" if v is None and k in ("paths", "steps") else "")
               for k, v in stated_fields(opts)]
    return {"checks": checks, "tolerances": tolerances,
            "upper_warnings": [prose(w) for w in (ub.warnings if ub is not None else [])],
            "versions": [row(str(k), v if v is not None else "not installed")
                         for k, v in versions.items()],
            "seeds": seeds_text(seeds),
            "sha256": prov.input_sha256, "input_path": prov.input_path,
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


