"""Monte Carlo of a mesh's received set against the exact law π(S) (MATH §13).

The sampler is written here from the hop model, independent of the library: every attempt is a
Bernoulli(q_h) draw; a hop succeeds in a period when one of its k_h + 1 attempts does; an
aggregating transmitter draws once per hop and period, a forwarding one once per packet; with a
slot budget each route spends one slot per attempt, hops in order. Seeded; per-cell binomial
bounds at 5σ and a chi-square test.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from kfcrit.model.mesh import build_mesh
from kfcrit.theory.mesh.law import mesh_law

SAMPLES = 100_000


def hop_success(rng, q, attempts, size):
    return (rng.random((size, attempts)) < q).any(axis=1)


def sample_hops(mesh, rng, n):
    """Received-set bit masks of n periods (no slot budget)."""
    draws = {}
    for r in mesh.routes:
        for a, b in zip(r.nodes[:-1], r.nodes[1:]):
            h = mesh.hops[mesh.hop_index(a, b)]
            key = (a, b) if mesh.mode_of(a) == "aggregate" else (a, b, r.sensor)
            if key not in draws:
                draws[key] = hop_success(rng, h.q, (h.retries or 0) + 1, n)
    got = np.zeros(n, dtype=np.int64)
    for r in mesh.routes:
        ok = np.ones(n, dtype=bool)
        for a, b in zip(r.nodes[:-1], r.nodes[1:]):
            ok &= draws[(a, b) if mesh.mode_of(a) == "aggregate" else (a, b, r.sensor)]
        got |= ok.astype(np.int64) << mesh.sensors.index(r.sensor)
    return got


def sample_slots(mesh, rng, n):
    """Received-set bit masks with a slot budget: each route runs its own D slots."""
    D = mesh.slots_per_period
    got = np.zeros(n, dtype=np.int64)
    for r in mesh.routes:
        hops = [mesh.hops[mesh.hop_index(a, b)] for a, b in zip(r.nodes[:-1], r.nodes[1:])]
        stage = np.zeros(n, dtype=np.int64)          # index of the hop being attempted
        tries = np.zeros(n, dtype=np.int64)          # attempts spent on it
        q = np.array([h.q for h in hops] + [0.0])
        cap = np.array([h.retries + 1 if h.retries is not None else D for h in hops] + [0])
        for _ in range(D):                            # one attempt per slot
            on = (stage < len(hops)) & (tries < cap[stage])
            win = on & (rng.random(n) < q[stage])
            tries[on] += 1
            stage[win] += 1
            tries[win] = 0
        got |= (stage == len(hops)).astype(np.int64) << mesh.sensors.index(r.sensor)
    return got


def compare(mesh, masks):
    law = mesh_law(mesh)
    pi = law.weights()
    n = masks.size
    counts = np.bincount(masks, minlength=pi.size)
    for k, (c, p) in enumerate(zip(counts, pi)):
        bound = 5 * np.sqrt(p * (1 - p) / n) + 2 / n
        assert abs(c / n - p) <= bound, (k, c / n, p)
    keep = pi * n >= 5
    expected = pi[keep] * n
    observed = counts[keep]
    expected *= observed.sum() / expected.sum()
    if keep.sum() > 1:
        assert stats.chisquare(observed, expected).pvalue > 1e-4


MESHES = {
    "aggregate relay": dict(
        nodes=[("s1", "sensor"), ("s2", "sensor"), ("s3", "sensor"), ("r", "relay"),
               ("q", "relay"), ("g", "gateway")],
        hops=[("s1", "r", "1/2"), ("s2", "r", "7/10", 1), ("r", "g", "4/5"), ("s3", "q", "3/5"),
              ("q", "g", "2/3"), ("s3", "r", "1/3"), ("s2", "q", "1/4")],
        routes=[("s1", "r", "g"), ("s2", "r", "g"), ("s2", "q", "g"), ("s3", "q", "g"),
                ("s3", "r", "g")]),
}


@pytest.mark.parametrize("mode", ["aggregate", "forward"])
def test_empirical_law_matches_the_exact_law(mode):
    spec = MESHES["aggregate relay"]
    mesh = build_mesh(spec["nodes"], spec["hops"], spec["routes"], relay_mode=mode)
    rng = np.random.default_rng(20240613 + (mode == "forward"))
    compare(mesh, sample_hops(mesh, rng, SAMPLES))


def test_empirical_law_with_a_slot_budget():
    mesh = build_mesh([("s1", "sensor"), ("s2", "sensor"), ("a", "relay"), ("b", "relay"),
                       ("g", "gateway")],
                      [("s1", "a", "4/5"), ("a", "b", "4/5"), ("b", "g", "4/5"),
                       ("s2", "b", "1/2", 1), ("s2", "g", "1/5")],
                      [("s1", "a", "b", "g"), ("s2", "b", "g"), ("s2", "g")], slots_per_period=4)
    rng = np.random.default_rng(7)
    compare(mesh, sample_slots(mesh, rng, SAMPLES))


def test_the_check_rejects_the_independent_links_law():
    """Power of the check: aggregated samples are far from the product of their marginals."""
    spec = MESHES["aggregate relay"]
    mesh = build_mesh(spec["nodes"], spec["hops"], spec["routes"])
    masks = sample_hops(mesh, np.random.default_rng(3), SAMPLES)
    law = mesh_law(mesh)
    marg = [float(law.marginal(s)) for s in mesh.sensors]
    prod = np.array([np.prod([m if k >> i & 1 else 1 - m for i, m in enumerate(marg)])
                     for k in range(2 ** len(marg))])
    counts = np.bincount(masks, minlength=prod.size) / SAMPLES
    assert np.max(np.abs(counts - prod) / np.sqrt(prod * (1 - prod) / SAMPLES)) > 5
