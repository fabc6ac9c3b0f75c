"""p_up for large unstable blocks (k > ``NEWTON_MAX_REDUCED``): matrix-free Newton on the
threshold, a Stein certificate at hi, and the verified float64 check (docs/theory.md §3,
"Large unstable blocks").

.. math::

    X_u - L_{K,hi}(X_u) = I \\;\\Rightarrow\\; X_u \\succ L_{K,hi}(X_u)
    \\;\\Rightarrow\\; p_{up} \\le hi \\quad(\\text{after lifting, checked on the exact } A, C)

Steps: (0) the face-root certificate of :mod:`kfcrit.theory.upper.stein` at p_low + tol/2 (a
gain that cancels the modes of modulus ρ(A), the MARE gain on the rest of the unstable block,
a block-triangular Stein solution on the full state), with the lower end p_low proven by
:func:`verified_p_low` when no ball enclosure of ρ(A) is available; otherwise
(1) a start from the MARE with Q = I, R = I at some p > p_up (fixed point, cheap there);
(2) damped threshold Newton (:func:`kfcrit.theory.upper.krylov.threshold_newton_krylov`), which
either converges to p* > p_low or runs into the floor p_low (a face root: p_up = p_low);
(3) at hi = base + w (w from :func:`stein_widths`: 0.9·tol, 0.5·tol, then the wider
widths) the gain K of the threshold eigenvector and the preconditioned Stein solution
X_u − L_{K,hi}(X_u) = I, lifted block by block to the full state and proven by
:func:`kfcrit.theory.upper.floatcheck.verify_upper_float_basis`; only when every width fails,
the costlier :func:`float_certificate` (cone eigenpair of G_hi, its Stein solution, the cruder
lift) at the few :func:`fallback_widths`.
The lower end is p_low (Sinopoli Thm 3, proven) for a face root; otherwise lo = hi − tol
(never above the Newton root p*) proven by :func:`kfcrit.theory.upper.lowercert.prove_lower_end`
(a Y ⪰ 0 with G_lo(Y) ⪰ Y on the enclosed exact unstable invariant subspace), or, when that
fails, the Newton root with numerical evidence G_lo(X*) = X* + (p* − lo) P ⪰ X*, labelled not
certified.
"""
from __future__ import annotations

from fractions import Fraction
from typing import Any

import numpy as np

from kfcrit.model.system import System
from kfcrit.records.bounds import UpperLowerEvidence
from kfcrit.theory.covariance.riccati import symmetrize
from kfcrit.theory.upper import certify, floatcheck, krylov, lowercert, stein
from kfcrit.theory.upper.certs import lower_end
from kfcrit.theory.upper.cone import (
    UNSTABLE_TOL,
    Reduced,
    full_gain,
    lift_certificate,
    reduce_system,
    stable_gramian,
)
from kfcrit.theory.upper.record import (
    certificate_summary,
    evidence_p_low,
    native_number,
)

START_OFFSETS = (0.02, 0.1, 0.3, 1.0)
"""p − p_low tried (clipped to 1) for the MARE start, until its fixed point converges."""
EIGEN_STEPS = 6
"""Eigen-Newton steps at hi: only the gain of the eigenvector is used (the Stein solve gives
the certificate), and near a face root the eigenvector turns singular, so more steps buy
nothing."""
FACE_GAP = 1e-6
"""A converged threshold root this close to p_low is treated as the face root p_up = p_low."""
FLOAT_CHECK = ("verified float64: midpoint-radius products with a priori rounding-error bounds "
               "(gamma_q |U||V| + underflow) on the exact A, C (one ulp from their float views) "
               "and the float certificate taken exactly; positive definiteness by a Cholesky "
               "residual bound (docs/theory.md §3, Verified float64 check)")


def _start(red: Reduced, p_low: float, stats: dict[str, Any]) -> tuple[np.ndarray, float] | None:
    """A normalised MARE solution at the first p = p_low + offset where the iteration converges."""
    for off in START_OFFSETS:
        p0 = min(1.0, p_low + off)
        X0, ok = krylov.mare_start(red.Au, red.Cu, p0)
        stats["mare_start_p"] = p0
        if ok and np.trace(X0) > 0:
            return X0 / np.trace(X0), p0
    return None


