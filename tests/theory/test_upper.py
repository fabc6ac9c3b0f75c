"""The upper bound p_up (bracket and LMI modules): closed forms, paper values, cross-checks.

Expected values: MATH.md §3 and tests/data/cases/expected.json (paper values); the single-output
closed form p_up = 1 − 1/Π|λ_u|² ([beyond] in MATH.md, tested here as a property); p_low
(Sinopoli Thm 3); the issue's MARE observations for random_system(20, 6, 0). Cross-checks use
independent methods: the LMI, the MARE iteration and the static-gain critical value.
"""
from __future__ import annotations

import json
import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import assume, example, given
from hypothesis import strategies as st

from kfcrit.io.systemfile import read_system_file
from kfcrit.model.system import System
from kfcrit.theory.covariance import bounds
from kfcrit.theory.upper.bracket import UpperBound, upper_bound, upper_section

from ..conftest import SHARED_CASES
from ..data.bench_systems import random_system  # noqa: E402


def make(A, C) -> System:
    A, C = np.atleast_2d(np.asarray(A, float)), np.atleast_2d(np.asarray(C, float))
    return System(A, C, np.eye(A.shape[0]), np.eye(C.shape[0]))


def closed_form_single_output(A) -> float:
    lam = np.linalg.eigvals(np.asarray(A, float))
    prod = float(np.prod([abs(v) ** 2 for v in lam if abs(v) > 1]))
    return 1.0 - 1.0 / prod if prod > 1 else 0.0


def assert_contains(ub: UpperBound, value: float, slack: float = 1e-12):
    lo, hi = ub.interval
    assert lo - slack <= value <= hi + slack, (ub.interval, value)


# ---------------------------------------------------------------------------------------------
# paper values
# ---------------------------------------------------------------------------------------------

EXPECTED = json.loads((SHARED_CASES / "expected.json").read_text())
CASES = sorted(k for k, v in EXPECTED.items() if k.endswith(".yaml")
               and ("upper_bound" in v or "upper_bound_approx" in v))


@pytest.mark.parametrize("name", CASES)
def test_expected_upper_bounds(name):
    spec = read_system_file(SHARED_CASES / name)
    ub = upper_bound(spec.system, tol=1e-9)
    d = ub.to_dict()
    assert d["certified"] and d["status"] == "determined"
    assert d["interval"][1] - d["interval"][0] <= 1e-9
    want = EXPECTED[name]
    if "upper_bound" in want:
        assert_contains(ub, float(Fraction(want["upper_bound"])))
    else:  # given to 1e-6
        assert abs(d["value"] - want["upper_bound_approx"]) <= 1e-6
    json.dumps(d, allow_nan=False)


def test_random_5_1_closed_form_inside_certified_interval():
    A, C, _, _ = random_system(5, 1, 0)
    ub = upper_bound(make(A, C), tol=1e-9)
    want = closed_form_single_output(A)
    assert abs(want - 0.54115) < 1e-5                      # the issue's ≈ 0.54115
    assert ub.certified and ub.status == "determined"
    assert_contains(ub, want, slack=1e-10)


def test_random_20_6_matches_mare_observations():
    A, C, Q, R = random_system(20, 6, 0)
    s = make(A, C)
    ub = upper_bound(s, tol=1e-9)
    p_low = 1 - 1 / max(abs(np.linalg.eigvals(A))) ** 2
    assert abs(p_low - 0.40828) < 1e-5
    assert ub.certified and ub.interval[1] <= 0.409
    # p_low here is from float64 eigenvalues (a few ulps off); the record's lower end is the
    # exact p_low rounded down, so compare within float eigenvalue accuracy
    assert ub.interval[0] >= p_low - 1e-13
    # the MARE iteration from 0 is bounded at 0.409 (above p_up) and not at 0.405 (< p_low)
    V, _ = bounds.mare_iteration(A, C, Q, R, 0.409, rtol=1e-9)
    assert V is not None
    V, _ = bounds.mare_iteration(A, C, Q, R, 0.405, max_iterations=20_000)
    assert V is None


# ---------------------------------------------------------------------------------------------
# single-output closed form ([beyond] claim) as a property
# ---------------------------------------------------------------------------------------------

entry = st.floats(-2.0, 2.0, allow_nan=False, allow_infinity=False).map(lambda v: round(v, 3))


@st.composite
def single_output_systems(draw):
    n = draw(st.integers(1, 4))
    A = np.array(draw(st.lists(st.lists(entry, min_size=n, max_size=n), min_size=n,
                               max_size=n)))
    C = np.array([draw(st.lists(entry, min_size=n, max_size=n))])
    return A, C


