"""Sensor networks on decoupled modes against their closed forms (theory §9.4, §15.6).

With diagonal A and Q and each scalar sensor seeing one mode k (a_k), the network is
mean-stable iff for every unstable mode

.. math:: a_k^2 \\prod_{i \\text{ on } k} (1 - p_i) < 1 ,

and sensor i's critical value (the others at their operating values) is
p_i* = max(0, 1 − 1/(a_k² Π_{j≠i on k}(1 − p_j))), none when another mode fails regardless of
p_i. The expected values below are computed here with fractions from these formulas, never
from kfcrit.
"""
from __future__ import annotations

import json
from fractions import Fraction as F

from click.testing import CliRunner

from kfcrit.cli.main import main


def network_yaml(modes: list[str], sensors: list[tuple[str, int, str]]) -> str:
    """A system file: A = diag(modes), Q = I, sensor (name, mode, p) with C = e_mode', R = 1."""
    n = len(modes)
    rows = [[modes[i] if i == j else "0" for j in range(n)] for i in range(n)]
    eye = [[1 if i == j else 0 for j in range(n)] for i in range(n)]
    lines = ["name: decoupled", "A: " + json.dumps(rows), "Q: " + json.dumps(eye), "sensors:"]
    for name, k, p in sensors:
        c = [[1 if j == k else 0 for j in range(n)]]
        lines.append(f"  - {{name: {name}, C: {json.dumps(c)}, R: 1, channel: {{model: "
                     f"bernoulli, arrival_probability: \"{p}\"}}}}")
    return "\n".join(lines) + "\n"


def closed_form(modes: list[F], sensors: list[tuple[str, int, F]]
                ) -> tuple[bool, dict[str, F | None]]:
    """(mean-stable, critical value per sensor) of decoupled modes, exactly."""
    def factor(k: int, skip: int | None = None) -> F:
        out = modes[k] ** 2
        for j, (_, kj, pj) in enumerate(sensors):
            if kj == k and j != skip:
                out *= 1 - pj
        return out
    unstable = [k for k in range(len(modes)) if abs(modes[k]) >= 1]
    stable = all(factor(k) < 1 for k in unstable)
    crit: dict[str, F | None] = {}
    for i, (name, k, _) in enumerate(sensors):
        if any(factor(m) >= 1 for m in unstable if m != k):
            crit[name] = None
        elif k in unstable:
            crit[name] = max(F(0), 1 - 1 / factor(k, skip=i))
        else:
            crit[name] = F(0)
    return stable, crit


def analyze(tmp_path, text: str) -> tuple[int, dict]:
    path = tmp_path / "net.yaml"
    path.write_text(text)
    res = CliRunner().invoke(main, ["analyze", str(path), "--json", "--quick", "--no-simulate"])
    return res.exit_code, json.loads(res.stdout)


def check_critical(net: dict, crit: dict[str, F | None]) -> None:
    for row in net["sensors"]:
        expected = crit[row["name"]]
        cv = row["critical_value"]
        if expected is None:
            assert cv["value"] is None and cv["interval"] is None
            assert "no p_i" in cv["basis"]
            continue
        lo, hi = cv["interval"]
        assert lo <= float(expected) <= hi
        if cv["exact"] and cv["expression"] is not None:
            assert F(cv["expression"].replace(" ", "")) == expected


def test_a_mode_unstable_whatever_the_other_sensors_do_gives_no_critical_value(tmp_path):
    # mode 3 seen by b, c at 1/2: (1/2)²·9 = 9/4 ≥ 1 whatever a does
    modes, sensors = ["2", "3"], [("a", 0, "9/10"), ("b", 1, "1/2"), ("c", 1, "1/2")]
    stable, crit = closed_form([F(m) for m in modes], [(s, k, F(p)) for s, k, p in sensors])
    code, rec = analyze(tmp_path, network_yaml(modes, sensors))
    assert not stable and crit["a"] is None and crit["b"] == F(7, 9)
    assert code == 5
    assert rec["network"]["verdict"] == "mean-unstable"
    check_critical(rec["network"], crit)
    a = rec["network"]["sensors"][0]
    assert a["margin"]["interval"] is None and a["surfaces"]["necessary"] is None


def test_seven_states_keep_the_necessary_constraints_without_an_exact_modulus(tmp_path):
    modes = ["1.5"] + ["0.5"] * 6
    sensors = [(f"s{i}", 0, "0.9") for i in range(3)]
    stable, crit = closed_form([F(m) for m in modes], [(s, k, F(p)) for s, k, p in sensors])
    code, rec = analyze(tmp_path, network_yaml(modes, sensors))
    assert stable and code == 0
    assert rec["network"]["verdict"] == "mean-stable"
    check_critical(rec["network"], crit)
    (c,) = rec["network"]["necessary_constraints"]
    assert abs(c["modulus2"] - 2.25) < 1e-12


def test_nine_sensors_just_inside_the_boundary(tmp_path):
    # mode 3 seen by two sensors: (1/3 − 10⁻⁴⁰)(1/3)·9 < 1; seven sensors on a stable mode
    # make N = 9 > 8 (the one-sensor maps decide)
    modes = ["3", "1/2"]
    sensors = ([("u0", 0, "2/3 + 10^-40"), ("u1", 0, "2/3")]
               + [(f"v{i}", 1, "1/2") for i in range(7)])
    exact = [(s, k, F(2, 3) + F(1, 10 ** 40) if p.endswith("-40") else F(p))
             for s, k, p in sensors]
    stable, crit = closed_form([F(3), F(1, 2)], exact)
    code, rec = analyze(tmp_path, network_yaml(modes, sensors))
    assert stable and code == 0
    assert rec["network"]["verdict"] == "mean-stable"
    check_critical(rec["network"], crit)


def test_a_report_renders_a_sensor_without_critical_value(tmp_path):
    path = tmp_path / "net.yaml"
    path.write_text(network_yaml(["2", "3"], [("a", 0, "9/10"), ("b", 1, "1/2"),
                                             ("c", 1, "1/2")]))
    out = tmp_path / "r.html"
    res = CliRunner().invoke(main, ["report", str(path), "-o", str(out), "--quick"])
    assert res.exit_code in (0, 5), res.output
    assert "none (no p_i suffices)" in out.read_text()