def float_certificate(system: System, red: Reduced, hi: float, X_start: np.ndarray,
                      stats: dict[str, Any], Ys: np.ndarray | None):
    """The Stein certificate at hi (gain of the cone eigenvector of G_hi), lifted and checked by
    the verified float64 check; then the eigenvector itself. Returns (basis triple, X, K,
    CheckResult) or None."""
    eig = krylov.eigen_newton_krylov(red.Au, red.Cu, X_start, hi, EIGEN_STEPS)
    stats["newton_iterations"] += eig.iterations
    stats["operator_applications"] += eig.matvecs
    candidates = []
    if np.all(np.isfinite(eig.K)):
        Xs, mv = krylov.stein_solve_krylov(red.Au, red.Cu, eig.K, hi, np.eye(red.k))
        stats["operator_applications"] += mv
        candidates.append((Xs, eig.K))
    if eig.converged and eig.value < 1:
        candidates.append((eig.X, eig.K))
    for Xu, Ku in candidates:
        if not (np.all(np.isfinite(Xu)) and krylov._positive_definite(Xu)):
            continue
        Z, Xz, Kz = lift_certificate(red, system.c, Xu, Ku, hi, Ys)
        Xz = np.triu(Xz) + np.triu(Xz, 1).T                 # exactly symmetric
        ok, mx, mm, why = floatcheck.verify_upper_float_basis(system.a, system.c, hi, Z, Xz,
                                                              Kz, red.M)
        stats["certificate_checks"] += 1
        if ok:
            check = certify.CheckResult(True, "upper: X > 0 and X - L_{K,p}(X) > 0", hi, mx, mm,
                                        why, FLOAT_CHECK)
            return (Z, Xz, Kz), symmetrize(Z @ Xz @ Z.T), full_gain(red, Z @ Kz), check
    return None


FACE_OFFSET = 0.5
"""The face-root certificate is tried first at hi = p_low + FACE_OFFSET·tol."""
WIDER_WIDTHS = (1e-8, 1e-7, 1e-6, 1e-5, 1e-4)
"""Widths hi − base tried in turn (those above the first try) when the certificate at the
requested width fails the verified check: the Stein solution's condition number grows like
1/(hi − p_up), so a bracket narrower than about 1e-8 can be beyond float64 at a few hundred
states. A wider certified bracket is reported as such (status "undetermined", with a warning
naming both widths) rather than the trivial [p_low, 1]."""


def certificate_widths(tol: float, first: float) -> list[float]:
    r"""hi − base to try: ``first·tol``, then each of :data:`WIDER_WIDTHS` above it.

    .. math::  w_0 = c\,\mathrm{tol},\quad w_{k} \in \{10^{-8}, \dots, 10^{-4}\},\ w_k > w_0
    """
    w0 = first * tol
    return [w0] + [w for w in WIDER_WIDTHS if w > w0]


def widened_warning(width: float, tol: float) -> str:
    """The warning of a certified bracket wider than the requested tolerance."""
    return (f"p_up certified to width {width:.1e} only: the certificate at the requested width "
            f"{tol:.1e} did not pass the verified float64 check (float64 conditioning near "
            "the threshold)")
FACE_CHECK = FLOAT_CHECK + ("; the leading dominant-block columns of Z'AZ and Z'Z and the "
                            "products with the dominant block of X_z by compensated dot "
                            "products (Ogita-Rump-Oishi Dot2)")


