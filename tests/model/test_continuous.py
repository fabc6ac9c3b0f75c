"""Continuous-time models sampled with a zero-order hold (kfcrit.model.continuous).

Expected values are derived by hand (integrator chains, the scalar Ornstein–Uhlenbeck process)
or by two independent numerical methods: SciPy's ``expm`` of the Van Loan block, and adaptive
quadrature of the defining integral ``∫_0^T e^{A s} Q_c e^{A' s} ds``; the certified error bound
is checked against a 50-digit mpmath computation.
"""
from __future__ import annotations

import math
from pathlib import Path

import jsonschema
import mpmath
import numpy as np
import pytest
import sympy as sp
import yaml
from click.testing import CliRunner
from scipy.integrate import quad_vec
from scipy.linalg import expm

from kfcrit.analysis.spec import load_spec
from kfcrit.cli.main import main
from kfcrit.errors import InputError
from kfcrit.io.fileschema import system_schema
from kfcrit.io.systemfile import read_system_mapping
from kfcrit.model.continuous import EXACT_MAX_STATES, from_continuous_statespace, sample

from ..conftest import REPORTS

R_ = sp.Rational
EXAMPLE = REPORTS / "continuous-cv-tracker.yaml"


def van_loan_scipy(A: np.ndarray, Qc: np.ndarray, T: float) -> tuple[np.ndarray, np.ndarray]:
    """Van Loan (1978) with SciPy's Padé ``expm``: exp([[−A, Qc], [0, A']] T)."""
    n = A.shape[0]
    M = np.block([[-A, Qc], [np.zeros((n, n)), A.T]]) * T
    F = expm(M)
    Ad = F[n:, n:].T
    return Ad, Ad @ F[:n, n:]


def quadrature(A: np.ndarray, Qc: np.ndarray, T: float) -> tuple[np.ndarray, np.ndarray]:
    """The defining integral by adaptive quadrature (no block exponential)."""
    Q, _ = quad_vec(lambda s: expm(A * s) @ Qc @ expm(A * s).T, 0.0, T, epsabs=1e-15,
                    epsrel=1e-13)
    return expm(A * T), Q


def mpmath_reference(A: np.ndarray, Qc: np.ndarray, T: str) -> tuple[list, list]:
    """50-digit mpmath Van Loan (an independent high-precision exponential)."""
    with mpmath.workdps(50):
        n = A.shape[0]
        t = mpmath.mpf(sp.Rational(T).p) / sp.Rational(T).q
        M = mpmath.zeros(2 * n, 2 * n)
        for i in range(n):
            for j in range(n):
                M[i, j] = -mpmath.mpf(A[i, j]) * t
                M[i, n + j] = mpmath.mpf(Qc[i, j]) * t
                M[n + i, n + j] = mpmath.mpf(A[j, i]) * t
        F = mpmath.expm(M)
        Ad = mpmath.matrix([[F[n + j, n + i] for j in range(n)] for i in range(n)])
        F12 = mpmath.matrix([[F[i, n + j] for j in range(n)] for i in range(n)])
        Qd = Ad * F12
        return ([[Ad[i, j] for j in range(n)] for i in range(n)],
                [[Qd[i, j] for j in range(n)] for i in range(n)])


# -- exact cases, derived by hand ------------------------------------------------------------

def test_double_integrator_is_sampled_exactly() -> None:
    T, q = R_(1, 10), 2
    m = sample([[0, 1], [0, 0]], [[0, 0], [0, q]], "1/10")
    assert m.exact and m.method == "exact-nilpotent" and m.error_bound == 0
    assert m.A == sp.ImmutableMatrix([[1, T], [0, 1]])
    assert m.Q == q * sp.ImmutableMatrix([[T**3 / 3, T**2 / 2], [T**2 / 2, T]])
    assert m.Q == sp.ImmutableMatrix([[R_(1, 1500), R_(1, 100)], [R_(1, 100), R_(1, 5)]])


