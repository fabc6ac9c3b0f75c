"""Measured traces through the command line, as a user runs them (theory §14).

Trace files in the three formats, the review's exit codes (0 pass, 5 fail, 3 undetermined),
bad logs refused with exit 2 and one line naming the field and the line, ``check`` and
``report``. Expected arrays and intervals are worked out here by hand or with scipy.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

ROOT = Path(__file__).resolve().parents[2]
PLANT = "name: t\nA: [[1.25]]\nC: [[1]]\nQ: 1\nR: 1\n"   # p_c = 1 − 1/a² = 9/25


def kfcrit(*args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, "-m", "kfcrit", *args], capture_output=True,
                          text=True, timeout=600, env=env, cwd=ROOT)


def system_file(tmp_path: Path, channel: str) -> Path:
    p = tmp_path / "system.yaml"
    p.write_text(PLANT + f"channel: {channel}\n")
    return p


def analyze(path: Path) -> tuple[int, dict]:
    r = kfcrit("analyze", str(path), "--json", "--quick", "--no-simulate")
    return r.returncode, (json.loads(r.stdout) if r.stdout.strip() else {})


def one_error_line(r: subprocess.CompletedProcess) -> str:
    lines = [ln for ln in r.stderr.splitlines() if ln.startswith("kfcrit: error:")]
    assert r.returncode == 2 and len(lines) == 1, r.stderr
    return lines[0]


def test_sequence_numbers_trace(tmp_path: Path) -> None:
    # 200 packets numbered 1..200; every 10th (10, 20, …, 200) lost: 180 of 200 received,
    # losses isolated, so f̂ = 20/… and r̂ = 1; first/last given so the ends count
    received = [s for s in range(1, 201) if s % 10]
    (tmp_path / "seq.txt").write_text("\n".join(map(str, received)) + "\n")
    code, rec = analyze(system_file(
        tmp_path, "{model: trace, path: seq.txt, format: sequence-numbers, first: 1, last: 200}"))
    fit = rec["channel_fit"]
    assert fit["n"] == 200 and fit["p_hat"] == 0.9
    lo = stats.beta.ppf(0.025, 180, 21)
    assert fit["p_interval"][0] == pytest.approx(lo, rel=1e-12)
    assert fit["bursts"]["lengths"] == [1] and fit["bursts"]["counts"] == [19]  # 200 censored
    assert code == 0 and rec["review"]["decision"] == "pass"


def test_receive_log_binned_per_period(tmp_path: Path) -> None:
    # T = 0.1 s: arrivals at k·0.1 (exactly on the period's start, read as exact decimals, so
    # 0.3 falls in period 3) for every k except multiples of 4 → 300 of 400 periods received
    times = [f"{k // 10}.{k % 10}" for k in range(400) if k % 4]
    (tmp_path / "log.txt").write_text("\n".join(times) + "\n")
    code, rec = analyze(system_file(
        tmp_path, "{model: trace, path: log.txt, format: receive-log, period_s: 0.1}"))
    fit = rec["channel_fit"]
    assert fit["n"] == 400
    assert fit["p_hat"] == 0.75 and fit["bursts"]["counts"] == [99]  # 99 complete 1-runs
    assert code == 0


def test_exit_codes_pass_fail_undetermined(tmp_path: Path) -> None:
    rng = np.random.default_rng(11)
    for p, want in ((0.85, 0), (0.2, 5)):
        x = (rng.random(2000) < p).astype(int)
        (tmp_path / "b.txt").write_text("".join(map(str, x)))
        code, rec = analyze(system_file(tmp_path, "{model: trace, path: b.txt}"))
        assert code == want, rec["operating_point"]["basis"]
    # 19 of 50: the interval [B⁻¹(.025; 19, 32), B⁻¹(.975; 20, 31)] ∋ 9/25
    (tmp_path / "b.txt").write_text("01110000000101010010110001000001100100010101101010")
    code, rec = analyze(system_file(tmp_path, "{model: trace, path: b.txt}"))
    assert code == 3 and rec["channel_fit"]["length_to_decide"] > 50


@pytest.mark.parametrize("channel, content, needle", [
    ("{model: trace, path: t.txt}", "1 1 0\n1 2 1\n", "channel.path: t.txt line 2: '2'"),
    ("{model: trace, path: t.txt, format: sequence-numbers}", "1\n2\n2\n",
     "channel.path: t.txt line 3: sequence number 2 is repeated"),
    ("{model: trace, path: t.txt, format: sequence-numbers}", "1\n5\n3\n",
     "channel.path: t.txt line 3: sequence number 3 is smaller"),
    ("{model: trace, path: t.txt, format: receive-log, period_s: 0.1}", "0.1\n0.3\n0.2\n",
     "channel.path: t.txt line 3: time 0.2 is earlier"),
    ("{model: trace, path: t.txt, format: receive-log, period_s: 0.1}", "0.1 a\n0.3\n",
     "channel.path: t.txt line 2: has 1 column(s)"),
    ("{model: trace, path: t.txt, format: receive-log}", "0.1\n", "channel.period_s: is required"),
    ("{model: trace, path: t.txt, format: receive-log, period_s: 0.1, sensor: b}", "0.1 a\n",
     "channel.sensor: 'b' does not occur"),
    ("{model: trace, path: t.txt, format: receive-log, period_s: 0.1}", "0.1 a\n0.2 b\n",
     "channel.sensor: the receive log has 2 sensors"),
    ("{model: trace, path: t.txt, confidence: 1.5}", "1 0\n", "channel.confidence: must be"),
    ("{model: trace, path: t.txt, format: pcap}", "1 0\n", "channel.format: unknown trace format"),
    ("{model: trace, path: t.txt, first: 3}", "1 0\n", "channel.first: is not used by format"),
])
def test_bad_logs_exit_2_naming_the_field(tmp_path: Path, channel: str, content: str,
                                           needle: str) -> None:
    (tmp_path / "t.txt").write_text(content)
    path = system_file(tmp_path, channel)
    for command in ("analyze", "check"):
        line = one_error_line(kfcrit(command, str(path)))
        assert needle in line, line


def test_check_accepts_a_good_trace_channel(tmp_path: Path) -> None:
    (tmp_path / "t.txt").write_text("0.05 s1\n0.15 s2\n")
    path = system_file(tmp_path, "{model: trace, path: t.txt, format: receive-log, "
                                 "period_s: 0.1, sensor: s1, confidence: 0.9}")
    assert kfcrit("check", str(path)).returncode == 0


def test_shipped_examples_and_report(tmp_path: Path) -> None:
    code, rec = analyze(ROOT / "reports" / "trace-contention-hidden4.yaml")
    # computed from the log's source (tests/data/ns3): 3719 of 5000 periods lost by all four
    lo = stats.beta.ppf(0.025, 3719, 1282)
    assert code == 5 and lo * 6.25 >= 1
    assert rec["channel_fit"]["joint_law"]["p_all_lost"] == 3719 / 5000
    code, rec = analyze(ROOT / "reports" / "trace-bursty-link.yaml")
    assert code == 0 and rec["channel_fit"]["model"] == "gilbert-elliott"
    out = tmp_path / "review.html"
    r = kfcrit("report", str(ROOT / "reports" / "trace-bursty-link.yaml"), "-o", str(out),
               "--quick")
    assert r.returncode == 0, r.stderr
    html = out.read_text()
    assert "Measured trace" in html and 'id="fig-trace-bursts"' in html
    assert 'id="fig-trace-region"' in html and "Bonferroni" in html
    for fig_id in ("fig-trace-bursts", "fig-trace-region"):   # both figures drawn
        assert "<svg" in html.split(f'id="{fig_id}"')[1].split("</figure>")[0]
    text = kfcrit("analyze", str(ROOT / "reports" / "trace-bursty-link.yaml"), "--quick",
                  "--no-simulate").stdout
    assert "measured trace" in text and "loss bursts" in text and "worst corner" in text
