"""The analysis record end to end: the papers' cases through ``kfcrit analyze --json``."""
from __future__ import annotations

import json
from pathlib import Path

import pytest
import sympy as sp
from click.testing import CliRunner

import kfcrit
from kfcrit.analysis import CONTRACT_KEYS
from kfcrit.cli import main

from .conftest import REPORTS, SHARED_CASES
from .util import assert_all_finite

EXPECTED = (json.loads((SHARED_CASES / "expected.json").read_text())
            if (SHARED_CASES / "expected.json").exists() else {})
CASES = sorted(k for k in EXPECTED if not k.startswith("_"))


def analyze_json(path: Path, *extra: str) -> tuple[int, dict, str]:
    r = CliRunner().invoke(main, ["analyze", str(path), "--json", *extra])
    return r.exit_code, (json.loads(r.stdout) if r.stdout else {}), r.stdout


@pytest.fixture(scope="module")
def records() -> dict[str, tuple[int, dict, str]]:
    return {name: analyze_json(REPORTS / name, "--quick") for name in CASES}


@pytest.mark.skipif(not CASES, reason="shared/cases/expected.json not beside the repository")
@pytest.mark.parametrize("name", CASES)
def test_paper_cases(name: str, records: dict) -> None:
    code, rec, _ = records[name]
    want = EXPECTED[name]
    assert code == 0
    assert list(rec)[: len(CONTRACT_KEYS)] == list(CONTRACT_KEYS)
    assert rec["classification"] == want["classification"]
    cv = rec["critical_value"]
    pc = sp.Rational(want["critical_value"])
    assert sp.simplify(sp.sympify(cv["expression"]) - pc) == 0
    assert abs(cv["value"] - float(pc)) < 1e-12
    assert cv["exact"] is True
    assert abs(rec["lower_bound"]["value"] - float(sp.Rational(want["lower_bound"]))) < 1e-12
    ub = rec["upper_bound"]
    target = float(sp.Rational(want["upper_bound"])) if "upper_bound" in want \
        else want["upper_bound_approx"]
    tol = 1e-6 if "upper_bound_approx" in want else 1e-8
    lo, hi = ub["interval"]
    assert lo - tol <= target <= hi + tol
    assert ub["certified"] is True
    if "q" in want:
        assert f"q = {want['q']}" in cv["reason"]
    # the margin at the file's operating point against the exact critical value
    op = rec["operating_point"]
    assert abs(op["margin"] - (op["arrival_probability"] - float(pc))) < 1e-12
    assert op["verdict"] == ("mean-stable" if op["arrival_probability"] > float(pc)
                             else "mean-unstable")


@pytest.mark.parametrize("name", CASES)
def test_json_has_no_nan_and_checks_pass(name: str, records: dict) -> None:
    _, rec, text = records[name]
    json.loads(text, parse_constant=lambda c: pytest.fail(f"non-finite {c} in JSON"))
    assert all(c["passed"] is not False for c in rec["verification"]), rec["verification"]
    assert rec["provenance"]["input_sha256"] is not None


def test_same_input_and_seed_give_byte_identical_json() -> None:
    path = REPORTS / "sinopoli-general.yaml"
    _, _, a = analyze_json(path, "--quick", "--seed", "7")
    _, _, b = analyze_json(path, "--quick", "--seed", "7")
    assert a == b


def test_api_matches_cli() -> None:
    spec = kfcrit.load_spec(REPORTS / "rotation-third-turn.yaml")
    cv = kfcrit.critical_value(spec.system).to_dict()
    assert cv["critical_value"]["expression"] == "7/8"  # Mo–Sinopoli Thm 9 with q = 3
    ub = kfcrit.upper_bound(spec.system, tol=1e-7).to_dict()
    lo, hi = ub["interval"]
    assert lo <= 15 / 16 <= hi + 1e-9 and hi - lo <= 1e-7  # expected.json: 15/16
    rec = kfcrit.analyze(spec, simulate=False).to_dict()
    assert rec["simulation"]["skipped"] is True


def write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "s.yaml"
    p.write_text(text)
    return p


def test_stable_system_is_always_mean_stable(tmp_path: Path) -> None:
    code, rec, _ = analyze_json(write(tmp_path, "name: s\nA: [[0.5, 1], [0, 0.9]]\nC: [[1, 0]]\n"
                                      "Q: 1\nR: 1\nchannel: {model: bernoulli, "
                                      "arrival_probability: 0}\n"), "--no-simulate")
    assert code == 0
    assert rec["classification"] == "stable" and rec["critical_value"]["value"] == 0
    assert rec["operating_point"]["verdict"] == "mean-stable"


def test_not_detectable_is_mean_unstable(tmp_path: Path) -> None:
    # the unstable mode 2 is invisible through C = [0, 1]: divergence even with no losses
    code, rec, _ = analyze_json(write(tmp_path, "name: u\nA: [[2, 0], [0, 0.5]]\nC: [[0, 1]]\n"
                                      "Q: 1\nR: 1\nchannel: {model: bernoulli, "
                                      "arrival_probability: 1}\n"), "--no-simulate")
    assert rec["classification"] == "not-detectable"
    assert rec["critical_value"]["value"] is None
    assert rec["operating_point"]["verdict"] == "mean-unstable"
    assert code in (0, 3)


def test_gilbert_elliott_scalar_verdict_follows_burst_condition(tmp_path: Path) -> None:
    # a = 1.25: (1 - r) a^2 < 1 iff r > 1 - 1/1.5625 = 0.36 (MATH §7), whatever f is.
    base = "name: ge\nA: [[1.25]]\nC: [[1]]\nQ: 1\nR: 2.5\n"
    _, bad, _ = analyze_json(write(tmp_path, base + "channel: {model: gilbert-elliott, "
                                   "failure_rate: 0.1, recovery_rate: 0.3}\n"), "--quick")
    # stationary p = 0.75 > p_c = 0.36, yet bursts of mean length 1/0.3 make the mean diverge
    assert bad["operating_point"]["arrival_probability"] == pytest.approx(0.75)
    assert bad["operating_point"]["verdict"] == "mean-unstable"
    _, good, _ = analyze_json(write(tmp_path, base + "channel: {model: gilbert-elliott, "
                                    "failure_rate: 0.8, recovery_rate: 0.4}\n"), "--quick")
    # stationary p = 1/3 < p_c, but bursts are short enough: (1 - 0.4) * 1.5625 = 0.9375 < 1
    assert good["operating_point"]["arrival_probability"] == pytest.approx(1 / 3)
    assert good["operating_point"]["verdict"] == "mean-stable"


def test_terminal_summary_shows_verdict() -> None:
    r = CliRunner().invoke(main, ["analyze", str(REPORTS / "mo-degenerate-diagonal.yaml"),
                                  "--quick"])
    assert r.exit_code == 0
    assert "15/16" in r.stdout and "MEAN-STABLE" in r.stdout
    assert r.stderr == "" or "Traceback" not in r.stderr


def test_record_numbers_are_finite_everywhere(records: dict) -> None:
    for _, rec, _ in records.values():
        assert_all_finite(rec)
