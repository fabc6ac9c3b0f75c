"""Generate ns-3 lr-wpan facts for kfcrit's link-budget tests (run by hand; not a test).

Usage (needs the ns-3 Python wheel, ``pip install ns3==3.44.post0``; one process, ~1-3 min)::

    python tests/data/ns3/generate_facts.py [--packets 10000] [--periods 2000] [--out DIR]

Writes, next to this script unless ``--out`` is given:

``lrwpan_per.json``
    Two nodes (an ``LrWpanNetDevice`` each, 2.4 GHz O-QPSK, channel 11) on a
    ``SingleModelSpectrumChannel`` with ns-3's default ``LogDistancePropagationLossModel``
    (exponent 3, 46.6777 dB at 1 m) and a constant-speed delay; 0 dBm, 20-byte MSDU, short
    addresses, no acknowledgement, no retry (``txOptions = 0``); one packet every 10 ms,
    ``--packets`` per distance. For each distance: packets requested, PHY transmissions,
    MCPS-DATA.indications at the receiver, the Clopper–Pearson 95 % interval, and ns-3's own
    analytic success probability: ``LrWpanErrorModel::GetChunkSuccessRate(sinr, nbits)`` with
    the SINR computed like ``LrWpanPhy::StartRx`` (``TotalAvgPower`` of the received PSD over
    that of the PHY's noise PSD) and nbits = ceil(duration[ms] · 250) over the whole PPDU, as
    ``LrWpanPhy::CheckInterference`` counts it (0 when 10·log10(sinr) ≤ −5 dB, where
    ``StartRx`` drops the frame). The PSDU size is read from the ``PhyTxBegin`` trace.

``lrwpan_contention.json``
    Sensors sampling synchronously every 100 ms and sending one 20-byte MSDU each to a sink
    (unslotted CSMA-CA, no acknowledgement, no retry): (a) 4 sensors at 110 m from the sink on
    the vertices of a regular tetrahedron (pairwise 180 m: SINR < −5 dB, they never detect each
    other — hidden terminals); (b) 8 sensors on a 30 m circle (all within range of each other).
    Per-period 0/1 delivery traces of each sensor (period = floor(t_rx / 100 ms)), per-sensor
    delivery ratios, P(all lost), the product of the marginal loss ratios.

The C++ driver is JIT-compiled by cppyy inside the ns-3 wheel; ``from ns import ns`` costs
~10-40 s, so everything runs in this one process.
"""
from __future__ import annotations

import argparse
import datetime as _dt
import json
import math
import platform
import sys
import time
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
SEED = 20250611
PER_DISTANCES_M = [90.0, 95.0, 100.0, 105.0, 110.0, 115.0, 120.0, 125.0, 130.0, 135.0, 140.0]
PAYLOAD_BYTES = 20
TX_POWER_DBM = 0.0

