"""Link-budget formulas against values from the issue text and textbook closed forms."""
from __future__ import annotations

import math

import pytest
from scipy.special import erfc

from kfcrit.errors import InputError
from kfcrit.linkbudget import LinkBudget, thermal_noise_dbm
from kfcrit.radios import CoherentBpsk, Ieee802154Oqpsk

LINK = {"model": "link-budget", "radio": "ieee802154-oqpsk-2450", "tx_power_dbm": "0",
        "distance_m": "30", "packet_bytes": "40",
        "path_loss": {"model": "log-distance", "exponent": "3.0", "reference_distance_m": "1",
                      "reference_loss_db": "40.2"},
        "noise": {"noise_figure_db": "10", "bandwidth_hz": "2.0e6", "temperature_k": "290"}}


def test_oqpsk_values_from_issue() -> None:
    r = Ieee802154Oqpsk()
    assert r.per(0.0, 20) == pytest.approx(0.0255, abs=5e-5)
    assert r.per(0.0, 127) == pytest.approx(0.151, abs=5e-4)
    assert r.required_sinr_db(0.99, 20) == pytest.approx(0.4035, abs=5e-4)


def test_bpsk_textbook() -> None:
    for db in (0.0, 7.0, 9.6):
        assert CoherentBpsk().ber(10 ** (db / 10)) == pytest.approx(
            0.5 * erfc(math.sqrt(10 ** (db / 10))), rel=1e-12)
    assert CoherentBpsk().ber(10 ** 0.7) == pytest.approx(7.73e-4, rel=1e-3)


def test_noise_floor_and_path_loss() -> None:
    assert thermal_noise_dbm(2e6, 10) == pytest.approx(-174 + 10 * math.log10(2e6) + 10, abs=0.03)
    ch = LinkBudget.from_mapping(LINK, "channel")
    assert ch.path_loss_db == pytest.approx(40.2 + 30 * math.log10(30), abs=1e-12)


def test_unknown_key_names_field() -> None:
    bad = {**LINK, "path_loss": {**LINK["path_loss"], "exponnent": "3"}}
    with pytest.raises(InputError, match="channel.path_loss.exponnent"):
        LinkBudget.from_mapping(bad, "channel")
