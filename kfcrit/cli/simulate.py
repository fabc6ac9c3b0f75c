"""The ``kfcrit simulate`` command: run the Monte Carlo, print a summary or JSON, plot."""
from __future__ import annotations

import dataclasses
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

from kfcrit.analysis.spec import load_spec
from kfcrit.errors import InputError
from kfcrit.io.jsonio import dumps
from kfcrit.sim.engine import check_sizes, ergodic, simulate
from kfcrit.sim.results import QUANTILE_LEVELS, ErgodicResult, SimulationResult
from kfcrit.views.figures.sim import write_plot


def simulate_command(system_file: str, *, paths: int, steps: int, seed: int, as_json: bool,
                     plot: str | None, max_states: int, ergodic_steps: int | None = None,
                     tail: tuple[float, ...] | list[float] = ()) -> int:
    """Run the ``kfcrit simulate`` subcommand; return the exit code.

    Data (the summary or ``--json``) goes to stdout; a progress bar goes to stderr only when it
    is a terminal; ``--plot`` writes an SVG or PNG atomically. With ``ergodic_steps`` (or any
    ``tail`` level, default length max(10 · steps, 10 000)) the time averages along
    ``ERGODIC_REPLICAS`` long paths (Kar et al. Prop. 25, :func:`ergodic`) are added: time mean
    of tr P, tail probabilities (1/T) #{t : tr P_t > M} for every level M (and the system
    file's ``max_error_trace``), loss bursts and the almost-sure indicators; under ``ergodic``
    in ``--json``.
    """
    check_sizes(paths, steps, seed)
    levels = [_tail_level(x) for x in tail]
    if ergodic_steps is not None:
        if (isinstance(ergodic_steps, bool) or not isinstance(ergodic_steps, (int, np.integer))
                or ergodic_steps < 1):
            raise InputError("must be an integer >= 1", field="--ergodic-steps")
    elif levels:
        ergodic_steps = max(10 * steps, 10_000)
    if plot is not None:
        if Path(plot).suffix.lower() not in (".svg", ".png"):
            raise InputError("must end in .svg or .png", field="--plot")
        if not Path(plot).resolve().parent.is_dir():
            raise InputError(f"folder {str(Path(plot).resolve().parent)[:80]!r} does not exist",
                             field="--plot")
    spec = load_spec(system_file, max_states=max_states)
    if plot is not None:
        from kfcrit.cli.common import spec_inputs
        from kfcrit.io.atomic import refuse_replacing_inputs

        refuse_replacing_inputs([plot], spec_inputs(spec, system_file), "--plot")
    if spec.network is not None and spec.network.size == 1:   # one sensor: one link
        spec = dataclasses.replace(spec, channel=spec.network.sensors[0].channel)
    sensors = network_sensors(spec)
    if spec.mesh is not None:
        raise InputError("kfcrit simulate takes one channel or a sensors: network; a mesh is "
                         "simulated by kfcrit analyze (its simulation section)", field="mesh")
    if spec.channel is None and sensors is None:
        raise InputError("the system file has no channel (add channel: {model: bernoulli, "
                         "arrival_probability: ...})", field="channel")
    keep = min(paths, 5) if plot is not None and steps <= 1_000_000 else False
    if sensors is not None:
        result = simulate(spec.system, paths, steps, seed, record_traces=keep, sensors=sensors)
    elif sys.stderr.isatty() and paths * steps * spec.system.n ** 2 > 5e7:
        result = with_progress(spec, paths, steps, seed, keep)
    else:
        result = simulate(spec.system, paths, steps, seed, spec.channel, record_traces=keep)
    erg = None
    if ergodic_steps is not None and sensors is not None:
        raise InputError("time averages of a sensor network are not available; simulate without "
                         "--ergodic-steps/--tail", field="--ergodic-steps")
    if ergodic_steps is not None:
        req = spec.requirements.max_error_trace
        lv = sorted(set(levels + ([float(req)] if req is not None else [])))
        erg = ergodic(spec.system, int(ergodic_steps), seed, spec.channel,
                      replicas=ERGODIC_REPLICAS, levels=lv)
    no_mean = mean_does_not_exist(spec) if sensors is None else None
    if as_json:
        record = result.to_dict()
        record["ergodic"] = None if erg is None else erg.to_dict()
        if no_mean is not None:
            record["mean_exists"] = False
            record["mean_basis"] = no_mean
        print(dumps(record))
    else:
        text = summary_text(result, spec.requirements.max_error_trace)
        if no_mean is not None:
            text += ("\nwarning: the mean does not exist: " + no_mean + "; the sample mean "
                     "and its interval above estimate nothing")
        if erg is not None:
            text += "\n" + ergodic_text(erg)
        print(text)
    if plot is not None:
        write_plot(result, plot)
    return 0


