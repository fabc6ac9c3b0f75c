"""The ends of the transition of p(s) (exactly 0.0 below s_0, exactly 1.0 above s_1) that a
shadowing average skips: the skipped values are bit for bit those the radio would give."""
from __future__ import annotations

import math

import numpy as np
import pytest

from kfcrit.link.frames import arrival_with_retries
from kfcrit.link.radios import (
    CoherentBpsk,
    Ieee802154Oqpsk,
    certain_arrival_sinr_db,
    radio_profiles,
)

RADIOS = [Ieee802154Oqpsk(), CoherentBpsk(), CoherentBpsk(processing_gain_db=9.0),
          radio_profiles()["cc2420"]]


@pytest.mark.parametrize("radio", RADIOS, ids=lambda r: getattr(r, "model_name", r.name))
@pytest.mark.parametrize("per_bytes,retries", [(1, 0), (7, 2), (23, 0), (57, 3), (133, 7)])
def test_arrival_is_exactly_0_and_1_beyond_the_ends(radio, per_bytes, retries) -> None:  # noqa: ANN001
    s0, s1 = certain_arrival_sinr_db(radio, per_bytes, retries)
    assert s0 < s1
    # every SINR the radio is evaluated at, on a dense grid over the whole range of a sweep
    s = np.linspace(-100.0, 200.0, 300_001)
    p = arrival_with_retries(radio.log_arrival(s, per_bytes), retries)
    below, above = s <= s0, s >= s1
    assert np.array_equal(p[below], np.zeros(below.sum()))
    assert np.array_equal(p[above], np.ones(above.sum()))
    assert not np.signbit(p[below]).any()          # +0.0, as the full computation gives
    if math.isfinite(s1):
        # the end is within a few dB of where p first rounds to 1 (the e^-40 threshold and
        # the 1 dB margin): the skip is worth having
        first_one = s[np.argmax(p == 1.0)]
        assert 1.0 <= s1 - first_one <= 3.0


def test_tiny_frames_never_reach_an_exact_zero() -> None:
    # 8·L·log(1/2) > −40 for L ≤ 7: the arrival probability never rounds to 0
    assert certain_arrival_sinr_db(Ieee802154Oqpsk(), 7, 0)[0] == -math.inf
    assert certain_arrival_sinr_db(Ieee802154Oqpsk(), 8, 0)[0] > -math.inf
