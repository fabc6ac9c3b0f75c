"""One verdict per record: every verdict that describes the operating point agrees.

A record states the stability of its operating point in several places (the operating point,
the network section of a ``sensors:`` file, a bursty link's certificate, the review's
stability reason, a sweep row). They must all say the same thing, including at exact
thresholds where a float comparison would flip (p = p_c + 10⁻⁴⁰). Expected verdicts here are
derived by hand from the closed forms (Sinopoli's general plant: p_c = 9/25; a scalar plant a
seen by independent sensors: stable iff Π(1 − p_i)·a² < 1; a bursty link: unstable when
(1 − r)ρ(A)² ≥ 1).
"""
from __future__ import annotations

from fractions import Fraction
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import kfcrit
from kfcrit.analysis.spec import spec_from_mapping

REPORTS = Path(__file__).resolve().parents[2] / "reports"
GENERAL = {"A": [[1.25, 0], [1, 1.1]], "Q": [[20, 0], [0, 20]]}
STATUS = {"mean-stable": "pass", "mean-unstable": "fail", "undetermined": "undetermined"}


def operating_verdicts(record: dict) -> list[tuple[str, str]]:
    """Every (path, verdict) of the record that describes the operating point."""
    out = []
    op = record.get("operating_point") or {}
    if op.get("verdict"):
        out.append(("operating_point", op["verdict"]))
    net = record.get("network") or {}
    if net.get("verdict"):
        out.append(("network", net["verdict"]))
    mesh = record.get("mesh") or {}
    if mesh.get("verdict"):   # raw forwarding: the mesh file's operating point
        out.append(("mesh", mesh["verdict"]))
    link = record.get("link_budget")
    if isinstance(link, dict):
        for name, holder in (("link_budget", link), ("link_budget.bursty", link.get("bursty"))):
            cert = (holder or {}).get("certificate") if isinstance(holder, dict) else None
            if isinstance(cert, dict) and cert.get("verdict"):
                out.append((name + ".certificate", cert["verdict"]))
    loop = record.get("loop")
    if isinstance(loop, dict):
        # the loop's own verdict is mean-square stability of the closed loop; the operating
        # point's is estimator AND loop (README "Closed loops"): the loop's stamped copy must
        # equal it, an unstable loop makes it mean-unstable, and mean-stable needs a stable loop
        out.append(("loop.operating_verdict", loop["operating_verdict"]))
        if loop["verdict"] == "mean-square-unstable":
            out.append(("loop.verdict (unstable loop)", "mean-unstable"))
        elif op.get("verdict") == "mean-stable":
            assert loop["verdict"] == "mean-square-stable", loop["verdict"]
    return out


def mean_facts(record: dict) -> list[tuple[str, str]]:
    """Every other statement of the record about E[P_t] at the operating point, as the
    verdict it implies: the mean exists (stable) or not (unstable); S̄ ⪯ lim E[P_t] not
    existing, or a divergence warning, implies unstable."""
    out = []
    sim_op = (record.get("simulation") or {}).get("operating_point") or {}
    if sim_op.get("mean_exists") is not None:
        out.append(("simulation.mean_exists",
                    "mean-stable" if sim_op["mean_exists"] else "mean-unstable"))
    cb = record.get("covariance_bounds") or {}
    # a channel with memory states S̄, V̄ as an i.i.d. comparison (applicable False): they
    # bound nothing of its mean there, the Markov-jump bounds do
    bounds = [] if cb.get("applicable") is False else [("covariance_bounds.lower",
                                                        cb.get("lower"))]
    for path, bound in bounds + [("covariance_bounds.markov_jump.lower",
                                  (cb.get("markov_jump") or {}).get("lower"))]:
        if isinstance(bound, dict) and bound.get("exists") is False:
            out.append((path, "mean-unstable"))
    # V̄ ⪰ lim E[P_t] bounds the estimator's mean; a closed loop's verdict also needs the loop
    upper = cb.get("upper") if cb.get("applicable") is not False and not record.get("loop") \
        else None
    if isinstance(upper, dict) and upper.get("exists") is True:
        out.append(("covariance_bounds.upper", "mean-stable"))
    if any("diverges at this operating point" in w for w in record.get("warnings") or []):
        out.append(("warnings", "mean-unstable"))
    return out


def assert_one_verdict(record: dict) -> str | None:
    found = operating_verdicts(record) + mean_facts(record)
    verdicts = {v for _, v in found}
    assert len(verdicts) <= 1, f"verdicts disagree: {found}"
    if not found:
        return None
    verdict = verdicts.pop()
    stability = next(r for r in record["review"]["reasons"]
                     if r["check"] == "stability at the operating point")
    assert stability["status"] == STATUS[verdict]
    if verdict == "mean-unstable":
        assert record["review"]["decision"] == "fail"
    return verdict


