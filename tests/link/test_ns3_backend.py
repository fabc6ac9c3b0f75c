"""The ns-3 backend's pure parts (no ns-3 needed): the plan from a file, shadowing draws, loss
attribution, statistics, trace files. The real run is ``tests/cli/test_link_simulate.py``."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from kfcrit.analysis.spec import load_spec
from kfcrit.errors import InputError
from kfcrit.io.traceformats import parse_binary
from kfcrit.link.linkbudget import LinkBudget
from kfcrit.link.ns3.results import (
    CHANNEL_ACCESS_FAILURE,
    Ns3Run,
    analytic_arrival,
    cross_sensor_statistics,
    loss_causes,
    loss_correlation,
    overlapping,
    simulation_summary,
    trace_file_text,
)
from kfcrit.link.ns3.topology import (
    build_plan,
    default_period_s,
    file_links,
    ns3_log_distance_db,
    shadowing_draws,
)

REPORTS = Path(__file__).resolve().parents[2] / "reports"
NS3_NOISE_DBM = 10 * math.log10(1.3803e-23 * 290.0 * 5e6 / 1e-3)


def link(**extra: object) -> LinkBudget:
    data = {"model": "link-budget", "radio": "ieee802154-oqpsk-2450", "tx_power_dbm": "0",
            "distance_m": "110", "packet_bytes": "20",
            "path_loss": {"model": "log-distance", "exponent": "3", "reference_loss_db": "46.6777"},
            "noise": {"noise_floor_dbm": repr(NS3_NOISE_DBM)}}
    data.update(extra)
    return LinkBudget.from_mapping(data, "channel")


def plan_of(*links: LinkBudget, periods: int = 100, **kw: object):
    items = [(f"s{i}", ch, None) for i, ch in enumerate(links)]
    return build_plan(items, sink_position_m=None, periods=periods, period_s=0.1, seed=3, **kw)


# --- the plan -----------------------------------------------------------------------------------

def test_single_link_file_gives_one_sensor_at_its_distance() -> None:
    spec = load_spec(REPORTS / "link-oqpsk-sensor.yaml")
    links, sink = file_links(spec)
    assert [n for n, _, _ in links] == ["sensor"] and sink is None
    plan = build_plan(links, sink_position_m=sink, periods=10, period_s=0.1, seed=0)
    (s,) = plan.sensors
    assert math.dist(s.position_m, plan.sink_position_m) == pytest.approx(105.0)
    assert (plan.exponent, plan.reference_distance_m, plan.reference_loss_db) == (3.0, 1.0, 40.2)
    # noise: thermal 2 MHz + 10 dB noise figure, as the link budget says
    assert plan.noise_dbm == pytest.approx(s.link.noise.total_dbm)
    assert s.offset_db == pytest.approx(0.0, abs=1e-12)
    assert s.shadowing_mode == "per-link" and s.shadowing_db.size == 1


def test_network_file_keeps_positions_and_the_sink() -> None:
    spec = load_spec(REPORTS / "network-planar-tracker.yaml")
    links, sink = file_links(spec)
    plan = build_plan(links, sink_position_m=sink, periods=10, period_s=0.1, seed=0)
    assert plan.names == ("north", "east", "corner")
    assert plan.sensors[0].position_m == (0.0, 118.0, 0.0)
    assert plan.sensors[2].tx_power_dbm == 4.0  # the corner's own channel key
    assert plan.sink_tx_power_dbm == 4.0
    for s in plan.sensors:
        assert math.dist(s.position_m, plan.sink_position_m) == pytest.approx(s.link.distance_m)
        assert s.offset_db == pytest.approx(0.0, abs=1e-9)
    assert plan.to_dict()["sensors"][1]["name"] == "east"


def test_sensors_without_positions_sit_on_a_circle() -> None:
    plan = plan_of(link(), link(distance_m="50"), link(distance_m="80"))
    ds = [math.dist(s.position_m, plan.sink_position_m) for s in plan.sensors]
    assert ds == pytest.approx([110.0, 50.0, 80.0])
    assert len({s.position_m for s in plan.sensors}) == 3


def test_different_noise_and_path_loss_become_offsets() -> None:
    loud = link(noise={"noise_floor_dbm": repr(NS3_NOISE_DBM + 3)})
    steep = link(path_loss={"model": "log-distance", "exponent": "3.5",
                            "reference_loss_db": "46.6777"})
    plan = plan_of(link(), loud, steep)
    assert plan.noise_dbm == pytest.approx(NS3_NOISE_DBM)
    assert plan.sensors[1].offset_db == pytest.approx(3.0)
    assert plan.sensors[2].offset_db == pytest.approx(5 * math.log10(110.0))
    # the SINR ns-3 sees equals the link budget's
    for s in plan.sensors:
        d = math.dist(s.position_m, plan.sink_position_m)
        rx = s.tx_power_dbm - ns3_log_distance_db(d, plan.exponent, plan.reference_distance_m,
                                                  plan.reference_loss_db) - s.offset_db
        assert rx - plan.noise_dbm == pytest.approx(s.link.sinr_db)


def test_below_the_reference_distance_ns3_clamps_and_the_offset_corrects() -> None:
    near = link(distance_m="0.5")
    assert ns3_log_distance_db(0.5, 3.0, 1.0, 46.6777) == 46.6777
    (s,) = plan_of(near).sensors
    assert s.offset_db == pytest.approx(near.path_loss_db - 46.6777)


def test_free_space_is_log_distance_with_exponent_two() -> None:
    fs = link(path_loss={"model": "free-space", "frequency_hz": "2.45e9"})
    plan = plan_of(fs)
    assert plan.exponent == 2.0
    assert ns3_log_distance_db(110.0, 2.0, 1.0, plan.reference_loss_db) == pytest.approx(
        fs.path_loss_db)


def test_calibrated_radio_adds_its_implementation_loss_to_the_noise() -> None:
    cc = link(radio="cc2420")
    plan = plan_of(cc)
    assert plan.noise_dbm == pytest.approx(NS3_NOISE_DBM + cc.radio.implementation_loss_db)


@pytest.mark.parametrize("bad, field", [
    ({"radio": "bpsk"}, "channel.radio"),
    ({"per_over": "psdu"}, "channel.per_over"),
])
def test_links_ns3_cannot_simulate_are_refused_by_field(bad: dict, field: str) -> None:
    ch = link(**bad)
    with pytest.raises(InputError) as err:
        build_plan([("sensor", ch, None)], sink_position_m=None, periods=10, period_s=0.1,
                   seed=0)
    assert str(err.value).startswith(field)


@pytest.mark.parametrize("kw, field", [
    ({"periods": 0}, "--periods"), ({"period_s": 0.0}, "--period-ms"),
    ({"jitter_s": 0.1}, "--jitter-ms"), ({"nakagami_m": 0.2}, "--nakagami-m"),
])
def test_options_out_of_range(kw: dict, field: str) -> None:
    args = {"sink_position_m": None, "periods": 10, "period_s": 0.1, "seed": 0, **kw}
    with pytest.raises(InputError) as err:
        build_plan([("sensor", link(), None)], **args)
    assert str(err.value).startswith(field)


def test_default_period() -> None:
    assert default_period_s(load_spec(REPORTS / "link-oqpsk-sensor.yaml")) == 0.1
    assert default_period_s(load_spec(REPORTS / "continuous-cv-tracker.yaml")) > 0


# --- shadowing ----------------------------------------------------------------------------------

def _pl(mode: str) -> dict:
    return {"model": "log-distance", "exponent": "3", "reference_loss_db": "46.6777",
            "shadowing_sigma_db": "4", "shadowing": mode}


def test_shadowing_draws_per_mode() -> None:
    rng = np.random.default_rng(1)
    assert shadowing_draws(link(), 50, 0.1, rng)[0].size == 0
    assert shadowing_draws(link(path_loss=_pl("per-link")), 50, 0.1, rng)[0].size == 1
    table, sigma = shadowing_draws(link(path_loss=_pl("per-packet")), 20000, 0.1, rng)
    assert table.size == 20000 and sigma == 0.0
    assert table.std() == pytest.approx(4.0, rel=0.03)
    assert abs(np.corrcoef(table[:-1], table[1:])[0, 1]) < 0.03
    table, sigma = shadowing_draws(link(path_loss=_pl("per-packet"),
                                        fading_per_attempt="independent"), 50, 0.1, rng)
    assert table.size == 0 and sigma == 4.0


def test_time_correlated_shadowing_is_ar1_at_the_simulated_period() -> None:
    ch = link(path_loss=_pl("time-correlated"),
              shadowing_correlation={"sample_period_s": "0.1", "coherence_time_s": "1"})
    table, _ = shadowing_draws(ch, 40000, 0.1, np.random.default_rng(2))
    rho = math.exp(-0.1 / 1.0)
    assert table.std() == pytest.approx(4.0, rel=0.05)
    assert np.corrcoef(table[:-1], table[1:])[0, 1] == pytest.approx(rho, abs=0.02)
    table, _ = shadowing_draws(ch, 40000, 0.5, np.random.default_rng(2))
    assert np.corrcoef(table[:-1], table[1:])[0, 1] == pytest.approx(math.exp(-0.5), abs=0.03)


def test_plans_are_reproducible_from_the_seed() -> None:
    ch = link(path_loss=_pl("per-packet"))
    a, b = plan_of(ch, ch), plan_of(ch, ch)
    assert np.array_equal(a.sensors[0].shadowing_db, b.sensors[0].shadowing_db)
    assert not np.array_equal(a.sensors[0].shadowing_db, a.sensors[1].shadowing_db)


# --- loss attribution and statistics ------------------------------------------------------------

def test_overlap_of_transmissions() -> None:
    node = np.array([0, 1, 0, 2, 1])
    start = np.array([0.0, 0.5, 2.0, 3.0, 4.0])
    end = np.array([1.0, 1.5, 3.0, 3.5, 4.5])
    # 0 and 1 overlap; 2 ends where 3 starts (touching: no overlap); 4 alone
    assert overlapping(node, start, end).tolist() == [True, True, False, False, False]
    assert overlapping(node[:0], start[:0], end[:0]).size == 0


def fake_run(delivered: list[list[int]], status: list[list[int]],
             tx: list[tuple[int, int, float, float]]) -> Ns3Run:
    t = np.array(tx, dtype=float).reshape(-1, 4)
    return Ns3Run(np.array(delivered, dtype=np.int8), np.array(status, dtype=np.int16),
                  t[:, 0].astype(np.int64), t[:, 1].astype(np.int64), t[:, 2], t[:, 3],
                  -107.0, -107.0, 0, "test")


def test_each_lost_period_gets_one_cause() -> None:
    # sensor 0: period 0 ok; 1 late; 2 channel-access failure; 3 collided; 4 noise; 5 unsent
    run = fake_run([[1, 2, 0, 0, 0, 0]],
                   [[0, 0, CHANNEL_ACCESS_FAILURE, 0xE9, 0xE9, -1]],
                   [(0, 0, 0.00, 0.01), (0, 1, 0.10, 0.11), (0, 3, 0.30, 0.31),
                    (1, -1, 0.305, 0.315), (0, 4, 0.40, 0.41)])
    causes = loss_causes(run)
    got = {c: np.flatnonzero(causes[c][0]).tolist() for c in
           ("delivered", "late", "channel_access", "collision", "noise", "not_sent")}
    assert got == {"delivered": [0], "late": [1], "channel_access": [2], "collision": [3],
                   "noise": [4], "not_sent": [5]}
    assert run.traces.tolist() == [[1, 0, 0, 0, 0, 0]]


def test_cross_sensor_statistics() -> None:
    same = np.array([[1, 0, 1, 0, 1, 1, 0, 1], [1, 0, 1, 0, 1, 1, 0, 1]])
    st = cross_sensor_statistics(same)
    assert st["p_all_lost"] == pytest.approx(3 / 8)
    assert st["product_of_marginal_losses"] == pytest.approx((3 / 8) ** 2)
    assert st["loss_correlation"][0][1] == pytest.approx(1.0)
    lo, hi = st["p_all_lost_ci95"]
    assert lo <= 3 / 8 <= hi
    never = np.array([[1, 1, 1], [0, 1, 0]])
    corr = loss_correlation(never)
    assert corr[0][1] is None and corr[1][1] == pytest.approx(1.0)
    assert cross_sensor_statistics(never)["ratio"] is None


def test_independent_traces_are_recognised() -> None:
    rng = np.random.default_rng(5)
    traces = (rng.random((3, 20000)) < np.array([[0.6], [0.7], [0.8]])).astype(np.uint8)
    st = cross_sensor_statistics(traces)
    assert st["independence_in_ci95"]
    assert st["max_abs_pairwise_correlation"] < 0.03


def test_analytic_value_under_the_simulated_conditions() -> None:
    plain = plan_of(link()).sensors[0]
    assert analytic_arrival(plain) == plain.link.arrival_value
    drawn = plan_of(link(path_loss=_pl("per-link"))).sensors[0]
    x = float(drawn.shadowing_db[0])
    assert analytic_arrival(drawn) == pytest.approx(drawn.link.nominal_arrival(
        drawn.link.sinr_db - x))
    # Rayleigh fading at high SINR: one attempt succeeds with about 1 - (L-dependent) / SINR
    strong = plan_of(link(distance_m="20")).sensors[0]
    faded = analytic_arrival(strong, 1.0)
    assert 0.5 < faded < strong.link.arrival_value
    # large m: fading vanishes
    assert analytic_arrival(plain, 1000.0) == pytest.approx(plain.link.arrival_value, abs=5e-3)
    retry = plan_of(link(max_retries="3")).sensors[0]
    a = analytic_arrival(retry, 2.0)
    one = analytic_arrival(plain, 2.0)
    assert a == pytest.approx(1 - (1 - one) ** 4, rel=1e-9)


def test_summary_and_trace_files() -> None:
    plan = plan_of(link(), link(distance_m="60"), periods=4)
    run = fake_run([[1, 0, 1, 1], [1, 1, 0, 1]], [[0, 0, 0, 0], [0, 0, 0, 0]],
                   [(0, 1, 0.1, 0.101), (1, 2, 0.2, 0.201)])
    summary = simulation_summary(plan, run)
    rows = summary["sensors"]
    assert [r["received"] for r in rows] == [3, 3]
    assert rows[0]["lost"]["noise"] == 1 and rows[1]["lost"]["noise"] == 1
    assert rows[0]["arrival_analytic"] == plan.sensors[0].link.arrival_value
    assert summary["cross_sensor"]["all_lost_periods"] == 0
    text = trace_file_text("s0", run.traces[0], {"seed": 3})
    assert text.startswith("# kfcrit link simulate")
    assert parse_binary(text).astype(int).tolist() == [1, 0, 1, 1]
