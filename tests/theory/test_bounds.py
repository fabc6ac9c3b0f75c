"""Covariance bounds S̄ ⪯ V̄, the phase transition and static gains (kfcrit.theory.covariance.bounds).

Expected values: hand derivations for scalar systems, residuals of the defining equations, and
independent methods — the MARE iteration against Newton–Kleinman, and both against the SDP of
Sinopoli Thm 6(b) *with Q* (MATH.md §3 flags the printed version, which omits Q, as a misprint).
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from kfcrit.io.typed import to_json
from kfcrit.model.system import System
from kfcrit.records.covariance import Markers
from kfcrit.theory.covariance import bounds
from kfcrit.theory.covariance.riccati import g


def scalar(a: float, q: float = 1.0, r: float = 1.0) -> System:
    return System([[a]], [[1.0]], [[q]], [[r]])


GENERAL = System([["5/4", 0], [1, "11/10"]], [[1, 1]], [[20, 0], [0, 20]], [["5/2"]])


def mare_scalar(a: float, q: float, r: float, p: float) -> float:
    """Positive root of V = a²V + q − p a² V²/(V + r) (c = 1), by hand:
    (1 − a² + p a²) V² + (r − a² r − q) V − q r = 0."""
    A2 = a * a
    qa, qb, qc = 1 - A2 + p * A2, r - A2 * r - q, -q * r
    return (-qb + math.sqrt(qb * qb - 4 * qa * qc)) / (2 * qa)


def test_lower_covariance_scalar_hand_derivation():
    # S = (1−p) a² S + q  ⇒  S = q / (1 − (1−p) a²), exists iff (1−p) a² < 1
    S = bounds.lower_covariance(np.array([[2.0]]), np.array([[1.0]]), 0.8)
    assert S[0, 0] == pytest.approx(1 / (1 - 0.2 * 4))
    assert bounds.lower_covariance(np.array([[2.0]]), np.array([[1.0]]), 0.75) is None
    assert bounds.lower_covariance(np.array([[2.0]]), np.array([[1.0]]), 0.7) is None


@pytest.mark.parametrize("a, p", [(2.0, 0.8), (-1.25, 0.5), (1.5, 0.9), (0.5, 0.2)])
def test_upper_covariance_scalar_hand_derivation(a, p):
    d = bounds.covariance_bounds(scalar(a), p)
    assert d["upper"]["exists"]
    assert d["upper"]["trace"] == pytest.approx(mare_scalar(a, 1.0, 1.0, p), rel=1e-10)
    assert d["upper"]["residual"] < 1e-12


def test_newton_and_iteration_agree_and_solve_the_mare():
    s = GENERAL
    A, C, Q, R = s.a, s.c, s.q, s.r
    for p in (0.5, 0.6, 0.9):
        Vi, its = bounds.mare_iteration(A, C, Q, R, p)
        res = bounds.upper_covariance(s, p)
        Vn = res["V"]
        assert Vi is not None and Vn is not None and its > 1
        assert res["method"].startswith("newton")
        assert np.linalg.norm(Vn - Vi) <= 1e-9 * np.linalg.norm(Vn)
        assert np.linalg.norm(g(A, C, Q, R, Vn, p) - Vn) <= 1e-12 * np.linalg.norm(Vn)


@pytest.mark.parametrize("system, p", [(GENERAL, 0.6), (scalar(-1.25, 1.0, 2.5), 0.5),
                                       (System([[2, 0], [0, -2]], [[1, 1]], [[1, 0], [0, 1]],
                                               [[1]]), 0.97)])
def test_v_bar_matches_corrected_thm6b_sdp_with_q(system, p):
    cp = pytest.importorskip("cvxpy")
    A, C, Q, R = system.a, system.c, system.q, system.r
    n = system.n
    V = cp.Variable((n, n), symmetric=True)
    M = cp.bmat([[A @ V @ A.T + Q - V, np.sqrt(p) * A @ V @ C.T],
                 [np.sqrt(p) * C @ V @ A.T, C @ V @ C.T + R]])
    prob = cp.Problem(cp.Maximize(cp.trace(V)), [(M + M.T) / 2 >> 0, V >> 0])
    prob.solve(solver="CLARABEL")
    assert prob.status == cp.OPTIMAL
    d = bounds.covariance_bounds(system, p)
    assert d["upper"]["trace"] == pytest.approx(prob.value, rel=1e-5)
    assert np.allclose(np.array(d["upper"]["matrix"]), V.value, rtol=1e-4,
                       atol=1e-5 * abs(prob.value))


@pytest.mark.parametrize("p", [0.5, 0.6, 0.8, 0.99])
def test_lower_below_upper(p):
    d = bounds.covariance_bounds(GENERAL, p)
    assert d["lower"]["exists"] and d["upper"]["exists"]
    assert d["ordered"] is True
    S, V = np.array(d["lower"]["matrix"]), np.array(d["upper"]["matrix"])
    assert np.linalg.eigvalsh(V - S).min() >= -1e-9 * np.linalg.norm(V)
    assert d["lower"]["trace"] <= d["upper"]["trace"]
    json.dumps(d, allow_nan=False)


def test_bounds_absent_below_thresholds():
    d = bounds.covariance_bounds(GENERAL, 0.3)           # below p_low = 9/25
    assert not d["lower"]["exists"] and not d["upper"]["exists"] and d["ordered"] is None
    d = bounds.covariance_bounds(GENERAL, 0.4)           # p_low < 0.4 < p_up = 57/121
    assert d["lower"]["exists"] and not d["upper"]["exists"]
    assert set(d) == {"p", "lower", "upper", "ordered", "warnings"} and d["warnings"] == []
    assert set(d["upper"]) == {"exists", "trace", "max_eig", "matrix", "residual", "method",
                               "iterations"}
    json.dumps(d, allow_nan=False)


def test_phase_transition_resolves_both_blow_ups():
    out = to_json(bounds.phase_transition(
        GENERAL, Markers(p_low=None, p_c=None, p_up=None, operating=0.6), points=60))
    p = np.array(out["p"])
    assert np.all(np.diff(p) > 0) and p[0] == 0.0 and p[-1] == 1.0
    p_low, p_up = 9 / 25, 57 / 121
    assert out["markers"]["operating"] == 0.6
    assert out["markers"]["p_up"] == pytest.approx(p_up, abs=1e-9)
    assert np.min(np.abs(p[p > p_low] - p_low)) < 1e-5
    assert np.min(np.abs(p[p > p_up] - p_up)) < 1e-5
    for pi, lo, up in zip(p, out["trace_lower"], out["trace_upper"]):
        assert (lo is None) == (pi <= p_low)
        if pi <= p_up:
            assert up is None
        elif pi > p_up + 1e-6:
            assert up is not None and up >= lo
    # traces blow up towards the thresholds and decrease in p
    tl = [v for v in out["trace_lower"] if v is not None]
    tu = [v for v in out["trace_upper"] if v is not None]
    assert all(x >= y for x, y in zip(tl, tl[1:])) and all(x >= y for x, y in zip(tu, tu[1:]))
    assert tl[0] > 1e4 * tl[-1] and tu[0] > 1e3 * tu[-1]


def test_ms_critical_value_scalar_hand_derivation():
    # (1−p) a² + p (a + k)² < 1  ⇔  p > (a² − 1)/(a² − (a + k)²)
    a, k = 2.0, -1.5
    crit = bounds.ms_critical_value(np.array([[a]]), np.array([[1.0]]), np.array([[k]]))
    assert crit["critical_value"] == pytest.approx((a * a - 1) / (a * a - (a + k) ** 2))
    assert crit["stable_up_to_one"]
    # k = −a (deadbeat) attains p_low = 1 − 1/a² = p_up for scalar systems
    crit = bounds.ms_critical_value(np.array([[a]]), np.array([[1.0]]), np.array([[-a]]))
    assert crit["critical_value"] == pytest.approx(0.75)


def test_static_gain_best_equals_p_up_and_kalman_is_not_better():
    out = to_json(bounds.static_gain(GENERAL, 0.6))
    best, kalman = out["best"], out["kalman"]
    assert best["equals_p_up"] and abs(best["critical_value"] - 57 / 121) < 1e-9
    assert kalman["critical_value"] >= out["p_up_interval"][0] - 1e-12
    # at p = 0.6 > p_{K*} the best static gain has a steady covariance, and it is ⪰ V̄
    assert best["covariance_exists"]
    V = np.array(bounds.covariance_bounds(GENERAL, 0.6)["upper"]["matrix"])
    assert np.linalg.eigvalsh(np.array(best["covariance_matrix"]) - V).min() >= -1e-8
    json.dumps(out, allow_nan=False)


def diagonal_mare(a: np.ndarray, p: float) -> np.ndarray:
    """V̄ of A = diag(a), C = Q = R = I: the MARE decouples into scalar ones, each solved by
    :func:`mare_scalar` (hand derivation above)."""
    return np.array([mare_scalar(float(x), 1.0, 1.0, p) for x in a])


class CountingClock:
    """A clock that advances one unit per reading: the budget counts work, not seconds."""

    def __init__(self) -> None:
        self.readings = 0

    def __call__(self) -> float:
        self.readings += 1
        return float(self.readings)


@pytest.mark.slow
def test_phase_transition_200_state_diagonal_is_right_within_its_budget():
    # Newton–Kleinman would be a dense solve in n(n+1)/2 = 20100 unknowns at each of ~80 grid
    # points (minutes): large n uses fewer points, a warm-started fixed point and a budget
    # stated in the record. The budget is measured on an injected clock (one unit per
    # reading), so what gets computed does not depend on the machine's load.
    n = 200
    a = np.linspace(0.5, 1.3, n)
    s = System(np.diag(a).tolist(), np.eye(n).tolist(), 1, 1, max_states=1000)
    clock = CountingClock()
    pt = to_json(bounds.phase_transition(s, time_budget=400, clock=clock))
    assert clock.readings > 0
    assert len(pt["p"]) <= 40 and pt["limits"]["points"] == len(pt["p"])
    p_up = 1 - 1 / 1.3**2                 # C = I: every mode is seen, p_up = p_low (Thm 3)
    filled = [(p, v) for p, v in zip(pt["p"], pt["trace_upper"], strict=True) if v is not None]
    assert len(filled) >= 5
    for p, v in filled:                   # each filled point is V̄(p) of the decoupled MAREs
        assert p > p_up
        assert v == pytest.approx(diagonal_mare(a, p).sum(), rel=1e-6)
    for p, v in zip(pt["p"], pt["trace_lower"], strict=True):   # S̄ = Σ 1/(1 − (1−p)a_i²)
        if (1 - p) * 1.3**2 < 1:
            assert v == pytest.approx(np.sum(1 / (1 - (1 - p) * a * a)), rel=1e-8)
    missing = [p for p, v in zip(pt["p"], pt["trace_upper"], strict=True)
               if v is None and p > p_up]
    if missing:                           # points not reached are said, not silently empty
        assert pt["warnings"] and pt["limits"]["stopped"]


def test_phase_transition_time_budget_is_a_warning_not_a_failure():
    a = np.linspace(0.5, 1.3, 40)
    s = System(np.diag(a).tolist(), np.eye(40).tolist(), 1, 1)
    pt = to_json(bounds.phase_transition(s, time_budget=0.0))
    assert all(v is None for v in pt["trace_upper"])
    assert "time budget" in pt["limits"]["stopped"]
    assert any("time budget" in w for w in pt["warnings"])


def test_static_gain_section_is_skipped_with_a_reason_beyond_its_size_cap() -> None:
    """n = 31 > 30: no O(n⁶) eigenproblem; both gains say why, with the vech size 31·32/2."""
    from kfcrit.model.system import System
    from kfcrit.theory.covariance import bounds

    n = bounds.STATIC_GAIN_MAX_STATES + 1
    A = np.diag([1.2] + [0.5] * (n - 1))
    s = System(A, np.ones((1, n)), Q=1, R=1)
    sg = to_json(bounds.static_gain(s, 0.9))
    for key in ("kalman", "best"):
        assert sg[key]["available"] is False and "496" in sg[key]["reason"]


# ---------------------------------------------------------------------------------------------
# property: the best static gain's critical value lies in the p_up bracket
# ---------------------------------------------------------------------------------------------

from hypothesis import HealthCheck, assume, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from ..strategies import systems  # noqa: E402


@st.composite
def non_square_unstable_systems(draw):
    """2- or 3-state unstable systems with fewer outputs than states (C not invertible, so the
    general method and its gain are used, not the exact C-invertible case)."""
    n = draw(st.integers(2, 3))
    return draw(systems(n=n, m=draw(st.integers(1, n - 1)), kind="unstable"))


@settings(max_examples=8, suppress_health_check=[HealthCheck.too_slow,
                                                 HealthCheck.filter_too_much])
@given(non_square_unstable_systems())
def test_best_static_gain_critical_value_within_p_up_bracket(case):
    # Theory (MATH.md §3, journal §V): every static gain K has critical value p_K ≥ p_up, and
    # the certificate's gain is mean-square stable at hi (X ≻ L_{K,hi}(X)), so p_K ≤ hi; the
    # critical value is computed independently by the generalised eigenvalues of the pencil.
    from kfcrit.theory.upper.bracket import upper_bound

    s = System(case.A, case.C, case.Q, case.R)
    ub = upper_bound(s, tol=1e-9)
    assume(ub.certified and ub.status == "determined" and ub.method == "newton")
    out = to_json(bounds.static_gain(s, min(1.0, ub.interval[1] + 0.05)))
    best = out["best"]
    assert best["available"]
    lo, hi = ub.interval
    width = hi - lo
    slack = width + 1e-8
    assert best["critical_value"] is not None
    assert lo - slack <= best["critical_value"] <= hi + slack, (ub.interval, best)
    assert best["equals_p_up"]


# ---------------------------------------------------------------------------------------------
# extreme magnitudes: no RuntimeWarning on stderr, values or a record warning instead of null
# ---------------------------------------------------------------------------------------------


def test_huge_r_gives_a_residual_and_no_runtime_warning():
    import warnings

    s = System(np.array([[1.25, 0.0], [1.0, 1.1]]), np.array([[1.0, 1.0]]), 20 * np.eye(2),
               np.array([[1e250]]))
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        cb = bounds.covariance_bounds(s, 0.9)
    up = cb["upper"]
    assert up["exists"] and up["trace"] > 1e249
    assert up["residual"] is not None and up["residual"] < 1e-12
    assert cb["warnings"] == [] and cb["ordered"] is True


def test_huge_r_scalar_v_bar_is_found_not_null():
    import warnings

    # a = -1.25, p = 0.9, R = 1e250: V̄ = c R with (a² − 1)(c + 1) = p a² c, c = 2/3
    s = System(np.array([[-1.25]]), np.array([[1.0]]), np.array([[1.0]]), np.array([[1e250]]))
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        cb = bounds.covariance_bounds(s, 0.9)
    assert cb["upper"]["exists"]
    assert cb["upper"]["trace"] == pytest.approx(2e250 / 3, rel=1e-9)


def test_mare_residual_is_scaled_not_overflowing():
    import warnings

    A, C, Q, R = np.array([[2.0]]), np.array([[1.0]]), np.array([[1.0]]), np.array([[1.0]])
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        assert bounds.mare_residual(A, C, Q, R, np.array([[1e300]]), 0.5) is not None
        assert bounds.mare_residual(A, C, Q, R, np.array([[np.inf]]), 0.5) is None


def test_unreached_v_bar_is_a_record_warning(monkeypatch):
    s = System(np.array([[1.25, 0.0], [1.0, 1.1]]), np.array([[1.0, 1.0]]), 20 * np.eye(2),
               2.5 * np.eye(1))
    monkeypatch.setattr(bounds, "upper_covariance",
                        lambda *a, **k: {"V": None, "method": "mare-iteration",
                                         "iterations": 7, "residual": None})
    cb = bounds.covariance_bounds(s, 0.9)
    assert cb["upper"]["exists"] is False
    assert any("not computed" in w for w in cb["warnings"])


def test_huge_a_entry_analysis_has_no_runtime_warning(tmp_path):
    import subprocess
    import sys

    path = tmp_path / "huge.yaml"
    path.write_text('name: huge\nA: [["2**64", 0], [1, 1.1]]\nC: [[1, 1]]\nQ: [[1, 0], [0, 1]]\n'
                    'R: [[1e250]]\nchannel:\n  model: bernoulli\n  arrival_probability: 0.9\n')
    r = subprocess.run([sys.executable, "-W", "default", "-m", "kfcrit", "analyze", str(path),
                        "--json", "--no-simulate"], capture_output=True, text=True, timeout=600)
    # p_c ≈ 1 − 2^-128 > 0.9: mean-unstable, so the review fails (exit 5)
    assert r.returncode == 5, r.stderr[-2000:]
    assert json.loads(r.stdout)["operating_point"]["verdict"] == "mean-unstable"
    assert "RuntimeWarning" not in r.stderr, r.stderr[-2000:]
