"""``kfcrit simulate`` says when the mean it samples does not exist, as ``analyze`` does.

By hand: reports/ge-bursty-scalar.yaml has a = −5/4 and recovery rate r = 0.1, so
(1 − r)a² = 0.9 · 25/16 = 1.40625 ≥ 1: E[tr P_t] diverges (theory §7, §10). The Sinopoli
scalar example (p = 0.5 > 1 − 16/25 = 0.36) has a mean: no warning.
"""
from __future__ import annotations

import json

from click.testing import CliRunner

from kfcrit.cli.main import main

from ..conftest import REPORTS


def _run(name: str, *extra: str):
    return CliRunner().invoke(main, ["simulate", str(REPORTS / name), "--paths", "50",
                                     "--steps", "30", "--seed", "1", *extra])


def test_diverging_bursty_link_warns():
    r = _run("ge-bursty-scalar.yaml")
    assert r.exit_code == 0
    assert "the mean does not exist" in r.stdout and "1.40625" in r.stdout
    rec = json.loads(_run("ge-bursty-scalar.yaml", "--json").stdout)
    assert rec["mean_exists"] is False


def test_stable_link_does_not_warn():
    r = _run("sinopoli-scalar.yaml")
    assert r.exit_code == 0 and "does not exist" not in r.stdout
