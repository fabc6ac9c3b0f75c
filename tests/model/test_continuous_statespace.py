"""python-control systems into kfcrit: ``kfcrit.from_statespace`` (discrete and continuous) and
``kfcrit.from_continuous_statespace``.

Expected values are derived by hand: the double integrator sampled with period T has
A = [[1, T], [0, 1]] and Q = q [[T³/3, T²/2], [T²/2, T]] for Q_c = diag(0, q)
(Q = ∫_0^T [s, 1]' q [s, 1] ds); the triple integrator has A = [[1, T, T²/2], [0, 1, T],
[0, 0, 1]]. Inexact inputs are compared with SciPy's ``expm`` of the Van Loan block and with
python-control's own ``c2d``.
"""
from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
import sympy as sp
from scipy.linalg import expm

import kfcrit
from kfcrit.errors import InputError
from kfcrit.model.continuous import from_continuous_statespace, from_statespace
from kfcrit.model.system import System, statespace_entries

control = pytest.importorskip("control")
R_ = sp.Rational


def double_integrator() -> object:
    return control.ss([[0, 1], [0, 0]], [[0], [1]], [[1, 0]], 0)


def hand_double_integrator(T: sp.Rational, q: int) -> tuple[sp.Matrix, sp.Matrix]:
    return (sp.Matrix([[1, T], [0, 1]]),
            q * sp.Matrix([[T**3 / 3, T**2 / 2], [T**2 / 2, T]]))


def test_sampling_time_string_is_exact() -> None:
    s = kfcrit.from_continuous_statespace(double_integrator(), "1/10", [[0, 0], [0, 2]], 1)
    A, Q = hand_double_integrator(R_(1, 10), 2)
    assert s.exact
    assert s.A == A and s.Q == Q
    assert s.A[0, 1] == R_(1, 10) and s.Q[0, 0] == R_(1, 1500)
    assert s.C == sp.Matrix([[1, 0]])


def test_from_statespace_continuous_double_integrator() -> None:
    s = kfcrit.from_statespace(double_integrator(), sampling_time="1/10",
                               Q=[[0, 0], [0, 2]], R=1, name="di")
    A, Q = hand_double_integrator(R_(1, 10), 2)
    assert s.exact and s.name == "di"
    assert s.A == A and s.Q == Q and s.R == sp.Matrix([[1]])


def test_from_statespace_triple_integrator_any_rational_period() -> None:
    sys_c = control.ss([[0, 1, 0], [0, 0, 1], [0, 0, 0]], [[0], [0], [1]], [[1, 0, 0]], 0)
    T = R_(3, 7)
    s = from_statespace(sys_c, sampling_time="3/7", Q=[[0, 0, 0], [0, 0, 0], [0, 0, 5]], R=2)
    assert s.A == sp.Matrix([[1, T, T**2 / 2], [0, 1, T], [0, 0, 1]])
    # Q = q ∫_0^T v v' ds with v = [s²/2, s, 1]
    sym = sp.Symbol("s")
    v = sp.Matrix([sym**2 / 2, sym, 1])
    assert s.Q == (5 * v * v.T).applyfunc(lambda e: sp.integrate(e, (sym, 0, T)))


def test_float_sampling_time_is_its_binary_value() -> None:
    s = from_statespace(double_integrator(), sampling_time=0.1, Q=[[0, 0], [0, 2]], R=1)
    assert not s.exact
    assert s.a[0, 1] == 0.1
    T = 0.1
    np.testing.assert_allclose(s.q, 2 * np.array([[T**3 / 3, T**2 / 2], [T**2 / 2, T]]),
                               rtol=1e-15)


