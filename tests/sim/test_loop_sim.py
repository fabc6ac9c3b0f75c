"""Closed-loop Monte Carlo (kfcrit.sim.loop) against the closed-loop theory (MATH §12)."""
from __future__ import annotations

import math
from fractions import Fraction as F

import numpy as np

from kfcrit.sim.loop import simulate_fixed, simulate_tcp
from kfcrit.theory.loop.curve import spectral_radius
from kfcrit.theory.loop.fixed import fixed_loop
from kfcrit.theory.loop.stack import fixed_design
from kfcrit.theory.loop.tcp import tcp_loop

PLANT = ([[1.25, 1], [0, 1.1]], [[0], [1]], [[1, 0]])


def test_tcp_scalar_cost_inside_the_confidence_interval() -> None:
    # a = 5/4, b = c = 1, unit noises and weights, γ̄ = ν̄ = 0.8; formula J ≈ 5.6589
    J = tcp_loop([[F(5, 4)]], [[1]], [[1]], 1, 1, 1, 1, 0.8, 0.8).cost.value
    sim = simulate_tcp(1.25, 1, 1, 1, 1, 1, 1, 0.8, 0.8, paths=2000, steps=2000, seed=1,
                       confidence=0.99)
    assert sim.finite and sim.ci[0] <= J <= sim.ci[1]
    assert sim.ci[1] - sim.ci[0] < 0.1


def test_fixed_design_cost_matches_the_lyapunov_equation() -> None:
    for acked, on_loss, g, v in ((True, "zero", 0.8, 0.8), (False, "zero", 0.95, 0.95),
                                 (True, "hold", 0.95, 0.9)):
        d = fixed_design(*PLANT, 1, 1, 1, 1, acked=acked, on_loss=on_loss)
        theory = fixed_loop(d, g, v)
        assert theory.stability.holds is True
        sim = simulate_fixed(d, g, v, paths=1000, steps=1500, seed=3, confidence=0.99)
        assert sim.ci[0] <= theory.cost.value <= sim.ci[1], (acked, on_loss, theory.cost.value,
                                                             sim.ci)


def test_kronecker_radius_matches_monte_carlo_growth() -> None:
    # scalar state feedback with a + b l = 0.75, a = 1.25, ν̄ = 0.2: the second moment grows by
    # ρ = 0.8·1.5625 + 0.2·0.5625 = 1.3625 per step (computed by hand)
    d = fixed_design(1.25, 1, 1, 1, 0, 1, 1, K=1, L=-0.5)
    rho = spectral_radius(d, 1.0, 0.2)
    assert math.isclose(rho, 1.3625, rel_tol=1e-12)
    sim = simulate_fixed(d, 1.0, 0.2, paths=20000, steps=40, burn_in=0, seed=5, noise=False)
    assert abs(sim.growth_rate - math.log(rho)) < 0.05
    # a two-state design with an estimator: unstable and stable operating points
    d2 = fixed_design(*PLANT, 1, 1, 1, 1, acked=True, on_loss="zero")
    rho_u = spectral_radius(d2, 0.5, 0.5)
    assert rho_u > 1
    sim_u = simulate_fixed(d2, 0.5, 0.5, paths=20000, steps=40, burn_in=0, seed=6,
                           noise=False)
    assert abs(sim_u.growth_rate - math.log(rho_u)) < 0.25 * math.log(rho_u)
    rho_s = spectral_radius(d2, 0.8, 0.8)
    assert rho_s < 1
    sim_s = simulate_fixed(d2, 0.8, 0.8, paths=2000, steps=400, burn_in=0, seed=7)
    assert abs(sim_s.growth_rate) < 0.01


def test_seeded_runs_repeat() -> None:
    d = fixed_design(*PLANT, 1, 1, 1, 1)
    a = simulate_fixed(d, 0.9, 0.9, paths=50, steps=100, seed=11)
    b = simulate_fixed(d, 0.9, 0.9, paths=50, steps=100, seed=11)
    assert a.cost == b.cost and np.array_equal(a.second_moment, b.second_moment)