def face_root_certificate(system: System, red: Reduced, p_low: float, tol: float,
                          stats: dict[str, Any]):
    """p_up ≤ hi = p_low + FACE_OFFSET·tol by the face-root certificate of
    :mod:`kfcrit.theory.upper.stein` (the gain kills the modes of modulus ρ(A); the rest of the
    unstable block is stabilised by its own MARE gain), checked by the verified float64 check.
    Returns (hi, basis triple, X, K, CheckResult, verified lower bound on p_low or None) or None
    (not a face root, or not proven)."""
    split = stein.dominant_split(red)
    if split is None:
        return None
    red_d, d = split
    for width in certificate_widths(tol, FACE_OFFSET):
        hi = float(min(p_low + width, 1.0))
        mats = stein.face_certificate_matrices(red_d, d, hi)
        if mats is None:
            return None
        Xz, Kz = mats
        ok, mx, mm, why = floatcheck.verify_upper_float_basis(system.a, system.c, hi, red_d.Z,
                                                              Xz, Kz, red.M, sharp=d)
        stats["certificate_checks"] += 1
        if ok:
            break
    else:
        return None
    stats["certificate_from"] = (f"face root: gain killing the {d} dominant modes (|λ| = ρ(A)), "
                                 "MARE gain on the rest of the unstable block, block-triangular "
                                 "Stein solution on the full state")
    check = certify.CheckResult(True, "upper: X > 0 and X - L_{K,p}(X) > 0", hi, mx, mm, why,
                                FACE_CHECK)
    Z = red_d.Z
    rho2 = floatcheck.dominant_radius_lower(system.a, Z, d)
    verified = None
    if rho2 is not None and rho2 > 1.0:
        verified = certify.float_down(1 - 1 / Fraction(rho2))
    return hi, (Z, Xz, Kz), symmetrize(Z @ Xz @ Z.T), full_gain(red, Z @ Kz), check, verified


def verified_p_low(system: System, red: Reduced | None = None) -> float | None:
    """A rigorous lower bound on p_low = 1 − 1/ρ(A)² from the dominant Schur block
    (:func:`kfcrit.theory.upper.floatcheck.dominant_radius_lower`), or None."""
    red = reduce_system(system) if red is None else red
    split = stein.dominant_split(red)
    if split is None:
        return None
    rho2 = floatcheck.dominant_radius_lower(system.a, split[0].Z, split[1])
    if rho2 is None or not rho2 > 1.0:
        return None
    return certify.float_down(1 - 1 / Fraction(rho2))


P_LOW_VERIFIED = ("p_low >= 1 - 1/rho2 with rho(A)^2 >= rho2 proven in verified float64 "
                  "(Stewart's theorem on the dominant Schur block: an exactly A-invariant "
                  "subspace whose 2x2 or 1x1 restriction M has |det M| >= rho2, the separation "
                  "proven by a Cholesky residual bound; docs/theory.md §3, Verified float64 "
                  "check)")


STEIN_OFFSETS = (0.9, 0.5)
"""hi = base + offset·tol tried first with the preconditioned Stein certificate (the lower end
hi − tol stays at or below the Newton root)."""


def float_views_exact(system: System) -> bool:
    """True when every entry of the exact A and C is the binary float of its view (NumPy input):
    the verified check may then take a and c with radius 0."""
    for M, view in ((system.A, system.a), (system.C, system.c)):
        for e, f in zip(M, view.ravel()):
            if not (e.is_Rational and Fraction(int(e.p), int(e.q)) == Fraction(float(f))):
                return False
    return True


def system_offsets(system: System, exact_views: bool
                  ) -> tuple[floatcheck.Offsets, floatcheck.Offsets]:
    """The exact A and C as float view + offset
    (:func:`kfcrit.theory.upper.floatcheck.exact_offsets`; zero offsets when every entry is a
    binary float)."""
    if exact_views:
        return floatcheck.no_offsets(system.a), floatcheck.no_offsets(system.c)
    return (floatcheck.exact_offsets(system.A, system.a),
            floatcheck.exact_offsets(system.C, system.c))


