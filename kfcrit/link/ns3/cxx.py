"""The C++ side of the ns-3 backend: a driver JIT-compiled by cppyy inside the ns-3 wheel.

Only text lives here (no import of ``ns``); :mod:`kfcrit.link.ns3.driver` compiles it once per
process. The driver builds one lr-wpan network (2.4 GHz O-QPSK, channel 11, a
``SingleModelSpectrumChannel``), runs it, and returns raw per-period outcomes and the log of
every PHY transmission; every statistic is computed in Python (:mod:`kfcrit.link.ns3.results`).

Propagation chain (``PropagationLossModel::SetNext``): ns-3's ``LogDistancePropagationLossModel``
(exponent, reference distance and loss of the link budget) → ``KfcritLinkLoss`` (on a
sensor–sink link only: a fixed offset in dB, the shadowing value of the period — a table from
Python — and, when asked, a normal value drawn per transmission) → optionally ns-3's
``NakagamiPropagationLossModel`` (m0 = m1 = m2 = m, a fresh draw per transmission).
"""
from __future__ import annotations

DRIVER_SOURCE = r"""
#include "ns3/core-module.h"
#include "ns3/lr-wpan-module.h"
#include "ns3/spectrum-module.h"
#include "ns3/propagation-module.h"
#include "ns3/mobility-module.h"
#include "ns3/network-module.h"
#include <cmath>
#include <cstring>
#include <deque>
#include <vector>

namespace kfcrit_ns3 {
using namespace ns3;
using namespace ns3::lrwpan;

struct Config {
    uint32_t sensors = 0, periods = 0, channel = 11;
    double period = 0.1, jitter = 0.0;
    std::vector<double> xs, ys, zs;
    double sinkX = 0, sinkY = 0, sinkZ = 0;
    std::vector<double> txPowerDbm;
    double sinkTxPowerDbm = 0;
    std::vector<uint32_t> payload, retries;
    std::vector<double> offsetDb;
    std::vector<double> shadowDb;          // flattened, sensor s at shadowStart[s]
    std::vector<uint32_t> shadowStart, shadowLen;  // length 0 (none), 1 (per link) or periods
    std::vector<double> attemptSigmaDb;    // > 0: a normal value per transmission
    double exponent = 3, refDistance = 1, refLoss = 46.6777;
    double nakagamiM = 0;                  // 0: no fading
    double noiseDbm = 0;                   // noise of every receiver (TotalAvgPower), dBm
};

struct Result {
    std::vector<int> delivered;            // sensors x periods: 0 no, 1 in its period, 2 late
    std::vector<int> status;               // sensors x periods: MCPS-DATA.confirm status, -1 none
    std::vector<int> txNode;               // transmitting node: sensor index, or sensors (sink)
    std::vector<int> txPeriod;             // the period of a sensor's frame (-1 for the sink)
    std::vector<double> txStart, txEnd;    // seconds
    double baseNoiseDbm = 0, noiseDbm = 0;
    uint32_t duplicates = 0;
};

class KfcritLinkLoss : public PropagationLossModel {
  public:
    static TypeId GetTypeId() {
        static TypeId tid = TypeId("ns3::KfcritLinkLoss")
                                .SetParent<PropagationLossModel>()
                                .SetGroupName("Propagation")
                                .AddConstructor<KfcritLinkLoss>();
        return tid;
    }
    KfcritLinkLoss() : m_normal(CreateObject<NormalRandomVariable>()) {}
    const Config* cfg = nullptr;
    std::vector<const MobilityModel*> sensorMob;
    const MobilityModel* sinkMob = nullptr;

  private:
    double DoCalcRxPower(double txPowerDbm, Ptr<MobilityModel> a,
                         Ptr<MobilityModel> b) const override {
        const MobilityModel* other = nullptr;
        if (PeekPointer(a) == sinkMob) other = PeekPointer(b);
        else if (PeekPointer(b) == sinkMob) other = PeekPointer(a);
        if (!other) return txPowerDbm;  // sensor to sensor: the median path loss only
        for (uint32_t s = 0; s < sensorMob.size(); s++) {
            if (sensorMob[s] != other) continue;
            double loss = cfg->offsetDb[s];
            uint32_t len = cfg->shadowLen[s];
            if (len == 1) loss += cfg->shadowDb[cfg->shadowStart[s]];
            else if (len > 1) {
                uint64_t k = uint64_t(std::floor(Simulator::Now().GetSeconds() / cfg->period));
                if (k >= len) k = len - 1;
                loss += cfg->shadowDb[cfg->shadowStart[s] + k];
            }
            double sigma = cfg->attemptSigmaDb[s];
            if (sigma > 0) loss += sigma * m_normal->GetValue(0.0, 1.0);
            return txPowerDbm - loss;
        }
        return txPowerDbm;
    }
    int64_t DoAssignStreams(int64_t stream) override {
        m_normal->SetStream(stream);
        return 1;
    }
    Ptr<NormalRandomVariable> m_normal;
};

static Config g_cfg;
static Result g_res;
static std::vector<Ptr<LrWpanNetDevice>> g_devs;
static std::vector<std::deque<uint32_t>> g_pending;
static Ptr<UniformRandomVariable> g_jitter;
static const uint16_t SINK_ADDRESS = 0x7fff;

static Mac16Address Address16(uint16_t a) {
    char text[6];
    snprintf(text, sizeof text, "%02x:%02x", a >> 8, a & 0xff);
    return Mac16Address(text);
}

static void OnSinkIndication(McpsDataIndicationParams params, Ptr<Packet> p) {
    uint8_t addr[2];
    params.m_srcAddr.CopyTo(addr);
    uint32_t s = (uint32_t(addr[0]) << 8 | addr[1]) - 1;
    if (s >= g_cfg.sensors) return;
    uint8_t tag[4] = {0, 0, 0, 0};
    uint32_t nbytes = std::min<uint32_t>(4, p->GetSize());
    p->CopyData(tag, nbytes);
    uint64_t modulus = nbytes >= 4 ? (uint64_t(1) << 32) : (uint64_t(1) << (8 * nbytes));
    uint64_t value = uint64_t(tag[0]) | uint64_t(tag[1]) << 8 | uint64_t(tag[2]) << 16 |
                     uint64_t(tag[3]) << 24;
    // the latest period up to now whose tag is this value
    uint64_t now = uint64_t(std::floor(Simulator::Now().GetSeconds() / g_cfg.period));
    if (now >= g_cfg.periods) now = g_cfg.periods - 1;
    uint64_t k = now - ((now - value) % modulus + modulus) % modulus;
    if (k > now) return;
    int& cell = g_res.delivered[size_t(s) * g_cfg.periods + k];
    if (cell) { g_res.duplicates++; return; }
    double deadline = g_cfg.period * double(k + 1);
    cell = Simulator::Now().GetSeconds() < deadline ? 1 : 2;
}

static void OnConfirm(uint32_t s, McpsDataConfirmParams params) {
    if (g_pending[s].empty()) return;
    uint32_t k = g_pending[s].front();
    g_pending[s].pop_front();
    g_res.status[size_t(s) * g_cfg.periods + k] = int(params.m_status);
}

static void OnTxBegin(uint32_t node, Ptr<const Packet> p) {
    double start = Simulator::Now().GetSeconds();
    // PPDU airtime at 250 kb/s: (6-byte PHY header + PSDU) x 32 us
    double airtime = 32e-6 * double(6 + p->GetSize());
    int period = -1;
    if (node < g_cfg.sensors && !g_pending[node].empty()) period = int(g_pending[node].front());
    g_res.txNode.push_back(int(node));
    g_res.txPeriod.push_back(period);
    g_res.txStart.push_back(start);
    g_res.txEnd.push_back(start + airtime);
}

static void Request(uint32_t s, uint32_t k) {
    McpsDataRequestParams params;
    params.m_srcAddrMode = SHORT_ADDR;
    params.m_dstAddrMode = SHORT_ADDR;
    params.m_dstPanId = 5;
    params.m_dstAddr = Address16(SINK_ADDRESS);
    params.m_msduHandle = uint8_t(k & 0xff);
    params.m_txOptions = g_cfg.retries[s] > 0 ? TX_OPTION_ACK : 0;
    std::vector<uint8_t> body(g_cfg.payload[s], 0);
    for (uint32_t i = 0; i < 4 && i < body.size(); i++) body[i] = uint8_t((k >> (8 * i)) & 0xff);
    g_pending[s].push_back(k);
    g_devs[s]->GetMac()->McpsDataRequest(params, Create<Packet>(body.data(), body.size()));
    if (k + 1 < g_cfg.periods) {
        double offset = g_cfg.jitter > 0 ? g_jitter->GetValue(0.0, g_cfg.jitter) : 0.0;
        Time at = Seconds(g_cfg.period * double(k + 1) + offset);
        Simulator::Schedule(at - Simulator::Now(), &Request, s, k + 1);
    }
}

static Ptr<LrWpanNetDevice> MakeDevice(Ptr<SpectrumChannel> channel, uint16_t addr, Vector pos,
                                       double txPowerDbm) {
    Ptr<Node> node = CreateObject<Node>();
    Ptr<LrWpanNetDevice> dev = CreateObject<LrWpanNetDevice>();
    dev->SetAddress(Address16(addr));
    dev->SetChannel(channel);
    node->AddDevice(dev);
    Ptr<ConstantPositionMobilityModel> mob = CreateObject<ConstantPositionMobilityModel>();
    mob->SetPosition(pos);
    node->AggregateObject(mob);
    dev->GetPhy()->SetMobility(mob);
    dev->GetMac()->SetPanId(5);
    LrWpanSpectrumValueHelper svh;
    dev->GetPhy()->SetTxPowerSpectralDensity(
        svh.CreateTxPowerSpectralDensity(txPowerDbm, g_cfg.channel));
    return dev;
}

Result Run(const Config& cfg, uint32_t seed, uint32_t run) {
    RngSeedManager::SetSeed(seed);
    RngSeedManager::SetRun(run);
    g_cfg = cfg;
    g_res = Result();
    uint32_t n = cfg.sensors;
    g_res.delivered.assign(size_t(n) * cfg.periods, 0);
    g_res.status.assign(size_t(n) * cfg.periods, -1);
    g_pending.assign(n, std::deque<uint32_t>());
    g_devs.clear();
    g_jitter = CreateObject<UniformRandomVariable>();

    Ptr<LogDistancePropagationLossModel> logd = CreateObject<LogDistancePropagationLossModel>();
    logd->SetAttribute("Exponent", DoubleValue(cfg.exponent));
    logd->SetAttribute("ReferenceDistance", DoubleValue(cfg.refDistance));
    logd->SetAttribute("ReferenceLoss", DoubleValue(cfg.refLoss));
    Ptr<KfcritLinkLoss> link = CreateObject<KfcritLinkLoss>();
    link->cfg = &g_cfg;
    logd->SetNext(link);
    if (cfg.nakagamiM > 0) {
        Ptr<NakagamiPropagationLossModel> fading = CreateObject<NakagamiPropagationLossModel>();
        fading->SetAttribute("m0", DoubleValue(cfg.nakagamiM));
        fading->SetAttribute("m1", DoubleValue(cfg.nakagamiM));
        fading->SetAttribute("m2", DoubleValue(cfg.nakagamiM));
        link->SetNext(fading);
    }
    Ptr<SingleModelSpectrumChannel> channel = CreateObject<SingleModelSpectrumChannel>();
    channel->AddPropagationLossModel(logd);
    channel->SetPropagationDelayModel(CreateObject<ConstantSpeedPropagationDelayModel>());

    Ptr<LrWpanNetDevice> sink = MakeDevice(channel, SINK_ADDRESS,
                                           Vector(cfg.sinkX, cfg.sinkY, cfg.sinkZ),
                                           cfg.sinkTxPowerDbm);
    link->sinkMob = PeekPointer(sink->GetPhy()->GetMobility());
    sink->GetMac()->SetMcpsDataIndicationCallback(MakeCallback(&OnSinkIndication));
    sink->GetPhy()->TraceConnectWithoutContext("PhyTxBegin", MakeBoundCallback(&OnTxBegin, n));
    for (uint32_t s = 0; s < n; s++) {
        Ptr<LrWpanNetDevice> dev = MakeDevice(channel, uint16_t(s + 1),
                                              Vector(cfg.xs[s], cfg.ys[s], cfg.zs[s]),
                                              cfg.txPowerDbm[s]);
        dev->GetMac()->SetMacMaxFrameRetries(uint8_t(cfg.retries[s]));
        dev->GetMac()->SetMcpsDataConfirmCallback(MakeBoundCallback(&OnConfirm, s));
        dev->GetPhy()->TraceConnectWithoutContext("PhyTxBegin", MakeBoundCallback(&OnTxBegin, s));
        link->sensorMob.push_back(PeekPointer(dev->GetPhy()->GetMobility()));
        g_devs.push_back(dev);
    }
    // fixed random streams: a run does not depend on what ran before in this process
    int64_t stream = 1000;
    stream += logd->AssignStreams(stream);
    stream += sink->AssignStreams(stream);
    for (auto& dev : g_devs) stream += dev->AssignStreams(stream);
    g_jitter->SetStream(stream++);
    // every receiver gets the link budget's noise: ns-3's thermal PSD scaled
    Ptr<const SpectrumValue> base = sink->GetPhy()->GetNoisePowerSpectralDensity();
    double baseW = LrWpanSpectrumValueHelper::TotalAvgPower(base, cfg.channel);
    g_res.baseNoiseDbm = 10 * std::log10(baseW) + 30;
    double factor = std::pow(10.0, (cfg.noiseDbm - g_res.baseNoiseDbm) / 10.0);
    Ptr<SpectrumValue> noise = base->Copy();
    *noise *= factor;
    sink->GetPhy()->SetNoisePowerSpectralDensity(noise);
    for (auto& dev : g_devs) dev->GetPhy()->SetNoisePowerSpectralDensity(noise);
    g_res.noiseDbm = 10 * std::log10(LrWpanSpectrumValueHelper::TotalAvgPower(
                         sink->GetPhy()->GetNoisePowerSpectralDensity(), cfg.channel)) + 30;

    for (uint32_t s = 0; s < n; s++) {
        double offset = cfg.jitter > 0 ? g_jitter->GetValue(0.0, cfg.jitter) : 0.0;
        Simulator::Schedule(Seconds(offset), &Request, s, 0u);
    }
    // one more period (at least 1 s) lets the last frames finish; they are then late
    Simulator::Stop(Seconds(cfg.period * double(cfg.periods) + std::max(cfg.period, 1.0)));
    Simulator::Run();
    Simulator::Destroy();
    g_devs.clear();
    g_pending.clear();
    return g_res;
}
}  // namespace kfcrit_ns3
"""
"""The driver's C++ text (namespace ``kfcrit_ns3``: ``Config``, ``Result``, ``Run``)."""