@given(single_output_systems())
@example((np.array([[-1.25]]), np.array([[1.0]])))                   # p_up = 9/25
@example((np.array([[1.25, 0.0], [1.0, 1.1]]), np.array([[1.0, 1.0]])))  # p_up = 57/121
@example((np.array([[0.0, -2.0], [2.0, 0.0]]), np.array([[1.0, 0.0]])))  # q = 2: 15/16
def test_single_output_closed_form(system):
    A, C = system
    lam, V = np.linalg.eig(A)
    mods = np.abs(lam)
    assume(np.all(np.abs(mods - 1) > 0.05))
    assume(np.linalg.cond(V) < 1e3)
    unstable = mods > 1
    assume(np.prod(mods[unstable] ** 2) < 50)
    n = A.shape[0]
    for i in np.flatnonzero(unstable):          # detectable (PBH test), with some margin
        pbh = np.vstack([A - lam[i] * np.eye(n), C])
        assume(np.linalg.svd(pbh, compute_uv=False)[-1] > 0.05)
    ub = upper_bound(make(A, C), tol=1e-9, method="newton")
    want = closed_form_single_output(A)
    assert ub.certified
    assert_contains(ub, want, slack=1e-8)


# ---------------------------------------------------------------------------------------------
# edge cases
# ---------------------------------------------------------------------------------------------


def test_stable_a_gives_zero():
    ub = upper_bound(make([[0.5, 1.0], [0.0, -0.3]], [[1.0, 0.0]]))
    assert ub.interval == (0.0, 0.0) and ub.value == 0.0 and ub.certified


@pytest.mark.parametrize("A, C", [([[0.0, -1.0], [1.0, 0.0]], [[1.0, 0.0]]),   # |λ| = 1
                                  ([[1.0, 0.0], [0.0, 1.0]], [[1.0, 0.0], [0.0, 1.0]])])
def test_marginally_stable_gives_zero(A, C):
    ub = upper_bound(make(A, C), tol=1e-9)
    assert ub.interval[0] == 0.0 and ub.interval[1] <= 1e-9 and ub.certified


def test_invertible_c_gives_p_low():
    A = np.array([[1.2, 0.5, 0.0], [0.0, -1.5, 1.0], [0.3, 0.0, 0.9]])
    ub = upper_bound(make(A, np.eye(3)), tol=1e-9)
    p_low = 1 - 1 / max(abs(np.linalg.eigvals(A))) ** 2
    assert ub.certified and ub.interval[0] == pytest.approx(p_low, abs=1e-15)
    assert ub.interval[1] - p_low <= 1e-9
    assert ub.lower_evidence.kind == "theorem"


def test_undetectable_is_undetermined_not_an_error():
    d = upper_section(make([[2.0, 0.0], [0.0, 0.5]], [[0.0, 1.0]]))
    assert d["status"] == "undetermined" and d["value"] is None and not d["certified"]
    assert d["warnings"]


def test_upper_section_never_raises(monkeypatch):
    from kfcrit.theory.upper import bracket as upper

    def boom(*_a, **_k):
        raise np.linalg.LinAlgError("singular matrix")

    monkeypatch.setattr(upper, "newton_method", boom)
    # C not square (the exact C-invertible case does not reach the Newton method)
    d = upper_section(make([[2.0, 0.0], [0.0, 0.5]], [[1.0, 1.0]]))
    assert d["status"] == "undetermined" and d["interval"] == [0.75, 1.0]
    json.dumps(d, allow_nan=False)


def test_record_keys():
    d = upper_bound(make([[1.25, 0.0], [1.0, 1.1]], [[1.0, 1.0]])).to_dict()
    assert set(d) == {"value", "interval", "certified", "status", "method", "certificate",
                      "lower_evidence", "solver", "warnings", "tolerance", "applicable",
                      "not_applicable_reason"}
    assert d["value"] == d["interval"][1]
    assert {"kind", "ok", "margin_lower", "verified_by"} <= set(d["certificate"])
    assert "X" in d["certificate"]               # small system: the matrix is included
    assert d["solver"]["seconds"] >= 0


# ---------------------------------------------------------------------------------------------
# cross-checks: LMI, MARE iteration, static gain
# ---------------------------------------------------------------------------------------------

SMALL = [(3, 1, 1), (3, 2, 2), (4, 2, 3)]


