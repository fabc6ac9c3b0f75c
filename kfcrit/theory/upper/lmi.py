"""Sinopoli's LMI for the upper bound p_up, solved so that it stays honest near the threshold.

    Ψ_p(Y, Z) = [ Y               √p (Y A + Z C)   √(1−p) Y A ]
                [ √p (A'Y + C'Z')  Y               0          ]  ≻ 0        (docs/theory.md §3)
                [ √(1−p) A'Y       0               Y          ]

is feasible iff p > p_up (Y = X^{-1}, Z = Y K). Ψ is homogeneous in (Y, Z), so we solve the
*margin* problem

    maximise t  subject to  Ψ_p(Y, Z) ⪰ t I,  Y ⪯ I,

whose optimum t* is > 0 iff the LMI is feasible and 0 otherwise ((Y, Z) = 0 gives t = 0).
The problem is built once with DPP parameters √p and √(1−p) and re-solved with Clarabel.
Scaling: the LMI is posed for the unstable Schur block (T_uu, C Z_u) of A (p_up depends on it
only, see :mod:`kfcrit.theory.upper.bracket`; the stable modes make Y = X^{-1} needlessly ill-conditioned),
balanced by a diagonal similarity D (powers of two: A_b = D^{-1} T_uu D, C_b = C Z_u D).
Certificates are lifted back to the full state and checked there, on the exact matrices.

Each solve is classified, never guessed:

* feasible — status optimal, the a-posteriori eigenvalues of Ψ_p(Y, Z) and Y are positive,
  *and* X = T Y^{-1} T, K = T Y^{-1} Z pass :func:`kfcrit.theory.upper.certify.verify_upper` (balls);
* infeasible — status optimal and t* ≤ ``INFEASIBLE_MARGIN``, *and independently confirmed*:
  the cone spectral radius r(p) of the noise-free MARE map on the unstable block is ≥ 1
  (power iteration + Newton, :func:`~kfcrit.theory.upper.certs.cone_lower_check`); the
  confirmation is a proof
  when X_u ≻ 0 with G_p(X_u) ≻ X_u passes in balls on an exactly invariant subspace, else it is
  labelled numerical. Clarabel's INFEASIBLE status for the unit form Ψ_p ⪰ I is recorded but
  never trusted alone (measured: it is wrong near the threshold, see below);
* undetermined — anything else (solver error, ``*_INACCURATE``, a small positive t* that the
  checks cannot confirm, t* ≈ 0 without confirmation). Bisection tries two off-centre points,
  then stops there and reports the bracket reached; its lower end is the last confirmed
  infeasible point (p_low, the theorem, at worst) and ``solver["ends"]`` says which ends are
  proven.

Measured: on random_system(20, 6, 0) (p_up = p_low = 0.4082840237, a single critical mode,
singular critical cone eigenvector) the margins near p_up are below the solver's accuracy and
Clarabel reports Ψ_p ⪰ I infeasible at feasible p (formerly a "determined" lower end 0.4082897
above the proven p_up ≤ 0.4082840242). Those points now fail the cone confirmation
(r(p) ≈ 0.99999 < 1), and the LMI reports the honest, undetermined bracket [p_low, hi].
"""
from __future__ import annotations

import time
import warnings
from dataclasses import replace
from typing import Any

import numpy as np
import scipy.linalg as sla

from kfcrit.model.system import System
from kfcrit.records.bounds import UpperLowerEvidence
from kfcrit.theory.critical.plow import p_low_of
from kfcrit.theory.upper import certify
from kfcrit.theory.upper.certs import cone_lower_check
from kfcrit.theory.upper.cone import lift_certificate, reduce_system
from kfcrit.theory.upper.newton import newton_method
from kfcrit.theory.upper.record import (
    RECORD_MATRIX_MAX,
    UpperBound,
    certificate_summary,
    compression_note,
    evidence_p_low,
    matrix_list,
    native_number,
)

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
        self.confirm = None
        """``confirm(p)`` → a :func:`~kfcrit.theory.upper.certs.cone_lower_check`-style dict (set
        by the caller); without it a margin t* ≈ 0 is never read as infeasible."""

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
        """A margin t* ≈ 0 is read as infeasible only with independent confirmation.

        First the unit form Ψ_p ⪰ I is solved: a solution that passes the ball check makes p
        feasible. Clarabel's INFEASIBLE status for it is *not* trusted (near the threshold it
        is wrong: random_system(20, 6, 0) gave "infeasible" at 0.4082897 > p_up): "infeasible"
        needs ``self.confirm(p)`` (:func:`~kfcrit.theory.upper.certs.cone_lower_check`), the cone
        spectral radius r(p) ≥ 1 of the noise-free MARE map on the unstable block — proven in
        balls when possible, else numerical — and is otherwise undetermined.
        """
        cp = self.cp
        t0 = time.perf_counter()
        self.solves += 1
        status = None
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                self.unit.solve(solver="CLARABEL")
            status = self.unit.status
        except (cp.error.SolverError, ValueError, ArithmeticError) as exc:
            status = f"solver error: {exc}"
        self.seconds += time.perf_counter() - t0
        out = {**out, "unit_status": status}
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
        if self.confirm is None:
            return {**out, "decision": "undetermined",
                    "reason": f"margin {out['margin']:.3g} ~ 0 (Psi >= I: status {status}) and "
                              "no independent confirmation available"}
        conf = self.confirm(p)
        out["cone_radius"] = conf["r"]
        if conf["certified"]:
            return {**out, "decision": "infeasible", "evidence": "certificate",
                    "confirmation": conf}
        if conf["numerical"]:
            return {**out, "decision": "infeasible", "evidence": "numerical",
                    "confirmation": conf}
        return {**out, "decision": "undetermined",
                "reason": f"margin {out['margin']:.3g} ~ 0 (Psi >= I: status {status}) but the "
                          f"cone spectral radius r(p) = {conf['r']} is not confirmed >= 1 "
                          "(the solver's infeasibility is not trusted alone)"}


