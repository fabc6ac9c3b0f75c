"""No output of a run may replace one of its inputs (exit 2 naming the output option), sweep
tables are inert in spreadsheets (OWASP CSV injection rule), and network errors name the field
the user wrote."""
from __future__ import annotations

import csv
import io
import os
from pathlib import Path

from click.testing import CliRunner

from kfcrit.analysis.sweep.points import csv_cell
from kfcrit.cli.main import main

SCALAR = "name: s\nA: [[-1.25]]\nC: [[1]]\nQ: 1\nR: 2.5\n"


def _cli(cwd: Path, *args: str):
    old = os.getcwd()
    os.chdir(cwd)
    try:
        return CliRunner().invoke(main, list(args))
    finally:
        os.chdir(old)


def test_plot_symlinked_to_the_system_file(tmp_path):
    src = tmp_path / "in.yaml"
    src.write_text(SCALAR + "channel: {model: bernoulli, arrival_probability: 0.5}\n")
    (tmp_path / "p.svg").symlink_to("in.yaml")
    r = _cli(tmp_path, "simulate", "in.yaml", "--paths", "5", "--steps", "5", "--seed", "1",
             "--plot", "p.svg")
    assert r.exit_code == 2 and "--plot" in r.output
    assert src.read_text().startswith("name: s")


def test_report_over_the_trace_it_reads(tmp_path):
    (tmp_path / "trace.html").write_text("1\n0\n1\n1\n")
    (tmp_path / "sys.yaml").write_text(SCALAR + "channel: {model: trace, path: trace.html}\n")
    r = _cli(tmp_path, "report", "sys.yaml", "-o", "trace.html", "--quick")
    assert r.exit_code == 2 and "output" in r.output
    assert (tmp_path / "trace.html").read_text() == "1\n0\n1\n1\n"


def test_sweep_outputs_over_the_sweep_file_or_its_base(tmp_path):
    base = SCALAR + "channel: {model: bernoulli, arrival_probability: 0.5}\n"
    (tmp_path / "base.yaml").write_text(base)
    sweep = "name: w\nsystem: %s\ngrid:\n  channel.arrival_probability: [0.3, 0.5]\n"
    (tmp_path / "sweep.json").write_text(sweep % "base.yaml")
    r = _cli(tmp_path, "sweep", "sweep.json", "-o", ".")
    assert r.exit_code == 2 and "--output" in r.output
    assert (tmp_path / "sweep.json").read_text() == sweep % "base.yaml"
    for name in ("sweep.csv", "run.json", "margin.svg"):
        (tmp_path / name).write_text(base)
        (tmp_path / "w.yaml").write_text(sweep % name)
        r = _cli(tmp_path, "sweep", "w.yaml", "-o", ".")
        assert r.exit_code == 2 and name in r.output and "--output" in r.output
        assert (tmp_path / name).read_text() == base


def test_csv_cells_are_inert():
    for bad in ("=cmd|' /C calc'!A0", "@SUM(1+1)", "+1", "-1+2", "\tx", "\rx"):
        assert csv_cell(bad) == "'" + bad
    assert csv_cell("plain") == "plain" and csv_cell(-0.5) == -0.5
    buf = io.StringIO()
    csv.writer(buf).writerow([csv_cell("=cmd|' /C calc'!A0")])
    assert buf.getvalue().startswith("'=cmd")


def test_sweep_table_with_formula_values(tmp_path):
    from kfcrit.analysis.sweep.points import table_csv

    class Spec:
        parameters = ("name",)

    from kfcrit.analysis.sweep.points import RESULT_COLUMNS
    row = {c: None for c in ("index", "key", "name", *RESULT_COLUMNS)}
    row.update(index=0, key="k", name="=cmd|' /C calc'!A0")
    text = table_csv(Spec(), [row])
    assert "\n0,k,'=cmd" in text.replace('"', "")


def test_network_errors_name_the_written_field(tmp_path):
    net = ("name: n\nA: [[1.2]]\nQ: 1\n%ssensors:\n"
           "  - {name: a, C: 1, R: 1%s}\n"
           "  - {name: b, C: 1, R: 1, channel: {model: bernoulli, arrival_probability: 0.5}}\n")
    ch = ", channel: {model: bernoulli, arrival_probability: 0.5}"
    f = tmp_path / "n.yaml"
    f.write_text(net % ("R_cross: [[1, 5], [5, 1]]\n", ch))       # not positive definite
    r = CliRunner().invoke(main, ["check", str(f)])
    assert r.exit_code == 2 and "R_cross" in r.output
    f.write_text(net % ("", ""))
    r = CliRunner().invoke(main, ["analyze", str(f), "--quick", "--no-simulate"])
    assert r.exit_code == 2 and "sensors.a.channel" in r.output and "p:" not in r.output