@pytest.mark.parametrize("n, m, seed", SMALL)
def test_lmi_mare_static_gain_agree(n, m, seed):
    A, C, Q, R = random_system(n, m, seed)
    s = make(A, C)
    fast = upper_bound(s, tol=1e-9, method="newton")
    lmi = upper_bound(s, tol=1e-6, method="lmi")
    assert fast.certified
    # both upper ends are proven, so each is >= p_up >= the other's (numerical) lower end
    if lmi.certified:
        assert fast.interval[0] <= lmi.interval[1] + 1e-12
    assert lmi.interval[0] <= fast.interval[1] + 1e-6
    # MARE iteration: bounded just above the bracket, unbounded just below it
    hi, lo = fast.interval[1], fast.interval[0]
    V, _ = bounds.mare_iteration(A, C, Q, R, min(hi + 1e-3, 1.0), rtol=1e-9)
    assert V is not None
    if lo - 1e-3 > 0:
        V, _ = bounds.mare_iteration(A, C, Q, R, lo - 1e-3, max_iterations=20_000)
        assert V is None
    # the best static gain's mean-square critical value is p_up
    crit = bounds.ms_critical_value(A, C, fast.extras["K"])["critical_value"]
    assert lo - 1e-9 <= crit <= hi + 1e-9


def test_lmi_never_reads_inaccurate_or_errors_as_a_decision(monkeypatch):
    import cvxpy as cp

    from kfcrit.theory.upper.lmi import PsiProblem

    s = make([[1.25, 0.0], [1.0, 1.1]], [[1.0, 1.0]])
    prob = PsiProblem(s.a, s.c)

    class Fake:
        def __init__(self, status=None, error=False):
            self.status, self.error = status, error

        def solve(self, **_k):
            if self.error:
                raise cp.error.SolverError("boom")

    lift = None
    for fake in (Fake(cp.OPTIMAL_INACCURATE), Fake(cp.INFEASIBLE_INACCURATE),
                 Fake(cp.INFEASIBLE), Fake(error=True)):
        monkeypatch.setattr(prob, "prob", fake)
        out = prob.solve(s, 0.6, lift)
        assert out["decision"] == "undetermined", fake.status


def test_lmi_brackets_the_paper_value():
    s = make([[1.25, 0.0], [1.0, 1.1]], [[1.0, 1.0]])
    ub = upper_bound(s, tol=1e-6, method="lmi")
    assert ub.method == "lmi" and ub.certified
    assert ub.interval[0] - 1e-9 <= 57 / 121 <= ub.interval[1]
    assert ub.solver["solves"] >= 1


def test_width_1e9_on_random_50_10_is_reachable():
    A, C, _, _ = random_system(50, 10, 0)
    ub = upper_bound(make(A, C), tol=1e-9)
    assert ub.certified and ub.status == "determined"
    assert ub.interval[1] - ub.interval[0] <= 1e-9
    assert math.isfinite(ub.value)


# ---------------------------------------------------------------------------------------------
# audit cases: ill-conditioned C, modes with |λ| = 1, exact rounding of p_low
# ---------------------------------------------------------------------------------------------


def exact_make(A, C) -> System:
    n, m = len(A), len(C)
    return System(A, C, [[int(i == j) for j in range(n)] for i in range(n)],
                  [[int(i == j) for j in range(m)] for i in range(m)])


def contains_exactly(interval, value: Fraction) -> bool:
    """lo ≤ value ≤ hi compared as exact rationals (no float slack)."""
    return Fraction(interval[0]) <= value <= Fraction(interval[1])


@pytest.mark.parametrize("A, C", [
    ([[0, -2], [2, 0]], [[1, 0], [0, Fraction(1, 10 ** 12)]]),          # the audit's case
    (np.array([[2.0, 1.0], [0.0, -1.9]]), np.array([[1.0, 0.5], [0.0, 1e-12]])),   # floats
    (np.diag([2.0, -2.0]), np.diag([1.0, 1e-12])),
])
def test_invertible_ill_conditioned_c_is_exact(A, C):
    # hand derivation: ρ(A) = 2 in all three; C invertible, K = −A C⁻¹ makes F = 0, so
    # p_up = p_c = p_low = 1 − 1/2² = 3/4 exactly (was: "certified" [0.93749999920, 0.9375])
    s = exact_make(A, C) if isinstance(A, list) else make(A, C)
    for method in ("auto", "newton"):
        ub = upper_bound(s, tol=1e-9, method=method)
        assert ub.interval == (0.75, 0.75) and ub.certified and ub.status == "determined"
        assert ub.method == "exact" and "K = −A C⁻¹" in ub.certificate.statement


def test_lmi_with_ill_conditioned_c_contains_true_value():
    s = make(np.array([[2.0, 1.0], [0.0, -1.9]]), np.array([[1.0, 0.5], [0.0, 1e-12]]))
    ub = upper_bound(s, tol=1e-7, method="lmi")
    assert ub.certified and contains_exactly(ub.interval, Fraction(3, 4))


