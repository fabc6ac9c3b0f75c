"""Traces of several sensors are replayed time-aligned in simulation (theory §13).

Two redundant sensors of a scalar plant with complementary traces (sensor 2 receives exactly
when sensor 1 loses): read from one start, every step gets exactly one measurement, so P_t
follows the deterministic recursion P ← a²P + q − a²P²/(P + r) (by hand) on every path. Read
from independent random starts, some steps would lose both packets and the paths would differ.
"""
from __future__ import annotations

import numpy as np

from kfcrit.model.channels import Trace
from kfcrit.model.system import System
from kfcrit.sim.montecarlo import simulate


def test_complementary_traces_give_one_measurement_every_step() -> None:
    rng = np.random.default_rng(1)
    x = (rng.random(997) < 0.5).astype(int)       # a prime length: offsets would rarely agree
    system = System([[1.5]], [[1], [1]], Q=1, R=1)
    sensors = [([0], Trace.from_arrivals(x, "a")), ([1], Trace.from_arrivals(1 - x, "b"))]
    steps = 60
    res = simulate(system, 64, steps, 3, sensors=sensors, record_traces=True,
                   track_lambda_max=False)
    P, expected = 1.0, []                         # Sigma0 = 1; one measurement (R = 1) per step
    for _ in range(steps):
        P = 2.25 * P + 1.0 - 2.25 * P * P / (P + 1.0)
        expected.append(P)
    traces = np.asarray(res.traces)
    assert traces.shape[0] == 64
    np.testing.assert_allclose(traces[:, -1], expected[-1], rtol=1e-9)
    assert np.ptp(traces[:, -1]) < 1e-9