DRIVER = r"""
#include "ns3/core-module.h"
#include "ns3/lr-wpan-module.h"
#include "ns3/spectrum-module.h"
#include "ns3/propagation-module.h"
#include "ns3/mobility-module.h"
#include "ns3/network-module.h"
#include <cmath>
#include <vector>

namespace kfns3 {
using namespace ns3;
using namespace ns3::lrwpan;

struct PerResult {
    uint32_t requested = 0, transmitted = 0, received = 0, psdu = 0, rxBegins = 0;
    double rxPowerW = 0, noiseW = 0, sinr = 0, durationMs = 0, success = 0;
    uint32_t nbits = 0;
};

static uint32_t g_rx = 0, g_tx = 0, g_psdu = 0, g_rxBegins = 0;
static Time g_rxBeginAt, g_rxDuration;
static std::vector<std::vector<int>> g_trace;
static double g_period = 0.1;

static void OnIndication(McpsDataIndicationParams, Ptr<Packet>) { g_rx++; }
static void OnTxBegin(Ptr<const Packet> p) { g_tx++; g_psdu = p->GetSize(); }
static void OnRxBegin(Ptr<const Packet>) { g_rxBegins++; g_rxBeginAt = Simulator::Now(); }
static void OnRxEnd(Ptr<const Packet>, double) { g_rxDuration = Simulator::Now() - g_rxBeginAt; }

static void OnSinkIndication(McpsDataIndicationParams params, Ptr<Packet>) {
    uint8_t buf[2];
    params.m_srcAddr.CopyTo(buf);
    uint32_t sensor = (uint32_t(buf[0]) << 8 | buf[1]) - 1;
    uint64_t period = uint64_t(std::floor(Simulator::Now().GetSeconds() / g_period));
    if (sensor < g_trace.size() && period < g_trace[sensor].size()) g_trace[sensor][period] = 1;
}

static Ptr<LrWpanNetDevice> MakeDevice(Ptr<SpectrumChannel> channel, uint16_t addr, Vector pos) {
    Ptr<Node> node = CreateObject<Node>();
    Ptr<LrWpanNetDevice> dev = CreateObject<LrWpanNetDevice>();
    char text[6];
    snprintf(text, sizeof text, "%02x:%02x", addr >> 8, addr & 0xff);
    dev->SetAddress(Mac16Address(text));
    dev->SetChannel(channel);
    node->AddDevice(dev);
    Ptr<ConstantPositionMobilityModel> mob = CreateObject<ConstantPositionMobilityModel>();
    mob->SetPosition(pos);
    node->AggregateObject(mob);
    dev->GetPhy()->SetMobility(mob);
    dev->GetMac()->SetPanId(5);
    return dev;
}

static Ptr<SingleModelSpectrumChannel> MakeChannel(Ptr<LogDistancePropagationLossModel> loss) {
    Ptr<SingleModelSpectrumChannel> channel = CreateObject<SingleModelSpectrumChannel>();
    channel->AddPropagationLossModel(loss);
    channel->SetPropagationDelayModel(CreateObject<ConstantSpeedPropagationDelayModel>());
    return channel;
}

static McpsDataRequestParams DataParams(uint16_t dst) {
    McpsDataRequestParams params;
    params.m_srcAddrMode = SHORT_ADDR;
    params.m_dstAddrMode = SHORT_ADDR;
    params.m_dstPanId = 5;
    char text[6];
    snprintf(text, sizeof text, "%02x:%02x", dst >> 8, dst & 0xff);
    params.m_dstAddr = Mac16Address(text);
    params.m_msduHandle = 0;
    params.m_txOptions = 0;  // no acknowledgement, hence no retry
    return params;
}

PerResult RunPer(double distance, uint32_t packets, uint32_t payload, double txPowerDbm,
                 uint32_t run) {
    RngSeedManager::SetRun(run);
    g_rx = g_tx = g_psdu = g_rxBegins = 0;
    g_rxDuration = Seconds(0);
    Ptr<LogDistancePropagationLossModel> loss = CreateObject<LogDistancePropagationLossModel>();
    Ptr<SingleModelSpectrumChannel> channel = MakeChannel(loss);
    Ptr<LrWpanNetDevice> tx = MakeDevice(channel, 1, Vector(0, 0, 0));
    Ptr<LrWpanNetDevice> rx = MakeDevice(channel, 2, Vector(distance, 0, 0));
    LrWpanSpectrumValueHelper svh;
    Ptr<SpectrumValue> psd = svh.CreateTxPowerSpectralDensity(txPowerDbm, 11);
    tx->GetPhy()->SetTxPowerSpectralDensity(psd);
    rx->GetMac()->SetMcpsDataIndicationCallback(MakeCallback(&OnIndication));
    tx->GetPhy()->TraceConnectWithoutContext("PhyTxBegin", MakeCallback(&OnTxBegin));
    rx->GetPhy()->TraceConnectWithoutContext("PhyRxBegin", MakeCallback(&OnRxBegin));
    rx->GetPhy()->TraceConnectWithoutContext("PhyRxEnd", MakeCallback(&OnRxEnd));
    McpsDataRequestParams params = DataParams(2);
    for (uint32_t i = 0; i < packets; i++) {
        Simulator::Schedule(MilliSeconds(10) * (i + 1), &LrWpanMac::McpsDataRequest,
                            tx->GetMac(), params, Create<Packet>(payload));
    }
    Simulator::Run();

    PerResult r;
    r.requested = packets;
    r.transmitted = g_tx;
    r.received = g_rx;
    r.psdu = g_psdu;
    r.rxBegins = g_rxBegins;
    // The SINR as LrWpanPhy::StartRx computes it, on the PSD the channel delivers.
    Ptr<MobilityModel> ma = tx->GetPhy()->GetMobility(), mb = rx->GetPhy()->GetMobility();
    double rxDbm = loss->CalcRxPower(0.0, ma, mb);  // 0 dBm in: minus the path loss in dB
    double gain = std::pow(10.0, rxDbm / 10.0);
    Ptr<SpectrumValue> rxPsd = psd->Copy();
    *rxPsd *= gain;
    r.rxPowerW = LrWpanSpectrumValueHelper::TotalAvgPower(rxPsd, 11);
    r.noiseW = LrWpanSpectrumValueHelper::TotalAvgPower(
        rx->GetPhy()->GetNoisePowerSpectralDensity()->Copy(), 11);
    r.sinr = r.rxPowerW / r.noiseW;
    // PPDU duration: measured between PhyRxBegin and PhyRxEnd when the frame was received,
    // else PHY header + PSDU at 250 kb/s (what CalculateTxTime gives for O-QPSK 2.4 GHz).
    Time dur = g_rxDuration.IsStrictlyPositive()
                   ? g_rxDuration
                   : MicroSeconds(32 * (6 + g_psdu));
    r.durationMs = dur.ToDouble(Time::MS);
    r.nbits = uint32_t(std::ceil(r.durationMs * (250000.0 / 1000)));
    Ptr<LrWpanErrorModel> em = rx->GetPhy()->GetErrorModel();
    if (!em) em = CreateObject<LrWpanErrorModel>();
    r.success = (10 * std::log10(r.sinr) > -5) ? em->GetChunkSuccessRate(r.sinr, r.nbits) : 0.0;
    Simulator::Destroy();
    return r;
}

std::vector<std::vector<int>> RunContention(std::vector<double> xs, std::vector<double> ys,
                                                std::vector<double> zs, uint32_t periods,
                                                double period, uint32_t payload,
                                                double txPowerDbm, uint32_t run) {
    RngSeedManager::SetRun(run);
    g_period = period;
    uint32_t n = xs.size();
    g_trace.assign(n, std::vector<int>(periods, 0));
    Ptr<LogDistancePropagationLossModel> loss = CreateObject<LogDistancePropagationLossModel>();
    Ptr<SingleModelSpectrumChannel> channel = MakeChannel(loss);
    Ptr<LrWpanNetDevice> sink = MakeDevice(channel, 0x00ff, Vector(0, 0, 0));
    sink->GetMac()->SetMcpsDataIndicationCallback(MakeCallback(&OnSinkIndication));
    LrWpanSpectrumValueHelper svh;
    McpsDataRequestParams params = DataParams(0x00ff);
    for (uint32_t s = 0; s < n; s++) {
        Ptr<LrWpanNetDevice> dev = MakeDevice(channel, s + 1, Vector(xs[s], ys[s], zs[s]));
        dev->GetPhy()->SetTxPowerSpectralDensity(svh.CreateTxPowerSpectralDensity(txPowerDbm, 11));
        for (uint32_t k = 0; k < periods; k++) {
            Simulator::Schedule(Seconds(period * k), &LrWpanMac::McpsDataRequest, dev->GetMac(),
                                params, Create<Packet>(payload));
        }
    }
    Simulator::Stop(Seconds(period * periods));
    Simulator::Run();
    Simulator::Destroy();
    return g_trace;
}
}  // namespace kfns3
"""


