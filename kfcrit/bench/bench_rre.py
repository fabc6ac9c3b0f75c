"""Benchmark: kfcrit's RRE Monte Carlo against the plain batched-NumPy reference, in one process.

    python -m kfcrit.bench.bench_rre [--paths 4000] [--steps 300] [--repeat 3]
                                     [--reference-dir ../shared/bench]

Measures path-steps per second on ``random_system(n, m, seed=0, radius=1.1)`` (Q = I, R = I,
Bernoulli arrivals p = 0.9, P_0 = I) for (n, m) = (2, 1) and (6, 2), and prints the ratio to
``simulate_traces`` of ``reference_rre.py`` (which stores tr P_t for every step and path). The
default sizes are those of the default ``kfcrit.simulate(system, paths=4000, steps=300, seed=1,
arrival_probability=0.9)``. kfcrit is timed as

* ``default``: exactly that call (E[λ_max] at ``LAMBDA_MAX_SAMPLES`` sample times);
* ``streaming``: ``track_lambda_max=False`` (memory independent of the horizon);
* ``streaming, 1 thread``: the same on one thread (the kernel's own speed);
* ``all traces``: every trace recorded (the reference's output).

Targets: default ≥ 5× at (6, 2) and ≥ 10× at (2, 1); streaming ≥ 10× at both. Each figure is
the best of ``--repeat`` wall-clock runs, the reference and kfcrit alternating, so a load that
comes and goes hits both alike; the machine is often shared, so the load average is printed
before and after. The fraction of peak is the kernel's arithmetic (flops of one Joseph-form step,
counted below) per second over the nominal peak of the machine: cores × clock × double-precision
flops per cycle (32 with AVX-512 and two FMA units, 16 with AVX2 + FMA, 4 otherwise).
Compilation (numba) happens in a warm-up call and is reported separately.
"""
from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

TARGETS = {(2, 1): (10.0, 10.0), (6, 2): (5.0, 10.0)}
"""(n, m) → (target of the default call, target of the streaming kernel)."""
P_ARRIVAL = 0.9


def _reference_dir(given: str | None) -> Path:
    if given:
        return Path(given)
    env = os.environ.get("KFCRIT_REFERENCE_BENCH")
    if env:
        return Path(env)
    return Path(__file__).resolve().parents[3] / "shared" / "bench"


def _time(fn) -> float:
    t = time.perf_counter()
    fn()
    return time.perf_counter() - t


def _cpuinfo() -> dict[str, str]:
    info: dict[str, str] = {}
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            key, _, value = line.partition(":")
            info.setdefault(key.strip(), value.strip())
    except OSError:
        pass
    return info


def machine() -> str:
    """One line describing the machine (CPU model, cores, Python, NumPy)."""
    model = _cpuinfo().get("model name") or platform.processor() or platform.machine()
    return (f"{model}, {os.cpu_count()} logical cores, Python {platform.python_version()}, "
            f"NumPy {np.__version__}, OPENBLAS_CORETYPE={os.environ.get('OPENBLAS_CORETYPE')}")


def peak_flops() -> tuple[float, str]:
    """Nominal double-precision peak: cores × clock × flops per cycle, and how it was found."""
    info = _cpuinfo()
    flags = set(info.get("flags", "").split())
    per_cycle = 32 if "avx512f" in flags else 16 if {"avx2", "fma"} <= flags else 4
    try:
        mhz = float(info.get("cpu MHz", "0"))
    except ValueError:
        mhz = 0.0
    cores = os.cpu_count() or 1
    return (cores * mhz * 1e6 * per_cycle,
            f"{cores} cores x {mhz / 1e3:.2f} GHz x {per_cycle} flops/cycle")


def step_flops(n: int, m: int) -> int:
    """Flops of one Joseph-form Riccati step of the kernel (a multiply-add counts 2).

    X C' (n²m), S = C X C' + R lower triangle (n m(m+1)/2), its Cholesky (≈ m³/3), A X C'
    (n²m), the two triangular solves (n m²), F = A − AK C (n²m), AK R (n m²), F X (n³) and the
    upper triangle of F X F' + AK R AK' (n(n+1)/2 · (n + m)).
    """
    madds = (n * n * m + n * m * (m + 1) // 2 + n * n * m + n * m * m + n * n * m + n * m * m
             + n ** 3 + n * (n + 1) // 2 * (n + m))
    return 2 * madds + m ** 3 // 3


def rre_benchmark(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--paths", type=int, default=4000)
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--reference-dir", default=None)
    args = ap.parse_args(argv)

    ref_dir = _reference_dir(args.reference_dir)
    sys.path.insert(0, str(ref_dir))
    from reference_rre import simulate_traces  # noqa: E402 - found through sys.path
    from systems import random_system  # noqa: E402

    from kfcrit.model.system import System
    from kfcrit.sim.montecarlo import simulate

    peak, peak_how = peak_flops()
    print(f"machine: {machine()}")
    print(f"nominal peak: {peak / 1e9:.0f} GFLOP/s ({peak_how})")
    print(f"load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    print(f"reference: {ref_dir / 'reference_rre.py'}; paths={args.paths} steps={args.steps} "
          f"p={P_ARRIVAL}, best of {args.repeat} (wall clock)")
    t = time.perf_counter()
    simulate(System([[0.5]], [[1]], 1, 1), 2, 2, 0, arrival_probability=0.5)
    print(f"warm-up (numba compile or cache load): {time.perf_counter() - t:.2f} s")
    work = args.paths * args.steps
    ok = True
    for (n, m), (target_default, target_stream) in TARGETS.items():
        A, C, Q, R = random_system(n, m, seed=0, radius=1.1)
        system = System(A, C, Q, R)
        configs = {
            "default": ({}, target_default),
            "streaming": ({"track_lambda_max": False}, target_stream),
            "streaming, 1 thread": ({"track_lambda_max": False, "threads": 1}, None),
            "all traces": ({"track_lambda_max": False, "record_traces": True}, None),
        }
        simulate(system, 64, 4, 1, arrival_probability=P_ARRIVAL)   # compile for this (n, m)
        t_ref = float("inf")
        best = dict.fromkeys(configs, float("inf"))
        for _ in range(args.repeat):
            t_ref = min(t_ref, _time(lambda A=A, C=C, Q=Q, R=R: simulate_traces(
                A, C, Q, R, P_ARRIVAL, args.paths, args.steps)))
            for label, (kw, _) in configs.items():
                best[label] = min(best[label], _time(
                    lambda kw=kw, s=system: simulate(s, args.paths, args.steps, 1,
                                                     arrival_probability=P_ARRIVAL, **kw)))
        flops = step_flops(n, m)
        print(f"(n, m) = ({n}, {m}): reference {work / t_ref / 1e6:8.2f} M path-steps/s "
              f"({flops} flops per path-step)")
        for label, (_, target) in configs.items():
            t_me = best[label]
            ratio = t_ref / t_me
            rate = work / t_me
            if target is None:
                flag = ""
            else:
                flag = f"  (target {target:g}x: {'ok' if ratio >= target else 'BELOW TARGET'})"
                ok &= ratio >= target
            print(f"    kfcrit {label:20s} {rate / 1e6:8.2f} M path-steps/s  ratio {ratio:6.1f}x  "
                  f"{rate * flops / 1e9:6.2f} GFLOP/s = {100 * rate * flops / peak:5.2f} % of "
                  f"peak{flag}")
    print(f"load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(rre_benchmark())
