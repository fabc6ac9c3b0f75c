"""Design inversion: the arrival probability an accuracy requirement lim E[tr P_t] ≤ L needs.

S̄(p) (Lyapunov) and V̄(p) (MARE fixed point) bound the steady error covariance, and both are
non-increasing in p (Sinopoli Lemma 1(d); docs/theory.md §11):

.. math::

    \\bar S(p) = (1-p) A \\bar S A' + Q, \\qquad \\bar V(p) = g_p(\\bar V(p)), \\qquad
    \\operatorname{tr}\\bar S(p) \\le \\lim E[\\operatorname{tr} P_t]
    \\le \\operatorname{tr}\\bar V(p).

So p with tr S̄(p) > L fails and p with tr V̄(p) ≤ L meets the requirement: the required
arrival probability lies in [p_S, p_V], tr S̄(p_S) = L, tr V̄(p_V) = L, found by bisection. Both
ends are rounded outwards and proven in ball arithmetic
(:func:`kfcrit.theory.upper.certify.verify_lyapunov_below` at p_S: every p ≤ p_S fails;
:func:`kfcrit.theory.upper.certify.verify_mare_above` at p_V: every p ≥ p_V meets L). Below the floor
tr P_∞ (the DARE solution: every packet delivered) no arrival probability suffices.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import numpy as np
import sympy as sp

from kfcrit.io.typed import to_json
from kfcrit.model.system import System
from kfcrit.records.bounds import CertificateCheck
from kfcrit.records.covariance import (
    RequiredArrivalEnd,
    RequiredArrivalProbability,
)
from kfcrit.theory.covariance import bounds
from kfcrit.theory.covariance.riccati import optimal_gain, solve_generalized_stein, symmetrize
from kfcrit.theory.critical import plow
from kfcrit.theory.upper import bracket as upper_module
from kfcrit.theory.upper import certify

BISECTION_WIDTH = 1e-9
"""Width of the bisection brackets for p_S and p_V (before the outward certified rounding)."""
CERTIFY_MAX_STATES = 60
"""Largest n for the ball checks of the two ends (beyond: numerical ends, labelled)."""
CERTIFY_TRIES = 6
"""Steps (each doubling the distance) taken outwards when a ball check fails at an end."""


MEANING = ("p <= p_S: lim E[tr P] > L (proven when p_S.certified); "
           "p >= p_V: lim E[tr P] <= L (proven when p_V.certified)")
"""What the two ends of the required-probability interval state."""


@dataclass(frozen=True)
class DesignEnd:
    """One end of the required-probability interval."""

    value: float | None
    certified: bool
    how: str
    check: CertificateCheck | None = None

    def record(self) -> RequiredArrivalEnd:
        """The end as its record class (``design.required_arrival_probability.p_S``/``p_V``)."""
        return RequiredArrivalEnd(value=bounds.native_number(self.value),
                                  certified=bool(self.certified), how=self.how,
                                  check=self.check)


@dataclass(frozen=True)
class RequiredArrival:
    """The arrival probability interval [p_S, p_V] for lim E[tr P_t] ≤ L.

    ``status``: "interval" (both ends exist), "impossible" (L below the floor tr P_∞, or
    below tr Q = tr S̄(1)), "undetermined" (an end could not be computed).
    """

    status: str
    level: float
    interval: tuple[float, float] | None
    p_s: DesignEnd
    p_v: DesignEnd
    floor_trace: float | None
    floor_certified: bool
    reason: str
    seconds: float

    def record(self) -> RequiredArrivalProbability:
        """The interval as its record class (``design.required_arrival_probability``; the
        wall-clock ``seconds`` are not part of it)."""
        return RequiredArrivalProbability(
            status=self.status, level=float(self.level),
            interval=None if self.interval is None else [float(v) for v in self.interval],
            p_S=self.p_s.record(), p_V=self.p_v.record(),
            floor_trace=bounds.native_number(self.floor_trace),
            floor_certified=bool(self.floor_certified), reason=self.reason, meaning=MEANING)

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON data: the record's form and the wall-clock ``seconds``."""
        return {**to_json(self.record()), "seconds": self.seconds}


def _exact_level(level: Any) -> Fraction:
    if isinstance(level, bool) or not isinstance(level, int | float | Fraction):
        raise TypeError(f"max_mean_error_trace must be a number, got {level!r}")
    if isinstance(level, float):
        if not np.isfinite(level):
            raise ValueError(f"max_mean_error_trace must be finite, got {level!r}")
        value = Fraction(repr(level))
    else:
        value = Fraction(level)
    if value <= 0:
        raise ValueError(f"max_mean_error_trace must be positive, got {level!r}")
    return value