def lmi_upper_bound(system: System, tol: float = 1e-6, max_solves: int = 80):
    """Bisection on p over the margin LMI from [p_low, 1] to width ``tol`` (stops if undetermined).

    Returns an :class:`kfcrit.theory.upper.record.UpperBound` with method "lmi".
    """
    t0 = time.perf_counter()
    A, C = system.a, system.c
    p_low = p_low_of(A)
    red = reduce_system(system)      # output compressed when C Z_u is ill-conditioned
    if red.k == 0:
        return newton_method(system, tol)

    def lift(Xu, Ku, p):
        return lift_certificate(red, C, Xu, Ku, p)

    problem = PsiProblem(red.Au, red.Cu, red.M)
    warm: dict[str, Any] = {"X": None}
    cone_stats: dict[str, Any] = {}
    block_memo: dict[str, Any] = {}

    def confirm(p):
        conf = cone_lower_check(system, red, p, warm["X"], cone_stats, block_memo)
        if conf["X"] is not None and conf["numerical"]:
            warm["X"] = conf["X"]
        return conf

    problem.confirm = confirm
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
        solver["output_compression"] = compression_note(red)
    if cone_stats:
        solver["cone_checks"] = cone_stats
    cert = None
    if best is not None:
        check = best["check"]
        cert = certificate_summary(
            system, check, best["X"], best["K"],
            "LMI solution (Y, Z) of the balanced unstable block, X_u = D Y^-1 D, "
            "K_u = D Y^-1 Z, lifted to the full state",
            (best["basis"], best["X_basis"], best["K_basis"]), red.M)
        cert = replace(cert, lmi_margin=native_number(best["margin"]))
    if last_infeasible is None:
        lower = evidence_p_low(p_low)
    else:
        conf = last_infeasible["confirmation"]
        proven = last_infeasible["evidence"] == "certificate"
        lower = UpperLowerEvidence(
            kind="certificate" if proven else "numerical", value=native_number(lo),
            certified=bool(proven),
            statement=(f"LMI margin t* = {last_infeasible['margin']:.3g} <= "
                       f"{INFEASIBLE_MARGIN:g} at p = {lo:.12g} (Clarabel's status for "
                       f"Psi_p >= I: {last_infeasible.get('unit_status')}, not trusted "
                       "alone), confirmed independently: cone spectral radius r(p) = "
                       f"{conf['r']:.15g} >= 1 of the noise-free MARE map on the "
                       f"unstable block ({conf['how']})"
                       + ("; X_u > 0 with G_p(X_u) - X_u > 0 proven in ball arithmetic "
                          "on an exactly A-invariant subspace" if proven else
                          "; numerical, not proven")),
            p_low_theorem=native_number(p_low))
        if proven:
            lower = replace(lower, check=conf["check"].record())
            if system.n <= RECORD_MATRIX_MAX:
                lower = replace(lower, X_u=matrix_list(conf["X"]), basis=matrix_list(red.Z),
                                reduced_states=int(red.k))
    ends = ("upper end proven (ball-checked certificate)" if best is not None else
            "upper end not proven (no verified feasible point)")
    ends += "; lower end " + (
        "proven (ball-checked cone certificate)" if lower.kind == "certificate" else
        "the theorem p_low (no confirmed infeasible point above it)" if lower.kind == "theorem"
        else "numerical (cone spectral radius >= 1, not proven)")
    solver["ends"] = ends
    if status != "determined":
        notes.append("LMI bracket not determined to the requested width: " + ends)
    return UpperBound(hi if best is not None else None, (lo, hi), best is not None, status, "lmi",
                      cert, lower, solver, tuple(notes),
                      {} if best is None else {k: best[k] for k in
                                               ("X", "K", "basis", "X_basis", "K_basis")})
