"""Sinopoli's LMI for the upper bound p_up, solved so that it stays honest near the threshold.

    Ψ_p(Y, Z) = [ Y               √p (Y A + Z C)   √(1−p) Y A ]
                [ √p (A'Y + C'Z')  Y               0          ]  ≻ 0        (MATH.md §3)
                [ √(1−p) A'Y       0               Y          ]

is feasible iff p > p_up (Y = X^{-1}, Z = Y K). Ψ is homogeneous in (Y, Z), so we solve the
*margin* problem

    maximise t  subject to  Ψ_p(Y, Z) ⪰ t I,  Y ⪯ I,

whose optimum t* is > 0 iff the LMI is feasible and 0 otherwise ((Y, Z) = 0 gives t = 0).
The problem is built once with DPP parameters √p and √(1−p) and re-solved with Clarabel.
Scaling: the LMI is posed for the unstable Schur block (T_uu, C Z_u) of A (p_up depends on it
only, see :mod:`kfcrit.upper`; the stable modes make Y = X^{-1} needlessly ill-conditioned),
balanced by a diagonal similarity D (powers of two: A_b = D^{-1} T_uu D, C_b = C Z_u D).
Certificates are lifted back to the full state and checked there, on the exact matrices.

Each solve is classified, never guessed:

* feasible — status optimal, the a-posteriori eigenvalues of Ψ_p(Y, Z) and Y are positive,
  *and* X = T Y^{-1} T, K = T Y^{-1} Z pass :func:`kfcrit.certify.verify_upper` (balls);
* infeasible (numerical) — status optimal, t* ≤ ``INFEASIBLE_MARGIN`` *and* Clarabel returns
  status infeasible (a primal infeasibility certificate: W ⪰ 0 with Ψ_p*(W) = 0, tr W > 0, the
  theorem of alternatives) for the unit form Ψ_p ⪰ I;
* undetermined — anything else (solver error, ``*_INACCURATE``, a small positive t* that the
  checks cannot confirm). Bisection tries two off-centre points, then stops there and reports
  the bracket reached.

Known limitation (measured): when the critical cone eigenvector is singular — e.g. p_up = p_low
with one critical mode, as for random_system(20, 6, 0) — the feasible set is very thin near
p_up, the margins there are below the solver's accuracy, and Clarabel may report Ψ_p ⪰ I
infeasible at a feasible p: the LMI's lower end was 0.4082897 against p_up = p_low = 0.4082840.
The upper end is always proven; the lower end is labelled "numerical (solver)". The default
method (:mod:`kfcrit.upper`) does not have this problem.
"""
from __future__ import annotations

import time
import warnings
from typing import Any

import numpy as np
import scipy.linalg as sla

from . import certify
from .system import System

INFEASIBLE_MARGIN = 1e-10
"""Optimal margins t* at or below this are read as t* = 0 (infeasible, numerically)."""
CLARABEL_SETTINGS = {"tol_gap_abs": 1e-9, "tol_gap_rel": 1e-9, "tol_feas": 1e-9,
                     "max_iter": 400}
"""Tighter than Clarabel's defaults (1e-8), so that t* is resolved near the threshold."""