def lyapunov_trace(system: System, p: float) -> float:
    """tr S̄(p) (inf when (1 − p)ρ(A)² ≥ 1)."""
    S = bounds.lower_covariance(system.a, system.q, float(p))
    return float("inf") if S is None else float(np.trace(S))


def mare_trace(system: System, p: float, gains: list[np.ndarray] | None = None
               ) -> tuple[float, np.ndarray | None]:
    """(tr V̄(p), V̄) — inf and None when the MARE fixed point is not reached."""
    out = bounds.upper_covariance(system, float(p), gains=gains)
    V = out.get("V")
    if V is None or not np.all(np.isfinite(V)):
        return float("inf"), None
    return float(np.trace(V)), V


def _bisect(fn, lo: float, hi: float, width: float) -> tuple[float, float]:
    """Bisection for a non-increasing fn with fn(lo) > 0 ≥ fn(hi): returns (lo, hi)."""
    while hi - lo > width:
        mid = 0.5 * (lo + hi)
        if fn(mid) > 0:
            lo = mid
        else:
            hi = mid
    return lo, hi


def _certify_p_s(system: System, p: float, level: Fraction, p_low_down: float) -> DesignEnd:
    """Prove that every p' ≤ p fails: tr S̄(p) ≥ L in balls (stepping down when needed)."""
    if p <= p_low_down:
        return DesignEnd(p, True, "p <= p_low = 1 - 1/rho(A)^2: S_bar does not exist, E[P_t] "
                                  "diverges (Sinopoli Thm 3)")
    if system.n > CERTIFY_MAX_STATES:
        return DesignEnd(p, False, f"bisection on tr S_bar (numerical; ball check not run for "
                                   f"n > {CERTIFY_MAX_STATES})")
    step = BISECTION_WIDTH
    q = p
    for _ in range(CERTIFY_TRIES):
        pf = Fraction(q)
        S = bounds.lower_covariance(system.a, system.q, q)
        if S is None:
            break
        # S_e = (1−q) A S_e A' + Q − εI: a sub-solution with margin εI, its trace
        # tr S̄ − ε tr Ψ (Ψ = Σ L^k(I)) kept ≥ L by ε = (tr S̄ − L)/(2 tr Ψ)
        Psi = bounds.lower_covariance(system.a, np.eye(system.n), q)
        room = float(np.trace(S)) - float(level)
        if Psi is None or not room > 0:
            q, step = max(q - step, 0.0), 2 * step
            continue
        eps = 0.5 * room / max(float(np.trace(Psi)), 1e-300)
        Se = S - eps * Psi
        check = certify.verify_lyapunov_below(system, pf, symmetrize(Se), level)
        if check.ok:
            return DesignEnd(q, True, "tr S_bar(p_S) >= L proven in ball arithmetic "
                                      "(sub-solution of the Lyapunov equation)",
                             check.record())
        q = max(q - step, 0.0)
        step *= 2
        if q <= p_low_down:
            return DesignEnd(q, True, "p <= p_low: E[P_t] diverges (Sinopoli Thm 3)")
    return DesignEnd(p, False, "bisection on tr S_bar (numerical; the ball check did not pass)")


def _certify_p_v(system: System, p: float, level: Fraction,
                 gains: list[np.ndarray]) -> DesignEnd:
    """Prove that every p' ≥ p meets L: a super-solution V ⪰ φ(K, V) with tr V ≤ L in balls
    (stepping up when needed)."""
    if system.n > CERTIFY_MAX_STATES:
        return DesignEnd(p, False, f"bisection on tr V_bar (numerical; ball check not run for "
                                   f"n > {CERTIFY_MAX_STATES})")
    A, C, Q, R = system.a, system.c, system.q, system.r
    step = BISECTION_WIDTH
    q = p
    for _ in range(CERTIFY_TRIES):
        tr, V = mare_trace(system, q, gains)
        if V is not None and tr <= float(level):
            K = optimal_gain(A, C, R, V)
            # V_e = φ(K, V_e) + εI: margin εI; tr V_e ≤ L when ε tr Ψ ≤ (L − tr V̄)/2,
            # Ψ = L_{K,q}(Ψ) + I
            try:
                Psi = solve_generalized_stein(A, C, K, q, np.eye(system.n))
                W = symmetrize(Q + q * K @ R @ K.T)
                room = float(level) - tr
                eps = 0.5 * room / max(float(np.trace(Psi)), 1e-300)
                Ve = solve_generalized_stein(A, C, K, q, W + eps * np.eye(system.n))
            except np.linalg.LinAlgError:
                Ve = None
            if Ve is not None and np.all(np.isfinite(Ve)):
                check = certify.verify_mare_above(system, Fraction(q), symmetrize(Ve), K, level)
                if check.ok:
                    return DesignEnd(q, True, "tr V_bar(p_V) <= L proven in ball arithmetic "
                                              "(super-solution V >= phi(K, V))", check.record())
        q = min(q + step, 1.0)
        step *= 2
    return DesignEnd(p, False, "bisection on tr V_bar (numerical; the ball check did not pass)")


