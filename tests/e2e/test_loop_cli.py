"""Closed loops from the command line: exit codes, JSON keys, bad files (theory §12)."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

SCALAR = """name: scalar loop
A: [[1.25]]
C: [[1]]
Q: 1
R: 1
channel: {{model: {sensing}}}
loop:
  B: {B}
  channel: {{model: bernoulli, arrival_probability: {nu}}}
  acknowledged: {acked}
"""


def run(*args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, "-m", "kfcrit", *args], capture_output=True,
                          text=True, env=env, timeout=600)


def write(tmp_path: Path, sensing: str = "bernoulli, arrival_probability: 0.8", B: str = "[[1]]",
          nu: str = "0.8", acked: str = "true") -> Path:
    path = tmp_path / "loop.yaml"
    path.write_text(SCALAR.format(sensing=sensing, B=B, nu=nu, acked=acked))
    return path


def test_pass_and_json_keys(tmp_path: Path) -> None:
    out = run("analyze", str(write(tmp_path)), "--json", "--quick", "--no-simulate")
    assert out.returncode == 0, out.stderr
    loop = json.loads(out.stdout)["loop"]
    for key in ("acknowledged", "on_loss", "sensing_critical", "actuation_critical", "verdict",
                "spectral_radius", "cost", "critical_curve"):
        assert key in loop
    for key in ("value", "expression", "exact", "interval"):
        assert key in loop["sensing_critical"] and key in loop["actuation_critical"]
    assert set(loop["cost"]) >= {"value", "lower", "upper"}
    assert loop["verdict"] == "mean-square-stable"


def test_unstable_loop_fails_with_exit_5(tmp_path: Path) -> None:
    # ν̄ = 0.3 ≤ ν_c = 9/25: the loop is mean-square unstable though the estimator is fine
    out = run("analyze", str(write(tmp_path, nu="0.3")), "--json", "--quick", "--no-simulate")
    assert out.returncode == 5
    rec = json.loads(out.stdout)
    assert rec["loop"]["verdict"] == "mean-square-unstable"
    assert rec["operating_point"]["verdict"] == "mean-unstable"


def test_measured_sensing_trace_is_undetermined_exit_3(tmp_path: Path) -> None:
    (tmp_path / "t.txt").write_text(" ".join("1" if i % 5 else "0" for i in range(400)))
    out = run("analyze", str(write(tmp_path, sensing="trace, path: t.txt")), "--quick",
              "--no-simulate")
    assert out.returncode == 3, out.stderr


def test_udp_like_terminal_and_check(tmp_path: Path) -> None:
    path = write(tmp_path, acked="false", nu="0.95")
    assert run("check", str(path)).returncode == 0
    out = run("analyze", str(path), "--quick", "--no-simulate")
    assert "closed loop" in out.stdout and "UDP-like" in out.stdout


@pytest.mark.parametrize("B, field", [("[[1], [2]]", "loop.B"), ("[[1, x]]", "loop.B[0][1]")])
def test_bad_loop_file_exits_2_naming_the_field(tmp_path: Path, B: str, field: str | None
                                                ) -> None:
    out = run("check", str(write(tmp_path, B=B)))
    assert out.returncode == 2
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1
    if field:
        assert f"{field}:" in lines[0]


def test_missing_actuation_channel(tmp_path: Path) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text("name: x\nA: 1.25\nC: 1\nQ: 1\nR: 1\n"
                    "channel: {model: bernoulli, arrival_probability: 0.8}\nloop: {B: 1}\n")
    out = run("analyze", str(path))
    assert out.returncode == 2 and "loop.channel" in out.stderr


def test_report_has_the_loop_section(tmp_path: Path) -> None:
    html = tmp_path / "r.html"
    out = run("report", str(write(tmp_path)), "-o", str(html), "--quick")
    assert out.returncode == 0, out.stderr
    text = html.read_text()
    assert 'id="loop"' in text and 'id="loop-comparison"' in text and "fig-loop-plane" in text