@pytest.mark.parametrize("method", ["newton", "lmi"])
def test_ill_conditioned_output_on_the_unstable_block(method):
    # A = rotation by 90° scaled by 2 (+ a stable mode 1/2); C restricted to the unstable
    # block is diag(1, 1e-12): invertible there, so p_up = p_low = 3/4 (was 0.9375 "determined")
    A = [[0, -2, 0], [2, 0, 0], [0, 0, Fraction(1, 2)]]
    C = [[1, 0, 1], [0, Fraction(1, 10 ** 12), 1]]
    ub = upper_bound(exact_make(A, C), tol=1e-9 if method == "newton" else 1e-7, method=method)
    assert ub.certified and contains_exactly(ub.interval, Fraction(3, 4))
    assert ub.interval[1] - 0.75 <= (1e-9 if method == "newton" else 2e-7)


def test_marginal_modes_bracket_contains_p_low():
    # A = diag(1, −1, 3), C = [1 1 1]: p_low = 1 − 1/9 = 8/9 and (single output, one unstable
    # mode) p_c = p_up = 8/9; the old bracket [0.88888891, 0.88888891] excluded it
    ub = upper_bound(exact_make([[1, 0, 0], [0, -1, 0], [0, 0, 3]], [[1, 1, 1]]), tol=1e-9)
    assert ub.certified and contains_exactly(ub.interval, Fraction(8, 9))
    assert Fraction(ub.interval[0]) <= Fraction(8, 9)
    assert ub.interval[1] - 8 / 9 < 1e-6


def test_jordan_block_on_the_unit_circle():
    # A = [[1, 1], [0, 1]], C = [1 0]: ρ = 1, p_low = 0; the MARE settles for every p > 0, so
    # p_up = 0: the bracket must start at 0 exactly and its certified upper end be small
    s = exact_make([[1, 1], [0, 1]], [[1, 0]])
    ub = upper_bound(s, tol=1e-9)
    assert ub.certified and ub.interval[0] == 0.0 and ub.interval[1] <= 1e-4
    V, _ = bounds.mare_iteration(s.a, s.c, np.eye(2), np.eye(1), 0.01, rtol=1e-9)
    assert V is not None


def test_kar_scalar_lower_end_is_exact():
    # A = √2: p_low = 1 − 1/2 = 1/2 exactly; floats give 1 − 1/√2² = 0.5000000000000001
    import sympy as sp
    ub = upper_bound(exact_make([[sp.sqrt(2)]], [[1]]), tol=1e-9)
    assert contains_exactly(ub.interval, Fraction(1, 2)) and ub.interval[0] == 0.5
    # the same p_low through the Newton path (C not square): lower end rounded down
    ub = upper_bound(exact_make([[sp.sqrt(2), 0], [0, Fraction(1, 2)]], [[1, 1]]), tol=1e-9)
    assert ub.interval[0] == 0.5 and ub.interval[1] - 0.5 <= 1e-9 and ub.certified


def test_p_low_bounds_enclose_independent_values():
    import mpmath
    import sympy as sp

    from kfcrit.theory.upper.bracket import p_low_bounds
    A = [[1, 2, 0], [0, 3, 1], [1, 0, -1]]
    mpmath.mp.dps = 50
    roots = mpmath.polyroots([float(c) for c in sp.Matrix(A).charpoly().all_coeffs()],
                             maxsteps=200, extraprec=200)
    rho2 = max(abs(r) ** 2 for r in roots)
    exact = Fraction(str(mpmath.nstr(1 - 1 / rho2, 40)))
    pl = p_low_bounds(exact_make(A, [[1, 0, 0]]))
    assert pl.rigorous and Fraction(pl.down) <= exact + Fraction(1, 10 ** 35)
    assert exact - Fraction(1, 10 ** 35) <= Fraction(pl.up) and pl.up - pl.down < 1e-14


def test_undetectable_is_not_applicable():
    d = upper_section(exact_make([[2, 0, 0], [0, 3, 0], [0, 0, Fraction(1, 2)]],
                                 [[1, 0, 1]]))
    assert d["applicable"] is False and d["value"] is None and d["not_applicable_reason"]
    assert d["interval"][1] == 1.0


# ---------------------------------------------------------------------------------------------
# audit: the LMI's "infeasible" must be confirmed independently
# ---------------------------------------------------------------------------------------------