def test_triple_integrator_is_sampled_exactly() -> None:
    # e^{A s} = [[1, s, s²/2], [0, 1, s], [0, 0, 1]]; with Q_c = q e3 e3', the integrand is
    # q v(s) v(s)' with v(s) = (s²/2, s, 1), so Q = q ∫_0^T [[s⁴/4, s³/2, s²/2], [·, s², s],
    # [·, ·, 1]] ds = q [[T⁵/20, T⁴/8, T³/6], [T⁴/8, T³/3, T²/2], [T³/6, T²/2, T]].
    T, q = R_(1, 4), 3
    m = sample([[0, 1, 0], [0, 0, 1], [0, 0, 0]], [[0, 0, 0], [0, 0, 0], [0, 0, q]], "1/4")
    assert m.exact and m.method == "exact-nilpotent"
    assert m.A == sp.ImmutableMatrix([[1, T, T**2 / 2], [0, 1, T], [0, 0, 1]])
    assert m.Q == q * sp.ImmutableMatrix([[T**5 / 20, T**4 / 8, T**3 / 6],
                                          [T**4 / 8, T**3 / 3, T**2 / 2],
                                          [T**3 / 6, T**2 / 2, T]])


def test_scalar_ornstein_uhlenbeck_is_exact() -> None:
    # dx = −a x dt + dw: A = e^{−aT}, Q = q (1 − e^{−2aT}) / (2a).
    a, q, T = R_(3, 2), R_(5), R_(1, 5)
    m = sample([[-a]], [[q]], T)
    assert m.exact and m.method == "exact-rational-eigenvalues"
    assert sp.expand(m.A[0, 0] - sp.exp(-a * T)) == 0
    assert sp.expand(m.Q[0, 0] - q * (1 - sp.exp(-2 * a * T)) / (2 * a)) == 0


def test_exact_forms_agree_with_two_numerical_methods() -> None:
    # Jordan block, distinct rational poles, and a nilpotent chain with a full Q_c.
    cases = [([[-1, 1], [0, -1]], [[1, 0], [0, 2]], "1/10"),
             ([[-1, 3], [0, 2]], [[2, 1], [1, 1]], "3/10"),
             ([[0, 1, 0], [0, 0, 1], [0, 0, 0]], [[1, 0, 0], [0, 2, 1], [0, 1, 3]], "1/2")]
    for A, Qc, T in cases:
        m = sample(A, Qc, T)
        assert m.exact
        a, qc, t = np.array(A, float), np.array(Qc, float), float(sp.Rational(T))
        for Ad, Qd in (van_loan_scipy(a, qc, t), quadrature(a, qc, t)):
            np.testing.assert_allclose(m.float_a(), Ad, rtol=1e-12, atol=1e-14)
            np.testing.assert_allclose(m.float_q(), Qd, rtol=1e-10, atol=1e-14)


# -- certified float cases -------------------------------------------------------------------

