"""Benchmark: ``kfcrit analyze`` (``--quick`` and full) on large random systems, with the peak
resident memory and the load average.

    python -m kfcrit.bench.bench_analyze [--sizes 200 400] [--skip-full]

Writes ``random_system(n, m, 0)`` (``../shared/bench/systems.py``; m = 40 at n = 200, 60 at
n = 400) with a Bernoulli channel (arrival probability 0.9) to a temporary YAML file and runs
``python -m kfcrit analyze FILE [--quick]`` in a child process, reporting its wall time, CPU
time, peak RSS (the child's own ``wait4`` resource usage) and the load average before and after
(1, 5, 15 minutes). On a loaded machine CPU time is the comparable number; OpenBLAS threads
that wait for a busy core add CPU time, so ``--blas-threads 1`` is also worth a run.
Targets (issue 27): --quick at 200 states within 10 s; full within 60 s at 200 and 5 minutes
at 400, under 2 GB. Timings live here, never in unit tests.
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from kfcrit.bench.bench_upper import shared_bench

OUTPUTS = {200: 40, 400: 60}
TARGETS = {(200, True): 10.0, (200, False): 60.0, (400, False): 300.0}
"""Wall-clock targets of issue 27 in seconds, (n, quick) → seconds."""


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


def analyze_once(path: Path, quick: bool, timeout: float, env: dict[str, str] | None = None) -> dict:
    """Wall time, CPU time (user + system), exit code and peak RSS (MiB) of one
    ``kfcrit analyze`` child process, read from its own ``wait4`` resource usage."""
    cmd = [sys.executable, "-m", "kfcrit", "analyze", str(path), "--max-states", "100000"] + \
        (["--quick"] if quick else [])
    load = os.getloadavg()
    t = time.perf_counter()
    with tempfile.TemporaryFile() as out:
        proc = subprocess.Popen(cmd, stdout=out, stderr=subprocess.STDOUT,
                                env={**os.environ, **(env or {})})
        deadline = t + timeout
        code: int | str = "timeout"
        usage = None
        while time.perf_counter() < deadline:
            pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
            if pid:
                code = os.waitstatus_to_exitcode(status)
                break
            time.sleep(0.2)
        else:
            proc.kill()
            _, _, usage = os.wait4(proc.pid, 0)
        proc.returncode = code if isinstance(code, int) else -9
        seconds = time.perf_counter() - t
        out.seek(0)
        tail = out.read().decode(errors="replace").strip().splitlines()[-3:]
    return {"seconds": seconds, "cpu": usage.ru_utime + usage.ru_stime, "exit": code,
            "peak_rss_mib": usage.ru_maxrss / 1024, "load_before": load,
            "load_after": os.getloadavg(), "tail": tail}


def analyze_benchmark(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[200, 400])
    ap.add_argument("--skip-full", action="store_true", help="time --quick only")
    ap.add_argument("--timeout", type=float, default=900.0)
    ap.add_argument("--blas-threads", type=int, default=None,
                    help="OPENBLAS_NUM_THREADS of the child (default: inherited)")
    args = ap.parse_args(argv)
    env = {} if args.blas_threads is None else {"OPENBLAS_NUM_THREADS": str(args.blas_threads)}
    print(f"machine: {os.cpu_count()} cores, OPENBLAS_NUM_THREADS="
          f"{env.get('OPENBLAS_NUM_THREADS', os.environ.get('OPENBLAS_NUM_THREADS', 'unset'))}; "
          f"targets: --quick n=200 < {TARGETS[(200, True)]:g} s, full n=200 < "
          f"{TARGETS[(200, False)]:g} s, n=400 < {TARGETS[(400, False)]:g} s, RSS < 2048 MiB")
    with tempfile.TemporaryDirectory() as tmp:
        for n in args.sizes:
            path = Path(tmp) / f"big{n}.yaml"
            write_system(n, path)
            for quick in (True, False):
                if not quick and args.skip_full:
                    continue
                r = analyze_once(path, quick, args.timeout, env)
                target = TARGETS.get((n, quick))
                lb, la = r["load_before"], r["load_after"]
                print(f"n={n:>4} {'--quick' if quick else 'full   '} wall {r['seconds']:7.1f} s "
                      f"cpu {r['cpu']:7.1f} s  peak RSS {r['peak_rss_mib']:6.0f} MiB  "
                      f"exit={r['exit']}  target {'-' if target is None else f'{target:g} s'}  "
                      f"load 1/5/15 min {lb[0]:.2f}/{lb[1]:.2f}/{lb[2]:.2f} -> "
                      f"{la[0]:.2f}/{la[1]:.2f}/{la[2]:.2f}", flush=True)
                if r["exit"] not in (0, 3, 5):
                    print("    " + "\n    ".join(r["tail"]), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(analyze_benchmark())