def test_lmi_random_20_6_lower_end_is_not_above_the_proven_p_up():
    # The audit: the LMI reported the "determined" bracket [0.4082897, 0.4082902] although
    # p_up <= 0.4082840242 is proven. Expected values, independently: p_low = 1 − 1/1.3² of the
    # float A (Thm 3, p_up ≥ p_low) and the fast method's certificate, re-checked here in ball
    # arithmetic (X ≻ 0, X − L_{K,hi}(X) ≻ 0) — so p_up ∈ [p_low, 0.4082840242].
    from kfcrit.theory.upper import certify

    A, C, _, _ = random_system(20, 6, 0)
    s = make(A, C)
    fast = upper_bound(s, tol=1e-9, method="newton")
    ex = fast.extras
    hi_proven = fast.interval[1]
    assert hi_proven <= 0.4082840242
    assert certify.verify_upper(s, hi_proven, ex["X_basis"], ex["K_basis"], basis=ex["basis"],
                                output_map=ex["output_map"]).ok
    lmi = upper_bound(s, tol=1e-6, method="lmi")
    lo, hi = lmi.interval
    assert lo <= 0.4082840242 and lo <= hi_proven
    p_low = 1 - 1 / max(abs(np.linalg.eigvals(A))) ** 2
    if lmi.certified:                       # its own upper end is proven, hence ≥ p_up ≥ p_low
        assert hi >= p_low - 1e-12
    if lmi.status == "determined":          # then [lo, hi] meets [p_low, hi_proven] ∋ p_up
        assert lo <= hi_proven and hi >= p_low - 1e-12
    else:                                   # honestly undetermined, and says which ends hold
        assert "ends" in lmi.solver and lmi.warnings
    # the lower end is the theorem p_low or an independently confirmed point, never the
    # solver's word alone
    assert lmi.lower_evidence.kind in ("theorem", "certificate", "numerical")
    if lmi.lower_evidence.kind != "theorem":
        assert "cone spectral radius" in lmi.lower_evidence.statement


def test_lmi_infeasible_needs_an_independent_confirmation(monkeypatch):
    import cvxpy as cp

    from kfcrit.theory.upper.lmi import PsiProblem

    s = make([[1.25, 0.0], [1.0, 1.1]], [[1.0, 1.0]])
    prob = PsiProblem(s.a, s.c)

    class Unit:                                # Clarabel says "infeasible" for Ψ ⪰ I
        status = cp.INFEASIBLE

        def solve(self, **_k):
            pass

    monkeypatch.setattr(prob, "unit", Unit())
    out = {"p": 0.6, "margin": 0.0}
    # no confirmation available: undetermined, whatever the solver says
    assert prob._confirm_infeasible(s, 0.6, out, None)["decision"] == "undetermined"
    # the cone radius says r(p) < 1 (feasible side): undetermined, never "infeasible"
    prob.confirm = lambda p: {"r": 0.99, "numerical": False, "certified": False,
                              "check": None, "how": "test", "X": None}
    assert prob._confirm_infeasible(s, 0.6, out, None)["decision"] == "undetermined"
    # confirmed (numerically): infeasible, labelled as such
    prob.confirm = lambda p: {"r": 1.01, "numerical": True, "certified": False,
                              "check": None, "how": "test", "X": None}
    res = prob._confirm_infeasible(s, 0.6, out, None)
    assert res["decision"] == "infeasible" and res["evidence"] == "numerical"


def test_lmi_lower_end_is_confirmed_on_the_paper_example():
    # A = [[1.25, 0], [1, 1.1]], C = [1 1]: p_up = 57/121 (MATH.md §3); the LMI's lower end
    # must be below it, and its evidence is the cone radius (proven in balls here)
    s = make([[1.25, 0.0], [1.0, 1.1]], [[1.0, 1.0]])
    ub = upper_bound(s, tol=1e-6, method="lmi")
    assert ub.interval[0] <= 57 / 121 <= ub.interval[1]
    ev = ub.lower_evidence
    assert ev.kind in ("certificate", "theorem", "numerical")
    if ev.kind == "certificate":
        assert ev.certified and ev.check.ok


# ---------------------------------------------------------------------------------------------
# audit: proven lower ends for systems with stable modes
# ---------------------------------------------------------------------------------------------


