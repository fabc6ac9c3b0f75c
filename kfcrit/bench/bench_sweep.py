"""Benchmark of ``kfcrit sweep``: a 10 000-point link-budget sweep, local processes vs Dask.

The sweep is a distance × packet-size grid over the IEEE 802.15.4 link of a scalar plant
(a = 5/4, p_c = 9/25) with 4 dB log-normal shadowing, so every point computes the link chain,
the required SINR, the outage probability and the shadowing average. It runs twice, from an
empty output folder each time:

* ``local``: the default local process pool (``--workers``; forked or spawned as
  :func:`kfcrit.analysis.sweep.run.start_method` chooses, and the time includes starting
  them);
* ``dask``: a ``distributed.LocalCluster`` on 127.0.0.1 (started before the clock, as an
  existing cluster would be; the time includes connecting the client).

Prints points per second for each, the ratio dask / local and the load average (the machine
may be shared), and checks that both produced byte-identical tables. For the local run it also
prints the CPU time per point (this process and its worker processes, start-up included), which
a loaded machine does not hide the way it hides wall-clock speed. Run::

    python -m kfcrit.bench.bench_sweep [--points 10000] [--workers N] [--dask-workers N]
                                       [--no-dask]
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path
from typing import Any, TextIO

BASE_SYSTEM = """\
name: scalar plant over an IEEE 802.15.4 link
A: [[1.25]]
C: [[1]]
Q: [[1]]
R: [[2.5]]
channel:
  model: link-budget
  radio: ieee802154-oqpsk-2450
  tx_power_dbm: 0
  distance_m: 50
  packet_bytes: 40
  path_loss: {model: log-distance, exponent: 3.0, reference_distance_m: 1,
              reference_loss_db: 40.2, shadowing_sigma_db: 4}
  noise: {noise_figure_db: 10, bandwidth_hz: 2.0e6, temperature_k: 290}
  margin_db: 2
  max_outage: 0.1
