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
    # the analytic-against-simulated figure: the link budget's curve and the ns-3 point
    assert sa["figure"] == "arrival.svg" and (a / "arrival.svg").read_text().startswith("<?xml")


def test_arrival_figure_from_a_summary_without_ns3(tmp_path: Path) -> None:
    """The figure of analytic against simulated arrival by distance is drawn from the plan's
    link budgets and the summary alone (no ns-3 needed): one curve per sensor, whose value at
    the sensor's distance is the link budget's own arrival probability."""
    from kfcrit.analysis.spec import load_spec
    from kfcrit.cli.link import write_simulation
    from kfcrit.link.ns3.results import analytic_arrival_curve, simulated_distance_grid
    from kfcrit.link.ns3.topology import build_plan, file_links

    spec = load_spec(REPORTS / "network-planar-tracker.yaml")
    links, sink = file_links(spec)
    plan = build_plan(links, sink_position_m=sink, periods=10, period_s=0.1, seed=1,
                      jitter_s=0.0, nakagami_m=None)
    rows = [{"name": s.name, "distance_m": s.link.distance_m, "arrival_simulated": 0.5,
             "arrival_simulated_ci95": [0.4, 0.6],
             "arrival_analytic_simulated_conditions": 0.55} for s in plan.sensors]
    summary = {"plan": {"periods": 10, "period_s": 0.1, "seed": 1, "jitter_s": 0.0},
               "ns3_version": "test", "sensors": rows}
    for s in plan.sensors:
        (value,) = analytic_arrival_curve(s, [s.link.distance_m])
        assert value == pytest.approx(s.link.arrival_value, abs=1e-12)
    grid = simulated_distance_grid(summary)
    assert grid[0] <= min(r["distance_m"] for r in rows) <= max(r["distance_m"] for r in rows) \
        <= grid[-1]
    traces = [[1, 0] * 5 for _ in rows]
    import numpy as np

    write_simulation(tmp_path, summary, [np.array(t, dtype=bool) for t in traces], plan)
    svg = (tmp_path / "arrival.svg").read_text()
    assert summary["figure"] == "arrival.svg" and svg.count("<path") > len(rows)
    assert json.loads((tmp_path / "summary.json").read_text())["figure"] == "arrival.svg"
