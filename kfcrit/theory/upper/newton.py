"""The fast method for p_up: Schur reduction, a power-iteration bracket, Newton on the
threshold of the cone spectral radius, and ball-checked certificates (module docstring of
:mod:`kfcrit.theory.upper.bracket` for the four steps).

.. math::

    p^* :\\ r(p^*) = 1, \\qquad r(p) = \\text{cone spectral radius of } G_p
"""
from __future__ import annotations

import time
from dataclasses import replace
from typing import Any

import numpy as np

from kfcrit.model.system import System
from kfcrit.records.bounds import UpperLowerEvidence
from kfcrit.theory.covariance.riccati import symmetrize
from kfcrit.theory.critical.plow import p_low_of
from kfcrit.theory.upper import certify
from kfcrit.theory.upper.certs import (
    fixed_p_certificate,
    lower_end,
    lower_evidence,
    regularised_certificate,
)
from kfcrit.theory.upper.cone import (
    FLOAT_SCREEN_MARGIN,
    NEWTON_MAX_REDUCED,
    ROOT_CHECK_FACTOR,
    Reduced,
    cone_radius,
    float_upper_margin,
    full_gain,
    lift_certificate,
    optimal_gain_noise_free,
    reduce_system,
    refine_bracket,
    root_error,
    stable_certificate,
    stable_gramian,
    threshold_newton,
    undetected_modes,
)
from kfcrit.theory.upper.large import large_method
from kfcrit.theory.upper.record import (
    UpperBound,
    certificate_summary,
    compression_note,
    evidence_p_low,
    native_number,
)

KRYLOV_MIN_REDUCED = 61
"""Unstable blocks of at least this many states (and above ``NEWTON_MAX_REDUCED``) go to the
matrix-free method of :mod:`kfcrit.theory.upper.large`; smaller ones above the dense limit (only
when that limit is lowered) to :func:`power_bisection`."""
NEAR_P_LOW = 1e-6
"""A Newton root this close to p_low is first tried as p_up = p_low (certificate at p_low + tol)."""


