"""Certificates for the two ends of the p_up bracket, each checked in ball arithmetic.

Upper end: X ≻ 0 with X − L_{K,p}(X) ≻ 0 (Sinopoli Thm 5 with Q, R scaled away) from a cone
eigenvector of the (regularised) noise-free MARE map or from the Stein solution of a gain,

.. math::

    X_u = (1-p) A_u X_u A_u' + p F_u X_u F_u' + I, \\qquad F_u = A_u + K C_u,

lifted to the full state (:func:`kfcrit.theory.upper.cone.lift_certificate`) and proven by
:func:`kfcrit.theory.upper.certify.verify_upper`. Lower end: a PSD X_u with G_p(X_u) ≻ X_u on an
exactly A-invariant subspace (:func:`cone_lower_check`).
"""
from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import scipy.linalg as sla

from kfcrit.model.system import System
from kfcrit.records.bounds import ProvenLowerEnd, UpperLowerEvidence
from kfcrit.theory.covariance.riccati import stein_matrix, symmetrize, unvech, vech
from kfcrit.theory.upper import certify
from kfcrit.theory.upper.cone import (
    MARGINAL_TOL,
    NEWTON_MAX_REDUCED,
    NewtonResult,
    Reduced,
    balanced_reduction,
    collatz_wielandt,
    cone_radius,
    lift_certificate,
    perron_newton,
    threshold_newton,
)
from kfcrit.theory.upper.record import (
    RECORD_MATRIX_MAX,
    evidence_p_low,
    matrix_list,
    native_number,
)


def lower_end(hi: float, tol: float, p_low: float) -> float:
    """The smallest float lo ≥ max(p_low, hi − tol) with hi − lo ≤ tol (in floating point)."""
    lo = max(p_low, hi - tol)
    while hi - lo > tol:
        lo = float(np.nextafter(lo, hi))
    return lo


def regularised_certificate(system: System, red: Reduced, plain: NewtonResult | None,
                             start: np.ndarray, p_start: float, p_star: float | None,
                             p_low: float, tol: float, stats: dict[str, Any]):
    """Continuation in ε of the regularised Newton, then a ball-checked lifted certificate.

    From a starting ε (1e-6, else 1e-4, 1e-8, 1e-3), ε goes down (at most tenfold per step, each
    solve warm-started, each eigenvector checked to be positive definite) until
    p_ε − p* ≤ tol/4 (slope dp_ε/dε estimated on the way). The certificate is tried from the
    smallest ε back. Returns (hi, (Z, X_z, K_z), check, ε) or None.
    """
    p0 = plain.p if plain is not None else p_start
    X0 = plain.X if plain is not None else start
    base = max(p_star if p_star is not None else p_start, p_low)
    for eps0 in (1e-6, 1e-4, 1e-8, 1e-3):
        good = _continuation(red, X0, p0, eps0, p_star, tol, stats)
        for eps_used, reg in reversed(good[-3:]):
            hi = float(np.nextafter(max(reg.p, p_low), 2.0))
            Z, Xz, Kz = lift_certificate(red, system.c, reg.X, reg.K, hi)
            check = certify.verify_upper(system, hi, Xz, Kz, basis=Z, output_map=red.M)
            stats["certificate_checks"] += 1
            if check.ok:
                stats["regularisation"] = eps_used
                return hi, (Z, Xz, Kz), check, eps_used
    return fixed_p_certificate(system, red, base, X0, tol, stats)