"""


def grid_shape(points: int) -> tuple[int, int]:
    """(packet sizes, distances) with product ``points``: at most 10 packet sizes."""
    if points < 1:
        raise ValueError("points must be >= 1")
    sizes = max(d for d in range(1, 11) if points % d == 0)
    return sizes, points // sizes


def sweep_text(points: int) -> str:
    """The sweep file: packet sizes 20 … 127 bytes × distances 10 … 200 m."""
    sizes, distances = grid_shape(points)
    if sizes == 1:
        packets = "[40]"
    else:
        packets = "[" + ", ".join(str(20 + round(107 * k / (sizes - 1)))
                                  for k in range(sizes)) + "]"
    dist = f"{{start: 10, stop: 200, num: {distances}}}" if distances > 1 else "[100]"
    return (f"name: benchmark {points} points\nsystem: system.yaml\ngrid:\n"
            f"  channel.packet_bytes: {packets}\n  channel.distance_m: {dist}\n")


def cpu_seconds() -> float:
    """CPU seconds (user + system) of this process and of its finished child processes."""
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


def _load() -> str:
    try:
        return "load average {:.2f} {:.2f} {:.2f}".format(*os.getloadavg())
    except OSError:  # pragma: no cover - not on every platform
        return "load average unavailable"


def sweep_throughput(points: int = 10_000, workers: int | None = None, dask_workers: int | None = None,
        dask_processes: bool = True, out: TextIO | None = None,
        dask: bool = True) -> dict[str, Any]:
    """Run the benchmark and print its report.

    Parameters
    ----------
    points : int
        Number of sweep points.
    workers : int, optional
        Local worker processes (default: number of cores).
    dask_workers : int, optional
        Dask workers of the LocalCluster (default: the same as ``workers``), one thread each.
    dask_processes : bool
        Dask workers as processes (True, comparable with the local pool) or threads.
    out : file, optional
        Where to print (default stdout).
    dask : bool
        Also run on a Dask LocalCluster (False: local processes only; ``identical`` is then
        None).

    Returns
    -------
    dict
        ``points, local {seconds, points_per_second, workers, start_method, cpu_seconds,
        cpu_ms_per_point}, dask {...}, ratio, identical, load_before, load_after``.
    """
    from kfcrit.analysis.sweep.points import load_sweep, run_sweep, table_csv
    from kfcrit.analysis.sweep.run import start_method

    out = out or sys.stdout
    workers = workers or os.cpu_count() or 1
    dask_workers = dask_workers or workers
    result: dict[str, Any] = {"points": points, "load_before": _load()}
    with tempfile.TemporaryDirectory(prefix="kfcrit-bench-sweep-") as tmp:
        folder = Path(tmp)
        (folder / "system.yaml").write_text(BASE_SYSTEM)
        (folder / "sweep.yaml").write_text(sweep_text(points))
        t0 = time.perf_counter()
        spec = load_sweep(folder / "sweep.yaml")
        load_seconds = time.perf_counter() - t0
        print(f"machine: {platform.machine()} {os.cpu_count()} cores, python "
              f"{platform.python_version()}; {result['load_before']}", file=out)
        print(f"sweep: {points} points ({' x '.join(map(str, grid_shape(points)))} packet sizes "
              f"x distances), read and keyed in {load_seconds:.2f} s", file=out)

        method = start_method()
        t0, c0 = time.perf_counter(), cpu_seconds()
        local = run_sweep(spec, folder / "local", workers=workers)
        dt, cpu = time.perf_counter() - t0, cpu_seconds() - c0
        result["local"] = {"seconds": dt, "points_per_second": points / dt, "workers": workers,
                           "errors": local.errors, "cpu_seconds": cpu,
                           "cpu_ms_per_point": 1000 * cpu / points, "start_method": method}
        print(f"local processes ({workers}, {method}): {dt:8.2f} s  {points / dt:9.1f} points/s; "
              f"CPU {cpu:.2f} s = {1000 * cpu / points:.3f} ms per point (workers' start-up "
              f"included; {workers} cores at this CPU cost: "
              f"{workers * points / cpu:.0f} points/s); {_load()}", file=out)
        if not dask:
            result["identical"] = None
            result["load_after"] = _load()
            return result
        from distributed import LocalCluster

        with LocalCluster(n_workers=dask_workers, threads_per_worker=1,
                          processes=dask_processes, protocol="tcp", host="127.0.0.1",
                          dashboard_address=None) as cluster:
            t0 = time.perf_counter()
            dask = run_sweep(spec, folder / "dask", scheduler=cluster.scheduler_address)
            dt = time.perf_counter() - t0
        result["dask"] = {"seconds": dt, "points_per_second": points / dt,
                          "workers": dask_workers, "processes": dask_processes,
                          "errors": dask.errors}
        kind = "processes" if dask_processes else "threads"
        print(f"dask LocalCluster ({dask_workers} {kind}, 127.0.0.1): {dt:8.2f} s  "
              f"{points / dt:9.1f} points/s", file=out)
        result["ratio"] = result["dask"]["points_per_second"] / \
            result["local"]["points_per_second"]
        result["identical"] = (table_csv(spec, local.rows) == table_csv(spec, dask.rows)
                               and json.dumps(local.rows) == json.dumps(dask.rows))
    result["load_after"] = _load()
    print(f"ratio dask / local (points per second): {result['ratio']:.3f}; tables identical: "
          f"{result['identical']}; {result['load_after']}", file=out)
    return result


def sweep_benchmark(argv: list[str] | None = None) -> None:
    """Command-line entry: ``python -m kfcrit.bench.bench_sweep``."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=10_000)
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--dask-workers", type=int, default=None)
    ap.add_argument("--dask-threads", action="store_true",
                    help="Dask workers as threads instead of processes.")
    ap.add_argument("--no-dask", action="store_true",
                    help="Local processes only (no Dask LocalCluster).")
    args = ap.parse_args(argv)
    sweep_throughput(args.points, args.workers, args.dask_workers, dask_processes=not args.dask_threads,
        dask=not args.no_dask)


if __name__ == "__main__":
    sweep_benchmark()