def newton_method(system: System, tol: float,
                   progress: dict[str, Any] | None = None) -> UpperBound:
    """The fast method (module docstring). ``progress`` receives the stage and the numerical
    bracket as they are reached (read by :func:`upper_bound` if a numerical failure stops it)."""
    progress = {} if progress is None else progress
    progress.update(stage="Schur reduction", method="newton")
    t0 = time.perf_counter()
    A, C = system.a, system.c
    stats: dict[str, Any] = {"power_iterations": 0, "newton_iterations": 0, "certificate_checks": 0}
    warnings: list[str] = []
    p_low = p_low_of(A)
    red = reduce_system(system)
    stats["reduced_states"] = red.k
    if red.M is not None:
        stats["output_compression"] = compression_note(red)

    def done(value, interval, certified, status, cert, lower, extras=None):
        stats["seconds"] = time.perf_counter() - t0
        stats["solves"] = stats["newton_iterations"]      # dense Newton linear solves
        return UpperBound(value, (float(interval[0]), float(interval[1])), certified, status,
                          "newton", cert, lower, dict(stats), tuple(warnings), extras or {})

    if red.k == 0:
        X, K = stable_certificate(A, C)
        check = certify.verify_upper(system, 0.0, X, K)
        stats["certificate_checks"] += 1
        cert = certificate_summary(system, check, X, K, "Lyapunov X = A X A' + I, K = 0")
        lower = UpperLowerEvidence(
            kind="trivial", value=0.0, certified=True,
            statement="p ≥ 0; ρ(A) < 1, so p = 0 is already mean-square stable")
        return done(0.0, (0.0, 0.0), check.ok, "determined", cert, lower)

    Au, Cu = red.Au, red.Cu
    blind = undetected_modes(Au, Cu)
    if blind:
        warnings.append("upper bound not applicable: (A, C) is not detectable in float64 (PBH: "
                        + ", ".join(f"λ ≈ {z:.6g} with σ_min([A − λI; C]) ≈ {s:.1e}"
                                    for z, s in blind[:3])
                        + "); no gain makes the error system mean-square stable")
        return done(None, (p_low, 1.0), False, "undetermined", None, evidence_p_low(p_low),
                    {"not_applicable": "(A, C) is not detectable: a mode with |λ| ≥ 1 is "
                                       "invisible to C, so (A + KC) keeps it for every K and no "
                                       "p makes E[P_t] bounded; p_up is not defined"})
    if red.k > NEWTON_MAX_REDUCED and red.k >= KRYLOV_MIN_REDUCED:
        progress["stage"] = "matrix-free threshold Newton (large unstable block)"
        return large_method(system, red, p_low, tol, stats, warnings, done)
    # 2. bracket by bisection on the power-iteration radius
    lo, hi = p_low, 1.0
    progress["stage"] = "power-iteration bracket"
    r1, X1, it = cone_radius(Au, Cu, 1.0)
    stats["power_iterations"] += it
    if not (r1 < 1.0):
        warnings.append("upper bound undetermined: in float64 the noise-free Riccati map has cone "
                        f"spectral radius {r1:.6g} >= 1 even at p = 1, so no p_up < 1 was found; "
                        "(A, C) is either not detectable or too ill-conditioned for this method "
                        "(the exact structure analysis decides detectability)")
        return done(None, (p_low, 1.0), False, "undetermined", None, evidence_p_low(p_low),
                    {"not_applicable": "the noise-free Riccati map does not contract even at "
                                       "p = 1: (A, C) is not detectable (or numerically so); "
                                       "no p < 1 makes E[P_t] bounded, p_up is not defined"})
    Xh, Xl = X1, None
    while hi - lo > 1.0 / 64:
        mid = 0.5 * (lo + hi)
        r, Xm, it = cone_radius(Au, Cu, mid, Xh)
        stats["power_iterations"] += it
        if r < 1.0:
            hi, Xh = mid, Xm
        else:
            lo, Xl = mid, Xm
    progress.update(lo=lo, hi=hi, stage="threshold Newton and certificate")
    if red.k > NEWTON_MAX_REDUCED:
        progress["stage"] = "power-iteration bisection"
        return power_bisection(system, red, lo, hi, Xh, tol, stats, warnings, done)
    # 3. Newton on the threshold (plain and regularised) and 4. certificates; if Newton lands
    #    on a face of the cone (a boundary eigenvector: a lower bound only) or nothing can be
    #    certified, the power-iteration bracket is refined and Newton restarted from inside it.
    best, plain, plain_ok, p_star = None, None, False, None
    lo_seen = p_low                  # the largest lower end with (numerical) evidence
    for _round in range(4):
        start = Xl if Xl is not None else Xh
        plain = threshold_newton(Au, Cu, start, 0.5 * (lo + hi))
        stats["newton_iterations"] += plain.iterations
        lam = float(np.linalg.eigvalsh(plain.X).min()) if plain.converged else -1.0
        plain_ok = plain.converged and lo - 0.05 <= plain.p <= hi + 0.05 and lam > -1e-8
        p_star = max(plain.p, p_low) if plain_ok else None
        if p_star is not None and p_star - p_low <= NEAR_P_LOW:
            # the root sits at p_low (a single critical mode): try p_up <= p_low + tol
            best = fixed_p_certificate(system, red, p_low, plain.X, tol, stats)
            if best is not None:
                p_star = p_low
                break
        if plain_ok and p_star - p_low > NEAR_P_LOW:
            # the certificate point hi = p* + tol/2 (so that [hi - tol, hi] has the root in its
            # middle): eigenvector of G_hi, else the Stein certificate of its gain or of K*
            best = fixed_p_certificate(system, red, p_star, plain.X, tol, stats,
                                       offsets=(0.5,), gains=(plain.K,))
        if best is None and plain_ok and lam > 1e-9 * np.trace(plain.X):
            best = regularised_certificate(system, red, plain, start, 0.5 * (lo + hi), p_star,
                                            p_low, tol, stats)
        elif best is None and plain_ok:   # singular X*: a face root, or a degenerate one
            best = fixed_p_certificate(system, red, p_star, plain.X, tol, stats)
        if best is not None:
            break
        if plain_ok and lo < p_star < hi:
            lo = p_star          # an eigenvector X* ⪰ 0 with eigenvalue 1 shows p_up >= p*
            lo_seen = max(lo_seen, p_star)
        target = max((hi - lo) / 64, 1e-3 * (hi - lo), 4 * tol)
        lo_before = lo
        lo, hi, Xl, Xh = refine_bracket(Au, Cu, lo, hi, Xl, Xh, target, stats)
        if lo > lo_before:       # raised only by a Collatz–Wielandt bound r(lo) >= 1
            lo_seen = max(lo_seen, lo)
        progress.update(lo=lo_seen, hi=hi)
        plain_ok = False
    if best is None:
        warnings.append("no certificate could be verified; the upper end is a numerical "
                        "power-iteration estimate")
        lower = evidence_p_low(p_low) if lo_seen <= p_low else UpperLowerEvidence(
            kind="numerical", value=native_number(lo_seen), certified=False,
            statement="a cone eigenvector with eigenvalue >= 1 (Newton root or "
                      "Collatz-Wielandt bound of the power iterate)",
            p_low_theorem=native_number(p_low))
        return done(None, (lo_seen, hi), False, "undetermined", None, lower)
    hi_p, (Z, Xz, Kz), check, eps_used = best
    progress.update(stage="lower-end evidence", hi=hi_p)
    X, K = symmetrize(Z @ Xz @ Z.T), full_gain(red, Z @ Kz)
    stats["regularisation"] = eps_used
    origin = ("cone eigenvector of the regularised noise-free MARE map (epsilon = "
              f"{eps_used:.3g}), lifted from the unstable Schur block; checked as Z X_z Z', Z K_z "
              + ("M (M the output compression) " if red.M is not None else "")
              + "with the float Schur basis Z (X, K below are rounded copies)")
    cert = certificate_summary(system, check, X, K, origin, (Z, Xz, Kz), red.M)
    lo_p = lower_end(hi_p, tol, p_low)
    if p_star is None:
        warnings.append("plain Newton root not found; the lower end rests on p_low only")
        lo_p = p_low
    elif p_star - p_low <= NEAR_P_LOW:
        # a root this close to p_low is not numerical evidence of p_up > p_low: the
        # eigenvector there is (near) singular — e.g. one unstable mode plus modes with
        # |λ| = 1, A = diag(1, −1, 3), C = [1 1 1], whose Newton root 0.88888890690 lay above
        # p_up = p_low = 8/9. The lower end is the theorem p_low (rounded down below).
        lo_p = p_low
    elif p_star < lo_p:
        warnings.append(f"the certificate holds only at hi = {hi_p:.12g}, more than tol above "
                        f"the Newton root {p_star:.12g}: the bracket is wider than requested")
        lo_p = max(p_low, p_star)
    accuracy = ""
    if plain_ok and p_star is not None and lo_p > p_low:
        # the lower end rests on the Newton root: is the root itself accurate to the slack?
        err, its = root_error(Au, Cu, plain, p_star - lo_p)
        stats["newton_iterations"] += its
        if p_star - err < lo_p:
            lo_p = max(p_low, p_star - err)
            accuracy = root_accuracy_note(p_star, err, tol, lo_p)
            warnings.append(accuracy)
    lower = lower_evidence(system, red, plain, lo_p, p_low, stats, tol) if plain_ok else \
        evidence_p_low(p_low)
    if isinstance(lower, str):       # the evidence contradicts lo
        warnings.append(lower)
        lo_p = p_low
        lower = evidence_p_low(p_low)
    if accuracy and lower.kind == "numerical":
        lower = replace(lower, statement=lower.statement + "; " + accuracy)
    status = "determined" if hi_p - lo_p <= tol else "undetermined"
    return done(hi_p, (lo_p, hi_p), check.ok, status, cert, lower,
                {"X": X, "K": K, "basis": Z, "X_basis": Xz, "K_basis": Kz, "p_star": p_star,
                 "output_map": red.M})