def fixed_p_certificate(system: System, red: Reduced, base: float, X0: np.ndarray, tol: float,
                        stats: dict[str, Any],
                        offsets: tuple[float, ...] = (0.5, 1.0, 10.0, 100.0, 1e4),
                        gains: tuple[np.ndarray, ...] = ()):
    """Certificate at p = base + offset·tol (offsets 1/2 … 10^4) from the cone eigenvector of
    G^ε_p (ε = 0 first): r_ε(p) < 1 with X ≻ 0 gives X − L_{K,p}(X) ⪰ (1 − r) X ≻ 0.

    That margin is (1 − r)·λ_min(X): near the threshold it can sink below the rounding of X (a
    nearly singular eigenvector, r = 1 − O(tol)). When the eigenvector check fails, the gain K
    of the eigenvector (and then each of ``gains``) is tried in :func:`stein_certificate`,
    whose margin is the identity by construction."""
    for mult in offsets:
        offset = mult * tol
        hi = float(min(base + offset, 1.0))
        stein_tried = False
        for eps in (0.0, 1e-2 * offset, 1e-4 * offset):
            X, r, K, ok = perron_newton(red.Au, red.Cu, X0 + eps * np.eye(red.k), hi, eps=eps)
            stats["newton_iterations"] += 1
            if not (ok and r < 1 and float(np.linalg.eigvalsh(X).min()) > 0):
                _, Xs, its = cone_radius(red.Au, red.Cu, hi, X0, eps=eps, iterations=2000)
                stats["power_iterations"] += its
                X, r, K, ok = perron_newton(red.Au, red.Cu, Xs, hi, eps=eps)
                stats["newton_iterations"] += 1
            if ok and r < 1 and float(np.linalg.eigvalsh(X).min()) > 0:
                Z, Xz, Kz = lift_certificate(red, system.c, X, K, hi)
                check = certify.verify_upper(system, hi, Xz, Kz, basis=Z, output_map=red.M)
                stats["certificate_checks"] += 1
                if check.ok:
                    stats["regularisation"] = eps
                    return hi, (Z, Xz, Kz), check, eps
            if not stein_tried and np.all(np.isfinite(K)):
                stein_tried = True
                bal = X if (ok and np.all(np.isfinite(X))
                            and float(np.linalg.eigvalsh(X).min()) > 0) else None
                for Kc in (K, *gains):
                    found = stein_certificate(system, red, hi, Kc, stats, balance=bal)
                    if found is not None:
                        stats["regularisation"] = eps
                        return (hi, *found, eps)
    return None


STEIN_REFINE_STEPS = 2
"""Steps of iterative refinement of the Stein solution (residual in float64, LU reused)."""