def required_arrival(system: System, level: Any, structure: Any | None = None,
                     upper: Any | None = None) -> RequiredArrival:
    """The required arrival probability interval [p_S, p_V] for lim E[tr P_t] ≤ ``level``.

    Parameters
    ----------
    system : System
    level : float or Fraction
        The requirement L (``max_mean_error_trace``); floats by their decimal form.
    structure : optional
        The eigen-structure (exact p_low), as for :func:`kfcrit.theory.upper.bracket.upper_bound`.
    upper : UpperBound, optional
        The p_up result if already computed (its certified upper end bounds the V̄ search
        from below, its gain warm-starts Newton); computed when absent.

    Returns
    -------
    RequiredArrival
    """
    t0 = time.perf_counter()
    L = _exact_level(level)
    Lf = float(L)
    pl = plow.p_low_bounds(system, structure)
    trq = system.Q.trace()

    def done(status, interval, ps, pv, floor, floor_ok, reason):
        return RequiredArrival(status, Lf, interval, ps, pv, floor, floor_ok, reason,
                               time.perf_counter() - t0)

    none = DesignEnd(None, False, "not applicable")
    if sp.N(trq - sp.Rational(L.numerator, L.denominator), 50) > 0:
        return done("impossible", None, none, none, None, True,
                    f"L = {Lf:.6g} < tr Q = {float(trq):.6g} = tr S_bar(1): even with every "
                    "packet delivered the error exceeds the requirement (exact)")
    floor_tr, _ = mare_trace(system, 1.0)
    if not np.isfinite(floor_tr):
        return done("undetermined", None, none, none, None, False,
                    "the Riccati solution at p = 1 was not reached (is (A, C) detectable?)")
    if floor_tr > Lf:
        proven = False
        if system.n <= CERTIFY_MAX_STATES:
            proven, _steps = certify.riccati_floor_exceeds(system, L)
        return done("impossible", None, none, none, floor_tr, proven,
                    f"L = {Lf:.6g} < tr P_inf = {floor_tr:.6g} (the DARE solution, every packet "
                    "delivered): no arrival probability meets the requirement"
                    + (" (proven by ball Riccati iterates)" if proven else " (numerical)"))
    # p_S: tr S̄ non-increasing on (p_low, 1]; 0 when S̄(0) exists and already meets L
    if lyapunov_trace(system, 0.0) <= Lf:
        p_s = DesignEnd(0.0, True, "tr S_bar(0) <= L: the lower bound rules out no p")
    else:
        lo, _hi = _bisect(lambda p: lyapunov_trace(system, p) - Lf, max(pl.down, 0.0), 1.0,
                          BISECTION_WIDTH)
        p_s = _certify_p_s(system, lo, L, pl.down)
    # p_V: tr V̄ non-increasing on (p_up, 1]
    ub = upper if upper is not None else upper_module.upper_bound(system)
    gains = [ub.extras["K"]] if "K" in getattr(ub, "extras", {}) else []
    start = ub.interval[1] if ub.value is not None else pl.down
    if mare_trace(system, 0.0, gains)[0] <= Lf:
        p_v = DesignEnd(0.0, True, "tr V_bar(0) <= L (rho(A) < 1): every p meets L")
        if system.n <= CERTIFY_MAX_STATES:
            p_v = _certify_p_v(system, 0.0, L, gains)
    else:
        _lo, hi = _bisect(lambda p: mare_trace(system, p, gains)[0] - Lf, max(start, 0.0), 1.0,
                          BISECTION_WIDTH)
        p_v = _certify_p_v(system, hi, L, gains)
    interval = (float(p_s.value), float(p_v.value))
    reason = (f"p <= {interval[0]:.9g} fails (tr S_bar > L), p >= {interval[1]:.9g} meets "
              f"lim E[tr P] <= {Lf:.6g} (tr V_bar <= L); between, the bounds do not decide")
    return done("interval", interval, p_s, p_v, floor_tr, False, reason)
