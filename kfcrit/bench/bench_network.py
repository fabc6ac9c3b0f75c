"""Benchmark: the sensor-network analysis (issues 15 and 27) for small and large networks.

    python -m kfcrit.bench.bench_network [--small 4 8 12] [--large 25 50 100] [--no-ball]

Each network: a random plant A (n × n, Gaussian, scaled to spectral radius 1.3), one random
output row per sensor, every arrival probability 0.7. Times ``network_analysis`` with
``method="auto"`` (every received set, 2^N, up to ``AUTO_EXACT_MAX`` sensors; one-sensor maps,
docs/theory.md §15, beyond) and prints the method that decided, the verdict, the work counts and
the load average (``os.getloadavg()``, 1 minute) at the end of each run. Targets (issue 27):
N = 12 at n = 6 under 2 s; N = 100 at n = 6 and n = 12 under 30 s.
For stable timings on a loaded machine run with OPENBLAS_NUM_THREADS=1.
"""
from __future__ import annotations

import argparse
import os
import time

import numpy as np


def random_network(n: int, N: int, seed: int):
    """A random network (float input: the numeric structure path)."""
    from kfcrit.model.network import Network, Sensor

    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n))
    A *= 1.3 / max(abs(np.linalg.eigvals(A)))
    sensors = [Sensor(f"s{i}", rng.standard_normal((1, n)), 1.0) for i in range(N)]
    return Network(A, np.eye(n), None, sensors, name=f"random n={n} N={N}")


def run_one(n: int, N: int, seed: int, ball: bool) -> dict:
    """Analyse one random network; the row printed by :func:`main`."""
    from kfcrit.analysis.verdict import verdict_of
    from kfcrit.theory.links.network import network_analysis

    net = random_network(n, N, seed)
    t0 = time.perf_counter()
    res = network_analysis(net, [0.7] * N, certify=ball)
    dt = time.perf_counter() - t0
    m = res.method
    iv = res.uniform_margin.get("interval")
    ivs = "none" if iv is None else "[" + ", ".join(
        "—" if v is None else f"{v:.4g}" for v in iv) + "]"
    return {"n": n, "N": N, "seconds": dt, "method": m["decided_by"],
            "sets": m["received_sets"], "certs": m["certificates"],
            "verdict": verdict_of(res.facts)[0].value, "margin": ivs,
            "load": os.getloadavg()[0]}


def network_benchmark(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--small", type=int, nargs="*", default=[4, 8, 12],
                    help="sensor counts at n = 6")
    ap.add_argument("--large", type=int, nargs="*", default=[25, 50, 100],
                    help="sensor counts at n = 6 and n = 12")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--no-ball", action="store_true", help="float-checked certificates only")
    args = ap.parse_args(argv)
    cases = [(6, N) for N in args.small] + [(n, N) for n in (6, 12) for N in args.large]
    print(f"{'n':>3} {'N':>4} {'seconds':>8} {'method':>14} {'sets':>5} {'certs':>5} "
          f"{'verdict':>13} {'load1':>5}  margin interval")
    for n, N in cases:
        r = run_one(n, N, args.seed, not args.no_ball)
        print(f"{r['n']:>3} {r['N']:>4} {r['seconds']:>8.2f} {r['method']:>14} {r['sets']:>5} "
              f"{r['certs']:>5} {r['verdict']:>13} {r['load']:>5.2f}  {r['margin']}")
    return 0


if __name__ == "__main__":
    raise SystemExit(network_benchmark())