def stein_block_certificate(system: System, red: Reduced, K: np.ndarray, hi: float,
                            stats: dict[str, Any], exact_views: bool,
                            offsets: tuple[floatcheck.Offsets, floatcheck.Offsets] | None = None):
    """The certificate at hi from the gain K alone: X_u − L_{K,hi}(X_u) = I by preconditioned
    GMRES (:func:`kfcrit.theory.upper.krylov.stein_solve_preconditioned`), the exact block
    lift (:func:`kfcrit.theory.upper.stein.block_lift`), the verified float64 check with the
    unstable columns sharpened. Returns (basis triple, X, K, CheckResult) or None."""
    k = red.k
    Xu, mv = krylov.stein_solve_preconditioned(red.Au, red.Cu, K, hi, np.eye(k))
    stats["operator_applications"] += mv
    if Xu is None or not krylov._positive_definite(Xu):
        return None
    F = red.Au + K @ red.Cu
    Mu = symmetrize(Xu - stein.jump_second_moment(red.Au, F, Xu, hi))
    if not krylov._positive_definite(Mu):
        return None
    lifted = stein.block_lift(red, K, Xu, Mu, hi)
    if lifted is None:
        return None
    Xz, Kz = lifted
    ok, mx, mm, why = floatcheck.verify_upper_float_basis(
        system.a, system.c, hi, red.Z, Xz, Kz, red.M, sharp=k, exact_views=exact_views,
        offsets=offsets)
    stats["certificate_checks"] += 1
    if not ok:
        return None
    stats["certificate_from"] = ("stein: X_u = L_{K,hi}(X_u) + I (GMRES preconditioned by the "
                                 "one-term Stein solve), K the gain of the threshold "
                                 "eigenvector, exact block lift")
    how = FACE_CHECK.replace("dominant-block columns", "unstable-block columns") + (
        "; A and C are binary floats taken exactly" if exact_views else
        "; A and C as float view + float offset (their exact difference rounded once)"
        if offsets is not None else "")
    check = certify.CheckResult(True, "upper: X > 0 and X - L_{K,p}(X) > 0", hi, mx, mm, why,
                                how)
    Z = red.Z
    return (Z, Xz, Kz), symmetrize(Z @ Xz @ Z.T), full_gain(red, Z @ Kz), check


def stein_widths(tol: float) -> list[float]:
    r"""hi − base tried with the Stein block certificate: each of :data:`STEIN_OFFSETS` times
    tol, then each of :data:`WIDER_WIDTHS` above the first.

    .. math::  w \in \{0.9\,\mathrm{tol},\ 0.5\,\mathrm{tol}\} \cup
        \{w_k \in \{10^{-8}, \dots, 10^{-4}\} : w_k > 0.9\,\mathrm{tol}\}
    """
    first = [off * tol for off in STEIN_OFFSETS]
    return first + [w for w in WIDER_WIDTHS if w > first[0]]


def fallback_widths(tol: float) -> list[float]:
    """hi − base tried with :func:`float_certificate` once every Stein width has failed: the
    requested width and the widest of :data:`WIDER_WIDTHS` (each try costs an eigen-Newton,
    a Krylov Stein solve and a full-state check: tens of seconds at 400 states)."""
    return [tol] + [w for w in WIDER_WIDTHS[-1:] if w > tol]


def interior_certificate(system: System, red: Reduced, thr: krylov.KrylovResult, base: float,
                         tol: float, stats: dict[str, Any], exact_views: bool,
                         offsets: tuple[floatcheck.Offsets, floatcheck.Offsets]):
    """The upper certificate at hi = base + width: the cheap Stein block certificate at each
    of :func:`stein_widths` first (a width is skipped when the Stein solve, not the check,
    already failed at a wider one: the operator I − L_{K,hi} is nearer singular as hi
    approaches the root), then :func:`float_certificate` at :func:`fallback_widths`.
    Returns (hi, (basis triple, X, K, CheckResult)) or (hi, None)."""
    hi, unsolved = base, 0.0
    for width in stein_widths(tol):
        if width <= unsolved:
            # the solve already failed at a wider width: closer to the root it is harder
            continue
        hi = float(min(base + width, 1.0))
        checks = stats["certificate_checks"]
        found = stein_block_certificate(system, red, thr.K, hi, stats, exact_views,
                                        offsets=offsets)
        if found is not None:
            return hi, found
        if stats["certificate_checks"] == checks:
            unsolved = max(unsolved, width)
    Ys = stable_gramian(red) if red.k < system.n else None
    for width in fallback_widths(tol):
        hi = float(min(base + width, 1.0))
        found = float_certificate(system, red, hi, thr.X, stats, Ys)
        if found is not None:
            return hi, found
    return hi, None


