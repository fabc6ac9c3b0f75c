"""Benchmark: ``kfcrit analyze`` (``--quick`` and full) on large random systems, with the peak
resident memory and the load average.

    python -m kfcrit.bench.bench_analyze [--sizes 200 400] [--skip-full]

Writes ``random_system(n, m, 0)`` (``../shared/bench/systems.py``; m = 40 at n = 200, 60 at
n = 400) with a Bernoulli channel (arrival probability 0.9) to a temporary YAML file and runs
``python -m kfcrit analyze FILE [--quick]`` in a child process, reporting its wall time and
peak RSS (resource.getrusage of the children). Targets (issue 27): --quick at 200 states within
10 s; full within 60 s at 200 and 5 minutes at 400, under 2 GB. Timings live here, never in
unit tests.
"""
from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from kfcrit.bench.bench_upper import shared_bench

OUTPUTS = {200: 40, 400: 60}


def write_system(n: int, path: Path) -> None:
    """The YAML file of random_system(n, OUTPUTS[n], 0) with a Bernoulli(0.9) channel."""
    sys.path.insert(0, str(shared_bench()))
    from systems import random_system

    A, C, Q, R = random_system(n, OUTPUTS.get(n, max(1, n // 5)), 0)

    def mat(M):
        return "[" + ", ".join("[" + ", ".join(repr(float(v)) for v in row) + "]"
                               for row in M) + "]"

    path.write_text(f"name: random_system({n}, {OUTPUTS.get(n, max(1, n // 5))}, 0)\n"
                    f"A: {mat(A)}\nC: {mat(C)}\nQ: {mat(Q)}\nR: {mat(R)}\n"
                    "channel:\n  model: bernoulli\n  arrival_probability: 0.9\n")


def run(path: Path, quick: bool, timeout: float) -> dict:
    """Wall time, exit code and peak RSS (MiB) of one ``kfcrit analyze`` child process."""
    cmd = [sys.executable, "-m", "kfcrit", "analyze", str(path)] + (["--quick"] if quick else [])
    before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    load = os.getloadavg()[0]
    t = time.perf_counter()
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
        code = proc.returncode
    except subprocess.TimeoutExpired:
        code = "timeout"
    seconds = time.perf_counter() - t
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    return {"seconds": seconds, "exit": code, "peak_rss_mib": max(peak, before) / 1024,
            "load_before": load, "load_after": os.getloadavg()[0]}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[200, 400])
    ap.add_argument("--skip-full", action="store_true", help="time --quick only")
    ap.add_argument("--timeout", type=float, default=900.0)
    args = ap.parse_args(argv)
    print(f"machine: {os.cpu_count()} cores")
    with tempfile.TemporaryDirectory() as tmp:
        for n in args.sizes:
            path = Path(tmp) / f"big{n}.yaml"
            write_system(n, path)
            for quick in (True, False):
                if not quick and args.skip_full:
                    continue
                r = run(path, quick, args.timeout)
                print(f"n={n:>4} {'--quick' if quick else 'full   '} {r['seconds']:8.1f} s "
                      f"exit={r['exit']} peak RSS (max over children so far) "
                      f"{r['peak_rss_mib']:.0f} MiB load {r['load_before']:.2f}/"
                      f"{r['load_after']:.2f}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