def test_lower_end_proven_with_stable_modes():
    # random_system(5, 1, 0): 3 unstable and 2 stable modes, single output, so
    # p_up = 1 − 1/Π|λ_u|² ≈ 0.54115 > p_low (closed form, computed here from eigenvalues)
    from kfcrit.theory.upper import certify
    from kfcrit.theory.upper.bracket import invariant_block_of, reduce_system

    A, C, _, _ = random_system(5, 1, 0)
    s = make(A, C)
    mods = np.abs(np.linalg.eigvals(A))
    assert np.sum(mods < 1) >= 1                       # there are stable modes
    want = closed_form_single_output(A)
    p_low = 1 - 1 / mods.max() ** 2
    ub = upper_bound(s, tol=1e-9)
    assert_contains(ub, want, slack=1e-10)
    ev = ub.lower_evidence
    assert ub.interval[0] > p_low + 1e-3
    assert ev.kind == "certificate" and ev.certified and ev.check.ok
    assert ev.reduced_states < s.n
    # the same X_u re-verifies on the exactly invariant block, and is rejected above p_up
    red = reduce_system(s)
    block = invariant_block_of(s, red)
    Xu = np.array(ev.X_u)
    assert certify.verify_lower_block(block, ub.interval[0], Xu).ok
    assert not certify.verify_lower_block(block, want + 1e-4, Xu).ok
    assert not certify.verify_lower_block(block, 0.9, Xu).ok
    # a basis whose leading columns are not an invariant subspace gives no block
    Z = np.array(ev.basis)
    assert certify.invariant_block(s, Z[:, ::-1], red.k) is None
    # independent: the MARE iteration from 0 diverges just below the lower end
    V, _ = bounds.mare_iteration(A, C, np.eye(5), np.eye(1), ub.interval[0] - 1e-3,
                                 max_iterations=20_000)
    assert V is None


# ---------------------------------------------------------------------------------------------
# width 1e-9 on systems that were undetermined before the consistent regulariser and the
# Stein certificate (survey of random_system(n, m, seed), n ≤ 30)
# ---------------------------------------------------------------------------------------------

PREVIOUSLY_UNDETERMINED = [(12, 4, 0), (20, 1, 0), (20, 2, 3), (20, 6, 1)]


@pytest.mark.parametrize("n, m, seed", PREVIOUSLY_UNDETERMINED)
def test_previously_undetermined_systems_reach_width_1e9(n, m, seed):
    from kfcrit.theory.upper import certify

    A, C, Q, R = random_system(n, m, seed)
    s = System(A, C, Q, R)
    ub = upper_bound(s, tol=1e-9)
    lo, hi = ub.interval
    assert ub.status == "determined" and ub.certified, (ub.interval, ub.warnings)
    assert hi - lo <= 1e-9 + 4 * math.ulp(hi)
    # the certificate re-verifies on its own, exactly as recorded; it fails just below lo
    ex = ub.extras
    check = certify.verify_upper(s, ub.certificate.p, ex["X_basis"], ex["K_basis"],
                                 basis=ex["basis"], output_map=ex["output_map"])
    assert check.ok and ub.certificate.p == hi
    assert not certify.verify_upper(s, lo - 1e-6, ex["X_basis"], ex["K_basis"],
                                    basis=ex["basis"], output_map=ex["output_map"]).ok
    if m == 1:
        # independent: the single-output closed form, to float accuracy
        assert_contains(ub, closed_form_single_output(A), slack=1e-12)
    else:
        # independent: the MARE iteration from 0 (with Q, R) is bounded above hi and diverges
        # below lo ...
        V, _ = bounds.mare_iteration(A, C, Q, R, hi + 1e-3, max_iterations=100_000)
        assert V is not None
        V, _ = bounds.mare_iteration(A, C, Q, R, lo - 1e-3, max_iterations=100_000)
        assert V is None
        # ... and the certificate gain's own mean-square critical value (generalised
        # eigenvalues of the vech pencil, no certificate code) is in [lo, hi]: it is >= p_up
        # by definition and <= hi because the gain works there
        crit = bounds.ms_critical_value(A, C, ex["K"])["critical_value"]
        assert lo - 1e-10 <= crit <= hi + 1e-10, (crit, ub.interval)


# ---------------------------------------------------------------------------------------------
# numerical failures inside upper_bound: an undetermined record, never an exception
# ---------------------------------------------------------------------------------------------


def _raise(exc):
    def boom(*_a, **_k):
        raise exc
    return boom


@pytest.mark.parametrize("exc", [np.linalg.LinAlgError("Singular matrix (injected)"),
                                 FloatingPointError("overflow (injected)"),
                                 ZeroDivisionError("division by zero (injected)"),
                                 ValueError("array must not contain infs or NaNs (injected)")])