class PsiProblem:
    """The margin LMI built once for (A, C); :meth:`solve` classifies one value of p."""

    def __init__(self, A: np.ndarray, C: np.ndarray, output_map: np.ndarray | None = None) -> None:
        import cvxpy as cp

        self.cp = cp
        self.M = output_map
        _, (scale, _perm) = sla.matrix_balance(A, permute=False, separate=True)
        self.T = np.diag(scale)
        Ab = (A * scale[None, :]) / scale[:, None]          # T^{-1} A T, exact (powers of two)
        Cb = C * scale[None, :]
        self.Ab, self.Cb = Ab, Cb
        n, m = A.shape[0], C.shape[0]
        self.n, self.m = n, m
        self.Y = cp.Variable((n, n), symmetric=True)
        self.Z = cp.Variable((n, m))
        self.t = cp.Variable()
        self.s = cp.Parameter(nonneg=True)
        self.r = cp.Parameter(nonneg=True)
        O = np.zeros((n, n))
        top = self.s * (self.Y @ Ab + self.Z @ Cb)
        psi = cp.bmat([[self.Y, top, self.r * (self.Y @ Ab)],
                       [top.T, self.Y, O],
                       [self.r * (Ab.T @ self.Y), O, self.Y]])
        self.psi_constraint = (psi - self.t * np.eye(3 * n)) >> 0
        self.prob = cp.Problem(cp.Maximize(self.t),
                               [self.psi_constraint, np.eye(n) - self.Y >> 0])
        assert self.prob.is_dcp(dpp=True)
        # the unit form Ψ ⪰ I (the reference's normalisation): only its INFEASIBLE status,
        # Clarabel's primal infeasibility certificate, is used to decide "infeasible"
        self.unit = cp.Problem(cp.Minimize(cp.trace(self.Y)), [psi >> np.eye(3 * n)])
        assert self.unit.is_dcp(dpp=True)
        self.solves = 0
        self.seconds = 0.0

    def _gain(self, K: np.ndarray) -> np.ndarray:
        """The gain for the original C (rounded copy K M when the output is compressed)."""
        return K if self.M is None else K @ self.M

    def psi(self, Y: np.ndarray, Z: np.ndarray, p: float) -> np.ndarray:
        """Ψ_p(Y, Z) in the balanced coordinates (NumPy, for the a-posteriori check)."""
        s, r = np.sqrt(p), np.sqrt(1 - p)
        O = np.zeros_like(Y)
        top = s * (Y @ self.Ab + Z @ self.Cb)
        return np.block([[Y, top, r * Y @ self.Ab], [top.T, Y, O], [r * self.Ab.T @ Y, O, Y]])

    def dual_residual(self, W: np.ndarray, p: float) -> float:
        """‖Ψ_p*(W)‖ / ‖W‖ for the dual matrix W (0 for an exact infeasibility certificate)."""
        n = self.n
        s, r = np.sqrt(p), np.sqrt(1 - p)
        W11, W22, W33 = W[:n, :n], W[n:2 * n, n:2 * n], W[2 * n:, 2 * n:]
        W21, W31 = W[n:2 * n, :n], W[2 * n:, :n]
        AW21, AW31 = self.Ab @ W21, self.Ab @ W31
        DY = W11 + W22 + W33 + s * (AW21 + AW21.T) + r * (AW31 + AW31.T)
        DZ = self.Cb @ W21
        return float(max(np.abs(DY).max(), np.abs(DZ).max()) / max(np.abs(W).max(), 1e-300))

    def solve(self, system: System, p: float, lift) -> dict[str, Any]:
        """Classify p as "feasible", "infeasible" or "undetermined" (see the module docstring).

        ``lift(X_b, K_b, p)`` maps a certificate of the balanced reduced LMI to the full state
        as (basis Z, X_z, K_z) with X = Z X_z Z', K = Z K_z.
        """
        cp = self.cp
        self.s.value, self.r.value = float(np.sqrt(p)), float(np.sqrt(1.0 - p))
        t0 = time.perf_counter()
        self.solves += 1
        status = None
        for settings in (CLARABEL_SETTINGS, {}):      # tight first, Clarabel's defaults second
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    self.prob.solve(solver="CLARABEL", **settings)
            except (cp.error.SolverError, ValueError, ArithmeticError) as exc:
                self.seconds += time.perf_counter() - t0
                return {"p": p, "decision": "undetermined", "reason": f"solver error: {exc}"}
            status = self.prob.status
            if status == cp.OPTIMAL:
                break
        self.seconds += time.perf_counter() - t0
        if status != cp.OPTIMAL or self.t.value is None:
            return {"p": p, "decision": "undetermined", "reason": f"solver status {status}"}
        t_star = float(self.t.value)
        Y, Z = self.Y.value, self.Z.value
        lam_psi = float(np.linalg.eigvalsh(self.psi(Y, Z, p)).min())
        lam_y = float(np.linalg.eigvalsh(Y).min())
        out = {"p": p, "margin": t_star, "psi_min_eig": lam_psi, "status": status}
        if lam_psi > 0 and lam_y > 0:
            Xb = np.linalg.inv(Y)
            Xb = 0.5 * (Xb + Xb.T)
            Kb = Xb @ Z
            Z, Xz, Kz = lift(self.T @ Xb @ self.T, self.T @ Kb, p)
            check = certify.verify_upper(system, p, Xz, Kz, basis=Z, output_map=self.M)
            if check.ok:
                return {**out, "decision": "feasible", "check": check,
                        "X": Z @ Xz @ Z.T, "K": self._gain(Z @ Kz), "basis": Z, "X_basis": Xz,
                        "K_basis": Kz}
            return {**out, "decision": "undetermined",
                    "reason": f"positive margin not confirmed: {check.reason}"}
        if t_star > INFEASIBLE_MARGIN:
            return {**out, "decision": "undetermined",
                    "reason": f"margin {t_star:.3g} not confirmed by the eigenvalue check"}
        W = self.psi_constraint.dual_value
        if W is not None:        # tr W = 1 and Ψ_p*(W) = dual of Y ⪯ I, whose trace is t*
            out["dual_residual"] = self.dual_residual(np.asarray(W), p)
        return self._confirm_infeasible(system, p, out, lift)

    def _confirm_infeasible(self, system: System, p: float, out: dict[str, Any],
                            lift) -> dict[str, Any]:
        """A margin t* ≈ 0 is read as infeasible only if Clarabel proves Ψ_p ⪰ I infeasible."""
        cp = self.cp
        t0 = time.perf_counter()
        self.solves += 1
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                self.unit.solve(solver="CLARABEL")
        except (cp.error.SolverError, ValueError, ArithmeticError) as exc:
            self.seconds += time.perf_counter() - t0
            return {**out, "decision": "undetermined", "reason": f"solver error: {exc}"}
        self.seconds += time.perf_counter() - t0
        status = self.unit.status
        if status == cp.INFEASIBLE:
            return {**out, "decision": "infeasible", "unit_status": status}
        if status == cp.OPTIMAL and self.Y.value is not None:
            Y, Z = self.Y.value, self.Z.value
            if float(np.linalg.eigvalsh(self.psi(Y, Z, p)).min()) > 0:
                Xb = np.linalg.inv(Y)
                Xb = 0.5 * (Xb + Xb.T)
                Zb, Xz, Kz = lift(self.T @ Xb @ self.T, self.T @ (Xb @ Z), p)
                check = certify.verify_upper(system, p, Xz, Kz, basis=Zb,
                                             output_map=self.M)
                if check.ok:
                    return {**out, "decision": "feasible", "check": check,
                            "X": Zb @ Xz @ Zb.T, "K": self._gain(Zb @ Kz), "basis": Zb,
                            "X_basis": Xz, "K_basis": Kz}
        return {**out, "decision": "undetermined",
                "reason": f"margin {out['margin']:.3g} ~ 0 but Psi >= I gives status {status}"}