def mean_does_not_exist(spec: Any) -> str | None:
    """Why lim E[tr P_t] is infinite at the file's channel, or None when that is not proven.

    The necessary condition (1 − x)·ρ(A)² < 1 (theory §3 for i.i.d. losses with x = p, theory
    §10 for a Gilbert–Elliott link with x = r, the recovery rate) decided exactly, as
    ``kfcrit analyze`` does; measured traces and time-correlated shadowing are not judged."""
    from kfcrit.theory.links.markov import burst_necessary

    ch = spec.channel
    if ch is None or ch.model == "trace":
        return None
    if ch.model == "gilbert-elliott" and not ch.iid:
        x, what = ch.recovery_rate, "recovery rate r"
    elif ch.iid:
        x, what = ch.arrival_probability, "arrival probability p"
    else:
        return None
    nec = burst_necessary(spec.system, x)
    if nec.holds is not False:
        return None
    return (f"(1 − x)·ρ(A)² = {nec.value:.6g} ≥ 1 with x the {what} = {float(x):.6g} (theory "
            f"§{'10' if what.startswith('recovery') else '3'}): E[tr P_t] diverges")


ERGODIC_REPLICAS = 4
"""Independent long paths of ``kfcrit simulate --ergodic-steps`` (replica 0 is "the" path)."""


def _tail_level(x: Any) -> float:
    try:
        v = float(x)
    except (TypeError, ValueError):
        raise InputError(f"must be a number, got {str(x)[:40]!r}", field="--tail") from None
    if not (math.isfinite(v) and v > 0):
        raise InputError(f"must be a finite positive level, got {v!r}", field="--tail")
    return v


def ergodic_text(erg: ErgodicResult) -> str:
    """Terminal lines for the ergodic time averages (``kfcrit simulate --ergodic-steps``)."""
    d = erg.to_dict()
    ta = d["time_averages"]
    pooled = ta["pooled_mean_trace"]
    lines = [f"ergodic averages: {erg.replicas} paths x {erg.steps} steps, burn-in "
             f"{erg.burn_in}, streams SeedSequence({erg.seed}, spawn_key=(2, j))"]
    if pooled["mean"] is not None:
        lines.append(f"time average of tr P: {pooled['mean']:.6g} (95% batch-means interval "
                     f"{_fmt(pooled['lower'])} .. {_fmt(pooled['upper'])})")
    else:
        lines.append("time average of tr P: none (every long path crossed the divergence "
                     "threshold)")
    for t in erg.tail_probabilities():
        lines.append(f"P(tr P > {t.level:g}) by time average: {_fmt(t.probability)} "
                     f"({t.count} of {t.steps} path-steps of {t.replicas} long paths "
                     "that stayed below the divergence threshold; steps are correlated, no "
                     "interval)")
    div = d["divergence"]
    if div["diverged_replicas"]:
        lines.append(f"warning: {div['diverged_replicas']} of {erg.replicas} long paths crossed "
                     f"tr P > {erg.divergence_threshold:.3g}; their averages stop there (the "
                     "mean of the invariant law is infinite below p_c)")
    b = d["bursts"]
    if b["mean_length"] is not None:
        lines.append(f"loss bursts: mean length {b['mean_length']:.4g} (channel "
                     f"{_fmt(b['expected_mean_length'])}), longest {b['longest']}")
    return "\n".join(lines)