def clopper_pearson(k: int, n: int, level: float = 0.95) -> tuple[float, float]:
    """Exact binomial interval: Beta quantiles (0 and 1 at the ends)."""
    from scipy.stats import beta

    a = 1.0 - level
    lo = 0.0 if k == 0 else float(beta.ppf(a / 2, k, n - k + 1))
    hi = 1.0 if k == n else float(beta.ppf(1 - a / 2, k + 1, n - k))
    return lo, hi


def tetrahedron(radius: float) -> list[tuple[float, float, float]]:
    """Vertices of a regular tetrahedron inscribed in a sphere of ``radius`` (edge r·√(8/3))."""
    s = radius / math.sqrt(3.0)
    return [(s, s, s), (s, -s, -s), (-s, s, -s), (-s, -s, s)]


def circle(radius: float, count: int) -> list[tuple[float, float, float]]:
    return [(radius * math.cos(2 * math.pi * i / count),
             radius * math.sin(2 * math.pi * i / count), 0.0) for i in range(count)]


def contention_case(cpp: Any, name: str, positions: list[tuple[float, float, float]],
                    periods: int, run: int) -> dict[str, Any]:
    xs, ys, zs = ([p[i] for p in positions] for i in range(3))
    vec = cpp.gbl.std.vector["double"]
    trace = cpp.gbl.kfns3.RunContention(vec(xs), vec(ys), vec(zs), periods, 0.1,
                                        PAYLOAD_BYTES, TX_POWER_DBM, run)
    rows = [[int(v) for v in trace[s]] for s in range(len(positions))]
    delivered = [sum(r) for r in rows]
    all_lost = sum(1 for k in range(periods) if not any(r[k] for r in rows))
    marginal_loss = [1 - d / periods for d in delivered]
    pairwise = [[math.dist(a, b) for b in positions] for a in positions]
    return {
        "name": name, "sensors": len(positions), "run": run, "periods": periods,
        "sample_period_s": 0.1, "positions_m": [list(p) for p in positions],
        "distance_to_sink_m": [math.hypot(*p) for p in positions],
        "min_pairwise_distance_m": min(pairwise[i][j] for i in range(len(positions))
                                       for j in range(len(positions)) if i != j),
        "delivered": delivered, "delivery_ratio": [d / periods for d in delivered],
        "delivery_ci95": [list(clopper_pearson(d, periods)) for d in delivered],
        "all_lost_periods": all_lost, "p_all_lost": all_lost / periods,
        "p_all_lost_ci95": list(clopper_pearson(all_lost, periods)),
        "product_of_marginal_losses": math.prod(marginal_loss),
        "traces": ["".join(map(str, r)) for r in rows],
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--packets", type=int, default=10_000)
    ap.add_argument("--periods", type=int, default=2000)
    ap.add_argument("--out", type=Path, default=HERE)
    ap.add_argument("--skip-contention", action="store_true")
    args = ap.parse_args(argv)
    t0 = time.time()
    import cppyy
    from ns import ns  # noqa: F401  (loads every ns-3 library and its headers)

    cppyy.cppdef(DRIVER)
    cppyy.gbl.ns3.RngSeedManager.SetSeed(SEED)
    print(f"ns-3 loaded in {time.time() - t0:.1f} s", file=sys.stderr)
    try:
        from importlib.metadata import version
        ns3_version = version("ns3")
    except Exception:  # noqa: BLE001
        ns3_version = "unknown"
    meta = {"generator": "tests/data/ns3/generate_facts.py", "ns3_python_wheel": ns3_version,
            "date": _dt.date.today().isoformat(), "python": platform.python_version(),
            "seed": SEED, "confidence_level": 0.95, "interval": "Clopper-Pearson"}

    points = []
    for i, d in enumerate(PER_DISTANCES_M):
        r = cppyy.gbl.kfns3.RunPer(d, args.packets, PAYLOAD_BYTES, TX_POWER_DBM, i + 1)
        lo, hi = clopper_pearson(int(r.received), int(r.requested))
        points.append({
            "distance_m": d, "run": i + 1, "requested": int(r.requested),
            "transmitted": int(r.transmitted), "received": int(r.received),
            "rx_begins": int(r.rxBegins),
            "ratio": int(r.received) / int(r.requested), "ci95": [lo, hi],
            "psdu_bytes": int(r.psdu), "rx_power_w": float(r.rxPowerW),
            "rx_power_dbm": 10 * math.log10(float(r.rxPowerW)) + 30,
            "noise_w": float(r.noiseW), "noise_dbm": 10 * math.log10(float(r.noiseW)) + 30,
            "sinr": float(r.sinr), "sinr_db": 10 * math.log10(float(r.sinr)),
            "ppdu_duration_ms": float(r.durationMs), "error_model_bits": int(r.nbits),
            "ns3_analytic_success": float(r.success)})
        print(f"d = {d:5.1f} m: {int(r.received)}/{int(r.requested)} "
              f"(analytic {float(r.success):.6f}, psdu {int(r.psdu)}, bits {int(r.nbits)})",
              file=sys.stderr)
    per = {"meta": {**meta, "description": "ns-3 lr-wpan packet success against distance, "
                    "two nodes, no ACK, no retry, no shadowing",
                    "parameters": {
                        "tx_power_dbm": TX_POWER_DBM, "payload_bytes": PAYLOAD_BYTES,
                        "packets_per_distance": args.packets, "packet_interval_s": 0.01,
                        "channel_number": 11, "phy": "IEEE 802.15.4 2.4 GHz O-QPSK 250 kb/s",
                        "spectrum_channel": "SingleModelSpectrumChannel",
                        "propagation_loss": "LogDistancePropagationLossModel (defaults: "
                                            "exponent 3, reference distance 1 m, reference "
                                            "loss 46.6777 dB)",
                        "propagation_delay": "ConstantSpeedPropagationDelayModel",
                        "path_loss_exponent": 3.0, "reference_loss_db": 46.6777,
                        "reference_distance_m": 1.0, "rx_sensitivity_dbm": -106.58,
                        "noise": "LrWpanSpectrumValueHelper noise PSD: k T with k = 1.3803e-23 "
                                 "J/K, T = 290 K, noise factor 1, over 5 bands of 1 MHz",
                        "mac": "unslotted CSMA-CA, short addresses, txOptions 0 (no ACK)",
                        "analytic": "LrWpanErrorModel::GetChunkSuccessRate(sinr, nbits), "
                                    "nbits = ceil(PPDU duration [ms] * 250), 0 if sinr <= -5 dB"}},
           "points": points}
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "lrwpan_per.json").write_text(json.dumps(per, indent=1) + "\n")

    if not args.skip_contention:
        cases = [contention_case(cppyy, "hidden-4-tetrahedron-110m", tetrahedron(110.0),
                                 args.periods, 101),
                 contention_case(cppyy, "dense-8-circle-30m", circle(30.0, 8),
                                 args.periods, 102)]
        for c in cases:
            print(f"{c['name']}: delivery {c['delivery_ratio']}, P(all lost) "
                  f"{c['p_all_lost']:.4f}, product {c['product_of_marginal_losses']:.4f}",
                  file=sys.stderr)
        cont = {"meta": {**meta, "description": "synchronous sampling, one frame per sensor "
                         "per period, unslotted CSMA-CA, no ACK, no retry; trace character k of "
                         "sensor s is 1 iff the sink received sensor s's frame of period k",
                         "parameters": {"tx_power_dbm": TX_POWER_DBM,
                                        "payload_bytes": PAYLOAD_BYTES,
                                        "sample_period_s": 0.1, "periods": args.periods,
                                        "propagation_loss": "LogDistancePropagationLossModel "
                                                            "defaults"}},
                "cases": cases}
        (args.out / "lrwpan_contention.json").write_text(json.dumps(cont, indent=1) + "\n")
    print(f"done in {time.time() - t0:.1f} s", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
