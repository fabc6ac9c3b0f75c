"""The analysis record end to end: the papers' cases through ``kfcrit analyze --json``."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
import sympy as sp
from click.testing import CliRunner

import kfcrit
from kfcrit.analysis.sections import CONTRACT_KEYS
from kfcrit.cli.main import main

from ..conftest import REPORTS, SHARED_CASES
from ..util import assert_all_finite

EXPECTED = json.loads((SHARED_CASES / "expected.json").read_text())
CASES = sorted(k for k in EXPECTED if not k.startswith("_"))


def analyze_json(path: Path, *extra: str) -> tuple[int, dict, str]:
    r = CliRunner().invoke(main, ["analyze", str(path), "--json", *extra])
    return r.exit_code, (json.loads(r.stdout) if r.stdout else {}), r.stdout


@pytest.fixture(scope="module")
def records(example_records: dict) -> dict[str, tuple[int, dict, str]]:
    """The paper cases' records from the run's shared analyses (``--quick``), with the exit
    code ``kfcrit analyze`` gives them."""
    from kfcrit.analysis.verdict import exit_code

    out = {}
    for name in CASES:
        rec = example_records[name].to_dict()
        out[name] = (exit_code(rec), rec, json.dumps(rec))
    return out


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
    assert rec["review"]["decision"] == "fail"
    assert code == 5   # a determined result: the review fails


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


# --------------------------------------------------------------------------------------------
# audit fixes: near p_c, undetectable systems, trace and Gilbert–Elliott verdicts, text view


def run_cli(path: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "kfcrit", "analyze", str(path), *args],
                          capture_output=True, text=True, timeout=600)


@pytest.mark.parametrize("body", [
    # scalar a = -1.25: p_c = 1 - 1/a^2 = 0.36 (Sinopoli Thm 3 with p_low = p_up); p just above
    "A: [[-1.25]]\nC: [[1]]\nQ: 1\nR: 2.5\n"
    "channel: {model: bernoulli, arrival_probability: 0.3600000001}\n",
    "A: [[-1.25]]\nC: [[1]]\nQ: 1\nR: 2.5\n"
    "channel: {model: bernoulli, arrival_probability: 0.37}\n",
    # one unstable eigenvalue 1.1 (Mo–Sinopoli): p_c = 1 - 1/1.21 ≈ 0.174; strongly non-normal
    # (scipy's Lyapunov solver warns about conditioning) and heavy-tailed at p = 0.2
    "A: [[1.1, 1000], [0, 0.5]]\nC: [[1, 0]]\nQ: 1\nR: 1\n"
    "channel: {model: bernoulli, arrival_probability: 0.2}\n",
], ids=["p_c+1e-10", "p=0.37", "non-normal"])
def test_just_above_pc_monte_carlo_checks_are_inconclusive_not_failed(body: str,
                                                                        tmp_path: Path) -> None:
    path = write(tmp_path, "name: near\n" + body)
    r = run_cli(path, "--json", "--quick")
    assert r.stderr == ""                       # no RuntimeWarning / LinAlgWarning leaks
    assert r.returncode == 0, r.stdout[-2000:]  # no false verification failure
    rec = json.loads(r.stdout)
    assert rec["operating_point"]["verdict"] == "mean-stable"   # p > p_c
    checks = rec["verification"]
    assert not [c for c in checks if c["passed"] is False], checks
    unsure = [c for c in checks if c["status"] == "inconclusive"]
    for c in unsure:
        assert c["passed"] is None and c["reason"]
        assert any(c["check"] in w and "inconclusive" in w for w in rec["warnings"])
    rel = rec["simulation"]["operating_point"]["reliability"]
    assert rel["heavy_tailed"] is True          # (1 - p) rho^4 >= 1 in all three cases


def test_not_detectable_diverges_for_every_p_and_skips_p_up(tmp_path: Path) -> None:
    # eigenvalue 2 has eigenvector e1 and C e1 = 0: P_t ⪰ 4^t (e1 e1') even when every packet
    # arrives, so E[P_t] diverges for all p ∈ [0, 1] (hand: the (1,1) entry obeys x' = 4x + 1)
    path = write(tmp_path, "name: u\nA: [[2, 0], [0, 0.5]]\nC: [[0, 1]]\nQ: 1\nR: 1\n"
                           "channel: {model: bernoulli, arrival_probability: 1}\n")
    r = run_cli(path, "--json", "--quick")
    assert r.returncode == 5 and r.stderr == ""
    rec = json.loads(r.stdout)
    op = rec["operating_point"]
    assert op["verdict"] == "mean-unstable" and op["diverges_for_all_p"] is True
    assert "every arrival probability" in op["reason"] and "p = 1" in op["reason"]
    ub = rec["upper_bound"]
    assert ub["status"] == "not applicable" and ub["value"] is None and "detectable" in ub["reason"]
    assert rec["covariance_bounds"]["upper"]["exists"] is False
    assert rec["static_gain"]["best"]["available"] is False
    assert all(v is None for v in rec["phase_transition"]["trace_upper"])
    assert not [c for c in rec["verification"] if c["passed"] is False]
    text = run_cli(path, "--quick").stdout
    assert "MEAN-UNSTABLE" in text and "every arrival probability" in text
    assert "not applicable" in text


def test_trace_channel_passes_with_confidence(tmp_path: Path) -> None:
    from scipy import stats

    from kfcrit.analysis.record import exit_code

    # "1 1 1 0" repeated: 750 ones in 1000 packets; of the 750 ones (each followed by a value)
    # 250 go to 0, so f̂ = 1/3; the 249 zeros with a successor all recover, r̂ = 1. The LRT
    # rejects i.i.d. losses (every 0 is followed by 1), so the Gilbert–Elliott rectangle
    # decides: its worst r is the Clopper–Pearson lower end for 249 of 249 at level 0.975,
    # (0.0125)^(1/249) ≈ 0.9826 > 1 − 1/a² = 9/25, and for a scalar plant (1 − r)a² < 1 is
    # necessary and sufficient (theory §7): mean-stable with confidence 95 %.
    (tmp_path / "trace.txt").write_text("1 1 1 0\n" * 250)
    path = write(tmp_path, "name: t\nA: [[-1.25]]\nC: [[1]]\nQ: 1\nR: 2.5\n"
                           "channel: {model: trace, path: trace.txt}\n")
    code, rec, _ = analyze_json(path, "--quick")
    op = rec["operating_point"]
    assert op["verdict"] == "mean-stable" and "with confidence 95 %" in op["basis"]
    fit = rec["channel_fit"]
    assert fit["model"] == "gilbert-elliott" and fit["n"] == 1000 and fit["p_hat"] == 0.75
    assert fit["failure_rate_hat"] == pytest.approx(1 / 3) and fit["recovery_rate_hat"] == 1.0
    assert fit["recovery_rate_interval"][0] == pytest.approx(0.0125 ** (1 / 249), rel=1e-9)
    assert fit["failure_rate_interval"][1] == pytest.approx(
        stats.beta.ppf(1 - 0.0125, 251, 500), rel=1e-9)
    assert fit["region"]["outcome"] == "holds" and fit["length_to_decide"] is None
    assert not [c for c in rec["verification"] if c["passed"] is False]
    assert exit_code(rec) == 0 == code
    text = CliRunner().invoke(main, ["analyze", str(path), "--quick"]).stdout
    assert "MEAN-STABLE" in text and "Gilbert–Elliott" in text


def test_cli_exit_code_is_3_for_an_undetermined_verdict(tmp_path: Path) -> None:
    # 19 ones in 50 i.i.d.-looking periods: the 95 % Clopper–Pearson interval of p,
    # [B⁻¹(0.025; 19, 32), B⁻¹(0.975; 20, 31)] ≈ [0.2465, 0.5283], contains p_c = 9/25
    (tmp_path / "trace.txt").write_text("01110000000101010010110001000001100100010101101010\n")
    path = write(tmp_path, "name: t\nA: [[-1.25]]\nC: [[1]]\nQ: 1\nR: 2.5\n"
                           "channel: {model: trace, path: trace.txt}\n")
    assert analyze_json(path, "--quick", "--no-simulate")[0] == 3


@pytest.mark.parametrize("sufficient, recovery, want", [
    # A = -5/4: p_low = 1 - 16/25 = 9/25; the burst condition (1 - r)(25/16) < 1 <=> r > 9/25
    (True, sp.Rational(1, 2), "mean-stable"),       # (1/2)(25/16) = 25/32 < 1, proven
    (None, sp.Rational(1, 2), "undetermined"),      # necessary holds, nothing sufficient shown
    (True, sp.Rational(9, 25), "mean-unstable"),    # (16/25)(25/16) = 1: bursts diverge
    (None, sp.Rational(1, 10), "mean-unstable"),    # (9/10)(25/16) = 45/32 > 1
])
def test_burst_verdict_from_the_verdict_module(sufficient: bool | None, recovery: sp.Rational,
                                                want: str) -> None:
    from kfcrit.analysis import verdict as vd

    crit = vd.CriticalInputs(classification="non-degenerate", critical=0.36,
                             critical_exact=sp.Rational(9, 25), lower=0.36, p_low=0.36,
                             p_low_exact=sp.Rational(9, 25))
    burst = vd.BurstInputs(recovery=recovery, failure=sp.Rational(1, 10),
                           sufficient=sufficient, basis="hand")
    verdict, basis = vd.operating_verdict(sp.Rational(1, 2), crit, iid=False, burst=burst)
    assert verdict.value == want and basis


def test_gilbert_elliott_non_scalar_is_decided_by_the_coupled_certificate(tmp_path: Path
                                                                         ) -> None:
    # two unstable distinct moduli, non-degenerate: (1 - r) rho^2 < 1 alone is only the
    # literature's claim (f + r != 1: a genuinely bursty chain); the coupled fixed-gain
    # certificate of MATH §10 proves stability (checked in ball arithmetic)
    code, rec, _ = analyze_json(write(tmp_path, "name: ge2\nA: [[1.25, 0], [1, 1.1]]\n"
                                      "C: [[1, 1]]\nQ: 20\nR: 2.5\nchannel: {model: "
                                      "gilbert-elliott, failure_rate: 0.1, recovery_rate: 0.8}\n"),
                                "--no-simulate")
    cond = rec["link_budget"]["condition"]
    assert cond["decides"] is False and cond["holds"] is True   # (0.2)(1.5625) < 1
    assert rec["operating_point"]["verdict"] == "mean-stable"
    assert "coupled fixed-gain certificate" in rec["operating_point"]["basis"]
    cert = rec["link_budget"]["certificate"]
    assert cert["certificate"]["certified"] is True
    assert "claim" in cert["claim"]["label"]                     # the literature stays labelled
    assert code == 0


def test_terminal_summary_shows_link_design_outputs() -> None:
    r = CliRunner().invoke(main, ["analyze", str(REPORTS / "link-oqpsk-sensor.yaml"),
                                  "--no-simulate"])
    rec = kfcrit.analyze(kfcrit.load_spec(REPORTS / "link-oqpsk-sensor.yaml"),
                         simulate=False).to_dict()
    lb, dc = rec["link_budget"], rec["link_budget"]["design_check"]
    text = r.stdout
    # the configured 105 m exceeds the 81 m allowed by the 5.1 dB effective margin policy
    assert dc["margin_policy_met"] is False and "margin policy         NOT met" in text
    assert f"{dc['required_margin_db']:.4g} dB" in text
    assert "outage probability" in text and f"{dc['outage_probability']:.4g}" in text
    assert "EXCEEDED" in text
    assert "shadowing-averaged p" in text
    assert f"{lb['shadowing']['mean_arrival_probability']:.6g}" in text
    assert "required SINR" in text and f"{lb['required_sinr_db']:.6g}" in text
    assert "max distance" in text and f"{lb['max_distance_m']:.6g}" in text


@pytest.mark.parametrize("name, verdict", [("ge-bursty-scalar.yaml", "mean-unstable"),
                                           ("requirements-tail.yaml", "mean-stable")])
def test_new_examples_verdicts_follow_the_hand_derivation(name: str, verdict: str) -> None:
    # ge-bursty-scalar: (1 - r) a^2 = 0.9 * 25/16 = 45/32 > 1 (MATH §7), although r/(f+r) = 2/3
    # requirements-tail: p = 0.8 > p_c = 9/25; P(P > 20) >= (1 - p)^4 = 0.0016 (four losses
    # from P* ≈ 3.19 reach f_0^4(P*) ≈ 27.8 > 20)
    code, rec, _ = analyze_json(REPORTS / name, "--quick")
    # --quick: 300 paths cannot demonstrate the tail requirement (below), so its review is
    # undetermined (exit 3); the bursty link fails its review (exit 5)
    assert code == (5 if verdict == "mean-unstable" else 3)
    assert rec["operating_point"]["verdict"] == verdict
    if name.startswith("ge"):
        assert rec["link_budget"]["condition"]["value"] == pytest.approx(45 / 32)
        assert rec["link_budget"]["condition"]["decides"] is True
        # the simulation check must be able to see the growth for the shipped example
        assert rec["link_budget"]["simulation_consistent"] is True
    else:
        req = rec["requirements"]
        assert {k: req[k] for k in ("max_error_trace", "max_tail_probability")} == {
            "max_error_trace": 20.0, "max_tail_probability": 0.01}
        # 300 quick paths cannot show a probability ≈ 0.0025 below 0.01: the Wilson upper end
        # exceeds 0.01 for k ≤ 2, and k ≥ 8 would be needed to refute it
        assert req["assessment"]["status"] == "not demonstrated"
        assert rec["review"]["decision"] == "undetermined"
        ex = rec["simulation"]["operating_point"]["exceedance"]
        assert ex["level"] == 20.0 and ex["upper"] >= 0.2**4 * 0.5
        assert ex["estimate"] < 0.01


def test_undecided_p_up_width_does_not_undo_a_decided_verdict(tmp_path: Path) -> None:
    """Jordan block at λ = 1 observed by C = [1 0]: p_low = 0 and every p > 0 has a certificate
    (polynomial growth over geometric loss bursts), so p_up's bracket is [0, ε] with ε not
    reachable at 1e-9. At p = 1/2 the verdict is nonetheless decided (p > certified upper end):
    exit 0; without an operating point the undecided bracket is exit 3."""
    body = "name: j\nA: [[1, 1], [0, 1]]\nC: [[1, 0]]\nQ: 1\nR: 1\n"
    with_p = write(tmp_path, body + "channel: {model: bernoulli, arrival_probability: 0.5}\n")
    res = CliRunner().invoke(main, ["analyze", str(with_p), "--quick", "--json"])
    rec = json.loads(res.stdout)
    lo, hi = rec["upper_bound"]["interval"]
    assert lo == 0 and 0 < hi < 0.5 and rec["upper_bound"]["certified"]
    assert rec["operating_point"]["verdict"] == "mean-stable"
    assert res.exit_code == 0
    bare = tmp_path / "bare.yaml"
    bare.write_text(body)
    res = CliRunner().invoke(main, ["analyze", str(bare), "--quick", "--json"])
    if json.loads(res.stdout)["upper_bound"]["status"] == "undetermined":
        assert res.exit_code == 3
    else:
        assert res.exit_code == 0


def test_requirement_assessment_reads_the_wilson_interval() -> None:
    """met iff the interval's upper end ≤ allowed; not met iff its lower end > allowed; else
    not demonstrated. Wilson interval for 0 of 300 at 95 %: [0, z²/(N + z²)] = [0, 0.01264]."""
    from kfcrit.analysis.requirements import requirement_assessment, tail_assessment
    from kfcrit.records.simulation import Exceedance
    from kfcrit.sim.stats import proportion

    def tail(k, n):
        return tail_assessment(20.0, 0.01, Exceedance(level=20.0, **proportion(k, n)), 200)

    zero = proportion(0, 300)
    z2 = 1.959963984540054 ** 2
    assert zero["lower"] == 0.0 and zero["upper"] == pytest.approx(z2 / (300 + z2), rel=1e-9)
    assert tail(0, 300).status == "not demonstrated"
    assert tail(5, 2000).status == "met"
    assert tail(60, 2000).status == "not met"
    assert "5 of 2000 paths" in tail(5, 2000).basis
    req = {"max_error_trace": 20.0, "max_tail_probability": 0.01}
    assert requirement_assessment(req, None).assessment.status is None
    assert requirement_assessment({}, None) is None


def test_undetectable_system_text_view(tmp_path: Path) -> None:
    """A = diag(2, 1/2), C = [0 1]: the mode 2 is unobserved, so E[P] diverges for every p
    (PBH); verdict mean-unstable with exit 5 (review fails), p_up not applicable, no 'None' in
    the text."""
    path = write(tmp_path, "name: u\nA: [[2, 0], [0, 0.5]]\nC: [[0, 1]]\nQ: 1\nR: 1\n"
                           "channel: {model: bernoulli, arrival_probability: 0.9}\n")
    res = CliRunner().invoke(main, ["analyze", str(path), "--quick", "--no-simulate"])
    assert res.exit_code == 5
    assert "not-detectable" in res.stdout and "MEAN-UNSTABLE" in res.stdout
    assert "not applicable" in res.stdout and "None" not in res.stdout


def test_stable_but_near_undetectable_is_undetermined(tmp_path: Path) -> None:
    # λ = 1 − 1e-12 is unobservable through C = [0, 1]: as entered the system is stable
    # (p_c = 0), but moving λ by 1e-12 < tol·‖A‖ = 1e-9 puts an unobservable mode on the unit
    # circle, which no arrival probability fixes: the verdict at p = 0.9 cannot be decided.
    code, rec, _ = analyze_json(write(tmp_path, "name: s\nA: [[0.999999999999, 0], [0, 0.5]]\n"
                                      "C: [[0, 1]]\nQ: 1\nR: 1\nchannel: {model: bernoulli, "
                                      "arrival_probability: 0.9}\n"), "--no-simulate")
    assert rec["classification"] == "stable" and rec["critical_value"]["value"] == 0
    assert rec["operating_point"]["verdict"] == "undetermined" and code == 3
    assert rec["operating_point"]["margin"] == pytest.approx(0.9)
    assert rec["operating_point"]["margin_robust"] <= 0
