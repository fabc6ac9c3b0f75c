"""Links warmed together (a sweep's chunk) hold bit for bit the values each computes alone.

The reference is the link's own lazy path (its cached properties computed one link at a time);
the warmed copies must agree in every bit, over distances that put the median SINR below, in
and above the PER transition, for several radios, packet sizes, retries and shadowing modes.
"""
from __future__ import annotations

import json
import struct

import pytest

from kfcrit.link.linkbudget import LinkBudget, design_section, warm_links

BASE = {"radio": "ieee802154-oqpsk-2450", "tx_power_dbm": "0", "distance_m": "50",
        "packet_bytes": "40",
        "path_loss": {"model": "log-distance", "exponent": "3.0", "reference_distance_m": "1",
                      "reference_loss_db": "40.2", "shadowing_sigma_db": "4"},
        "noise": {"noise_figure_db": "10", "bandwidth_hz": "2.0e6", "temperature_k": "290"},
        "margin_db": "2", "max_outage": "0.1"}
DISTANCES = [f"{d:g}" for d in (1, 3.7, 10, 31, 47.5, 63, 79.9, 88, 101, 117, 130, 151, 170,
                                 233, 500, 1000, 4000, 1e5)]
CASES = {
    "oqpsk": {},
    "oqpsk-long": {"packet_bytes": "116"},
    "oqpsk-retries": {"max_retries": "3", "packet_bytes": "20"},
    "cc2420": {"radio": "cc2420", "noise": {"bandwidth_hz": "2.0e6", "temperature_k": "290"}},
    "bpsk": {"radio": {"model": "bpsk", "processing_gain_db": "3"}, "packet_bytes": "60"},
    "per-packet": {"path_loss": {**BASE["path_loss"], "shadowing": "per-packet"}},
    "no-shadowing": {"path_loss": {**BASE["path_loss"], "shadowing_sigma_db": "0"}},
    "independent": {"path_loss": {**BASE["path_loss"], "shadowing": "per-packet"},
                    "fading_per_attempt": "independent", "max_retries": "2"},
}
WARMED = ("median_ber", "median_log_arrival", "median_mean_arrival")


def links(case: dict) -> list[LinkBudget]:
    return [LinkBudget.from_mapping({**BASE, **case, "distance_m": d}, "channel")
            for d in DISTANCES]


def bits(value: object) -> bytes:
    return struct.pack("<d", float(value))


@pytest.mark.parametrize("name", sorted(CASES))
def test_warmed_values_equal_each_link_alone_bit_for_bit(name: str) -> None:
    alone, together = links(CASES[name]), links(CASES[name])
    assert warm_links(together) == len(DISTANCES)
    for a, b in zip(alone, together):
        for attr in WARMED:
            if attr in b.__dict__:
                assert bits(b.__dict__[attr]) == bits(getattr(a, attr)), (name, attr, a.distance_m)
        assert type(b.median_log_arrival) is type(a.median_log_arrival)
        assert bits(b.arrival_value) == bits(a.arrival_value)
        # the whole link section, as the record holds it
        args = dict(critical_value=0.36, robust_value=0.3600001, bracket=(None, None),
                    upper_bound=0.36000000000000004)
        assert json.dumps(design_section(b, **args)) == json.dumps(design_section(a, **args))
        assert json.dumps(b.to_dict()) == json.dumps(a.to_dict())


def test_shared_shadowing_links_get_their_average_warmed() -> None:
    together = links({})
    warm_links(together)
    assert all("median_mean_arrival" in link.__dict__ for link in together)
    alone = links(CASES["no-shadowing"]) + links(CASES["independent"])
    warm_links(alone)
    # σ = 0 and per-attempt shadowing keep their own (lazy) averages
    assert not any("median_mean_arrival" in link.__dict__ for link in alone)


def test_links_that_cannot_share_a_call_are_left_lazy() -> None:
    faded = links({"fading": {"model": "rayleigh"}})
    single = links({})[:1]
    mixed = [links({"packet_bytes": str(20 + k)})[0] for k in range(5)]   # five groups of one
    assert warm_links(faded) == warm_links(single) == warm_links(mixed) == 0
    assert warm_links(["not a link", None, *links({})[:2]]) == 2
    assert not any("median_log_arrival" in link.__dict__ for link in faded + single + mixed)