def analyze_doc(doc: dict) -> dict:
    spec = spec_from_mapping(doc, base_dir=Path("."))
    return kfcrit.analyze(spec, simulate=False, quick=True).to_dict()


@pytest.mark.parametrize("path", sorted(p for p in REPORTS.glob("*.yaml")
                                        if "sweep" not in p.name), ids=lambda p: p.stem)
def test_every_shipped_example_has_one_verdict(path: Path) -> None:
    record = kfcrit.analyze(kfcrit.load_spec(path), simulate=False, quick=True).to_dict()
    assert_one_verdict(record)


@pytest.mark.parametrize("p, expected", [
    ("9/25 + 10^-40", "mean-stable"), ("9/25", "mean-unstable"),
    ("9/25 - 10^-40", "mean-unstable"), ("1/2", "mean-stable")])
def test_one_sensor_network_at_the_threshold(p: str, expected: str) -> None:
    doc = {"name": "probe", **GENERAL, "sensors": [
        {"name": "s1", "C": [[1, 1]], "R": 2.5,
         "channel": {"model": "bernoulli", "arrival_probability": p}}]}
    record = analyze_doc(doc)
    assert assert_one_verdict(record) == expected
    net = record["network"]
    assert net["verdict"] == expected
    # every margin of the block has the verdict's sign (p − 9/25 exactly: ±10⁻⁴⁰, not 0)
    margins = [net["uniform_margin"]["value"], net["sensors"][0]["margin"]["value"],
               net["bottleneck"]["margin"], record["operating_point"]["margin"]]
    assert all((m > 0) == (expected == "mean-stable") for m in margins), margins
    assert net["facts"]["exact_region"] == net["exact_region"]["holds"]


@pytest.mark.parametrize("p2, expected", [
    ("1/2 + 10^-40", "mean-stable"), ("1/2", "mean-unstable"),
    ("1/2 - 10^-40", "mean-unstable")])
def test_two_sensor_network_at_the_threshold(p2: str, expected: str) -> None:
    """a = 2 seen by two sensors: stable iff (1 − p₁)(1 − p₂)·4 < 1, at p₁ = 1/2 iff p₂ > 1/2;
    S̄ exists exactly then, although 1 − 2·10⁻⁴⁰ rounds to 1."""
    doc = {"name": "two", "A": [[2]], "Q": 1, "sensors": [
        {"name": "s1", "C": [[1]], "R": 1,
         "channel": {"model": "bernoulli", "arrival_probability": "1/2"}},
        {"name": "s2", "C": [[1]], "R": 1,
         "channel": {"model": "bernoulli", "arrival_probability": p2}}]}
    record = analyze_doc(doc)
    assert assert_one_verdict(record) == expected
    assert record["covariance_bounds"]["lower"]["exists"] is (expected == "mean-stable")


@pytest.mark.parametrize("r, expected", [
    ("9/25 + 10^-40", None), ("9/25", "mean-unstable"), ("1/5", "mean-unstable")])
def test_bursty_link_at_the_burst_threshold(r: str, expected: str | None) -> None:
    """(1 − r)·ρ(A)² with ρ(A) = 5/4 equals 1 at r = 9/25: unstable there and below."""
    doc = {"name": "probe", **GENERAL, "C": [[1, 1]], "R": [[2.5]],
           "channel": {"model": "gilbert-elliott", "failure_rate": "1/10", "recovery_rate": r}}
    record = analyze_doc(doc)
    verdict = assert_one_verdict(record)
    if expected is not None:
        assert verdict == expected
    else:
        assert verdict != "mean-unstable"


def operating_margins(record: dict) -> list[tuple[str, float]]:
    """Every margin of the record that measures the operating point against its stability
    boundary (the labelled i.i.d. comparisons ``iid_*`` are not margins of a bursty link)."""
    out = []
    op = record.get("operating_point") or {}
    for key in ("margin", "margin_robust"):
        out.append((f"operating_point.{key}", op.get(key)))
    net = record.get("network") or {}
    um = net.get("uniform_margin") or {}
    bn = net.get("bottleneck") or {}
    out += [("network.uniform_margin.value", um.get("value")),
            ("network.bottleneck.margin", bn.get("margin"))]
    out += [(f"network.uniform_margin.interval[{i}]", v)
            for i, v in enumerate(um.get("interval") or [])]
    out += [(f"network.bottleneck.margin_interval[{i}]", v)
            for i, v in enumerate(bn.get("margin_interval") or [])]
    for row in net.get("sensors") or []:
        m = row.get("margin") or {}
        out.append((f"network.sensors.{row['name']}.margin.value", m.get("value")))
        out += [(f"network.sensors.{row['name']}.margin.interval[{i}]", v)
                for i, v in enumerate(m.get("interval") or [])]
    return [(path, v) for path, v in out if v is not None]