LOWER_FRACTIONS = (0.1, 1.0)
"""When the certified width exceeds the request the lower end sits at the Newton root p*,
where no lower certificate can pass (its margin vanishes there): the proof is tried at
p* − f·(hi − p*) for these f in turn, and a proven point replaces the numerical root."""
LOWER_CHECK = ("verified float64 on the exact A, C: real eigenbasis S of A with a verified "
               "approximate inverse, A S_u - S_u D_u, C S_u, Y C0' and C0 Y C0' by compensated "
               "products (Dot2), the other products with a priori rounding bounds; Stewart's "
               "theorem for the exact unstable invariant subspace; positive definiteness by a "
               "Cholesky residual bound (docs/theory.md §3, Certified lower end for large "
               "blocks)")


def interior_lower(system: System, red: Reduced, thr: krylov.KrylovResult, p_low: float,
                   lo: float, hi: float,
                   offsets: tuple[floatcheck.Offsets, floatcheck.Offsets],
                   stats: dict[str, Any], warnings: list[str]) -> tuple[float, UpperLowerEvidence]:
    """The lower end of an interior root: proven by
    :func:`kfcrit.theory.upper.lowercert.prove_lower_end` at lo (or, when lo is the Newton
    root itself, at the points of :data:`LOWER_FRACTIONS` below it), else the numerical Newton
    root. Returns (lo, lower-end evidence)."""
    p_star = thr.value
    points = [lo] if lo < p_star else [
        q for q in (p_star - f * (hi - p_star) for f in LOWER_FRACTIONS) if q > p_low]
    proof = lowercert.prove_lower_end(system.a, system.c, red.Z[:, :red.k], thr.X, points,
                                      offsets[0], offsets[1], UNSTABLE_TOL)
    stats["operator_applications"] += proof.operator_applications
    stats["lower_enclosure"] = lowercert.stats_of(proof.ball, proof.check)
    if proof.ok and proof.ball is not None and proof.check is not None:
        ck, ball = proof.check, proof.ball
        check = certify.CheckResult(True, "lower: Y > 0 and G_lo(Y) - Y >= 0 on the exact "
                                    "unstable pair", ck.p, ck.min_eig_y, ck.margin, "proven",
                                    LOWER_CHECK)
        statement = (
            f"p_up >= lo proven: Y > 0 with G_lo(Y) - Y >= 0 for every pair (T, C) in the "
            f"enclosure of the exact action of A and C on the {ball.k}-dimensional unstable "
            + (f"invariant subspace (eigenbasis condition ~{ball.condition:.3g}, "
               f"||I - RS|| <= {ball.neumann:.2g}; Stewart: eigenvalue gap >= {ball.gap:.3g}, "
               f"subspace tilt ||Phi||_F <= {ball.phi:.2g}; " if ball.gap < float("inf") else
               "invariant subspace, here the whole space (every mode unstable: the pair is "
               "(A, C) itself; ")
            + f"radii ||T - T0|| <= {ball.tau:.2g}, "
            f"||C - C0|| <= {ball.gamma:.2g}; Weyl shift {ck.perturbation:.2g}); then "
            "L_{K,lo}(Y) >= G_lo(Y) >= Y for every gain K, so no X > 0 has X > L_{K,lo}(X) "
            f"(Newton root p* = {p_star:.15g})")
        return ck.p, UpperLowerEvidence(kind="certificate", value=native_number(ck.p),
                                        certified=True, statement=statement,
                                        check=check.record(),
                                        p_low_theorem=native_number(p_low))
    warnings.append("the lower end is numerical (matrix-free Newton root); only the upper "
                    "end is certified")
    return lo, UpperLowerEvidence(
        kind="numerical", value=native_number(lo), certified=False,
        statement=(f"Newton root p* = {p_star:.15g} of r(p) = 1 (matrix-free "
                   f"Newton, residual < {krylov.NEWTON_RESIDUAL:.0e}): G_lo(X*) = X* "
                   "+ (p* - lo) P >= X* with X* > 0 numerically, so r(lo) >= 1 (no "
                   f"ball proof: {proof.reason})"),
        p_low_theorem=native_number(p_low))


