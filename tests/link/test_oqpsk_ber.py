"""The O-QPSK bit error rate keeps the bits of the textbook sum, at any number of SINRs."""
from __future__ import annotations

import math

import numpy as np
import pytest

from kfcrit.link.radios import oqpsk_ber


def _textbook(s: np.ndarray) -> np.ndarray:
    """(8/15)(1/16) Σ_{k=2}^{16} (−1)^k C(16,k) e^{20 s (1/k − 1)}, summed by NumPy over k."""
    k = np.arange(2, 17, dtype=float)
    coeff = np.array([(-1.0) ** j * math.comb(16, j) for j in range(2, 17)])
    terms = coeff * np.exp(20.0 * np.asarray(s, dtype=float)[..., None] * (1.0 / k - 1.0))
    return np.clip(terms.sum(axis=-1) * (8.0 / 15.0) / 16.0, 0.0, 0.5)


@pytest.mark.parametrize("size", [1, 3, 15, 16, 17, 200, 3601])
def test_same_bits_as_the_textbook_sum(size: int) -> None:
    rng = np.random.default_rng(size)
    s = 10.0 ** rng.uniform(-4.0, 2.5, size=size)   # −40 … 25 dB, past the underflow at 75
    got, want = oqpsk_ber(s), _textbook(s)
    assert got.shape == want.shape
    assert np.array_equal(got.view(np.int64), want.view(np.int64))


def test_scalar_and_underflow() -> None:
    assert oqpsk_ber(3.0) == _textbook(np.array(3.0))
    # above a linear SINR of 75 every term underflows: exactly +0.0, as the full sum gives
    high = oqpsk_ber(np.array([75.5, 80.0, 1e300, np.inf]))
    assert np.array_equal(high, _textbook(np.array([75.5, 80.0, 1e300, np.inf])))
    assert not np.signbit(high).any()
    grid = oqpsk_ber(np.zeros((3, 4)))
    assert grid.shape == (3, 4) and np.all(grid == _textbook(np.zeros((3, 4))))