ONE_BURSTY = {"name": "one gauge", "A": [["-5/4"]], "Q": 1, "sensors": [
    {"name": "gauge", "C": [[1]], "R": 2.5,
     "channel": {"model": "gilbert-elliott", "failure_rate": "1/20", "recovery_rate": "1/10"}}]}


@pytest.mark.parametrize("A, C, r, expected", [
    ([["-5/4"]], [[1]], Fraction(1, 10), "mean-unstable"),
    ([["-5/4"]], [[1]], Fraction(1, 2), "mean-stable"),
    (GENERAL["A"], [[1, 1]], Fraction(1, 5), "mean-unstable")])
def test_one_sensor_network_over_a_bursty_link(A, C, r, expected) -> None:
    """A one-sensor network is its one link: over a Gilbert–Elliott link with ρ(A) = 5/4 the
    burst condition (1 − r)·25/16 < 1 decides (necessary for any plant, and sufficient for a
    scalar one, theory §7, §10): r = 1/10 gives 45/32, r = 1/5 gives 5/4 (unstable), r = 1/2
    gives 25/32 (stable). Every verdict of the record agrees, and every margin is the link's
    r − r_nec, r_nec = 1 − 16/25 = 9/25, with the verdict's sign (by hand)."""
    doc = {**ONE_BURSTY, "A": A, "sensors": [
        {**ONE_BURSTY["sensors"][0], "C": C,
         "channel": {**ONE_BURSTY["sensors"][0]["channel"], "recovery_rate": str(r)}}]}
    if len(A) > 1:
        doc["Q"] = GENERAL["Q"]
    record = analyze_doc(doc)
    assert assert_one_verdict(record) == expected
    net = record["network"]
    assert net["verdict"] == expected
    facts = net["facts"]
    assert (facts["necessary"] is False) == (expected == "mean-unstable")
    assert facts["sufficient"] is (expected == "mean-stable")
    assert net["certificate"] is None   # the i.i.d. certificate proves nothing for bursts
    margins = operating_margins(record)
    assert len(margins) >= 6
    for path, value in margins:
        assert value == pytest.approx(float(r - Fraction(9, 25)), abs=1e-12), path
        assert (value > 0) is (expected == "mean-stable"), path


fractions = st.fractions(min_value=Fraction(1, 20), max_value=Fraction(19, 20),
                         max_denominator=20)


@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(a=st.sampled_from([Fraction(5, 4), Fraction(3, 2), Fraction(2), Fraction(5, 2)]),
       ps=st.lists(fractions, min_size=1, max_size=3))
def test_scalar_plant_behind_independent_sensors(a: Fraction, ps: list[Fraction]) -> None:
    """Scalar plant a seen by every sensor: mean-stable iff Π(1 − p_i)·a² < 1 (theory §9)."""
    doc = {"name": "scalar", "A": [[str(a)]], "Q": [[1]], "sensors": [
        {"name": f"s{i}", "C": [[1]], "R": 1,
         "channel": {"model": "bernoulli", "arrival_probability": str(p)}}
        for i, p in enumerate(ps)]}
    record = analyze_doc(doc)
    lost = Fraction(1)
    for p in ps:
        lost *= 1 - p
    expected = "mean-stable" if lost * a * a < 1 else "mean-unstable"
    assert assert_one_verdict(record) == expected


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(f=fractions, r=fractions)
def test_generated_bursty_links_have_one_verdict(f: Fraction, r: Fraction) -> None:
    doc = {"name": "bursty", **GENERAL, "C": [[1, 1]], "R": [[2.5]],
           "channel": {"model": "gilbert-elliott", "failure_rate": str(f),
                       "recovery_rate": str(r)}}
    verdict = assert_one_verdict(analyze_doc(doc))
    if (1 - r) * Fraction(25, 16) >= 1:
        assert verdict == "mean-unstable"


@pytest.mark.parametrize("gamma, nu, expected", [
    ("9/25 + 10^-40", "4/5", "mean-stable"), ("9/25", "4/5", "mean-unstable"),
    ("4/5", "9/25", "mean-unstable"), ("4/5", "9/25 + 10^-40", "mean-stable")])
