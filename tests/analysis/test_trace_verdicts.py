"""Measured traces to verdicts with confidence (theory §13, §14).

Expected values are derived here without kfcrit: Clopper–Pearson ends from scipy's Beta
quantiles, the model choice from scipy's G-test of the 2×2 transition table, thresholds from
the closed forms (p_c = 1 − 1/a² for a scalar plant, the burst condition (1 − r)a² < 1 of
theory §7, the joint-law condition P(all lost)·a² < 1 of theory §13 for redundant sensors).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

import kfcrit
from kfcrit.analysis.spec import spec_from_mapping
from kfcrit.errors import InputError

NS3 = Path(__file__).resolve().parents[1] / "data" / "ns3" / "lrwpan_contention.json"


def cp(k: int, n: int, level: float) -> tuple[float, float]:
    """Clopper–Pearson interval from Beta quantiles (the textbook form)."""
    a = 1 - level
    lo = 0.0 if k == 0 else stats.beta.ppf(a / 2, k, n - k + 1)
    hi = 1.0 if k == n else stats.beta.ppf(1 - a / 2, k + 1, n - k)
    return float(lo), float(hi)


def transitions(x: np.ndarray) -> np.ndarray:
    t = np.zeros((2, 2), dtype=int)
    for a, b in zip(x[:-1], x[1:]):
        t[int(a), int(b)] += 1
    return t


def g_test_p(x: np.ndarray) -> float:
    table = transitions(x)
    return float(stats.chi2_contingency(table, correction=False,
                                        lambda_="log-likelihood")[1])


def markov_trace(n: int, f: float, r: float, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    out, s = np.empty(n, dtype=int), 1
    for t in range(n):
        out[t] = s
        u = rng.random()
        s = (0 if u < f else 1) if s == 1 else (1 if u < r else 0)
    return out


def analyze_trace(tmp_path: Path, x: np.ndarray, a: float, **channel) -> dict:
    (tmp_path / "t.txt").write_text(" ".join(map(str, x)))
    doc = {"name": "t", "A": [[a]], "C": [[1]], "Q": 1, "R": 1,
           "channel": {"model": "trace", "path": "t.txt", **channel}}
    spec = spec_from_mapping(doc, base_dir=tmp_path)
    return kfcrit.analyze(spec, simulate=False, quick=True).to_dict()


def test_iid_trace_passes_with_confidence(tmp_path: Path) -> None:
    x = (np.random.default_rng(7).random(2000) < 0.8).astype(int)
    k, n = int(x.sum()), x.size
    assert g_test_p(x) >= 0.05                      # i.i.d. not rejected: Bernoulli model
    lo, hi = cp(k, n, 0.95)
    assert lo > 9 / 25                              # a = 5/4: p_c = 1 − 16/25
    rec = analyze_trace(tmp_path, x, 1.25)
    fit = rec["channel_fit"]
    assert fit["model"] == "bernoulli" and fit["n"] == n and fit["p_hat"] == k / n
    assert fit["p_interval"] == pytest.approx([lo, hi], rel=1e-12)
    assert fit["lrt_p_value"] == pytest.approx(g_test_p(x), rel=1e-9)
    assert fit["confidence"] == 0.95 and fit["length_to_decide"] is None
    assert rec["operating_point"]["verdict"] == "mean-stable"
    assert rec["review"]["decision"] == "pass"
    assert "with confidence 95 %" in rec["review"]["reasons"][0]["detail"]


def test_iid_trace_fails_with_confidence(tmp_path: Path) -> None:
    x = (np.random.default_rng(9).random(1500) < 0.25).astype(int)
    assert g_test_p(x) >= 0.05
    lo, hi = cp(int(x.sum()), x.size, 0.95)
    assert hi < 9 / 25
    rec = analyze_trace(tmp_path, x, 1.25)
    assert rec["channel_fit"]["p_interval"][1] == pytest.approx(hi, rel=1e-12)
    assert rec["operating_point"]["verdict"] == "mean-unstable"
    assert rec["review"]["decision"] == "fail"


def test_iid_trace_undetermined_says_how_long(tmp_path: Path) -> None:
    x = (np.random.default_rng(9).random(300) < 0.42).astype(int)
    assert g_test_p(x) >= 0.05
    k, n = int(x.sum()), x.size
    lo, hi = cp(k, n, 0.95)
    assert lo < 9 / 25 < hi
    rec = analyze_trace(tmp_path, x, 1.25)
    fit = rec["channel_fit"]
    assert rec["operating_point"]["verdict"] == "undetermined"
    assert fit["region"]["outcome"] == "neither"
    m = fit["length_to_decide"]
    assert isinstance(m, int) and m > n
    # at that length, the interval at the fitted frequency excludes p_c (checked with scipy)
    lo_m, _ = cp(int(np.floor(k / n * m + 0.5)), m, 0.95)
    assert lo_m > 9 / 25
    assert str(m) in rec["operating_point"]["basis"]


def test_bursty_trace_fails_at_the_best_corner(tmp_path: Path) -> None:
    # a = 3/2: the burst condition (1 − r)·9/4 < 1 needs r > 5/9 ≈ 0.556
    x = markov_trace(6000, 0.1, 0.35, seed=3)
    t = transitions(x)
    assert g_test_p(x) < 0.05                       # Markov: Gilbert–Elliott model
    r_lo, r_hi = cp(int(t[0, 1]), int(t[0].sum()), 0.975)
    f_lo, f_hi = cp(int(t[1, 0]), int(t[1].sum()), 0.975)
    assert (1 - r_hi) * 2.25 >= 1
    rec = analyze_trace(tmp_path, x, 1.5)
    fit = rec["channel_fit"]
    assert fit["model"] == "gilbert-elliott"
    assert fit["recovery_rate_interval"] == pytest.approx([r_lo, r_hi], rel=1e-12)
    assert fit["failure_rate_interval"] == pytest.approx([f_lo, f_hi], rel=1e-12)
    assert fit["recovery_rate_hat"] == t[0, 1] / t[0].sum()
    best = fit["region"]["best"]
    assert (best["failure_rate"], best["recovery_rate"]) == pytest.approx((f_lo, r_hi))
    assert best["necessary"] is False and fit["region"]["outcome"] == "fails"
    assert rec["operating_point"]["verdict"] == "mean-unstable"


def test_bursty_trace_passes_at_the_worst_corner(tmp_path: Path) -> None:
    x = markov_trace(6000, 0.1, 0.8, seed=4)
    t = transitions(x)
    assert g_test_p(x) < 0.05
    r_lo, _ = cp(int(t[0, 1]), int(t[0].sum()), 0.975)
    assert (1 - r_lo) * 2.25 < 1                    # scalar: exact condition (theory §7)
    rec = analyze_trace(tmp_path, x, 1.5, confidence=0.99)
    fit = rec["channel_fit"]
    r_lo99, _ = cp(int(t[0, 1]), int(t[0].sum()), 0.995)
    assert fit["confidence"] == 0.99
    assert fit["region"]["worst"]["recovery_rate"] == pytest.approx(r_lo99, rel=1e-12)
    assert rec["operating_point"]["verdict"] == "mean-stable"
    assert "with confidence 99 %" in rec["operating_point"]["basis"]
    # the histogram of complete loss runs, counted here directly
    runs = [len(s) for s in "".join(map(str, x)).strip("0").split("1") if s]
    lengths, counts = np.unique(runs, return_counts=True)
    assert fit["bursts"]["lengths"] == lengths.tolist()
    assert fit["bursts"]["counts"] == counts.tolist()


def test_bursty_trace_near_the_boundary_is_undetermined(tmp_path: Path) -> None:
    x = markov_trace(400, 0.3, 5 / 9, seed=6)
    t = transitions(x)
    r_lo, r_hi = cp(int(t[0, 1]), int(t[0].sum()), 0.975)
    assert r_lo < 5 / 9 < r_hi
    assert g_test_p(x) < 0.05
    rec = analyze_trace(tmp_path, x, 1.5)
    assert rec["channel_fit"]["model"] == "gilbert-elliott"
    assert rec["operating_point"]["verdict"] == "undetermined"
    assert rec["channel_fit"]["length_to_decide"] > x.size
    assert rec["review"]["decision"] == "undetermined"


# ---------------------------------------------------------------------------- joint law (ns-3)

def ns3_case(name: str) -> np.ndarray:
    data = json.loads(NS3.read_text())
    case = next(c for c in data["cases"] if c["name"] == name)
    return np.array([[ch == "1" for ch in t] for t in case["traces"]])


def network_record(tmp_path: Path, traces: np.ndarray, a: str) -> dict:
    sensors = []
    for i, t in enumerate(traces):
        (tmp_path / f"s{i}.txt").write_text("".join("1" if v else "0" for v in t))
        sensors.append({"name": f"s{i}", "C": 1, "R": 1,
                        "channel": {"model": "trace", "path": f"s{i}.txt"}})
    spec = spec_from_mapping({"name": "net", "A": a, "Q": 1, "sensors": sensors},
                             base_dir=tmp_path)
    return kfcrit.analyze(spec, simulate=False, quick=True).to_dict()


def joint_numbers(traces: np.ndarray) -> tuple[int, int, float, float, float]:
    n = traces.shape[1]
    k = int((~traces.any(axis=0)).sum())            # periods with every packet lost
    lo, hi = cp(k, n, 0.95)
    product = float(np.prod(1 - traces.mean(axis=1)))
    return k, n, lo, hi, product


def test_hidden_terminals_joint_law_at_a_2_5(tmp_path: Path) -> None:
    traces = ns3_case("hidden-4-tetrahedron-110m")
    k, n, lo, hi, product = joint_numbers(traces)
    assert k == 3719 and n == 5000
    assert lo * 6.25 >= 1 and product * 6.25 >= 1  # both say unstable at a = 5/2
    rec = network_record(tmp_path, traces, "2.5")
    j = rec["channel_fit"]["joint_law"]
    assert j["p_all_lost"] == k / n
    assert j["p_all_lost_interval"] == pytest.approx([lo, hi], rel=1e-12)
    assert j["p_all_lost_product"] == pytest.approx(product, rel=1e-12)
    assert rec["operating_point"]["verdict"] == "mean-unstable"
    assert rec["network"]["verdict"] == "mean-unstable"
    assert rec["review"]["decision"] == "fail"


def test_hidden_terminals_joint_law_passes_where_independence_fails(tmp_path: Path) -> None:
    # a = 23/20: a² = 529/400. Collisions make the losses negatively dependent here:
    # π̂(∅) < Π(1 − p̂_i), and only the joint law clears the bar
    traces = ns3_case("hidden-4-tetrahedron-110m")
    _, _, lo, hi, product = joint_numbers(traces)
    a2 = 529 / 400
    assert hi * a2 < 1 <= product * a2
    rec = network_record(tmp_path, traces, "23/20")
    j = rec["channel_fit"]["joint_law"]
    assert j["independent_necessary"] is False and j["region_covered"] is True
    assert rec["operating_point"]["verdict"] == "mean-stable"
    assert rec["network"]["verdict"] == "mean-stable"
    assert rec["review"]["decision"] == "pass"


def test_dense_network_no_longer_passes_falsely(tmp_path: Path) -> None:
    # eight sensors at 30 m: losses come together (π̂(∅) ≈ 8 × the product of marginals).
    # At a = 144 independent links would pass (product·a² < 1); the joint law fails with 95 %.
    traces = ns3_case("dense-8-circle-30m")
    _, _, lo, _, product = joint_numbers(traces)
    assert product * 144 ** 2 < 1 <= lo * 144 ** 2
    rec = network_record(tmp_path, traces, "144")
    j = rec["channel_fit"]["joint_law"]
    assert j["independent_necessary"] is True
    assert j["constraints"][0]["product_value"] == pytest.approx(product * 144 ** 2)
    assert rec["operating_point"]["verdict"] == "mean-unstable"
    assert rec["review"]["decision"] == "fail"


def test_network_traces_of_unequal_length_are_refused(tmp_path: Path) -> None:
    (tmp_path / "a.txt").write_text("0110")
    (tmp_path / "b.txt").write_text("011")
    sensors = [{"name": "a", "C": 1, "R": 1, "channel": {"model": "trace", "path": "a.txt"}},
               {"name": "b", "C": 1, "R": 1, "channel": {"model": "trace", "path": "b.txt"}}]
    spec = spec_from_mapping({"name": "net", "A": 2, "Q": 1, "sensors": sensors},
                             base_dir=tmp_path)
    with pytest.raises(InputError, match=r"^sensors\[1\]\.channel\.path: has 3 periods"):
        kfcrit.analyze(spec, simulate=False, quick=True)


def test_one_receive_log_gives_aligned_traces(tmp_path: Path) -> None:
    # two sensors in one log: periods of 0.1 s; s1 received in 0, 2; s2 in 1, 2; period 3 empty
    (tmp_path / "log.txt").write_text("0.01 s1\n0.12 s2\n0.25 s1\n0.27 s2\n0.35 s9\n")
    ch = {"model": "trace", "path": "log.txt", "format": "receive-log", "period_s": "0.1"}
    sensors = [{"name": s, "C": 1, "R": 1, "channel": {**ch, "sensor": s}} for s in ("s1", "s2")]
    spec = spec_from_mapping({"name": "net", "A": 2, "Q": 1, "sensors": sensors},
                             base_dir=tmp_path)
    got = [s.channel.arrivals.astype(int).tolist() for s in spec.network.sensors]
    assert got == [[1, 0, 1, 0], [0, 1, 1, 0]]
    rec = kfcrit.analyze(spec, simulate=False, quick=True).to_dict()
    j = rec["channel_fit"]["joint_law"]
    assert j["p_all_lost"] == 0.25 and j["law"] == [0.25, 0.25, 0.25, 0.25]
