"""Payloads of the ``upper_bound`` section: its certificate, the lower-end evidence and the
solver statistics.
"""
from __future__ import annotations

from dataclasses import dataclass

from kfcrit.io.typed import opt_key


@dataclass(frozen=True, kw_only=True)
class ProvenLowerEnd:
    """A point below the numerical lower end at which p_up >= p is proven in ball arithmetic."""

    value: float | None
    check: CertificateCheck
    statement: str


@dataclass(frozen=True, kw_only=True)
class UpperCertificate:
    """`upper_bound.certificate`"""

    kind: str
    origin: str
    ok: bool
    p: float | None
    min_eig_x_lower: float | None = opt_key()
    margin_lower: float | None = opt_key()
    reason: str
    margin_meaning: str = opt_key()
    verified_by: str
    X: list[list[float | None]] = opt_key()
    K: list[list[float | None]] = opt_key()
    matrices_verified: bool = opt_key()
    basis: list[list[float | None]] = opt_key()
    X_basis: list[list[float | None]] = opt_key()
    K_basis: list[list[float | None]] = opt_key()
    reverify: str = opt_key()
    output_map: list[list[float | None]] = opt_key()
    statement: str = opt_key()
    condition_number_C: float | None = opt_key()
    lmi_margin: float | None = opt_key()


@dataclass(frozen=True, kw_only=True)
class CertificateCheck:
    """`upper_bound.lower_evidence.check`"""

    ok: bool
    kind: str
    p: float | None
    min_eig_x_lower: float | None
    margin_lower: float | None
    reason: str
    margin_meaning: str
    verified_by: str


@dataclass(frozen=True, kw_only=True)
class UpperLowerEvidence:
    """`upper_bound.lower_evidence`"""

    kind: str
    value: float | None
    certified: bool
    statement: str
    p_low_enclosure: list[float | None] = opt_key()
    p_low_how: str = opt_key()
    expression: str | None = opt_key()
    p_low_theorem: float | None = opt_key()
    check: CertificateCheck = opt_key()
    X_u: list[list[float | None]] = opt_key()
    basis: list[list[float | None]] = opt_key()
    reduced_states: int = opt_key()
    proven_lower: ProvenLowerEnd = opt_key()


@dataclass(frozen=True, kw_only=True)
class UpperSolver:
    """`upper_bound.solver`"""

    power_iterations: int = opt_key()
    newton_iterations: int = opt_key()
    certificate_checks: int = opt_key()
    reduced_states: int = opt_key()
    certificate_from: str = opt_key()
    solves: int
    observer_rate: float | None = opt_key()
    regularisation: float | None = opt_key()
    output_compression: str = opt_key()
    special_case: str = opt_key()
    p_low: str = opt_key()
    failure: str = opt_key()
    failure_message: str = opt_key()
    failure_stage: str = opt_key()
    solver_seconds: float | None = opt_key()
    solver: str = opt_key()
    balancing: str = opt_key()
    ends: str = opt_key()
    cone_checks: dict[str, float | None] = opt_key()
    mare_start_p: float | None = opt_key()
    """Arrival probability at which the large-block path starts its MARE warm start."""
    operator_applications: int = opt_key()
    """Matrix-free applications of the Lyapunov-type operator (GMRES and Newton, large blocks)."""
    verified_by: str = opt_key()
    lower_enclosure: dict[str, float | None] = opt_key()
    """Numbers of the certified lower end of an interior root (large blocks): eigenbasis
    condition, eigenvalue gap, radii of the enclosed unstable pair, Weyl shift, margin."""
