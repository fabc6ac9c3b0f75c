"""On-demand benchmarks (``python -m kfcrit.bench.bench_critical``); never part of the test run."""