def stein_certificate(system: System, red: Reduced, p: float, K: np.ndarray,
                      stats: dict[str, Any], balance: np.ndarray | None = None):
    """Certificate at p from the gain K alone: X_u solves X_u = L_{K,p}(X_u) + I on the unstable
    block, lifted (:func:`lift_certificate`) and ball-checked (:func:`certify.verify_upper`).

    Why this is well conditioned where the eigenvector is not: with ρ(L_{K,p}) = 1 − δ the
    eigenvector X of G_p has X − L_{K,p}(X) ⪰ δ X, a margin δ·λ_min(X) that near the threshold
    (δ ~ tol, λ_min(X) ≪ 1) is at the level of the rounding of X. The Stein solution has the
    margin X_u − L(X_u) = I by construction, and its size ‖X_u‖ ~ 1/δ only scales the float
    residual, ~ u·‖X_u‖·‖I − L‖: the check has room as long as δ ≫ u (≈ 1e-16). X_u ≻ 0 with
    X_u − L(X_u) ≻ 0 holds iff ρ(L_{K,p}) < 1 (L is a positive map). The linear solve is only a
    proposal: the decision is the ball check on the exact matrices, so no solver error can make
    it pass.

    ‖X_u‖ is 1/δ only when the eigenvector of L_{K,p} is well conditioned; otherwise
    X_u = Σ L^j(I) can be far larger (1e15 for δ = 5e-10 on ``random_system(12, 4, 0)``). With
    ``balance`` = that eigenvector X the equation is solved in the coordinates of
    :func:`balanced_reduction` (there L(I) ≈ r I and X̃_u ≈ I/δ), and the unbalanced solve is
    the fallback. Returns ((Z, X_z, K_z), check) or None.
    """
    if red.k > NEWTON_MAX_REDUCED or not np.all(np.isfinite(K)):
        return None
    if balance is not None:
        bal = balanced_reduction(red, balance)
        if bal is not None:
            red_b, Tb = bal
            Kb = sla.solve_triangular(Tb, K, lower=True)     # F → T⁻¹ F T: K → T⁻¹ K
            found = stein_certificate(system, red_b, p, Kb, stats)
            if found is not None:
                stats["certificate_from"] += " (balanced by the cone eigenvector)"
                return found
    k = red.k
    Au, Cu = red.Au, red.Cu
    iu = np.triu_indices(k)
    eye = np.eye(k)
    try:
        with np.errstate(all="raise"):
            Lm = stein_matrix(Au, Cu, K, p)
            lu = sla.lu_factor(np.eye(Lm.shape[0]) - Lm, check_finite=True)
            Xu = unvech(sla.lu_solve(lu, vech(eye)), k)
            F = Au + K @ Cu
            for _ in range(STEIN_REFINE_STEPS):
                W = symmetrize(Xu - (1 - p) * Au @ Xu @ Au.T - p * F @ Xu @ F.T)
                res = eye - W
                if float(np.abs(res).max()) <= 1e-8:
                    break
                Xu = symmetrize(Xu + unvech(sla.lu_solve(lu, res[iu]), k))
    except (np.linalg.LinAlgError, FloatingPointError, ValueError, ZeroDivisionError):
        return None
    stats["newton_iterations"] += 1          # one dense solve of the vech system
    if not np.all(np.isfinite(Xu)):
        return None
    try:
        if float(np.linalg.eigvalsh(Xu).min()) <= 0:     # ρ(L_{K,p}) ≥ 1: no certificate
            return None
    except np.linalg.LinAlgError:
        return None
    Xu = Xu / float(np.trace(Xu))            # scale: immaterial to the check, tidy in the record
    Z, Xz, Kz = lift_certificate(red, system.c, Xu, K, p)
    check = certify.verify_upper(system, p, Xz, Kz, basis=Z, output_map=red.M)
    stats["certificate_checks"] += 1
    if not check.ok:
        return None
    stats["certificate_from"] = "stein: X_u = L_{K,p}(X_u) + I"
    return (Z, Xz, Kz), check


def _continuation(red: Reduced, X0: np.ndarray, p0: float, eps: float, p_star: float | None,
                  tol: float, stats: dict[str, Any]) -> list[tuple[float, NewtonResult]]:
    """The regularised Newton solutions (ε, result) along a decreasing sequence of ε."""
    _, X, its = cone_radius(red.Au, red.Cu, p0, X0, eps=eps)
    stats["power_iterations"] += its
    p = p0
    good: list[tuple[float, NewtonResult]] = []
    for _ in range(30):
        reg = threshold_newton(red.Au, red.Cu, X, p, eps=eps)
        stats["newton_iterations"] += reg.iterations
        if not (reg.converged and float(np.linalg.eigvalsh(reg.X).min()) > 0
                and reg.p >= (p_star if p_star is not None else -1.0) - 1e-12
                and reg.p <= 1.0):
            break
        good.append((eps, reg))
        X, p = reg.X, reg.p
        if p_star is None:
            if eps <= 0.02 * tol:
                break
            eps = max(0.1 * eps, 0.02 * tol)
            continue
        gap = reg.p - p_star
        if gap <= 0.25 * tol:
            break
        eps = max(0.1 * eps, 0.2 * tol * eps / gap)
    return good


def invariant_block_of(system: System, red: Reduced,
                       memo: dict[str, Any] | None = None) -> certify.InvariantBlock | None:
    """Ball enclosure of the exact unstable invariant block for ``red``.

    ``memo`` is the caller's per-computation store (one reduction of one system): the enclosure
    is computed once per store, never shared between computations.
    """
    if memo is not None and "block" in memo:
        return memo["block"]
    block = certify.invariant_block(system, red.Z, red.k)
    if memo is not None:
        memo["block"] = block
    return block


CONE_CONFIRM_MARGIN = 1e-11
"""A cone eigenvalue r(p) ≥ 1 + this (Newton-converged, PSD eigenvector) confirms p ≤ p_up
numerically."""


