"""Mesh files through the command line as a user runs them (theory §13): ``check``,
``analyze`` (terminal and ``--json``), ``report`` and the documented exit codes.

Expected values are derived by hand in each test (series route (1/2)^3, negative binomial slot
budget, the relaying cut of a series path).
"""
from __future__ import annotations

import json
from fractions import Fraction
from pathlib import Path

import pytest
import yaml
from click.testing import CliRunner

from kfcrit.cli.main import main

from ..conftest import REPORTS

SERIES = """\
name: three-hop series route
A: 1.25
Q: 1
mesh:
  nodes:
    - {name: s, role: sensor, C: 1, R: 1}
    - {name: r1, role: relay}
    - {name: r2, role: relay}
    - {name: g, role: gateway}
  hops:
    - {from: s, to: r1, attempt_success: 1/2}
    - {from: r1, to: r2, attempt_success: 1/2}
    - {from: r2, to: g, attempt_success: 1/2}
  routes:
    - [s, r1, r2, g]
"""


def run(*args: str):
    return CliRunner().invoke(main, list(args))


def write(tmp_path: Path, text: str, name: str = "mesh.yaml") -> str:
    path = tmp_path / name
    path.write_text(text)
    return str(path)


def edited(**changes) -> str:
    doc = yaml.safe_load(SERIES)
    for key, value in changes.items():
        doc["mesh"][key] = value
    return yaml.safe_dump(doc)


def test_series_route_fails_review_and_says_relay_estimates(tmp_path):
    path = write(tmp_path, SERIES)
    res = run("analyze", path, "--json", "--no-simulate", "--quick")
    assert res.exit_code == 5, res.stderr
    rec = json.loads(res.stdout)
    mesh = rec["mesh"]
    assert Fraction(mesh["arrival_expression"]["s"]) == Fraction(1, 2) ** 3
    assert mesh["verdict"] == rec["operating_point"]["verdict"] == "mean-unstable"
    assert mesh["relaying"] == {**mesh["relaying"], "p_cut": 0.5, "verdict": "mean-stable"}
    text = run("analyze", path, "--no-simulate", "--quick")
    assert text.exit_code == 5
    assert "relay estimates, not measurements" in text.stdout
    assert "N − 1" in text.stdout and "relay r1" in text.stdout


def test_slot_budget_in_the_cli_record(tmp_path):
    # 3 hops at 4/5 within 4 slots: (4/5)^3 (1 + 3·(1/5)) = 512/625 = 0.8192
    path = write(tmp_path, edited(slots_per_period=4).replace("1/2", "4/5"))
    rec = json.loads(run("analyze", path, "--json", "--no-simulate", "--quick").stdout)
    assert Fraction(rec["mesh"]["arrival_expression"]["s"]) == Fraction(512, 625)


@pytest.mark.parametrize("changes, field", [
    ({"routes": [["s", "r1", "ghost", "g"]]}, "mesh.routes[0]"),
    ({"routes": [["s", "r1", "r2", "r1", "g"]]}, "mesh.routes[0]"),
    ({"slots_per_period": 2}, "mesh.slots_per_period"),
    ({"hops": [{"from": "s", "to": "r1", "attempt_success": "1/2"}]}, "mesh.routes[0]"),
])
def test_bad_mesh_exits_2_naming_the_field(tmp_path, changes, field):
    path = write(tmp_path, edited(**changes))
    for command in (("check", path), ("analyze", path, "--quick")):
        res = run(*command)
        assert res.exit_code == 2, (command, res.exit_code, res.stdout, res.stderr)
        lines = res.stderr.strip().splitlines()
        assert len(lines) == 1 and field in lines[0], lines


def test_sensor_without_route_exits_2(tmp_path):
    doc = yaml.safe_load(SERIES)
    doc["mesh"]["nodes"].insert(1, {"name": "lonely", "role": "sensor", "C": 1, "R": 1})
    res = run("check", write(tmp_path, yaml.safe_dump(doc)))
    assert res.exit_code == 2 and "mesh.nodes[1]" in res.stderr


def test_check_accepts_the_examples():
    for name in ("mesh-wirelesshart.yaml", "mesh-pipeline-relaying.yaml"):
        res = run("check", str(REPORTS / name))
        assert res.exit_code == 0, res.stderr


def test_wirelesshart_example_passes_with_a_single_point_of_failure(tmp_path):
    res = run("analyze", str(REPORTS / "mesh-wirelesshart.yaml"), "--json", "--quick")
    assert res.exit_code == 0, res.stderr
    rec = json.loads(res.stdout)
    mesh = rec["mesh"]
    assert rec["review"]["decision"] == "pass"
    assert mesh["verdict"] == rec["operating_point"]["verdict"] == "mean-stable"
    assert len([n for n in mesh["nodes"] if n["role"] == "sensor"]) == 6
    assert mesh["slots_per_period"] == 6
    lt1 = [r for r in mesh["routes"] if r["sensor"] == "lt1"]
    assert len(lt1) == 2                                        # path diversity
    # two independent routes: 1 − Π(1 − route) (the slot budget schedules each route alone)
    miss = (1 - lt1[0]["arrival_probability"]) * (1 - lt1[1]["arrival_probability"])
    assert mesh["arrival_probability"]["lt1"] == pytest.approx(1 - miss, abs=1e-12)
    dead = {f["element"]: f for f in mesh["failures"]}
    assert dead["r1"]["verdict"] == "mean-unstable"             # both flow sensors behind r1
    assert mesh["bottleneck"] == "r1->gw"
    assert any(r["check"].startswith("link policy: margin (hop") for r in rec["review"]["reasons"])


def test_pipeline_example_needs_estimate_relaying(tmp_path):
    res = run("analyze", str(REPORTS / "mesh-pipeline-relaying.yaml"), "--json", "--quick")
    assert res.exit_code == 5
    mesh = json.loads(res.stdout)["mesh"]
    (route,) = mesh["routes"]
    q = route["hop_success"][0]
    assert route["arrival_probability"] == pytest.approx(q ** 4)   # four equal hops
    assert mesh["relaying"]["p_cut"] == pytest.approx(1 - q)        # series: the worst drop
    modes = {m["mode"].split(" ")[0]: m["verdict"] for m in mesh["modes"]}
    assert modes == {"raw": "mean-unstable", "estimate": "mean-stable", "smart": "mean-unstable"}


def test_report_has_the_mesh_section(tmp_path):
    out = tmp_path / "mesh.html"
    res = run("report", str(REPORTS / "mesh-pipeline-relaying.yaml"), "-o", str(out), "--quick")
    assert res.exit_code == 5, res.stderr
    html = out.read_text()
    for anchor in ('id="mesh"', 'id="mesh-modes"', 'id="mesh-sensors"', 'id="mesh-n-minus-1"',
                   'id="fig-mesh-topology"', "relay estimates, not measurements"):
        assert anchor in html, anchor
    assert "<svg" in html.split('id="fig-mesh-topology"')[1][:2000]
