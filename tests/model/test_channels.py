"""Channels: registry and record keys, arrival processes, and the two arrival generators.

The NumPy generator (``Channel.draw_arrivals``: geometric runs for Gilbert–Elliott) and the
kernel generator (``simulate.arrival_sequence``: a per-step Markov chain on SplitMix64 uniforms)
are independent implementations of the same law; they are compared with each other and with the
closed forms: stationary arrival frequency r/(f + r), mean loss burst 1/r, mean arrival run 1/f.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
import pytest
import sympy as sp
from hypothesis import given
from hypothesis import strategies as st

from kfcrit.analysis.spec import CHANNELS
from kfcrit.analysis.spec import parse_channel as channel_from_mapping
from kfcrit.errors import InputError
from kfcrit.model.channels import (
    ArrivalProcess,
    Bernoulli,
    Channel,
    GilbertElliott,
    Trace,
)
from kfcrit.sim.arrivals import KIND_CODE, arrival_sequence, path_keys


def runs(x: np.ndarray, value: bool) -> np.ndarray:
    """Lengths of the maximal runs of ``value`` in x, excluding runs touching either end."""
    change = np.flatnonzero(np.diff(x.astype(np.int8))) + 1
    bounds = np.concatenate(([0], change, [x.size]))
    lengths = np.diff(bounds)
    vals = x[bounds[:-1]]
    inner = np.ones(lengths.size, dtype=bool)
    inner[[0, -1]] = False
    return lengths[inner & (vals == value)]


def kernel_arrivals(channel: Channel, steps: int, key_index: int = 0, offset: int = 0):
    proc = channel.arrival_process()
    seq = (np.ascontiguousarray(proc.sequence, dtype=np.bool_) if proc.kind == "sequence"
           else np.zeros(1, dtype=np.bool_))
    key = path_keys(7, key_index, key_index + 1)[0]
    return arrival_sequence(key, KIND_CODE[proc.kind], proc.p, proc.failure_rate,
                            proc.recovery_rate, seq, offset, steps)


def test_registry_and_record_keys_unchanged():
    assert {"bernoulli", "gilbert-elliott", "trace", "link-budget"} <= set(CHANNELS)
    b = Bernoulli(sp.Rational(3, 5))
    assert set(b.to_dict()) == {"model", "arrival_probability", "arrival_probability_expression"}
    ge = GilbertElliott(sp.Rational(1, 10), sp.Rational(1, 2))
    assert set(ge.to_dict()) == {"model", "failure_rate", "recovery_rate", "arrival_probability",
                                 "arrival_probability_expression", "mean_burst_length"}
    assert ge.arrival_probability == sp.Rational(5, 6)


def test_arrival_processes_of_the_models():
    proc = Bernoulli(sp.Rational(1, 4)).arrival_process()
    assert (proc.kind, proc.p) == ("iid", 0.25)
    proc = GilbertElliott(sp.Rational(1, 5), sp.Rational(2, 5)).arrival_process()
    assert (proc.kind, proc.failure_rate, proc.recovery_rate) == ("markov", 0.2, 0.4)
    tr = Trace.from_arrivals([1, 0, 1, 1])
    assert tr.arrival_process().kind == "sequence"
    assert tr.arrival_probability == sp.Rational(3, 4)
    with pytest.raises(ValueError):
        ArrivalProcess("weird")


@dataclass(frozen=True)
class OnlyStationary(Channel):
    """A model that only knows its stationary arrival probability (like a link budget)."""

    value: float
    model: ClassVar[str] = "only-stationary"

    @property
    def arrival_probability(self) -> sp.Expr:
        return sp.Rational(self.value)

    def to_dict(self) -> dict[str, Any]:
        return {"model": self.model, "arrival_probability": self.value}


def test_base_class_default_is_iid_with_the_stationary_probability():
    ch = OnlyStationary(0.75)
    proc = ch.arrival_process()
    assert proc.kind == "iid" and proc.p == 0.75
    x = ch.draw_arrivals(np.random.default_rng(1), 40_000)
    se = math.sqrt(0.75 * 0.25 / x.size)
    assert abs(x.mean() - 0.75) < 5 * se
    from kfcrit.model.system import System
    from kfcrit.sim.montecarlo import simulate

    res = simulate(System([[0.5]], [[1]], 1, 1), 10, 5, 0, ch)
    assert res.channel["model"] == "only-stationary"


@pytest.mark.parametrize("f,r", [(0.1, 0.5), (0.6, 0.3)])
def test_gilbert_elliott_numpy_and_kernel_generators_match_closed_forms(f, r):
    ch = GilbertElliott(sp.nsimplify(f), sp.nsimplify(r))
    steps = 200_000
    for x in (ch.draw_arrivals(np.random.default_rng(3), steps), kernel_arrivals(ch, steps)):
        pi = r / (f + r)
        # arrivals are positively correlated: the variance of the frequency is inflated by
        # (1 + λ)/(1 − λ), λ = 1 − f − r the chain's second eigenvalue
        lam = 1 - f - r
        se = math.sqrt(pi * (1 - pi) / steps * (1 + lam) / (1 - lam))
        assert abs(x.mean() - pi) < 5 * se
        lost = runs(x, False)
        got = runs(x, True)
        # geometric runs: mean 1/r (losses), 1/f (arrivals); sd sqrt(1-q)/q per run
        assert abs(lost.mean() - 1 / r) < 5 * math.sqrt(1 - r) / r / math.sqrt(lost.size)
        assert abs(got.mean() - 1 / f) < 5 * math.sqrt(1 - f) / f / math.sqrt(got.size)


def test_iid_kernel_generator_frequency_and_independence():
    x = kernel_arrivals(Bernoulli(sp.Rational(3, 10)), 200_000)
    se = math.sqrt(0.21 / x.size)
    assert abs(x.mean() - 0.3) < 5 * se
    # lag-1 correlation of an i.i.d. sequence: 0 ± 1/sqrt(N)
    c = np.corrcoef(x[:-1], x[1:])[0, 1]
    assert abs(c) < 5 / math.sqrt(x.size)


@given(st.lists(st.booleans(), min_size=1, max_size=30), st.integers(0, 100),
       st.integers(0, 80))
def test_trace_is_read_cyclically_by_both_generators(seq, offset, steps):
    ch = Trace.from_arrivals(seq)
    expected = np.array([seq[(offset + t) % len(seq)] for t in range(steps)], dtype=bool)
    np.testing.assert_array_equal(ch.draw_arrivals(np.random.default_rng(0), steps,
                                                   offset=offset), expected)
    np.testing.assert_array_equal(kernel_arrivals(ch, steps, offset=offset), expected)


def test_trace_file_reading(tmp_path):
    good = tmp_path / "good.txt"
    good.write_text("1 0 1,1\n0 1\n")
    ch = channel_from_mapping({"model": "trace", "path": "good.txt"}, base_dir=tmp_path)
    assert isinstance(ch, Trace)
    np.testing.assert_array_equal(ch.arrivals, [1, 0, 1, 1, 0, 1])
    assert ch.arrival_probability == sp.Rational(4, 6)
    # the reader names the line and the value (shown only when short: the file may be no trace)
    for name, text, msg in (("bad.txt", "1 0 2", r"line 1: '2' \(value 3 on the line\) is not 0 or 1"),
                            ("empty.txt", "  \n", "empty"),
                            ("words.txt", "yes no", r"the value \(not shown\).* is not 0 or 1")):
        (tmp_path / name).write_text(text)
        with pytest.raises(InputError, match=msg):
            channel_from_mapping({"model": "trace", "path": name}, base_dir=tmp_path)
    with pytest.raises(InputError, match="cannot read"):
        channel_from_mapping({"model": "trace", "path": "missing.txt"}, base_dir=tmp_path)


def test_trace_from_arrivals_rejects_other_values():
    with pytest.raises(InputError):
        Trace.from_arrivals([0, 1, 2])
    with pytest.raises(InputError):
        Trace.from_arrivals([])
    with pytest.raises(InputError):
        Trace.from_arrivals([[0, 1]])


def test_probability_proven_equal_to_an_end_point_is_that_end_point() -> None:
    from kfcrit.model.channels import exact_probability

    assert exact_probability("cos(1)**2+sin(1)**2", "p") == 1
    assert exact_probability("1-cos(1)**2-sin(1)**2", "p") == 0
    with pytest.raises(InputError, match=r"^f: must be in \(0, 1\]"):
        exact_probability("1-cos(1)**2-sin(1)**2", "f", low_open=True)
    with pytest.raises(InputError, match=r"^p: must be in \[0, 1\]"):
        exact_probability("cos(1)**2+sin(1)**2+exp(-600)", "p")
    with pytest.raises(InputError, match=r"^channel\.arrival_probability: cannot decide"):
        exact_probability("(cos(1)**2+sin(1)**2)^64", "channel.arrival_probability")


def test_gilbert_elliott_memoryless_when_rates_sum_to_one_exactly() -> None:

    ch = channel_from_mapping({"model": "gilbert-elliott", "failure_rate": "cos(1)**2",
                               "recovery_rate": "sin(1)**2"})
    assert ch.iid


def test_trace_start_comes_from_the_path_key_not_the_number_of_paths():
    """Prefix independence for trace channels: path i starts at key_i mod L, key_i the first
    64-bit word of NumPy's SeedSequence(seed, spawn_key=(0, i)); running 3 or 300 paths gives
    the same first paths (the old ⌊i·L/paths⌋ start moved with the number of paths)."""
    from kfcrit.model.system import System
    from kfcrit.sim.montecarlo import simulate

    seq = (np.random.default_rng(11).random(37) < 0.6).tolist()
    system = System([[1.1]], [[1]], 1, 1)
    ch = Trace.from_arrivals(seq)
    few = simulate(system, 3, 50, 9, ch, record_traces=True, full_state_paths=3)
    many = simulate(system, 300, 50, 9, ch, record_traces=3, full_state_paths=3)
    np.testing.assert_array_equal(few.traces, many.traces)
    np.testing.assert_array_equal(few.full_state.arrivals, many.full_state.arrivals)
    for i in range(3):
        key = np.random.SeedSequence(9, spawn_key=(0, i)).generate_state(1, np.uint64)[0]
        k = int(key % np.uint64(37))
        expected = [seq[(k + t) % 37] for t in range(50)]
        np.testing.assert_array_equal(few.full_state.arrivals[i], expected)