def test_exact_overrides_replace_the_binary_floats() -> None:
    # velocity with drag 1/10: A_c = [[0, 1], [0, -1/10]], python-control holds -0.1 in binary
    sys_c = control.ss([[0, 1], [0, -0.1]], [[0], [1]], [[1, 0]], 0)
    plain = from_statespace(sys_c, sampling_time="1/2", Q=[[0, 0], [0, 1]], R=1)
    assert not plain.exact
    exact = from_statespace(sys_c, sampling_time="1/2", Q=[[0, 0], [0, 1]], R=1,
                            A=[[0, 1], [0, "-1/10"]], C=[[1, 0]])
    # by hand: e^{A_c T} = [[1, 10 (1 − e^{−T/10})], [0, e^{−T/10}]], T = 1/2
    e = sp.exp(R_(-1, 20))
    assert exact.exact and exact.A == sp.Matrix([[1, 10 * (1 - e)], [0, e]])
    np.testing.assert_allclose(plain.a, np.array(exact.A.evalf(30), dtype=float), rtol=1e-15)
    with pytest.raises(InputError, match=r"^A: differs from sys.A"):
        from_statespace(sys_c, sampling_time="1/2", Q=1, R=1, A=[[0, 1], [0, "-1/9"]])
    with pytest.raises(InputError, match=r"^C: must have the shape of sys.C"):
        from_statespace(sys_c, sampling_time="1/2", Q=1, R=1, C=[[1, 0, 0]])


def test_matches_control_c2d_and_van_loan() -> None:
    A = np.array([[0.0, 1.0], [-2.0, -0.5]])
    sys_c = control.ss(A, [[0.0], [1.0]], [[1.0, 0.0]], [[0.0]])
    s = from_statespace(sys_c, sampling_time="1/5", Q=[[0, 0], [0, 3]], R=[[0.25]])
    np.testing.assert_allclose(s.a, control.c2d(sys_c, 0.2, method="zoh").A, rtol=1e-12)
    M = np.block([[-A, np.diag([0.0, 3.0])], [np.zeros((2, 2)), A.T]]) * 0.2
    F = expm(M)
    np.testing.assert_allclose(s.q, F[2:, 2:].T @ F[:2, 2:], rtol=1e-12)


def test_discrete_statespace_as_before_and_exact_when_it_can_be() -> None:
    sys_d = control.ss([[1.25, 0], [1, 1.5]], [[1], [0]], [[1, 1]], [[0]], True)
    s = from_statespace(sys_d, Q=20, R="5/2")
    assert s.exact and s.A == sp.Matrix([[R_(5, 4), 0], [1, R_(3, 2)]])
    s2 = System.from_statespace(sys_d, Q=20, R="5/2")
    assert s2.A == s.A and s2.exact
    sys_b = control.c2d(double_integrator(), 0.1)
    sb = from_statespace(sys_b, Q=1, R=1)
    assert not sb.exact and sb.A[0, 1] == sp.Rational(Fraction(0.1))
    with pytest.raises(InputError, match=r"^sampling_time: applies to a continuous-time sys"):
        from_statespace(sys_d, sampling_time="1/10", Q=1, R=1)


def test_statespace_entries_exact_only_where_the_float_is_its_decimal() -> None:
    rows = statespace_entries(np.array([[0.0, 1.0, -1.25], [0.1, 3.0, 1e22]]))
    assert rows[0] == [0, 1, R_(-5, 4)] and all(isinstance(x, sp.Rational) for x in rows[0])
    assert isinstance(rows[1][0], float) and rows[1][0] == 0.1
    assert rows[1][1] == 3 and rows[1][2] == 10**22


def test_continuous_without_sampling_time_names_it() -> None:
    with pytest.raises(InputError, match=r"^sampling_time: is required for a continuous-time "
                                         r"sys .*kfcrit.from_statespace\(sys, sampling_time"):
        from_statespace(double_integrator(), Q=[[0, 0], [0, 2]], R=1)
    with pytest.raises(InputError, match=r"^sys: must be a discrete-time StateSpace.*"
                                         r"kfcrit.from_statespace\(sys, sampling_time=T"):
        System.from_statespace(double_integrator(), Q=1, R=1)
    with pytest.raises(InputError, match=r"^Q: is required"):
        from_statespace(double_integrator(), sampling_time="1/10", R=1)
    with pytest.raises(InputError, match=r"^sys: must be a python-control StateSpace"):
        from_statespace([[1]], Q=1, R=1)
    with pytest.raises(InputError, match=r"^sys: must be a continuous-time"):
        from_continuous_statespace(control.c2d(double_integrator(), 0.1), "1/10", 1, 1)


def test_exported() -> None:
    assert "from_statespace" in kfcrit.__all__ and "from_statespace" in dir(kfcrit)
    assert kfcrit.from_statespace is from_statespace