def cone_lower_check(system: System, red: Reduced, p: float, X0: np.ndarray | None,
                     stats: dict[str, Any] | None = None,
                     memo: dict[str, Any] | None = None) -> dict[str, Any]:
    """Independent evidence that p ≤ p_up: the cone eigenpair (X_u, r) of G_p on the unstable
    block (power iteration, then Newton), and a ball-checked proof when possible.

    Returns {"r", "X", "numerical": r ≥ 1 + CONE_CONFIRM_MARGIN with a converged PSD
    eigenvector, "certified": the proof passed, "check", "how"}.

    Why the unstable block suffices (and is valid for the full system): the first k Schur
    vectors span an A-invariant subspace V (exactly so for the enclosed W = Z[I; P] of
    :func:`kfcrit.theory.upper.certify.invariant_block`); for X = W X_u W' the noise-free map satisfies
    G_p(X) = W G^u_p(X_u) W', so the cone {W X_u W' : X_u ⪰ 0} is invariant and the cone
    spectral radius of the full map is at least that of G^u_p. An X_u ≻ 0 with
    G^u_p(X_u) ≻ X_u therefore gives X ⪰ 0, X ≠ 0 with G_p(X) ⪰ X, and the cone argument
    (:func:`kfcrit.theory.upper.certify.verify_lower_block`) shows that no Y ≻ 0 has Y ≻ G_p(Y): p ≤ p_up.
    (The converse direction — that p_up of the full system equals that of the block — is the
    reduction of the module docstring; the lower bound needs only the invariance.)
    """
    stats = stats if stats is not None else {}
    out: dict[str, Any] = {"r": None, "X": None, "numerical": False, "certified": False,
                           "check": None, "how": ""}
    start = X0 if X0 is not None and np.all(np.isfinite(X0)) else None
    r, Xp, its = cone_radius(red.Au, red.Cu, p, start, iterations=3000, rtol=1e-12)
    stats["power_iterations"] = stats.get("power_iterations", 0) + its
    X, r2, _K, ok = perron_newton(red.Au, red.Cu, Xp, p)
    stats["newton_iterations"] = stats.get("newton_iterations", 0) + 1
    if not (ok and np.isfinite(r2) and float(np.linalg.eigvalsh(X).min()) > -1e-10):
        c_lo, _ = collatz_wielandt(red.Au, red.Cu, Xp, p)
        out.update(r=c_lo, X=Xp, how="Collatz-Wielandt lower bound of the power iterate")
        X, r2 = Xp, c_lo
    else:
        out.update(r=r2, X=X, how="cone eigenpair of G_p by power iteration and Newton")
    out["numerical"] = bool(r2 >= 1.0 + CONE_CONFIRM_MARGIN)
    if not out["numerical"]:
        return out
    block = invariant_block_of(system, red, memo)
    if block is None:
        out["how"] += ("; no ball proof: the invariant subspace could not be enclosed "
                       f"(k(n-k) = {red.k * (system.n - red.k)}, limit {certify.KRONECKER_MAX})")
        return out
    for X_try in (X, X + 1e-9 * np.trace(X) * np.eye(red.k)):
        check = certify.verify_lower_block(block, p, symmetrize(X_try))
        stats["certificate_checks"] = stats.get("certificate_checks", 0) + 1
        if check.ok:
            out.update(certified=True, check=check, X=X_try)
            break
        out["check"] = check
    return out


