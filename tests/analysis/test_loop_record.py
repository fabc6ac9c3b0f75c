"""The closed-loop section of the record (theory §12), against independently derived answers.

Expected values are derived by hand in the comments (scalar plant a = 5/4: γ_c = ν_c =
1 − 1/a² = 9/25; B = I: ν_c = 1 − 1/ρ(A)²; one input and a scaled rotation: ν_c = 1 − 1/r⁴)
or computed here without kfcrit (the stacked second-moment operator of a fixed design built
from its equations, a closed-loop simulation written in this file).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

import kfcrit
from kfcrit.analysis.spec import spec_from_mapping
from kfcrit.errors import InputError


def loop_doc(gamma="4/5", nu="4/5", **loop) -> dict:
    body = {"B": [[1]], "W": 1, "U": 1,
            "channel": {"model": "bernoulli", "arrival_probability": nu}, **loop}
    return {"name": "scalar loop", "A": [[1.25]], "C": [[1]], "Q": 1, "R": 1,
            "channel": {"model": "bernoulli", "arrival_probability": gamma}, "loop": body}


def analyze(doc: dict, **opts) -> dict:
    opts = {"simulate": False, "quick": True, **opts}
    return kfcrit.analyze(spec_from_mapping(doc, base_dir=Path(".")), **opts).to_dict()


def test_scalar_tcp_thresholds_and_cost() -> None:
    rec = analyze(loop_doc())
    loop = rec["loop"]
    for key in ("sensing_critical", "actuation_critical"):
        assert loop[key]["exact"] and sp.sympify(loop[key]["expression"]) == sp.Rational(9, 25)
    assert loop["design"] == "tcp-optimal" and loop["verdict"] == "mean-square-stable"
    # by hand: S solves 11S² − 25S − 16 = 0 at ν̄ = 4/5; J = S + ν̄ a² S²/(S + 1) lim E[P_t|t],
    # lim E[P_t|t] from a depth-20 tree over arrival histories (P_0 = 0)
    S = (25 + math.sqrt(1329)) / 22
    P, w = np.array([0.0]), np.array([1.0])
    for _ in range(20):
        P = np.concatenate([1.5625 * P + 1, 1.5625 * P / (P + 1) + 1])
        w = np.concatenate([0.2 * w, 0.8 * w])
    Ptt = 0.2 * (w @ P) + 0.8 * (w @ (P / (P + 1)))
    J = S + 0.8 * 1.5625 * S * S / (S + 1) * Ptt
    cost = loop["cost"]
    assert math.isclose(cost["value"], J, rel_tol=2e-4) and abs(J - 5.65894) < 1e-4
    assert cost["lower"] <= cost["value"] <= cost["upper"]
    assert loop["critical_curve"]["points"] == [[0.36, 1.0], [0.36, 0.36], [1.0, 0.36]]
    assert rec["operating_point"]["verdict"] == "mean-stable"


@pytest.mark.parametrize("gamma, nu, loop_v, op_v", [
    ("9/25", "4/5", "mean-square-unstable", "mean-unstable"),
    ("4/5", "9/25", "mean-square-unstable", "mean-unstable"),
    ("4/5", "9/25 + 10^-40", "mean-square-stable", "mean-stable"),
])
def test_thresholds_compared_exactly(gamma: str, nu: str, loop_v: str, op_v: str) -> None:
    rec = analyze(loop_doc(gamma, nu))
    assert rec["loop"]["verdict"] == loop_v
    assert rec["operating_point"]["verdict"] == op_v == rec["loop"]["operating_verdict"]
    assert rec["review"]["decision"] == ("fail" if op_v == "mean-unstable" else "pass")


def test_b_identity_and_single_input_rotation() -> None:
    # B = I: ν_c = 1 − 1/ρ(A)², A = [[1, −1], [1, 1]] has |λ|² = 2: ν_c = 1/2
    doc = {"name": "B = I", "A": [[1, -1], [1, 1]], "C": [[1, 0], [0, 1]], "Q": 1, "R": 1,
           "channel": {"model": "bernoulli", "arrival_probability": 0.9},
           "loop": {"B": [[1, 0], [0, 1]],
                    "channel": {"model": "bernoulli", "arrival_probability": 0.9}}}
    act = analyze(doc)["loop"]["actuation_critical"]
    assert sp.sympify(act["expression"]) == sp.Rational(1, 2) and act["basis"] == "theorem"
    # r = 6/5 times a rotation with cos θ = 3/5, one input: ν_c = 1 − (5/6)⁴ = 671/1296
    r = sp.Rational(6, 5)
    A = [[str(r * sp.Rational(3, 5)), str(-r * sp.Rational(4, 5))],
         [str(r * sp.Rational(4, 5)), str(r * sp.Rational(3, 5))]]
    doc = {"name": "rotation", "A": A, "C": [[1, 0]], "Q": 1, "R": 1,
           "channel": {"model": "bernoulli", "arrival_probability": 0.9},
           "loop": {"B": [[1], [0]], "channel": {"model": "bernoulli",
                                                 "arrival_probability": 0.9}}}
    act = analyze(doc)["loop"]["actuation_critical"]
    assert sp.sympify(act["expression"]) == sp.Rational(671, 1296)
    assert act["interval"][0] - 1e-8 <= 671 / 1296 <= act["interval"][1] + 1e-8


def stacked_radius(a: float, c: float, k: float, l: float, gamma: float, nu: float,
                   acked: bool, hold: bool) -> float:
    """ρ(Σ_m π_m Φ_m ⊗ Φ_m) of a scalar fixed design, built here from its equations:
    x⁺ = a x + b_app, x̂_{t|t} = x̂ + γ k (c x − c x̂), u = l x̂_{t|t}, applied a_t = ν u
    (+ (1 − ν) a_{t−1} with hold); x̂⁺ = a x̂_{t|t} + applied (acknowledged) or its expectation
    ν̄ u (+ (1 − ν̄) â_{t−1}) (UDP-like); state z = (x, x̂[, a][, â])."""
    blocks = []
    for g in (0, 1):
        for v in (0, 1):
            size = 2 + (1 if hold else 0) + (1 if hold and not acked else 0)
            F = np.zeros(size)                       # x̂_{t|t} as a row over z
            F[1] = 1 - g * k * c
            F[0] = g * k * c
            U = l * F
            app = v * U.copy()
            if hold:
                app[2] += 1 - v
            if acked:
                est = app
            else:
                est = nu * U.copy()
                if hold:
                    est[3] += 1 - nu
            Phi = np.zeros((size, size))
            Phi[0] = a * np.eye(size)[0] + app
            Phi[1] = a * F + est
            if hold:
                Phi[2] = app
            if hold and not acked:
                Phi[3] = est
            p = (gamma if g else 1 - gamma) * (nu if v else 1 - nu)
            blocks.append(p * np.kron(Phi, Phi))
    return float(max(abs(np.linalg.eigvals(sum(blocks)))))


@pytest.mark.parametrize("acked, on_loss", [(True, "zero"), (False, "zero"), (True, "hold"),
                                            (False, "hold")])
@pytest.mark.parametrize("nu", ["3/10", "1/2", "9/10"])
def test_fixed_design_radius_against_an_independent_stack(acked: bool, on_loss: str,
                                                          nu: str) -> None:
    doc = loop_doc("9/10", nu, acknowledged=acked, on_loss=on_loss,
                   estimator_gain=[[0.5]], controller_gain=[[-1]])
    loop = analyze(doc)["loop"]
    rho = stacked_radius(1.25, 1.0, 0.5, -1.0, 0.9, float(sp.Rational(nu)), acked,
                         on_loss == "hold")
    assert math.isclose(loop["spectral_radius"], rho, rel_tol=1e-9)
    assert loop["verdict"] == ("mean-square-stable" if rho < 1 else "mean-square-unstable")
    assert loop["stability"]["holds"] is (rho < 1)


def test_perfect_state_feedback_boundary_is_nine_over_25() -> None:
    # γ̄ = 1, K = 1 (x̂_{t|t} = y = x + v), L = −a: the state's second moment grows by
    # (1 − ν̄)a² per step, so the loop is mean-square stable iff ν̄ > 1 − 1/a² = 9/25
    for nu, expect in (("9/25", "mean-square-unstable"), ("37/100", "mean-square-stable")):
        doc = loop_doc("1", nu, estimator_gain=[[1]], controller_gain=[[-1.25]])
        assert analyze(doc)["loop"]["verdict"] == expect


def _simulate_cost(a: float, k: float, l: float, gamma: float, nu: float, paths: int,
                   steps: int, seed: int) -> tuple[float, float]:
    """Scalar acknowledged zero-input loop, simulated here; J = E[x² + a_t²]."""
    rng = np.random.default_rng(seed)
    x = np.zeros(paths)
    xh = np.zeros(paths)
    acc = np.zeros(paths)
    burn = steps // 5
    for t in range(steps):
        g = rng.random(paths) < gamma
        v = rng.random(paths) < nu
        y = x + rng.standard_normal(paths)
        xf = xh + g * k * (y - xh)
        app = v * l * xf
        if t >= burn:
            acc += x * x + app * app
        x = a * x + app + rng.standard_normal(paths)
        xh = a * xf + app
    per = acc / (steps - burn)
    return float(per.mean()), float(per.std(ddof=1) / math.sqrt(paths))


def test_fixed_cost_against_an_independent_simulation() -> None:
    doc = loop_doc("9/10", "4/5", estimator_gain=[[0.6]], controller_gain=[[-1]])
    loop = analyze(doc)["loop"]
    mean, se = _simulate_cost(1.25, 0.6, -1.0, 0.9, 0.8, paths=4000, steps=1500, seed=11)
    assert abs(loop["cost"]["value"] - mean) <= 4 * se
    assert loop["cost"]["finite"] is True


def test_monte_carlo_check_and_cost_requirement() -> None:
    doc = {**loop_doc(), "requirements": {"max_cost": 5}}
    rec = analyze(doc, simulate=True)
    assert rec["loop"]["simulation"]["status"] == "passed"
    check = [c for c in rec["verification"] if c["check"].startswith("closed loop")]
    assert check and check[0]["passed"] is True
    # J ≈ 5.659 > 5: the requirement is not met (its lower bound is below 5, the value above)
    req = [r for r in rec["review"]["reasons"] if "cost" in r["check"]]
    assert req and req[0]["status"] == "fail" and rec["review"]["decision"] == "fail"


def test_udp_default_design_and_comparison_rows() -> None:
    rec = analyze(loop_doc("9/10", "9/10", acknowledged=False), quick=False)
    loop = rec["loop"]
    assert loop["design"] == "fixed" and not loop["acknowledged"]
    names = [r["design"] for r in loop["comparison"]]
    assert names[0] == "TCP-like optimal" and "this design" in names
    tcp = loop["comparison"][0]["cost"]["value"]
    udp = next(r for r in loop["comparison"] if r["design"] == "this design")["cost"]["value"]
    assert tcp <= udp * (1 + 1e-3)        # the optimal acknowledged loop costs no more
    assert {c["link"] for c in loop["cost_curves"]} == {"sensing", "actuation"}


@pytest.mark.parametrize("patch, field", [
    ({"B": {"x": 1}}, "loop.B"),
    ({"B": [["x"]]}, "loop.B[0][0]"),
    ({"B": [[1], [2]]}, "loop.B"),
    ({"W": [[-1]]}, "loop.W"),
    ({"U": 0}, "loop.U"),
    ({"channel": None}, "loop.channel"),
    ({"on_loss": "drop"}, "loop.on_loss"),
    ({"acknowledged": "yes"}, "loop.acknowledged"),
    ({"estimator_gain": [[1]]}, "loop.controller_gain"),
    ({"controller_gain": [[1, 2]], "estimator_gain": [[1]]}, "loop.controller_gain"),
    ({"channel": {"model": "bernoulli", "arrival_probability": 2}},
     "loop.channel.arrival_probability"),
    ({"gain": 1}, "loop.gain"),
])
def test_bad_loop_sections_name_the_field(patch: dict, field: str) -> None:
    doc = loop_doc()
    doc["loop"].update(patch)
    if patch.get("channel", 0) is None:
        del doc["loop"]["channel"]
    with pytest.raises(InputError) as exc:
        spec_from_mapping(doc, base_dir=Path("."))
    assert exc.value.field == field


def test_cost_requirement_needs_a_loop() -> None:
    doc = loop_doc()
    del doc["loop"]
    doc["requirements"] = {"max_cost": 3}
    with pytest.raises(InputError) as exc:
        spec_from_mapping(doc, base_dir=Path("."))
    assert exc.value.field == "requirements.max_cost"
