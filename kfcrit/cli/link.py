"""``kfcrit link simulate``: a file's 802.15.4 links in ns-3's lr-wpan model (``kfcrit[ns3]``).

The plan (sensors, sink, propagation, noise, shadowing) is built and checked before ns-3 is
loaded, so a bad file or option exits 2 at once; a machine without the wheel exits 2 with
"ns-3 is not installed: pip install 'kfcrit[ns3]'". ns-3 runs in this process (one load of
20–40 s per command). stdout carries the report (or exactly the JSON with ``--json``);
progress goes to stderr.
"""
from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import click

from kfcrit.cli.common import debug_option, handle_errors, max_states_option

LINK_EXAMPLES = """\b
Examples:
  kfcrit link simulate reports/link-oqpsk-sensor.yaml --periods 2000
  kfcrit link simulate reports/network-planar-tracker.yaml -o ns3-traces/ --jitter-ms 5
  kfcrit link simulate reports/network-planar-tracker.yaml --json > ns3.json

\b
Needs the optional extra: pip install 'kfcrit[ns3]'. Exit codes: 0 done, 2 bad file or
option (or ns-3 not installed), 4 internal error, 130 interrupted.
"""


@click.group(epilog=LINK_EXAMPLES)
def link() -> None:
    """Radio links: simulate a file's link budgets in ns-3."""


def _fmt(value: float | None, digits: int = 4) -> str:
    return "n/a" if value is None else f"{value:.{digits}f}"


def ns3_text(summary: dict[str, Any]) -> str:
    """The terminal report of a simulation summary."""
    plan = summary["plan"]
    jitter = f", jitter {plan['jitter_s'] * 1e3:g} ms" if plan["jitter_s"] else ", no jitter"
    fading = f", Nakagami m = {plan['nakagami_m']:g}" if plan["nakagami_m"] else ""
    lines = [f"ns-3 lr-wpan ({summary['ns3_version']}): {len(summary['sensors'])} sensor(s), "
             f"{plan['periods']} periods of {plan['period_s'] * 1e3:g} ms{jitter}{fading}, "
             f"seed {plan['seed']}",
             f"noise {summary['ns3_noise_dbm']:.2f} dBm; unslotted CSMA-CA to one sink", ""]
    head = (f"{'sensor':<12} {'d [m]':>7} {'simulated':>9} {'95% interval':>17} "
            f"{'analytic':>9} {'a.(sim)':>8} {'late':>5} {'CCA':>5} {'coll.':>5} "
            f"{'noise':>5} {'tx/per':>6}")
    lines += [head, "-" * len(head)]
    for r in summary["sensors"]:
        lo, hi = r["arrival_simulated_ci95"]
        lost = r["lost"]
        mark = "" if r["analytic_in_ci95"] else " *"
        lines.append(f"{r['name'][:12]:<12} {r['distance_m']:>7.1f} "
                     f"{r['arrival_simulated']:>9.4f} [{lo:.4f}, {hi:.4f}] "
                     f"{r['arrival_analytic']:>9.4f} "
                     f"{r['arrival_analytic_simulated_conditions']:>8.4f} {lost['late']:>5} "
                     f"{lost['channel_access']:>5} {lost['collision']:>5} {lost['noise']:>5} "
                     f"{r['mean_transmissions_per_period']:>6.2f}{mark}")
    lines += ["", "analytic: the link budget's arrival probability; a.(sim): the same under the "
              "simulated shadowing draw and fading;",
              "* marks a sensor whose a.(sim) lies outside the 95% interval. Lost periods by "
              "cause: late, CCA (channel-access",
              "failure), coll. (a transmission overlapped another node's), noise (sent, no "
              "overlap, not received)."]
    cross = summary.get("cross_sensor")
    if cross:
        lo, hi = cross["p_all_lost_ci95"]
        ratio = cross["ratio"]
        lines += ["", f"P(all lost) = {cross['p_all_lost']:.4g} [{lo:.4g}, {hi:.4g}]; product of "
                  f"marginal losses = {cross['product_of_marginal_losses']:.4g}"
                  + (f" (ratio {ratio:.3g})" if ratio is not None else "")
                  + ("; consistent with independence" if cross["independence_in_ci95"]
                     else "; NOT independent"),
                  f"largest pairwise loss correlation: "
                  f"{_fmt(cross['max_abs_pairwise_correlation'], 3)}"]
    if summary.get("trace_files"):
        lines += ["", f"traces: {', '.join(summary['trace_files'])} in {summary['output']}"]
    return "\n".join(lines)


def _output_folder(output: str) -> Path:
    from kfcrit.errors import OutputError

    out = Path(output)
    if out.exists() and not out.is_dir():
        raise OutputError("exists and is not a folder", field=output[:120])
    if not out.parent.is_dir():
        raise OutputError("its parent folder does not exist", field=output[:120])
    try:
        out.mkdir(exist_ok=True)
    except OSError as exc:
        raise OutputError(f"cannot create the folder: {exc.strerror or exc}",
                          field=output[:120]) from None
    return out


