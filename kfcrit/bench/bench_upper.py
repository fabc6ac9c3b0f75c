"""Benchmark: kfcrit's upper bound p_up against the reference LMI bisection, in one process.

    python -m kfcrit.bench.bench_upper [--quick] [--reference-seconds S]
    python -m kfcrit.bench.bench_upper --lower     # certified lower end at 400 states

Times ``upper_bound`` of ``../shared/bench/reference_lmi.py`` (cvxpy + Clarabel, bisection to
width 1e-6) and ``kfcrit.theory.upper.bracket.upper_bound`` (default method) on
``random_system(n, m, seed)`` from ``../shared/bench/systems.py``, and prints the brackets and
the ratios. Targets (issue 9):
(20, 6) ≥ 50× faster at width 1e-6; (50, 10) faster than the reference at (20, 6); width 1e-9
reachable. ``--reference-seconds`` skips the (slow) reference run and uses a given time.
For stable timings on a loaded machine run with OPENBLAS_NUM_THREADS=1 (applies to both).
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path


def shared_bench() -> Path:
    """../shared/bench relative to the repository (override: KFCRIT_SHARED_BENCH)."""
    env = os.environ.get("KFCRIT_SHARED_BENCH")
    if env:
        return Path(env)
    return Path(__file__).resolve().parents[3] / "shared" / "bench"


def _ours(n: int, m: int, seed: int, tol: float, repeat: int):
    from systems import random_system

    from kfcrit.model.system import System
    from kfcrit.theory.upper.bracket import upper_bound

    A, C, Q, R = random_system(n, m, seed)
    system = System(A, C, Q, R)
    times, result = [], None
    for _ in range(repeat):
        t = time.perf_counter()
        result = upper_bound(system, tol=tol)
        times.append(time.perf_counter() - t)
    return statistics.median(times), min(times), result


def _reference(n: int, m: int, seed: int, tol: float):
    import reference_lmi
    from systems import random_system

    A, C, _, _ = random_system(n, m, seed)
    t = time.perf_counter()
    lo, hi, solves = reference_lmi.upper_bound(A, C, tol)
    return time.perf_counter() - t, (lo, hi), solves


SCALING = ((20, 6), (50, 10), (100, 20), (200, 40), (400, 60))
"""The (n, m) of the scaling table (issue 27: (200, 40) within 10 s, (400, 60) within 60 s)."""


def scaling_table(tol: float = 1e-6) -> list[dict]:
    """Time p_up at each size of :data:`SCALING` (one run each) and print wall and CPU
    seconds (time.process_time, all threads), width, whether the upper end and the lower end
    are certified, the status and the load average (os.getloadavg) before and after the run."""
    print(f"{'n':>4} {'m':>3} {'wall s':>8} {'cpu s':>8} {'width':>9} {'upper':>6} "
          f"{'lower':>6} {'status':>12} {'load(1m) before/after':>22}")
    rows = []
    for n, m in SCALING:
        before = os.getloadavg()[0]
        cpu = time.process_time()
        med, _best, res = _ours(n, m, 0, tol, 1)
        cpu = time.process_time() - cpu
        after = os.getloadavg()[0]
        lo, hi = res.interval
        lower = bool(res.lower_evidence.certified)
        rows.append({"n": n, "m": m, "seconds": med, "cpu_seconds": cpu, "width": hi - lo,
                     "certified": res.certified, "lower_certified": lower,
                     "status": res.status})
        print(f"{n:>4} {m:>3} {med:>8.2f} {cpu:>8.2f} {hi - lo:>9.2e} {str(res.certified):>6} "
              f"{str(lower):>6} {res.status:>12} {before:>10.2f}/{after:<10.2f}", flush=True)
    return rows


LOWER_CASES = ((400, 60, 1e-6), (400, 60, 1e-9), (200, 40, 1e-6))
"""(n, m, tol) of :func:`lower_table`: the interior root of random_system(400, 60, 0) whose
lower end is proven by the enclosed unstable pair (docs/theory.md §3, Certified lower end for
large blocks), at the bench tolerance and at analyze's 1e-9, and a face root for contrast."""