def root_accuracy_note(p_star: float, err: float, tol: float, lo: float) -> str:
    """The warning for a Newton root less accurate than the bracket's slack
    (:func:`kfcrit.theory.upper.cone.root_error`)."""
    if not np.isfinite(err):
        return (f"the accuracy of the Newton root p* = {p_star:.12g} is unknown (with a "
                "larger regulariser Newton did not converge, or the root moved by more than "
                "the bracket's slack in a way no regulariser bias explains: a singular root "
                "or rounding); the lower end falls back to p_low")
    return (f"the Newton root p* = {p_star:.12g} is sensitive to the regulariser of the "
            f"noise-free MARE map (estimated error {err:.2g}, from the roots with "
            f"{ROOT_CHECK_FACTOR:g} and {ROOT_CHECK_FACTOR ** 2:g} times the regulariser; a "
            f"nearly singular or defective cone eigenvector): the lower end is moved down to "
            f"{lo:.12g} (numerical), and the bracket may be wider than the requested {tol:g}")


BALL_CHECK_MAX_STATES = 250
"""Beyond this many states the ball-arithmetic check of a power-bisection certificate (O(n³)
ball products, ~5 s at n = 200) is deferred: the certificate is checked in float64 only and
labelled not certified."""


def power_bisection(system: System, red: Reduced, lo: float, hi: float, Xh: np.ndarray,
                    tol: float, stats: dict[str, Any], warnings: list[str], done) -> UpperBound:
    """Large unstable blocks: bisection on r(p) by power iteration to width max(tol, 1e-6).

    Each feasible p yields a lifted certificate from the power-iteration eigenvector, screened
    in float64 (:func:`kfcrit.theory.upper.cone.float_upper_margin`); only the final ones are
    checked in balls (from the smallest p back, at most three), so the ball-arithmetic cost is
    one check, not one per bisection step. For n > :data:`BALL_CHECK_MAX_STATES` the ball
    check is deferred and the upper end is labelled numerical.
    """
    width = max(tol, 1e-6)
    Ys = stable_gramian(red) if red.k < system.n else None
    candidates: list[tuple[float, tuple[np.ndarray, np.ndarray, np.ndarray], float]] = []
    while hi - lo > width:
        mid = 0.5 * (lo + hi)
        r, X, it = cone_radius(red.Au, red.Cu, mid, Xh, iterations=2000, rtol=1e-11)
        stats["power_iterations"] += it
        found = None
        if r < 1.0:
            for eps in (0.0, 1e-3 * width, 1e-6 * width):   # regularised: X ⪰ ε tr(X) I
                _, Xe, it = cone_radius(red.Au, red.Cu, mid, X, iterations=2000, rtol=1e-11,
                                        eps=eps)
                stats["power_iterations"] += it
                if float(np.linalg.eigvalsh(Xe).min()) <= 0:
                    continue
                K = optimal_gain_noise_free(red.Au, red.Cu, Xe, eps)
                Z, Xz, Kz = lift_certificate(red, system.c, Xe, K, mid, Ys)
                margin = float_upper_margin(system, mid, Z, Xz, Kz, red.M)
                if margin > FLOAT_SCREEN_MARGIN:
                    found = (mid, (Z, Xz, Kz), margin)
                    break
        if found is not None:
            hi, Xh = mid, X
            candidates.append(found)
        elif r >= 1.0:
            lo = mid
        else:
            warnings.append(f"r({mid:.9g}) = {r:.12g} < 1 but no certificate passed the float64 "
                            "screen there; bisection stopped")
            break
    warnings.append(f"unstable block of {red.k} states: power-iteration bisection to width "
                    f"{width:g} (Newton is used up to {NEWTON_MAX_REDUCED}); the lower end is "
                    "numerical (power iteration r(lo) >= 1 or no certificate found)")
    lower = UpperLowerEvidence(
        kind="numerical", value=native_number(lo), certified=False,
        statement="power iteration: r(lo) >= 1, or no certificate could be verified")
    best, certified = None, False
    if candidates and system.n > BALL_CHECK_MAX_STATES:
        hi_p, basis, margin = candidates[-1]
        check = certify.CheckResult(
            False, "upper: X > 0 and X - L_{K,p}(X) > 0", hi_p, None, None,
            f"ball-arithmetic check deferred for n = {system.n} > {BALL_CHECK_MAX_STATES} "
            f"states; float64 check passed (equilibrated margin {margin:.3g})")
        best = (hi_p, basis, check)
        warnings.append(f"p_up certificate checked in float64 only (ball arithmetic deferred "
                        f"beyond {BALL_CHECK_MAX_STATES} states): the upper end is numerical")
    else:
        for hi_p, basis, _margin in reversed(candidates[-3:]):
            Z, Xz, Kz = basis
            check = certify.verify_upper(system, hi_p, Xz, Kz, basis=Z, output_map=red.M)
            stats["certificate_checks"] += 1
            if check.ok:
                best, certified = (hi_p, basis, check), True
                break
    if best is None:
        return done(None, (lo, 1.0), False, "undetermined", None, lower)
    hi_p, (Z, Xz, Kz), check = best
    cert = certificate_summary(system, check, Z @ Xz @ Z.T, full_gain(red, Z @ Kz),
                               "power-iteration cone eigenvector, lifted from the unstable block",
                               (Z, Xz, Kz), red.M)
    status = "determined" if certified and hi_p - lo <= tol else "undetermined"
    return done(hi_p, (lo, hi_p), certified, status, cert, lower,
                {"X": Z @ Xz @ Z.T, "K": full_gain(red, Z @ Kz), "basis": Z, "X_basis": Xz,
                 "K_basis": Kz, "output_map": red.M})