def network_sensors(spec: Any) -> list[tuple[list[int], Any]] | None:
    """Each sensor of a network file over its own link: (its rows of the stacked C, channel);
    None for a one-link file."""
    net = getattr(spec, "network", None)
    if net is None or net.size == 1:
        return None
    missing = [s.name for s in net.sensors if s.channel is None]
    if missing:
        raise InputError("has no channel", field=f"sensors.{missing[0]}.channel")
    return [(list(range(sl.start, sl.stop)), s.channel)
            for sl, s in zip(net.row_slices(), net.sensors)]


def with_progress(spec: Any, paths: int, steps: int, seed: int,
                   keep: int | bool) -> SimulationResult:
    from rich.console import Console
    from rich.progress import Progress

    with Progress(console=Console(stderr=True), transient=True) as bar:
        task = bar.add_task("simulating", total=paths * steps)
        return simulate(spec.system, paths, steps, seed, spec.channel, record_traces=keep,
                        progress=lambda done, total: bar.update(task, completed=done))


def _fmt(x: float | None) -> str:
    return "—" if x is None else f"{x:.4g}"


def summary_text(result: SimulationResult, level: float | None = None) -> str:
    """A readable summary of a simulation (the default output of ``kfcrit simulate``)."""
    lo, hi = result.band()
    q = dict(zip(QUANTILE_LEVELS, result.horizon_quantiles(), strict=True))
    lines = [
        f"{result.system_name}: {result.paths} paths x {result.steps} steps, seed {result.seed}",
        f"channel: {result.channel.get('model')}, arrival probability "
        f"{result.arrival_probability:.6g}",
        f"E[tr P_t] at t = {result.steps}: {result.mean_trace[-1]:.6g} "
        f"(95% CI {lo[-1]:.6g} .. {hi[-1]:.6g})"
        + (" [approximate: paths frozen after a numerical failure]"
           if result.mean_is_lower_bound else ""),
    ]
    if not math.isfinite(result.mean_trace[-1]):
        llo, lhi = result.log10_band()
        low = "0" if not math.isfinite(llo[-1]) else f"10^{llo[-1]:.4g}"
        lines[-1] = (f"E[tr P_t] at t = {result.steps}: 10^{result.log10_mean_trace[-1]:.6g} "
                     f"(95% CI {low} .. 10^{lhi[-1]:.4g}; beyond float64, shown as powers of "
                     "ten)")
    if result.mean_lambda_max is not None:
        v = result.mean_lambda_max[-1]
        text = (f"{v:.6g}" if math.isfinite(v) or result.log10_mean_lambda_max is None
                else f"10^{result.log10_mean_lambda_max[-1]:.6g}")
        lines.append(f"E[lambda_max P_t] at t = {result.steps}: {text}")
    lq = dict(zip(QUANTILE_LEVELS, result.horizon_log10_quantiles(), strict=True))
    lines.append("tr P at the horizon: " + ", ".join(
        f"q{int(round(100 * k))} "
        + (_fmt(q[k]) if q[k] is not None or lq[k] is None else f"10^{lq[k]:.5g}")
        for k in (0.05, 0.5, 0.95, 0.99)))
    if level is not None:
        e = result.exceedance(level)
        lines.append(f"P(tr P > {level:g}) at the horizon: {e.estimate:.4g} "
                     f"(95% CI {e.lower:.4g} .. {e.upper:.4g})")
    lines.append(f"diverged paths: {result.diverged_paths} (crossed tr P > "
                 f"{result.divergence_threshold:.3g}; continued in scaled form)")
    lines.extend(f"warning: {w}" for w in result.warnings)
    lines.append(f"runtime: {result.runtime_seconds:.2f} s")
    return "\n".join(lines)
