"""Benchmark: the sensor-network analysis (issue 15) for N = 4, 8, 12 sensors at n = 6.

    python -m kfcrit.bench.bench_network [--sizes 4 8 12] [--n 6] [--no-ball]

Each network: a random plant A (n × n, Gaussian, scaled to spectral radius 1.3), one random
output row per sensor, every arrival probability 0.7. Times ``network_analysis`` (every
received set enumerated, 2^N; certificates checked in ball arithmetic unless ``--no-ball``)
and prints the verdict, how many Newton solves and certificates it took, and the time per
received set. Target (issue 15): N = 12 at n = 6 within seconds, not minutes.
For stable timings on a loaded machine run with OPENBLAS_NUM_THREADS=1.
"""
from __future__ import annotations

import argparse
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


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[4, 8, 12])
    ap.add_argument("--n", type=int, default=6)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--no-ball", action="store_true", help="float-checked certificates only")
    args = ap.parse_args(argv)
    from kfcrit.theory.links.network import network_analysis

    print(f"{'N':>3} {'sets':>6} {'seconds':>8} {'ms/set':>7} {'newton':>6} {'certs':>5} "
          f"{'verdict':>13} {'margin interval'}")
    for N in args.sizes:
        net = random_network(args.n, N, args.seed)
        t0 = time.perf_counter()
        res = network_analysis(net, [0.7] * N, certify=not args.no_ball)
        dt = time.perf_counter() - t0
        m = res.method
        iv = res.uniform_margin.get("interval")
        ivs = "none" if iv is None else "[" + ", ".join(
            "—" if v is None else f"{v:.4g}" for v in iv) + "]"
        print(f"{N:>3} {m['received_sets']:>6} {dt:>8.2f} {1e3 * dt / m['received_sets']:>7.3f} "
              f"{m['newton']:>6} {m['certificates']:>5} {res.verdict:>13} {ivs}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