def test_numerical_failure_inside_upper_bound_is_undetermined(monkeypatch, exc):
    from kfcrit.theory.upper import bracket as upper
    from kfcrit.theory.upper import newton

    monkeypatch.setattr(newton, "threshold_newton", _raise(exc))
    s = System(*random_system(8, 2, 1))
    ub = upper_bound(s, tol=1e-9)
    assert ub.status == "undetermined" and not ub.certified and ub.value is None
    lo, hi = ub.interval
    # the bracket reached by the power iteration before the failure (width 1/64 at most)
    assert upper.p_low_of(s.a) <= lo < hi <= 1.0 and hi - lo <= 1 / 64 + 1e-12
    assert any(type(exc).__name__ in w and "bracket" in w for w in ub.warnings)
    assert ub.solver["failure"] == type(exc).__name__
    json.dumps(ub.to_dict(), allow_nan=False)
    monkeypatch.undo()                        # a failure is not memoised:
    assert upper_bound(s, tol=1e-9).status == "determined"


def test_numpy_solve_failure_is_undetermined(monkeypatch):

    monkeypatch.setattr(np.linalg, "solve", _raise(np.linalg.LinAlgError("Singular matrix")))
    ub = upper_bound(make([[1.25, 0.0], [1.0, 1.1]], [[1.0, 1.0]]))
    assert ub.status == "undetermined" and ub.interval[1] == 1.0
    assert any("LinAlgError" in w for w in ub.warnings)


def test_solver_error_of_the_lmi_is_undetermined(monkeypatch):
    import cvxpy

    from kfcrit.theory.upper import lmi

    monkeypatch.setattr(lmi, "lmi_upper_bound", _raise(cvxpy.error.SolverError("Clarabel")))
    ub = upper_bound(make([[1.25, 0.0], [1.0, 1.1]], [[1.0, 1.0]]), tol=1e-7, method="lmi")
    assert ub.status == "undetermined" and ub.method == "lmi"
    assert any("SolverError" in w for w in ub.warnings)


def test_programming_errors_are_not_swallowed(monkeypatch):
    from kfcrit.theory.upper import newton

    monkeypatch.setattr(newton, "threshold_newton", _raise(TypeError("a bug")))
    with pytest.raises(TypeError):
        upper_bound(System(*random_system(8, 2, 1)), tol=1e-9)


NO_CHANNEL = """name: no channel
A: [[1.25, 0], [1, 1.1]]
C: [[1, 1]]
Q: [[20, 0], [0, 20]]
R: [[2.5]]
"""


def test_numerical_failure_through_analyze_and_the_cli(monkeypatch, tmp_path):
    from click.testing import CliRunner

    import kfcrit
    from kfcrit.cli.main import main
    from kfcrit.theory.upper import newton

    path = tmp_path / "no-channel.yaml"
    path.write_text(NO_CHANNEL)
    monkeypatch.setattr(newton, "threshold_newton",
                        _raise(np.linalg.LinAlgError("Singular matrix (injected)")))
    rec = kfcrit.analyze(read_system_file(path), simulate=False).to_dict()
    assert rec["upper_bound"]["status"] == "undetermined"
    assert any("LinAlgError" in w for w in rec["upper_bound"]["warnings"])
    r = CliRunner().invoke(main, ["analyze", str(path), "--json", "--no-simulate"])
    assert r.exit_code == 3, (r.exit_code, r.output[-2000:])
    out = json.loads(r.stdout)
    assert out["upper_bound"]["status"] == "undetermined"
    assert "internal error" not in r.output


def test_bounds_sections_survive_a_failing_upper_bound(monkeypatch):
    from kfcrit.theory.upper import newton

    monkeypatch.setattr(newton, "threshold_newton",
                        _raise(np.linalg.LinAlgError("Singular matrix (injected)")))
    s = make([[1.25, 0.0], [1.0, 1.1]], [[1.0, 1.0]])
    cb = bounds.covariance_bounds(s, 0.9)
    assert cb["lower"]["exists"]
    pt = bounds.phase_transition(s, time_budget=5)
    assert len(pt.p) == len(pt.trace_upper)
    sg = bounds.static_gain(s, 0.9)
    from kfcrit.records.covariance import BestStaticGain

    assert sg.best == BestStaticGain(available=False)


SQRT3_SYSTEM = """name: exact sqrt(3)
A: [["sqrt(3)", 1, 0], [0, "1/2", 0], [0, 0, "1/3"]]
C: [[1, 1, 1]]
Q: [[1, 0, 0], [0, 1, 0], [0, 0, 1]]
R: [[1]]
"""


def _sqrt3_system(tmp_path, name):
    path = tmp_path / name
    path.write_text(SQRT3_SYSTEM)
    return read_system_file(path).system


