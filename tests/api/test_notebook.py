"""The package as a notebook uses it: public API, displays, figures, sweep tables."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

import kfcrit
from kfcrit.api import Analysis

from ..conftest import REPORTS, ROOT


def test_dir_lists_the_public_api() -> None:
    names = dir(kfcrit)
    for name in ("analyze", "System", "load_spec", "sweep", "Analysis", "simulate"):
        assert name in names


def test_record_displays_itself(example_records: dict) -> None:
    record = Analysis.of(example_records["link-oqpsk-sensor.yaml"])
    assert "review fail" in repr(record) and "9/25" in repr(record)
    html = record._repr_html_()
    assert "FAIL" in html.upper() and "<table" in html and "link policy" in html
    md = record._repr_markdown_()
    assert md.startswith("### ") and "| check |" in md


def test_figures_are_matplotlib_objects(example_records: dict) -> None:
    from matplotlib.figure import Figure

    record = Analysis.of(example_records["sinopoli-scalar.yaml"])
    names = record.figure_names()
    assert "phase_transition" in names
    assert isinstance(record.figure("phase_transition"), Figure)
    with pytest.raises(KeyError):
        record.figure("no-such-figure")


def test_analyze_from_python_returns_the_notebook_record() -> None:
    system = kfcrit.System([["5/4", 0], [1, "11/10"]], [[1, 1]], Q=20, R="5/2", name="g")
    record = kfcrit.analyze(system, simulate=False)
    assert isinstance(record, kfcrit.Analysis)
    assert record.critical_value.expression == "9/25"      # Mo–Sinopoli Thm 4 (MATH §3)
    assert record.decision == "pass" and record.verdict is None   # no channel: nothing to fail


def test_sweep_from_python_is_a_dataframe(tmp_path: Path) -> None:
    (tmp_path / "s.yaml").write_text(
        "name: s\nA: [[-1.25]]\nC: [[1]]\nQ: 1\nR: 2.5\n"
        "channel: {model: bernoulli, arrival_probability: 0.5}\n")
    (tmp_path / "sweep.yaml").write_text(
        "system: s.yaml\ngrid:\n  channel.arrival_probability: [0.2, 0.36, 0.5]\n")
    table = kfcrit.sweep(tmp_path / "sweep.yaml", tmp_path / "out")
    frame = table.to_pandas()
    assert list(frame["verdict"]) == ["mean-unstable", "mean-unstable", "mean-stable"]  # p_c 9/25
    assert list(frame["decision"]) == ["fail", "fail", "pass"]
    assert (tmp_path / "out" / "sweep.csv").exists()


def test_the_example_script_runs(tmp_path: Path) -> None:
    r = subprocess.run([sys.executable, str(REPORTS / "notebook_example.py")],
                       capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "review fail" in r.stdout and "9/25" in r.stdout and "decision" in r.stdout
    assert not (REPORTS / "sweep-link-distance-results").exists()
    assert ROOT.exists()
