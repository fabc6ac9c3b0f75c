"""p_up of systems with marginal modes (ρ(A) = 1): the slow-observer certificate.

For ρ(A) ≤ 1 and (C, A) detectable, p_c = 0 (MATH §11), and the single-output formula
p_up = 1 − 1/Π|λ_u|² (MATH §3) gives 0 as well. The Newton method's threshold sits at p = 0,
where the cone eigenvector is singular, so its bracket stayed at [0, 100·tol]. The slow observer
certifies p_up ≤ tol; each certificate is re-checked here independently of python-flint, in
exact rational arithmetic (sympy), by Sylvester's criterion on X and X − L_{K,p}(X).
"""
from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
import yaml
from click.testing import CliRunner

from kfcrit.cli.main import main
from kfcrit.model.system import System
from kfcrit.records.bounds import UpperCertificate
from kfcrit.theory.upper.bracket import upper_bound

R_ = sp.Rational

MARGINAL = {
    "double integrator T = 1/10": ([[1, "1/10"], [0, 1]], [[1, 0]]),
    "triple integrator": ([[1, "1/10", "1/200"], [0, 1, "1/10"], [0, 0, 1]], [[1, 0, 0]]),
    "rotation, irrational angle": ([["3/5", "-4/5"], ["4/5", "3/5"]], [[1, 0]]),
    "two double integrators, two outputs": ([[1, 1, 0, 0], [0, 1, 0, 0], [0, 0, 1, 1],
                                             [0, 0, 0, 1]], [[1, 0, 1, 0], [0, 0, 1, 0]]),
    "Jordan block and a stable mode": ([[1, 1, 0], [0, 1, 0], [0, 0, "1/2"]], [[1, 0, 1]]),
    "modes 1 and -1": ([[1, 0], [0, -1]], [[1, 1]]),
}


def exact(M: object) -> sp.Matrix:
    """A float matrix as the exact rationals its binary entries are."""
    return sp.Matrix([[R_(float(v)) for v in row] for row in np.atleast_2d(np.asarray(M))])


def positive_definite(M: sp.Matrix) -> bool:
    """Sylvester's criterion, exactly."""
    return all(M[:k, :k].det() > 0 for k in range(1, M.shape[0] + 1))


def recheck(system: System, certificate: UpperCertificate, p: float) -> bool:
    """X ≻ 0 and X − (1−p) A X A' − p F X F' ≻ 0 with X = Z X_z Z', K = Z K_z (M), exactly."""
    Z = exact(certificate.basis)
    X = Z * exact(certificate.X_basis) * Z.T
    K = Z * exact(certificate.K_basis)
    if certificate.output_map:
        K = K * exact(certificate.output_map)
    A, C, q = sp.Matrix(system.A), sp.Matrix(system.C), R_(p)
    F = A + K * C
    return positive_definite(X) and positive_definite(X - (1 - q) * A * X * A.T
                                                      - q * F * X * F.T)


@pytest.mark.parametrize("name", sorted(MARGINAL))
def test_marginal_p_up_is_certified_within_tol(name: str) -> None:
    A, C = MARGINAL[name]
    system = System(A, C, 1, 1)
    tol = 1e-9
    ub = upper_bound(system, tol=tol)
    assert ub.certified and ub.status == "determined", (ub.interval, ub.warnings)
    lo, hi = ub.interval
    assert lo == 0.0 and 0 < hi <= tol
    assert recheck(system, ub.certificate, hi)


def test_certificate_fails_the_recheck_at_p_zero() -> None:
    """The exact recheck is not vacuous: at p = 0 no X ≻ 0 has X ≻ A X A' for ρ(A) = 1."""
    system = System([[1, "1/10"], [0, 1]], [[1, 0]], 1, 1)
    ub = upper_bound(system, tol=1e-9)
    assert not recheck(system, ub.certificate, 0.0)


def test_unstable_system_keeps_its_newton_bracket() -> None:
    """Not marginal: p_up = 1 − 1/(1.25·1.1)² (single output, MATH §3), no slow observer."""
    system = System([["5/4", 0], [1, "11/10"]], [[1, 1]], 20, "5/2")
    ub = upper_bound(system, tol=1e-9)
    expected = 1 - 1 / (1.25 * 1.1) ** 2
    assert ub.status == "determined" and ub.interval[0] - 1e-9 <= expected <= ub.interval[1]
    assert "slow observer" not in ub.certificate.origin


def test_continuous_double_integrator_without_channel_passes(tmp_path) -> None:
    doc = {"name": "continuous double integrator",
           "continuous": {"A": [[0, 1], [0, 0]], "Q": [[0, 0], [0, 2]]},
           "sampling_time": "1/10", "C": [[1, 0]], "R": 1}
    path = tmp_path / "di.yaml"
    path.write_text(yaml.safe_dump(doc))
    r = CliRunner().invoke(main, ["analyze", str(path)])
    assert r.exit_code == 0, r.output
    assert "REVIEW: PASS" in r.output and "could not be narrowed" not in r.output
    assert "in [0, 1e-09]  certified" in r.output