def test_upper_bound_does_not_depend_on_call_order(tmp_path):
    # one unstable mode sqrt(3) seen by C: p_up = p_c = p_low = 1 - 1/3 = 2/3 (single mode)
    from kfcrit.theory.critical import section as critical

    first = _sqrt3_system(tmp_path, "a.yaml")
    before = upper_bound(first, tol=1e-9)
    second = _sqrt3_system(tmp_path, "b.yaml")
    critical.critical_value(second)            # runs (and memoises) the structure analysis
    after = upper_bound(second, tol=1e-9)
    assert after.interval == before.interval and after.lower_evidence == before.lower_evidence
    # the structure passed explicitly: the exact p_low 2/3 is enclosed by the interval
    st = critical.structure_of(second, 1e-9)
    given_st = upper_bound(second, tol=1e-9, structure=st)
    lo, hi = given_st.interval
    assert Fraction(lo) <= Fraction(2, 3) <= Fraction(hi) and hi - lo <= 1e-9
    assert given_st.lower_evidence.expression == "2/3"
    d = upper_section(second, tol=1e-9, structure=st)
    assert d["interval"] == [lo, hi]


def test_tiny_output_scale_does_not_bias_the_lower_end():
    # A = 2·rotation(1), one output: p_up = 1 − 1/Π|λ_u|² = 1 − 1/16 = 15/16 (closed form);
    # C = [[0, 2^-14]] makes C X C' ~ 4e-9 tr X, where the homogeneous regulariser once moved
    # the (numerical) lower end 3.6e-7 above 15/16
    th = 1.0
    A = 2.0 * np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
    ub = upper_bound(make(A, [[0.0, 2.0 ** -14]]), tol=1e-9)
    lo, hi = ub.interval
    assert ub.certified and lo <= 15 / 16 <= hi and hi - lo <= 1e-9 + 1e-15


def test_power_bisection_checks_once_in_balls_and_defers_beyond_the_size_limit(monkeypatch):
    # random_system(8, 2, 1) through the large-block path (NEWTON_MAX_REDUCED lowered): the
    # bracket must contain the Newton path's certified p_up; with the ball check deferred the
    # upper end is labelled numerical (not certified), never silently "proven"
    from kfcrit.theory.upper import newton

    s = System(*random_system(8, 2, 1))
    ref = upper_bound(s, tol=1e-9)
    assert ref.certified
    monkeypatch.setattr(newton, "NEWTON_MAX_REDUCED", 1)
    big = upper_bound(s, tol=1e-9, method="newton")
    assert big.certified and big.solver["certificate_checks"] <= 3
    assert big.interval[0] <= ref.interval[1] and ref.interval[0] <= big.interval[1]
    monkeypatch.setattr(newton, "BALL_CHECK_MAX_STATES", 0)
    deferred = upper_bound(s, tol=1e-9, method="newton")
    assert not deferred.certified and deferred.status == "undetermined"
    assert deferred.solver["certificate_checks"] == 0
    assert any("deferred" in w for w in deferred.warnings)


def test_defective_threshold_lower_end_is_widened_not_misplaced():
    # A = diag(block a, block b) up to a permutation: block a on (x1, x4) with eigenvalues
    # 2 ± i, block b on (x2, x3) with −2 ± i, both of modulus √5; y1 = x1, y2 = 2 x3 − x4.
    # p_up = 24/25 exactly: span(e2, e3) is A-invariant and C sees it through the one
    # column 2 e2' (rank 1), so p_up ≥ 1 − 1/|λ1 λ2|² = 1 − 1/25 of that single-output pair
    # (its noise-free MARE cone is invariant); a gain using y1 for block a and y2 for block b
    # makes A + K C block triangular with two single-output pairs on the diagonal, whose
    # thresholds are both 1 − 1/25, so p_up ≤ 24/25. The cone eigenvalue at 24/25 is
    # defective (two blocks cross 1 together), which once put the numerical lower end
    # 1.4e-8 (and, after the similarity T below, 2.8e-8) above 24/25 in a bracket of width 1e-9
    import sympy as sp

    A = sp.Matrix([[2, 0, 0, -1], [0, -2, 1, 0], [0, -1, -2, 0], [1, 0, 0, 2]])
    C = sp.Matrix([[1, 0, 0, 0], [0, 0, 2, -1]])
    T = sp.Matrix([[1, -2, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])
    Ti = T.inv()
    brackets = []
    for AA, CC in ((A, C), (T * A * Ti, C * Ti)):
        ub = upper_bound(System(AA, CC, sp.eye(4), sp.eye(2)), tol=1e-9)
        lo, hi = ub.interval
        assert ub.certified and Fraction(lo) <= Fraction(24, 25) <= Fraction(hi)
        assert not ub.lower_evidence.certified
        if hi - lo > 1e-9:
            assert ub.status == "undetermined" and any("regulariser" in w for w in ub.warnings)
        brackets.append((lo, hi))
    (la, ha), (lb, hb) = brackets
    assert la <= hb and lb <= ha