def write_simulation(out: Path, summary: dict[str, Any], traces: Any,
                     ns3_plan: Any = None) -> list[str]:
    """Write one ``<sensor>.trace`` per sensor, ``summary.json`` and (given the ``ns3_plan``) the
    figure ``arrival.svg`` of the analytic against the simulated arrival by distance."""
    from kfcrit.io.atomic import write_atomic
    from kfcrit.io.jsonio import dumps
    from kfcrit.link.ns3.results import trace_file_text

    plan = summary["plan"]
    header = {"periods": plan["periods"], "period_s": plan["period_s"], "seed": plan["seed"],
              "jitter_s": plan["jitter_s"], "ns3": summary["ns3_version"],
              "format": "binary: 1 = received within its period, period 0 first"}
    names = []
    for row, trace in zip(summary["sensors"], traces, strict=True):
        name = f"{row['name']}.trace"
        write_atomic(out / name, trace_file_text(row["name"], trace, header).encode())
        names.append(name)
    summary["trace_files"] = names
    summary["output"] = str(out)
    if ns3_plan is not None:
        summary["figure"] = _write_arrival_figure(out, summary, ns3_plan)
    write_atomic(out / "summary.json", (dumps(summary) + "\n").encode())
    return names


def _write_arrival_figure(out: Path, summary: dict[str, Any], plan: Any) -> str:
    """``arrival.svg``: each sensor's link-budget p(d) with the ns-3 rate and its interval."""
    import io

    from kfcrit.io.atomic import write_atomic
    from kfcrit.link.ns3.results import analytic_arrival_curve, simulated_distance_grid
    from kfcrit.views.figures.link import ns3_arrival_figure

    grid = simulated_distance_grid(summary)
    curves = {s.name: analytic_arrival_curve(s, grid) for s in plan.sensors}
    fig = ns3_arrival_figure(summary, grid, curves)
    buf = io.BytesIO()
    fig.savefig(buf, format="svg", metadata={"Date": None})
    write_atomic(out / "arrival.svg", buf.getvalue())
    return "arrival.svg"


@link.command("simulate", epilog=LINK_EXAMPLES)
@click.argument("file", type=click.Path(dir_okay=False))
@click.option("-o", "--output", default=None, type=click.Path(file_okay=False),
              help="Folder for the traces (<sensor>.trace, one 0/1 per period) and "
                   "summary.json; created if missing (its parent must exist).")
@click.option("--periods", type=click.IntRange(1, 10_000_000), default=1000, show_default=True,
              help="Sample periods to simulate.")
@click.option("--seed", type=click.IntRange(0, 2**32 - 1), default=0, show_default=True,
              help="Seed of ns-3 (RngSeedManager) and of the shadowing draws.")
@click.option("--period-ms", type=click.FloatRange(0.1, 3_600_000), default=None,
              help="Sample period [default: the link's shadowing_correlation.sample_period_s, "
                   "the file's sampling_time, else 100 ms].")
@click.option("--jitter-ms", type=click.FloatRange(0, 3_600_000), default=0.0,
              show_default=True, help="Delay each sample by a uniform time in [0, J) ms "
                                      "(0: all sensors sample together).")
@click.option("--nakagami-m", type=click.FloatRange(0.5, 1000), default=None,
              help="Add Nakagami-m fading per transmission (1 = Rayleigh).")
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON.")
@max_states_option
@debug_option
@handle_errors
def link_simulate_cli(file: str, output: str | None, periods: int, seed: int, period_ms: float | None,
             jitter_ms: float, nakagami_m: float | None, as_json: bool, max_states: int,
             debug: bool) -> None:
    """Simulate FILE's link budget (or every sensor of a network file) in ns-3's lr-wpan
    model: CSMA-CA, acknowledgements and retries, shadowing; traces and arrival statistics."""
    from kfcrit.analysis.spec import load_spec
    from kfcrit.io.jsonio import dumps
    from kfcrit.link.ns3.driver import require_ns3, run_plan
    from kfcrit.link.ns3.results import simulation_summary
    from kfcrit.link.ns3.topology import build_plan, default_period_s, file_links

    spec = load_spec(file, max_states=max_states)
    links, sink = file_links(spec)
    period_s = period_ms / 1e3 if period_ms is not None else default_period_s(spec)
    plan = build_plan(links, sink_position_m=sink, periods=periods, period_s=period_s,
                      seed=seed, jitter_s=jitter_ms / 1e3, nakagami_m=nakagami_m)
    out = _output_folder(output) if output is not None else None
    require_ns3()
    click.echo(f"kfcrit: simulating {len(plan.sensors)} sensor(s) x {periods} periods in ns-3 "
               "(loading ns-3 takes 20-40 s)", err=True)
    run = run_plan(plan)
    summary = simulation_summary(plan, run)
    if out is not None:
        write_simulation(out, summary, run.traces, plan)
    click.echo(dumps(summary) if as_json else ns3_text(summary))
    sys.exit(0)
