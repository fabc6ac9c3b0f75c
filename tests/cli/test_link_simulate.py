"""``kfcrit link simulate``: errors without ns-3, the import guard, and one short real ns-3 run.

The real run is marked ``ns3`` and skipped (with the reason) where the ns-3 wheel is not
importable; it starts one subprocess, whose import of ns-3 takes 20–40 s.
"""
from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from kfcrit.cli.main import main
from kfcrit.io.traceformats import read_binary
from kfcrit.link.ns3.driver import INSTALL_HINT

from ..conftest import REPORTS, ROOT

NS3_NOISE = "-106.98658509780566"  # ns-3's thermal noise over its 5 x 1 MHz bands (dBm)
ONE_LINK = f"""\
name: one sensor over ns-3's default lr-wpan link
A: [[1.1]]
C: [[1]]
Q: [[1]]
R: [[1]]
channel:
  model: link-budget
  radio: ieee802154-oqpsk-2450
  tx_power_dbm: 0
  distance_m: 110
  packet_bytes: 20
  max_retries: 2
  path_loss: {{model: log-distance, exponent: 3, reference_distance_m: 1, reference_loss_db: 46.6777}}
  noise: {{noise_floor_dbm: {NS3_NOISE}}}
"""


def run(*args: str):
    return CliRunner().invoke(main, list(args))


def one_error_line(result) -> str:
    assert result.exit_code == 2, (result.exit_code, result.stdout, result.stderr)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, lines
    return lines[0]


def test_without_ns3_one_line_and_exit_2(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "ns", None)  # ``import ns`` now raises ImportError
    line = one_error_line(run("link", "simulate", str(REPORTS / "link-oqpsk-sensor.yaml")))
    assert line == f"kfcrit: error: {INSTALL_HINT}"


def test_bad_input_is_reported_before_ns3_is_needed(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "ns", None)
    line = one_error_line(run("link", "simulate", str(REPORTS / "network-redundant-gauges.yaml")))
    assert line.startswith("kfcrit: error: sensors[0].channel.model: is bernoulli")
    line = one_error_line(run("link", "simulate", str(REPORTS / "link-oqpsk-sensor.yaml"),
                              "--jitter-ms", "100"))
    assert "--jitter-ms" in line
    line = one_error_line(run("link", "simulate", str(REPORTS / "link-oqpsk-sensor.yaml"),
                              "--periods", "0"))
    assert "--periods" in line


def test_output_must_be_a_folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "ns", None)
    target = tmp_path / "file.txt"
    target.write_text("x")
    line = one_error_line(run("link", "simulate", str(REPORTS / "link-oqpsk-sensor.yaml"),
                              "-o", str(target)))
    assert "--output" in line and "is a file" in line


def test_importing_kfcrit_never_imports_ns3() -> None:
    code = ("import sys, kfcrit, kfcrit.cli.main, kfcrit.link.ns3.driver, "
            "kfcrit.link.ns3.results, kfcrit.link.ns3.topology; "
            "print('ns' in sys.modules, 'cppyy' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True,
                         check=True, timeout=300)
    assert out.stdout.split() == ["False", "False"]


def test_link_group_is_listed() -> None:
    r = run("link", "--help")
    assert r.exit_code == 0 and "simulate" in r.stdout


NS3_MISSING = importlib.util.find_spec("ns") is None


@pytest.mark.ns3
@pytest.mark.skipif(NS3_MISSING, reason="the ns-3 wheel is not installed "
                                        "(pip install 'kfcrit[ns3]')")
def test_real_ns3_run_is_seeded_and_agrees_with_the_link_budget(tmp_path: Path) -> None:
    """One sensor, 200 periods, twice with the same seed in one ns-3 process."""
    system = tmp_path / "one.yaml"
    system.write_text(ONE_LINK)
    code = (
        "import sys\n"
        "from click.testing import CliRunner\n"
        "from kfcrit.cli.main import main\n"
        "for out in sys.argv[2:]:\n"
        "    r = CliRunner().invoke(main, ['link', 'simulate', sys.argv[1], '--periods', '200',\n"
        "                                  '--seed', '7', '-o', out])\n"
        "    assert r.exit_code == 0, (r.exit_code, r.output, r.exception)\n"
    )
    a, b = tmp_path / "a", tmp_path / "b"
    proc = subprocess.run([sys.executable, "-c", code, str(system), str(a), str(b)], cwd=ROOT,
                          capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr[-2000:]
    sa = json.loads((a / "summary.json").read_text())
    sb = json.loads((b / "summary.json").read_text())
    (row,) = sa["sensors"]
    trace = read_binary(a / "sensor.trace")
    assert trace.size == 200 and int(trace.sum()) == row["received"]
    assert (a / "sensor.trace").read_text() == (b / "sensor.trace").read_text()
    assert sa["sensors"] == sb["sensors"]
    # ns-3's noise is the link budget's, and the link budget's arrival (1 - 0.26^3 = 0.982)
    # lies in the simulated 95 % interval
    assert sa["ns3_noise_dbm"] == pytest.approx(float(NS3_NOISE), abs=1e-6)
    lo, hi = row["arrival_simulated_ci95"]
    assert lo <= row["arrival_analytic"] <= hi
    assert row["arrival_analytic"] == pytest.approx(0.9822, abs=5e-4)
    assert row["lost"]["collision"] == 0  # alone on the air (the sink's acks follow frames)
    assert 1.0 < row["mean_transmissions_per_period"] < 2.0  # retries happen
