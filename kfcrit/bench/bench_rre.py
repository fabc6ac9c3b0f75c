"""Benchmark: kfcrit's RRE Monte Carlo against the plain batched-NumPy reference, in one process.

    python -m kfcrit.bench.bench_rre [--paths 2000] [--steps 2000] [--repeat 3]
                                     [--reference-dir ../shared/bench]

Measures path-steps per second on ``random_system(n, m, seed=0, radius=1.1)`` (Q = I, R = I,
Bernoulli arrivals p = 0.9, P_0 = I) for (n, m) = (2, 1) and (6, 2), and prints the ratio to
``simulate_traces`` of ``reference_rre.py`` (which stores tr P_t for every step and path).
kfcrit is timed in three configurations: streaming statistics only (memory independent of the
horizon), streaming plus E[λ_max] at the sample times, and with every trace recorded (the
reference's output). Targets: ≥ 10× at (2, 1) and ≥ 5× at (6, 2). Compilation (numba) happens
in a warm-up call and is reported separately. The best of ``--repeat`` runs is used for both.
"""
from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

TARGETS = {(2, 1): 10.0, (6, 2): 5.0}
P_ARRIVAL = 0.9


def _reference_dir(given: str | None) -> Path:
    if given:
        return Path(given)
    env = os.environ.get("KFCRIT_REFERENCE_BENCH")
    if env:
        return Path(env)
    return Path(__file__).resolve().parents[3] / "shared" / "bench"


def _best(fn, repeat: int) -> float:
    best = float("inf")
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t)
    return best


def machine() -> str:
    """One line describing the machine (CPU model, cores, Python, NumPy)."""
    model = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return (f"{model}, {os.cpu_count()} logical cores, Python {platform.python_version()}, "
            f"NumPy {np.__version__}, OPENBLAS_CORETYPE={os.environ.get('OPENBLAS_CORETYPE')}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--paths", type=int, default=2000)
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--reference-dir", default=None)
    args = ap.parse_args(argv)

    ref_dir = _reference_dir(args.reference_dir)
    sys.path.insert(0, str(ref_dir))
    from reference_rre import simulate_traces  # noqa: E402 - found through sys.path
    from systems import random_system  # noqa: E402

    from kfcrit.model.system import System
    from kfcrit.sim.montecarlo import simulate

    print(f"machine: {machine()}")
    print(f"reference: {ref_dir / 'reference_rre.py'}; paths={args.paths} steps={args.steps} "
          f"p={P_ARRIVAL}, best of {args.repeat}")
    t = time.perf_counter()
    simulate(System([[0.5]], [[1]], 1, 1), 2, 2, 0, arrival_probability=0.5)
    print(f"warm-up (numba compile or cache load): {time.perf_counter() - t:.2f} s")
    work = args.paths * args.steps
    ok = True
    for (n, m), target in TARGETS.items():
        A, C, Q, R = random_system(n, m, seed=0, radius=1.1)
        system = System(A, C, Q, R)
        t_ref = _best(lambda A=A, C=C, Q=Q, R=R: simulate_traces(
            A, C, Q, R, P_ARRIVAL, args.paths, args.steps), args.repeat)
        configs = {
            "streaming": {"track_lambda_max": False},
            "streaming+lambda_max": {"track_lambda_max": True},
            "all traces": {"track_lambda_max": False, "record_traces": True},
        }
        print(f"(n, m) = ({n}, {m}): reference {work / t_ref / 1e6:8.2f} M path-steps/s")
        for label, kw in configs.items():
            t_me = _best(lambda kw=kw, s=system: simulate(s, args.paths, args.steps, 0,
                                                          arrival_probability=P_ARRIVAL, **kw),
                         args.repeat)
            ratio = t_ref / t_me
            flag = "ok" if ratio >= target else "BELOW TARGET"
            if label == "streaming" and ratio < target:
                ok = False
            print(f"    kfcrit {label:22s} {work / t_me / 1e6:8.2f} M path-steps/s  "
                  f"ratio {ratio:6.1f}x  (target {target:g}x: {flag})")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
