"""A bursty link's margin is measured against its own boundary (theory §10): r − r_nec with
r_nec = 1 − 1/ρ(A)², so its sign agrees with the verdict; p − p_c stays as ``iid_margin``.

By hand: the scalar a = −5/4 has r_nec = 1 − 16/25 = 9/25. reports/ge-bursty-scalar.yaml has
f = 0.05, r = 0.1 (stationary p = 2/3): margin 0.1 − 0.36 = −0.26 (mean-unstable), while the
i.i.d. comparison 2/3 − 9/25 = +0.3067 has the wrong sign. The Sinopoli general plant
(ρ(A) = 5/4, r_nec = 9/25) over f = 0.1, r = 0.5: margin 0.5 − 0.36 = +0.14 (mean-stable).
"""
from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from kfcrit.cli.main import main

from ..conftest import REPORTS

GENERAL = ("name: general\nA: [[1.25, 0], [1, 1.1]]\nC: [[1, 1]]\nQ: 20\nR: 2.5\n"
           "channel: {model: gilbert-elliott, failure_rate: 0.1, recovery_rate: 0.5}\n")


def _op(path: Path) -> dict:
    r = CliRunner().invoke(main, ["analyze", str(path), "--json", "--quick", "--no-simulate"])
    return json.loads(r.stdout)["operating_point"]


def test_unstable_bursty_link_has_a_negative_margin():
    op = _op(REPORTS / "ge-bursty-scalar.yaml")
    assert op["verdict"] == "mean-unstable"
    assert op["margin"] == pytest.approx(0.1 - 9 / 25, abs=1e-12)
    assert op["recovery_threshold"] == pytest.approx(9 / 25, abs=1e-12)
    assert op["iid_margin"] == pytest.approx(2 / 3 - 9 / 25, abs=1e-12)
    assert "r_nec" in op["margin_basis"]


def test_stable_bursty_link_has_a_positive_margin(tmp_path):
    p = tmp_path / "general.yaml"
    p.write_text(GENERAL)
    op = _op(p)
    assert op["verdict"] == "mean-stable"
    assert op["margin"] == pytest.approx(0.5 - 9 / 25, abs=1e-12)
    assert op["iid_margin"] == pytest.approx(5 / 6 - 9 / 25, abs=1e-12)
    # the certified sufficient curve lies between r_nec and the operating r
    assert 0 < op["margin_to_sufficient"] <= op["margin"]


def test_report_labels_the_bursty_margin(tmp_path):
    from kfcrit.views.report.render import template_dir

    assert (template_dir() / "report.html.j2").is_file()
    p = tmp_path / "general.yaml"
    p.write_text(GENERAL)
    out = tmp_path / "review.html"
    r = CliRunner().invoke(main, ["report", str(p), "-o", str(out), "--quick"])
    assert r.exit_code == 0, r.output
    html = out.read_text()
    assert "margin r − r<sub>nec</sub>" in html and "+0.14" in html


SCALAR = ("name: scalar\nA: [[-1.25]]\nC: [[1]]\nQ: 1\nR: 2.5\n"
          "channel: {model: gilbert-elliott, failure_rate: 0.05, recovery_rate: 0.5}\n")


def test_scalar_bursty_link_has_no_undetermined_band(tmp_path):
    """Scalar theorem (theory §7): n = 1, c ≠ 0, E[P_t] bounded iff (1 − r)a² < 1, so the
    sufficient threshold is the necessary one, 1 − 16/25 = 9/25 (by hand), at every f; at
    r = 1/2 ((1 − r)a² = 25/32 < 1, mean-stable) both margins are 0.5 − 0.36 = +0.14."""
    p = tmp_path / "scalar.yaml"
    p.write_text(SCALAR)
    r = CliRunner().invoke(main, ["analyze", str(p), "--json", "--quick", "--no-simulate"])
    rec = json.loads(r.stdout)
    op, curve = rec["operating_point"], rec["link_budget"]["critical_curve"]
    assert op["verdict"] == "mean-stable"
    assert op["margin"] == pytest.approx(0.5 - 9 / 25, abs=1e-12)
    assert op["margin_to_sufficient"] == op["margin"]
    assert curve["sufficient_recovery"] == curve["necessary_recovery"]
    assert all(v == pytest.approx(9 / 25, abs=1e-15) for v in curve["sufficient_recovery"])
    assert "undetermined" not in curve["meaning"].replace("no undetermined band", "")


def test_scalar_bursty_report_names_no_undetermined_band(tmp_path):
    p = tmp_path / "scalar.yaml"
    p.write_text(SCALAR)
    out = tmp_path / "review.html"
    r = CliRunner().invoke(main, ["report", str(p), "-o", str(out), "--quick"])
    assert r.exit_code == 0, r.output
    html = out.read_text()
    assert "no band is undetermined" in html and "between, undetermined" not in html