def large_method(system: System, red: Reduced, p_low: float, tol: float,
                 stats: dict[str, Any], warnings: list[str], done):
    """The bracket for a large unstable block (module docstring); ``done`` builds the result."""
    stats.setdefault("operator_applications", 0)
    face = face_root_certificate(system, red, p_low, tol, stats)
    if face is not None:
        hi, _basis, X, K, check, verified = face
        origin = ("face root p_up = p_low: the gain sends the modes of modulus rho(A) to 0 "
                  "(K_1 = -T_11 C_1^+) and stabilises the rest of the unstable block with its "
                  "own MARE gain (Q = I, R = I); X solves X - L_{K,hi}(X) = W (W > 0 block "
                  "diagonal) block by block in the float Schur basis Z, checked as "
                  "X = Z X_z Z', K = Z K_z" + (" M" if red.M is not None else "")
                  + " (X, K in the record are rounded copies)")
        cert = certificate_summary(system, check, X, K, origin, None, None)
        lower = evidence_p_low(p_low, "; the upper end is certified at p_low + tol/2 (face "
                                      "root: p_up = p_low)")
        status = "determined" if hi - p_low <= tol else "undetermined"
        if status == "undetermined":
            warnings.append(widened_warning(hi - p_low, tol))
        return done(hi, (p_low, hi), True, status, cert, lower,
                    {"X": X, "K": K, "p_star": None, "face_root": True,
                     "output_map": red.M, "p_low_verified": verified})
    start = _start(red, p_low, stats)
    if start is None:
        warnings.append("upper bound undetermined: the MARE iteration (Q = I, R = I) did not "
                        "converge at any start point, so no Newton start was found")
        return done(None, (p_low, 1.0), False, "undetermined", None, evidence_p_low(p_low))
    X0, p0 = start
    thr = krylov.threshold_newton_krylov(red.Au, red.Cu, X0, p0, p_low)
    stats["newton_iterations"] += thr.iterations
    stats["operator_applications"] += thr.matvecs
    face = thr.face or (thr.converged and thr.value - p_low <= FACE_GAP)
    if not (face or thr.converged):
        warnings.append("upper bound undetermined: the threshold Newton did not converge "
                        f"(stopped at p = {thr.value:.12g})")
        return done(None, (p_low, 1.0), False, "undetermined", None, evidence_p_low(p_low))
    base = p_low if face else thr.value
    exact_views = float_views_exact(system)
    offsets = system_offsets(system, exact_views)
    hi, found = interior_certificate(system, red, thr, base, tol, stats, exact_views, offsets)
    if found is None:
        warnings.append("no certificate could be verified; the upper end 1 is the trivial one")
        return done(None, (p_low, 1.0), False, "undetermined", None, evidence_p_low(p_low))
    basis, X, K, check = found
    origin = ("Stein solution X_u - L_{K,hi}(X_u) = I on the unstable Schur block (GMRES), K the "
              "gain of the cone eigenvector of G_hi; lifted to the full state and checked in the "
              "float Schur basis Z as X = Z X_z Z', K = Z K_z" + (" M" if red.M is not None
                                                                else "")
              + " (X, K in the record are rounded copies)")
    cert = certificate_summary(system, check, X, K, origin, None, None)
    lo = lower_end(hi, tol, p_low)
    if face:
        lo, lower = p_low, evidence_p_low(
            p_low, "; the threshold Newton ran into p_low with a singular eigenvector (face "
                   "root), so p_up = p_low within the bracket")
    else:
        # a widened hi must not lift lo above the Newton root
        lo = max(min(lo, thr.value), p_low)
        lo, lower = interior_lower(system, red, thr, p_low, lo, hi, offsets, stats, warnings)
    status = "determined" if hi - lo <= tol else "undetermined"
    if status == "undetermined":
        warnings.append(widened_warning(hi - lo, tol))
    return done(hi, (lo, hi), True, status, cert, lower,
                {"X": X, "K": K, "p_star": None if face else thr.value, "face_root": face,
                 "output_map": red.M})
