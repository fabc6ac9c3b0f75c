"""The record of the upper bound p_up: the :class:`UpperBound` result type and the helpers that
build its certificate and lower-end evidence as the record's classes
(:mod:`kfcrit.records.bounds`)."""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from kfcrit.io.jsonio import native_number
from kfcrit.io.typed import ABSENT, to_json
from kfcrit.model.system import System
from kfcrit.records.bounds import UpperCertificate, UpperLowerEvidence, UpperSolver
from kfcrit.records.contract import UpperBoundRecord
from kfcrit.theory.upper import certify
from kfcrit.theory.upper.cone import OUTPUT_CONDITION_LIMIT, Reduced

SMALL_MATRIX = 6
"""Up to this many states the LMI's certificate matrices were included in older records (kept
for compatibility; now :data:`RECORD_MATRIX_MAX` applies to every method)."""
RECORD_MATRIX_MAX = 60
"""Certificates of systems with at most this many states are included in the record: the
matrices exactly as checked (``basis``, ``X_basis``, ``K_basis``, ``output_map``; JSON floats
round-trip exactly) and the rounded full-state copies ``X``, ``K``."""


@dataclass(frozen=True)
class UpperBound:
    """The upper bound p_up with its bracket, certificate and evidence.

    ``certificate`` and ``lower_evidence`` are the record's classes as built; ``solver`` holds
    the statistics accumulated along the way (plain numbers, ``seconds`` among them), read once
    by :meth:`record`.
    """

    value: float | None
    interval: tuple[float, float]
    certified: bool
    status: str
    method: str
    certificate: UpperCertificate | None
    lower_evidence: UpperLowerEvidence
    solver: dict[str, Any]
    warnings: tuple[str, ...] = ()
    extras: dict[str, Any] = field(default_factory=dict, compare=False, repr=False)
    tolerance: float | None = None

    def record(self) -> UpperBoundRecord:
        """The record's ``upper_bound`` section (its wall-clock ``seconds`` left out)."""
        reason = self.extras.get("not_applicable")
        return UpperBoundRecord(
            value=native_number(self.value),
            interval=[float(self.interval[0]), float(self.interval[1])],
            certified=bool(self.certified), status=self.status, method=self.method,
            certificate=self.certificate, warnings=list(self.warnings),
            tolerance=native_number(self.tolerance), lower_evidence=self.lower_evidence,
            solver=solver_record(self.solver), applicable=not reason,
            not_applicable_reason=None if reason is None else str(reason))

    def to_dict(self) -> dict[str, Any]:
        """The JSON form of :meth:`record`, with the solver's wall-clock ``seconds`` (no
        NaN/inf)."""
        out = to_json(self.record())
        if "seconds" in self.solver:
            out["solver"]["seconds"] = native_number(self.solver["seconds"])
        return out


SOLVER_INTEGERS = ("power_iterations", "newton_iterations", "certificate_checks",
                   "reduced_states", "solves", "operator_applications")
"""The solver statistics that are counts (the others are numbers, texts or tables)."""


def solver_record(stats: dict[str, Any]) -> UpperSolver:
    """The record's ``upper_bound.solver`` from the statistics accumulated by a method
    (``seconds``, wall-clock, left out): counts as int, numbers as float, tables of numbers
    entry by entry."""
    fields: dict[str, Any] = {}
    for key, v in stats.items():
        if key == "seconds":
            continue
        if key in SOLVER_INTEGERS:
            fields[key] = int(v)
        elif isinstance(v, dict):
            fields[key] = {str(k): native_number(x) for k, x in v.items()}
        elif isinstance(v, str) or v is None:
            fields[key] = v
        else:
            fields[key] = native_number(v)
    return UpperSolver(**fields)


def evidence_p_low(p_low: float, note: str = "") -> UpperLowerEvidence:
    """The lower end p_low of Sinopoli's Theorem 3 (proven), ``note`` appended to its
    statement."""
    return UpperLowerEvidence(kind="theorem", value=native_number(p_low), certified=True,
                              statement="p_up ≥ p_c ≥ p_low = 1 − 1/ρ(A)² (Sinopoli Thm 3)"
                                        + note)




def compression_note(red: Reduced) -> str:
    return (f"output compressed: C replaced by M C (rank {red.M.shape[0]}; C Z_u has condition "
            f"number > {OUTPUT_CONDITION_LIMIT:g} or dependent rows); gains checked as K M on "
            "the exact C")




def matrix_list(M: np.ndarray) -> list[list[float]]:
    """A float matrix as nested lists (JSON floats round-trip exactly)."""
    return [[float(v) for v in row] for row in np.atleast_2d(M)]


def certificate_summary(system: System, check: certify.CheckResult, X: np.ndarray,
                         K: np.ndarray, origin: str, basis: tuple | None = None,
                         output_map: np.ndarray | None = None) -> UpperCertificate:
    """The record's certificate: what was proven, how, and (n ≤ RECORD_MATRIX_MAX) the matrices.

    A certificate checked in a basis (X = Z X_z Z', K = Z K_z, times M with an output map) is
    included exactly as checked (``basis``, ``X_basis``, ``K_basis``, ``output_map``), so the
    record alone re-verifies; the rounded full-state copies ``X``, ``K`` are re-checked directly
    (``matrices_verified``) — they may fail on their own when the margin is below the rounding.
    """
    c = check.record()
    cert = UpperCertificate(kind=c.kind, origin=origin, ok=c.ok, p=c.p,
                            min_eig_x_lower=c.min_eig_x_lower, margin_lower=c.margin_lower,
                            reason=c.reason, margin_meaning=c.margin_meaning,
                            verified_by=c.verified_by)
    if system.n > RECORD_MATRIX_MAX:
        return cert
    direct = check if basis is None else certify.verify_upper(system, check.p, X, K)
    in_basis = basis is not None
    Z, Xz, Kz = basis if in_basis else (None, None, None)
    return replace(
        cert, X=matrix_list(X), K=matrix_list(K), matrices_verified=bool(direct.ok),
        basis=matrix_list(Z) if in_basis else ABSENT,
        X_basis=matrix_list(Xz) if in_basis else ABSENT,
        K_basis=matrix_list(Kz) if in_basis else ABSENT,
        output_map=matrix_list(output_map) if in_basis and output_map is not None else ABSENT,
        reverify=("X = basis X_basis basis', K = basis K_basis (output_map): check "
                  "X > 0 and X - (1-p) A X A' - p F X F' > 0, F = A + K C, p = the "
                  "certificate's p, exactly" if in_basis else
                  "check X > 0 and X - (1-p) A X A' - p F X F' > 0, F = A + K C, "
                  "p = the certificate's p, exactly"))