def lower_table() -> list[dict]:
    """Time p_up at each of :data:`LOWER_CASES` (one run each, seed 0): wall and CPU seconds,
    the bracket width, whether each end is certified, the numbers of the lower-end enclosure
    (eigenbasis condition, eigenvalue gap, radii, Weyl shift) and the load average before and
    after the run."""
    rows = []
    for n, m, tol in LOWER_CASES:
        before = os.getloadavg()
        cpu = time.process_time()
        wall, _best, res = _ours(n, m, 0, tol, 1)
        cpu = time.process_time() - cpu
        after = os.getloadavg()
        lo, hi = res.interval
        enc = res.solver.get("lower_enclosure") or {}
        row = {"n": n, "m": m, "tol": tol, "seconds": wall, "cpu_seconds": cpu,
               "width": hi - lo, "upper": res.certified,
               "lower": bool(res.lower_evidence.certified),
               "lower_kind": res.lower_evidence.kind, "status": res.status, **enc}
        rows.append(row)
        print(f"({n}, {m}) tol {tol:g}: [{lo:.15f}, {hi:.15f}] width {hi - lo:.2e} "
              f"wall {wall:.2f} s cpu {cpu:.2f} s upper={res.certified} "
              f"lower={row['lower']} ({row['lower_kind']}) status={res.status} "
              f"load(1m/5m) {before[0]:.2f}/{before[1]:.2f} -> {after[0]:.2f}/{after[1]:.2f}",
              flush=True)
        if enc:
            print("    lower enclosure: " + ", ".join(
                f"{k}={v:.3g}" for k, v in enc.items() if isinstance(v, float)), flush=True)
    return rows


def upper_benchmark(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="skip the reference (uses 41 s)")
    ap.add_argument("--reference-seconds", type=float, default=None,
                    help="use this reference time for (20, 6) instead of running it")
    ap.add_argument("--repeat", type=int, default=3, help="runs of kfcrit per case (median)")
    ap.add_argument("--scaling", action="store_true",
                    help="print the scaling table n = 20, 50, 100, 200, 400 (issue 27)")
    ap.add_argument("--large", action="store_true",
                    help="also time n = 100 and n = 200 (issue 18: analyze --quick at n = 200 "
                         "within 60 s; p_up's share is printed as a ratio to that budget)")
    ap.add_argument("--lower", action="store_true",
                    help="only the certified-lower-end table (400, 60) at 1e-6 and 1e-9, "
                         "(200, 40) at 1e-6: times, load, both ends")
    args = ap.parse_args(argv)
    sys.path.insert(0, str(shared_bench()))
    if args.lower:
        print(f"machine: {os.cpu_count()} cores, OPENBLAS_NUM_THREADS="
              f"{os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}")
        lower_table()
        return 0

    print(f"machine: {os.cpu_count()} cores, OPENBLAS_NUM_THREADS="
          f"{os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}")
    if args.quick and args.reference_seconds is None:
        args.reference_seconds = 41.0
    if args.reference_seconds is None:
        ref_t, ref_br, ref_solves = _reference(20, 6, 0, 1e-6)
        print(f"reference  (20, 6) tol 1e-6: [{ref_br[0]:.9f}, {ref_br[1]:.9f}] "
              f"solves={ref_solves} time={ref_t:.2f} s")
    else:
        ref_t, ref_br = args.reference_seconds, None
        print(f"reference  (20, 6) tol 1e-6: not run, time taken as {ref_t:.2f} s")

    rows = [(20, 6, 1e-6), (20, 6, 1e-9), (50, 10, 1e-6), (50, 10, 1e-9), (30, 5, 1e-9)]
    results, results_interval = {}, {}
    for n, m, tol in rows:
        med, best, res = _ours(n, m, 0, tol, args.repeat)
        results[(n, m, tol)] = med
        results_interval[(n, m, tol)] = res.interval
        lo, hi = res.interval
        print(f"kfcrit     ({n}, {m}) tol {tol:g}: [{lo:.12f}, {hi:.12f}] width={hi - lo:.2e} "
              f"certified={res.certified} status={res.status} lower={res.lower_evidence.kind}"
              f" time median={med:.3f} s min={best:.3f} s")
    if ref_br is not None:
        ours = results_interval[(20, 6, 1e-6)]
        verdict = ("consistent" if ref_br[0] <= ours[1] else
                   "WRONG: its lower end exceeds kfcrit's certified upper end")
        print(f"reference bracket at (20, 6) vs kfcrit's certified hi {ours[1]:.9f}: {verdict}")
    print()
    r1 = ref_t / results[(20, 6, 1e-6)]
    print(f"ratio reference(20,6)/kfcrit(20,6) at 1e-6: {r1:.0f}x   (target >= 50x)")
    r2 = ref_t / results[(50, 10, 1e-6)]
    print(f"ratio reference(20,6)/kfcrit(50,10) at 1e-6: {r2:.0f}x   (target > 1x)")
    r3 = ref_t / results[(50, 10, 1e-9)]
    print(f"ratio reference(20,6)/kfcrit(50,10) at 1e-9: {r3:.0f}x")
    if args.scaling:
        scaling_table()
    if args.large:
        for n, m in ((100, 10), (200, 20)):
            med, _best, res = _ours(n, m, 0, 1e-9, 1)
            lo, hi = res.interval
            print(f"kfcrit     ({n}, {m}) tol 1e-9: [{lo:.12f}, {hi:.12f}] "
                  f"certified={res.certified} status={res.status} time={med:.2f} s = "
                  f"{med / 60:.2f} of the 60 s analyze --quick budget")
    return 0


if __name__ == "__main__":
    raise SystemExit(upper_benchmark())