def test_damped_oscillator_float_case_against_two_methods_and_its_bound() -> None:
    # λ² + λ/2 + 2 = 0: λ = −1/4 ± j·sqrt(31)/4, not rational, so not exact.
    A = np.array([[0.0, 1.0], [-2.0, -0.5]])
    Qc = np.array([[0.0, 0.0], [0.0, 3.0]])
    m = sample([[0, 1], [-2, "-1/2"]], [[0, 0], [0, 3]], "1/5")
    assert not m.exact and m.method == "certified-van-loan"
    assert "not all rational" in m.reason
    assert 0 < m.error_bound < 1e-15
    for Ad, Qd in (van_loan_scipy(A, Qc, 0.2), quadrature(A, Qc, 0.2)):
        np.testing.assert_allclose(m.float_a(), Ad, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(m.float_q(), Qd, rtol=1e-10, atol=1e-15)
    ref_a, ref_q = mpmath_reference(A, Qc, "1/5")
    with mpmath.workdps(50):
        for i in range(2):
            for j in range(2):
                assert abs(mpmath.mpf(m.float_a()[i, j]) - ref_a[i][j]) <= m.error_bound
                assert abs(mpmath.mpf(m.float_q()[i, j]) - ref_q[i][j]) <= m.error_bound
    assert np.array_equal(m.float_q(), m.float_q().T)


def test_irrational_entries_and_large_systems_take_the_certified_path() -> None:
    m = sample([[0, "sqrt(2)"], [0, 0]], [[0, 0], [0, 1]], "1/10")
    assert not m.exact and "irrational entries" in m.reason
    # Closed form with a = sqrt(2): A = [[1, aT], [0, 1]], Q = [[a²T³/3, aT²/2], [aT²/2, T]].
    a, T = math.sqrt(2), 0.1
    expected = np.array([[a * a * T**3 / 3, a * T**2 / 2], [a * T**2 / 2, T]])
    assert np.max(np.abs(m.float_q() - expected)) <= m.error_bound + 1e-17
    n = EXACT_MAX_STATES + 1
    big = sample(np.diag(np.ones(n - 1), 1), 1, "1/3")
    assert not big.exact and f"n = {n}" in big.reason
    # e^{N T} for the shift N has T^k/k! on the k-th superdiagonal.
    for k in range(n):
        assert abs(big.float_a()[0, k] - (1 / 3) ** k / math.factorial(k)) <= big.error_bound


def test_overflowing_exponential_is_a_one_line_error() -> None:
    with pytest.raises(InputError, match=r"^sampling_time: .*overflows"):
        sample([[1000]], 1, 10)
    with pytest.raises(InputError, match=r"^sampling_time: .*overflows"):
        sample([[0, 1], [2, 0]], 1, 1000)


# -- python-control --------------------------------------------------------------------------

def test_from_continuous_statespace_matches_control_c2d_and_van_loan() -> None:
    control = pytest.importorskip("control")
    A = np.array([[0.0, 1.0], [-2.0, -0.5]])
    sys_c = control.ss(A, [[0.0], [1.0]], [[1.0, 0.0]], [[0.0]])
    Qc = [[0, 0], [0, 3]]
    s = from_continuous_statespace(sys_c, "1/5", Qc, [[0.25]], name="osc")
    assert not s.exact and s.name == "osc"
    np.testing.assert_allclose(s.a, control.c2d(sys_c, 0.2, method="zoh").A, rtol=1e-12)
    np.testing.assert_allclose(s.q, van_loan_scipy(A, np.array(Qc, float), 0.2)[1], rtol=1e-12)
    np.testing.assert_array_equal(s.c, [[1.0, 0.0]])
    with pytest.raises(InputError, match=r"^sys: must be a continuous-time"):
        from_continuous_statespace(control.c2d(sys_c, 0.2), "1/5", Qc, [[0.25]])


# -- system files ----------------------------------------------------------------------------

BASE = {"name": "cv", "C": [[1, 0]], "R": [[1]],
        "continuous": {"A": [[0, 1], [0, 0]], "Q": [[0, 0], [0, 2]]}, "sampling_time": "1/10"}


def test_example_file_is_sampled_exactly_and_recorded() -> None:
    spec = load_spec(EXAMPLE)
    T = R_(1, 10)
    assert spec.system.exact
    assert spec.system.A == sp.ImmutableMatrix([[1, T], [0, 1]])
    assert spec.system.Q == 2 * sp.ImmutableMatrix([[T**3 / 3, T**2 / 2], [T**2 / 2, T]])
    rec = spec.continuous.to_dict()
    assert rec["A"] == [["0", "1"], ["0", "0"]] and rec["Q"] == [["0", "0"], ["0", "2"]]
    assert rec["sampling_time"] == "1/10" and rec["method"] == "exact-nilpotent"


def test_example_file_is_accepted_by_the_command_line() -> None:
    r = CliRunner().invoke(main, ["check", str(EXAMPLE)])
    assert r.exit_code == 0, r.output
    r = CliRunner().invoke(main, ["analyze", str(EXAMPLE), "--quick"])
    assert r.exit_code == 0, r.output
    assert "input exact" in r.output


def test_yaml_numbers_are_exact_in_continuous_files() -> None:
    doc = yaml.safe_load("name: x\ncontinuous: {A: [[0, 1], [0, 0]], Q: [[0, 0], [0, 2]]}\n"
                         "sampling_time: 0.1\nC: [[1, 0]]\nR: [[1]]\n")
    # yaml.safe_load gives a binary 0.1, taken as the rational it is and flagged inexact
    # (load_spec keeps the text "0.1" instead: the example-file test).
    spec = read_system_mapping(doc)
    assert spec.continuous.sampling_time == sp.Rational(0.1)
    assert spec.continuous.input_exact is False


BAD = [
    ({**BASE, "A": [[1, 0], [0, 1]]}, r"^A: give either A and Q"),
    ({**BASE, "Q": [[1, 0], [0, 1]]}, r"^Q: give either A and Q"),
    ({k: v for k, v in BASE.items() if k != "sampling_time"}, r"^sampling_time: is required"),
    ({k: v for k, v in BASE.items() if k != "continuous"}, r"^continuous: is required"),
    ({k: v for k, v in BASE.items() if k not in ("continuous", "sampling_time")},
     r"^A: is required \(or continuous: with sampling_time\)"),
    ({**BASE, "sampling_time": "-1/10"}, r"^sampling_time: must be positive"),
    ({**BASE, "sampling_time": 0}, r"^sampling_time: must be positive"),
    ({**BASE, "sampling_time": [1]}, r"^sampling_time: must be a number"),
    ({**BASE, "sampling_time": "import os"}, r"^sampling_time"),
    ({**BASE, "continuous": [[0, 1], [0, 0]]}, r"^continuous: must be a mapping"),
    ({**BASE, "continuous": {"A": [[0, 1], [0, 0]]}}, r"^continuous\.Q: is required"),
    ({**BASE, "continuous": {**BASE["continuous"], "B": 1}}, r"^continuous\.B: unknown key"),
    ({**BASE, "continuous": {"A": [[0, 1]], "Q": 1}}, r"^continuous\.A: must be square"),
    ({**BASE, "continuous": {"A": [[0, 1], [0, 0]], "Q": [[1]]}},
     r"^continuous\.Q: must be 2x2"),
    ({**BASE, "continuous": {"A": [[0, 1], [0, 0]], "Q": [[1, 1], [0, 1]]}},
     r"^continuous\.Q: must be symmetric"),
    ({**BASE, "continuous": {"A": [[0, 1], [0, 0]], "Q": [[0, 0], [0, -1]]}},
     r"^continuous\.Q: must be symmetric positive semidefinite"),
    ({**BASE, "continuous": {"A": [[0, "x"], [0, 0]], "Q": 1}}, r"^continuous\.A\[0\]\[1\]"),
]


@pytest.mark.parametrize(("doc", "message"), BAD)
def test_bad_continuous_input_is_a_one_line_error_naming_the_field(doc: dict,
                                                                   message: str) -> None:
    with pytest.raises(InputError, match=message) as info:
        read_system_mapping(doc)
    assert "\n" not in str(info.value)


def test_bad_file_exits_2_with_one_line(tmp_path: Path) -> None:
    p = tmp_path / "bad.yaml"
    p.write_text(EXAMPLE.read_text().replace("sampling_time: 0.1", "sampling_time: -0.1"))
    r = CliRunner().invoke(main, ["check", str(p)])
    assert r.exit_code == 2
    assert "sampling_time: must be positive" in r.output
    assert "Traceback" not in r.output


def test_schema_takes_either_form_not_both() -> None:
    validator = jsonschema.Draft202012Validator(system_schema())
    discrete = {"name": "s", "A": [[1]], "Q": 1, "C": [[1]], "R": 1}
    assert validator.is_valid(discrete)
    assert validator.is_valid(BASE)
    assert validator.is_valid(yaml.safe_load(EXAMPLE.read_text()))
    assert not validator.is_valid({**BASE, "A": [[1]]})
    assert not validator.is_valid({k: v for k, v in BASE.items() if k != "sampling_time"})
    assert not validator.is_valid({**discrete, "sampling_time": 1})
    assert not validator.is_valid({**BASE, "continuous": {"A": [[0]]}})


def test_above_the_certified_size_floats_say_they_have_no_bound() -> None:
    from kfcrit.model.continuous import CERTIFIED_MAX_STATES

    n = CERTIFIED_MAX_STATES + 1
    # A_c = −I/2 (not exact: too many states): A = e^{−T/2} I, Q = (1 − e^{−T}) I.
    m = sample(np.diag(np.full(n, -0.5)), 1, "1/2")
    assert m.method == "float-van-loan" and m.error_bound == math.inf
    assert "no proven error bound" in m.reason
    np.testing.assert_allclose(m.float_a(), math.exp(-0.25) * np.eye(n), rtol=1e-14, atol=1e-300)
    np.testing.assert_allclose(m.float_q(), (1 - math.exp(-0.5)) * np.eye(n), rtol=1e-13,
                               atol=1e-300)
