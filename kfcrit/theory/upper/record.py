"""The record of the upper bound p_up: the :class:`UpperBound` result type and the helpers that
turn a checked certificate and its lower-end evidence into JSON-able record entries."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from kfcrit.model.system import System
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
    """The upper bound p_up with its bracket, certificate and evidence (a plain record)."""

    value: float | None
    interval: tuple[float, float]
    certified: bool
    status: str
    method: str
    certificate: dict[str, Any] | None
    lower_evidence: dict[str, Any]
    solver: dict[str, Any]
    warnings: tuple[str, ...] = ()
    extras: dict[str, Any] = field(default_factory=dict, compare=False, repr=False)
    tolerance: float | None = None

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-able data (no NaN/inf)."""
        return {"value": self.value, "interval": [float(self.interval[0]), float(self.interval[1])],
                "certified": self.certified, "status": self.status, "method": self.method,
                "certificate": self.certificate, "lower_evidence": self.lower_evidence,
                "solver": self.solver, "warnings": list(self.warnings),
                "tolerance": self.tolerance,
                "applicable": not self.extras.get("not_applicable"),
                "not_applicable_reason": self.extras.get("not_applicable")}




def evidence_p_low(p_low: float) -> dict[str, Any]:
    return {"kind": "theorem", "value": p_low, "certified": True,
            "statement": "p_up ≥ p_c ≥ p_low = 1 − 1/ρ(A)² (Sinopoli Thm 3)"}




def compression_note(red: Reduced) -> str:
    return (f"output compressed: C replaced by M C (rank {red.M.shape[0]}; C Z_u has condition "
            f"number > {OUTPUT_CONDITION_LIMIT:g} or dependent rows); gains checked as K M on "
            "the exact C")




def matrix_list(M: np.ndarray) -> list[list[float]]:
    """A float matrix as nested lists (JSON floats round-trip exactly)."""
    return [[float(v) for v in row] for row in np.atleast_2d(M)]


def certificate_summary(system: System, check: certify.CheckResult, X: np.ndarray,
                         K: np.ndarray, origin: str, basis: tuple | None = None,
                         output_map: np.ndarray | None = None) -> dict[str, Any]:
    """The record's certificate: what was proven, how, and (n ≤ RECORD_MATRIX_MAX) the matrices.

    A certificate checked in a basis (X = Z X_z Z', K = Z K_z, times M with an output map) is
    included exactly as checked (``basis``, ``X_basis``, ``K_basis``, ``output_map``), so the
    record alone re-verifies; the rounded full-state copies ``X``, ``K`` are re-checked directly
    (``matrices_verified``) — they may fail on their own when the margin is below the rounding.
    """
    out = {"kind": "X > 0 and X - L_{K,hi}(X) > 0 (Sinopoli Thm 5, Psi_hi(X^-1, X^-1 K) > 0)",
           "origin": origin, **check.to_dict()}
    if system.n <= RECORD_MATRIX_MAX:
        out["X"] = matrix_list(X)
        out["K"] = matrix_list(K)
        direct = check if basis is None else certify.verify_upper(system, check.p, X, K)
        out["matrices_verified"] = direct.ok
        if basis is not None:
            for name, M in zip(("basis", "X_basis", "K_basis"), basis):
                out[name] = matrix_list(M)
            if output_map is not None:
                out["output_map"] = matrix_list(output_map)
        out["reverify"] = ("X = basis X_basis basis', K = basis K_basis (output_map): check "
                           "X > 0 and X - (1-p) A X A' - p F X F' > 0, F = A + K C, p = the "
                           "certificate's p, exactly" if basis is not None else
                           "check X > 0 and X - (1-p) A X A' - p F X F' > 0, F = A + K C, "
                           "p = the certificate's p, exactly")
    return out

