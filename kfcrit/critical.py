"""Critical arrival probability (placeholder: lower bound only; filled by the critical-value work)."""
from __future__ import annotations

from typing import Any

import numpy as np
import sympy as sp

from .system import System


def lower_bound(system: System) -> dict[str, Any]:
    """Sinopoli Thm 3 lower bound p_low = 1 − 1/ρ(A)², 0 when ρ(A) ≤ 1."""
    if system.exact and system.n <= 6:
        eigs = list(sp.Matrix(system.A).eigenvals())
        mod2 = [sp.nsimplify(sp.expand(e * sp.conjugate(e))) for e in eigs]
        rho2 = max(mod2, key=lambda v: float(sp.N(v, 30)))
        if bool(rho2 <= 1):
            return {"value": 0.0, "expression": "0"}
        expr = sp.nsimplify(1 - 1 / rho2)
        return {"value": float(sp.N(expr, 30)), "expression": sp.sstr(expr)}
    rho = float(max(abs(np.linalg.eigvals(system.a))))
    value = max(0.0, 1 - 1 / rho**2)
    return {"value": value, "expression": repr(value)}