def test_closed_loop_at_its_thresholds(gamma: str, nu: str, expected: str) -> None:
    # scalar a = 5/4, b = c = 1, TCP-like: γ_c = ν_c = 1 − 1/a² = 9/25 (by hand); the
    # operating point is mean-stable iff γ̄ > 9/25 and ν̄ > 9/25
    doc = {"name": "loop", "A": [[1.25]], "C": [[1]], "Q": 1, "R": 1,
           "channel": {"model": "bernoulli", "arrival_probability": gamma},
           "loop": {"B": [[1]], "channel": {"model": "bernoulli",
                                            "arrival_probability": nu}}}
    assert assert_one_verdict(analyze_doc(doc)) == expected


def analyze_simulated(doc: dict) -> dict:
    spec = spec_from_mapping(doc, base_dir=Path("."))
    return kfcrit.analyze(spec, quick=True).to_dict()


@pytest.mark.parametrize("p, expected", [
    ("9/25 + 10^-40", "mean-stable"), ("9/25", "mean-unstable"),
    ("9/25 - 10^-40", "mean-unstable")])
def test_simulated_record_at_the_threshold_has_one_verdict(p: str, expected: str) -> None:
    """With the Monte Carlo, the bounds and the tail exponent: p_c = 1 − 1/a² = 9/25 for
    a = 5/4 (by hand), and every section that states whether E[P_t] exists agrees with it,
    although p rounds to 9/25 in float64."""
    doc = {"name": "probe", "A": [[1.25]], "C": [[1]], "Q": 1, "R": 2.5,
           "channel": {"model": "bernoulli", "arrival_probability": p}}
    record = analyze_simulated(doc)
    assert assert_one_verdict(record) == expected
    finite = record["tail"]["exponent"]["finite_mean"]   # β > 1 iff (1 − p)a² < 1
    assert finite is (expected == "mean-stable")


@pytest.mark.parametrize("r, expected", [
    ("9/25 + 10^-40", "mean-stable"), ("9/25", "mean-unstable"),
    ("9/25 - 10^-40", "mean-unstable")])
def test_scalar_bursty_link_at_the_threshold(r: str, expected: str) -> None:
    """Scalar theorem (theory §7): n = 1, c ≠ 0, E[P_t] bounded iff (1 − r)a² < 1; a = −5/4
    gives the threshold r = 9/25 (by hand)."""
    doc = {"name": "ge", "A": [[-1.25]], "C": [[1]], "Q": 1, "R": 2.5,
           "channel": {"model": "gilbert-elliott", "failure_rate": "1/20",
                       "recovery_rate": r}}
    record = analyze_simulated(doc)
    assert assert_one_verdict(record) == expected
    assert record["link_budget"]["condition"]["holds"] is (expected == "mean-stable")
    assert record["review"]["decision"] == STATUS[expected]


def test_bursty_link_on_a_general_plant_just_above_the_burst_threshold() -> None:
    """(1 − r)ρ(A)² = 1 − 1.5625·10⁻⁴⁰ < 1 (ρ(A) = 5/4, by hand): the necessary condition holds,
    nothing proves more, so the verdict is undetermined — and no section may call E[P_t]
    unbounded on a float comparison that rounds (1 − r)ρ(A)² to 1."""
    doc = {"name": "ge general", **GENERAL, "C": [[1, 1]], "R": [[2.5]],
           "channel": {"model": "gilbert-elliott", "failure_rate": "1/20",
                       "recovery_rate": "9/25 + 10^-40"}}
    record = analyze_simulated(doc)
    assert assert_one_verdict(record) != "mean-unstable"
    assert record["link_budget"]["certificate"]["facts"]["necessary"] is True


def test_upper_covariance_bound_exists_just_above_an_exact_p_up() -> None:
    """Scalar plant (C invertible): p_up = p_c = 1 − 1/a² = 9/25 exactly (Sinopoli Section IV),
    so V̄ exists at p = 9/25 + 10⁻⁴⁰ although p rounds onto 9/25 in float64."""
    doc = {"name": "probe", "A": [[1.25]], "C": [[1]], "Q": 1, "R": 2.5,
           "channel": {"model": "bernoulli", "arrival_probability": "9/25 + 10^-40"}}
    cb = analyze_simulated(doc)["covariance_bounds"]
    assert cb["upper"]["exists"] is True and cb["lower"]["exists"] is True


def test_iid_bounds_of_a_bursty_link_are_labelled_a_comparison() -> None:
    """ge-bursty-scalar is mean-unstable (r = 1/10 < r_nec = 9/25, by hand): its S̄ and V̄ at
    the stationary p exist, so they are stated as an i.i.d. comparison, not as bounds."""
    record = kfcrit.analyze(kfcrit.load_spec(REPORTS / "ge-bursty-scalar.yaml"),
                            simulate=False, quick=True).to_dict()
    assert assert_one_verdict(record) == "mean-unstable"
    cb = record["covariance_bounds"]
    assert cb["applicable"] is False and "i.i.d. comparison" in cb["reason"]