def lower_evidence(system: System, red: Reduced, plain: NewtonResult, lo: float, p_low: float,
                    stats: dict[str, Any], tol: float | None = None) -> UpperLowerEvidence | str:
    """The strongest evidence for p_up ≥ lo that we can check, labelled.

    p_low (theorem) when lo ≤ p_low; else the cone eigenpair (X, r) of G_lo on the unstable
    block (:func:`cone_lower_check`): r ≥ 1 supports lo numerically, and is proven when
    X_u ≻ 0, G^u_lo(X_u) − X_u ≻ 0 pass in balls on an exactly A-invariant subspace enclosed
    by :func:`kfcrit.theory.upper.certify.invariant_block` (valid for the full system, stable modes
    included: see :func:`cone_lower_check`). When the proof fails at lo itself (its margin
    (r − 1)·λ_min(X_u) is below the ball widths), the largest of a few points lo − δ where it
    passes is reported as ``proven_lower`` (a proven p_up ≥ lo − δ beside the numerical lo).
    An eigenvalue r < 1 contradicts lo: the result is then the text saying why (a warning),
    not evidence.
    """
    if lo <= p_low:
        return evidence_p_low(p_low)
    memo: dict[str, Any] = {}
    conf = cone_lower_check(system, red, lo, plain.X, stats, memo)
    r = conf["r"]
    if r is None or not np.isfinite(r):
        return UpperLowerEvidence(
            kind="numerical", value=native_number(lo), certified=False,
            statement=(f"Newton root p* = {plain.p:.15g} of r(p) = 1 (residual "
                       f"{plain.residual:.2g}); the eigenpair at lo did not converge"),
            p_low_theorem=native_number(p_low))
    evidence = UpperLowerEvidence(
        kind="numerical", value=native_number(lo), certified=False,
        statement=("Newton root p* of the cone spectral radius r(p) = 1 of the noise-free "
                   f"MARE map (p* = {plain.p:.15g}, residual {plain.residual:.2g}); at lo "
                   f"the cone eigenvalue of the unstable block is r(lo) = {r:.15g} >= 1, so "
                   "no X > 0 has X > G_lo(X) (numerically; " + conf["how"] + ")"),
        p_low_theorem=native_number(p_low))
    if r < 1 - 1e-12:
        return (f"cone eigenvalue r({lo:.12g}) = {r:.15g} < 1 contradicts the "
                "Newton root; the lower end falls back to p_low")
    marginal = np.abs(np.abs(np.linalg.eigvals(red.Au)) - 1.0) <= MARGINAL_TOL
    if not conf["certified"] and np.any(marginal):
        # a mode on the unit circle makes the cone eigenvector nearly singular, and the
        # homogeneous regulariser then biases r(p) upward by more than tol (seen: r(lo) =
        # 1 + 2e-8 at a lo 1.7e-8 above a p_up proven by a certificate of the similar system)
        return (f"r({lo:.12g}) = {r:.15g} ≥ 1 is not evidence here: A has a "
                "mode with |λ| ≈ 1 in the unstable block, where the "
                "regularised cone eigenvalue is biased upward; the lower end "
                "falls back to p_low")
    if conf["certified"]:
        evidence = replace(
            evidence, kind="certificate", certified=True,
            statement="X_u > 0 with G_lo(X_u) - X_u > 0 (cone eigenvalue "
                      f"{r:.15g} > 1 of the noise-free MARE map) on the "
                      f"{red.k}-dimensional unstable invariant subspace, proven "
                      "in ball arithmetic; valid for the full system because "
                      "G_p maps the cone of that subspace into itself",
            check=conf["check"].record())
        if system.n <= RECORD_MATRIX_MAX:
            evidence = replace(evidence, X_u=matrix_list(conf["X"]), basis=matrix_list(red.Z),
                               reduced_states=int(red.k))
    elif conf["numerical"] and conf["check"] is not None:
        step = max(tol if tol is not None else 1e-9, 1e-12)
        for mult in (1, 10, 100, 1000):
            p = lo - mult * step
            if p <= p_low:
                break
            c2 = cone_lower_check(system, red, p, conf["X"], stats, memo)
            if c2["certified"]:
                evidence = replace(evidence, proven_lower=ProvenLowerEnd(
                    value=native_number(p), check=c2["check"].record(),
                    statement=f"p_up >= {p!r} proven: X_u > 0 with G_p(X_u) - X_u > 0 on "
                              "the unstable invariant subspace, ball arithmetic (at lo "
                              "itself the margin was below the ball widths: "
                              f"{conf['check'].reason})"))
                break
    return evidence