def lmi_upper_bound(system: System, tol: float = 1e-6, max_solves: int = 80):
    """Bisection on p over the margin LMI from [p_low, 1] to width ``tol`` (stops if undetermined).

    Returns an :class:`kfcrit.upper.UpperBound` with method "lmi".
    """
    from .upper import (
        UpperBound,
        _compression_note,
        _evidence_p_low,
        lift_certificate,
        p_low_of,
        reduce_system,
    )

    t0 = time.perf_counter()
    A, C = system.a, system.c
    p_low = p_low_of(A)
    red = reduce_system(system)      # output compressed when C Z_u is ill-conditioned
    if red.k == 0:
        from .upper import _newton_method
        return _newton_method(system, tol)

    def lift(Xu, Ku, p):
        return lift_certificate(red, C, Xu, Ku, p)

    problem = PsiProblem(red.Au, red.Cu, red.M)
    lo, hi = p_low, 1.0
    best = None
    last_infeasible = None
    notes: list[str] = []
    status = "determined"
    while hi - lo > tol and problem.solves < max_solves:
        # bisection point; if the solve there is undetermined, two off-centre points are tried
        for frac in (0.5, 0.618, 0.382):
            mid = lo + frac * (hi - lo)
            out = problem.solve(system, mid, lift)
            if out["decision"] != "undetermined":
                break
            notes.append(f"LMI undetermined at p = {mid:.12g}: {out['reason']}")
        if out["decision"] == "feasible":
            hi, best = mid, out
        elif out["decision"] == "infeasible":
            lo, last_infeasible = mid, out
        else:
            notes.append("bisection stopped")
            status = "undetermined"
            break
    if hi - lo > tol:
        status = "undetermined"
    solver = {"solves": problem.solves, "seconds": time.perf_counter() - t0,
              "solver_seconds": problem.seconds, "solver": "CLARABEL via cvxpy (DPP)",
              "reduced_states": red.k,
              "balancing": "diagonal similarity (scipy matrix_balance) of the unstable block"}
    if red.M is not None:
        solver["output_compression"] = _compression_note(red)
    cert = None
    if best is not None:
        check = best["check"]
        cert = {"kind": "X > 0 and X - L_{K,hi}(X) > 0 (Sinopoli Thm 5, Psi_hi(X^-1, X^-1 K) > 0)",
                "origin": "LMI solution (Y, Z) of the balanced unstable block, X_u = D Y^-1 D, "
                          "K_u = D Y^-1 Z, lifted to the full state",
                "lmi_margin": best["margin"], **check.to_dict()}
        if system.n <= 6:
            cert["X"] = [[float(v) for v in row] for row in best["X"]]
            cert["K"] = [[float(v) for v in row] for row in best["K"]]
            direct = certify.verify_upper(system, hi, best["X"], best["K"])
            cert["matrices_verified"] = direct.ok
            if not direct.ok:
                for name in ("basis", "X_basis", "K_basis"):
                    cert[name] = [[float(v) for v in row] for row in best[name]]
                if red.M is not None:
                    cert["output_map"] = [[float(v) for v in row] for row in red.M]
    if last_infeasible is None:
        lower = _evidence_p_low(p_low)
    else:
        lower = {"kind": "numerical", "value": lo, "certified": False,
                 "statement": (f"LMI margin t* = {last_infeasible['margin']:.3g} <= "
                               f"{INFEASIBLE_MARGIN:g} at p = {lo:.12g} and Clarabel's primal "
                               "infeasibility certificate for Psi_p >= I (W >= 0, Psi_p*(W) = 0, "
                               "checked by the solver to its tolerance); margin-problem dual "
                               "residual |Psi_p*(W)|/|W| = "
                               f"{last_infeasible.get('dual_residual')}"),
                 "p_low_theorem": p_low}
    return UpperBound(hi if best is not None else None, (lo, hi), best is not None, status, "lmi",
                      cert, lower, solver, tuple(notes),
                      {} if best is None else {k: best[k] for k in
                                               ("X", "K", "basis", "X_basis", "K_basis")})
