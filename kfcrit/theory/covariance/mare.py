"""A verified enclosure of the MARE fixed point V̄ (a convergence certificate for any solver).

Given a computed V ≈ V̄ = g_p(V̄), two float matrices bracket V̄ (docs/theory.md §2, §3):

* upper: X_hi = (1 + ε) V with X_hi ≻ φ(K, X_hi) for the float gain K = K_V. By Lemma 1(b)
  g_p(X_hi) ⪯ φ(K, X_hi) ≺ X_hi, and X_hi ≻ 0 with X_hi ≻ φ(K, X_hi) is the hypothesis of
  Sinopoli Lemma 4 / Theorem 1: the MARE iteration converges from every P_0 ⪰ 0 to the unique PSD
  fixed point V̄ (so V̄ exists: p > p_up), and from P_0 = X_hi it is non-increasing (Lemma 2),
  hence V̄ ⪯ X_hi;
* lower: X_lo = (1 − ε) V with g_p(X_lo) ≻ X_lo, proven through the Schur complement

  .. math::

      \\begin{bmatrix} A X A' + Q - X & \\sqrt p\\, A X C' \\\\ \\sqrt p\\, C X A' & C X C' + R
      \\end{bmatrix} \\succ 0 \\iff g_p(X) - X \\succ 0 \\quad (C X C' + R \\succ 0),

  (the constraint of the corrected Theorem 6(b) SDP, no inverse needed); the orbit from X_lo is
  then non-decreasing and converges to V̄, so X_lo ⪯ V̄.

Both definiteness statements are proven in float64 with a priori rounding-error bounds
(:mod:`kfcrit.theory.upper.floatcheck`: midpoint-radius products, a verified Cholesky margin) for
the exact A, C, Q, R within one ulp of their float views and the exact p within one ulp of its
float. Hence (1 − ε) V ⪯ V̄ ⪯ (1 + ε) V and tr V̄ is enclosed to relative width about ε.
Q ≻ 0 is what makes a small ε work (the margins are ε·Q − O(residual)).
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from kfcrit.theory.covariance.riccati import optimal_gain, symmetrize
from kfcrit.theory.upper import floatcheck as fc

ENCLOSURE_WIDTHS = (1e-10, 1e-8, 1e-6, 1e-4, 1e-2)
"""Relative widths ε tried in turn by :func:`mare_enclosure` (the first proven is kept)."""


def _prob(p: float) -> tuple[fc.Interval, fc.Interval, fc.Interval]:
    """Scalar enclosures of p, 1 − p and √p for the exact p within one ulp of the float p."""
    rp = fc.U * p + fc.ETA
    s = math.sqrt(p)
    return (p, rp), (1.0 - p, 2 * fc.U + rp), (s, 2 * fc.U * s + rp / max(s, 1e-300))


def upper_side(a, c, q, r, p: float, X: np.ndarray, K: np.ndarray) -> float | None:
    """Verified margin of X − φ(K, X) ≻ 0 (None if not proven), φ of Sinopoli eq. (23).

    .. math:: X - (1-p)(A X A' + Q) - p\\,(F X F' + Q + K R K'),\\quad F = A + K C
    """
    A, C, Q, R = (fc.from_exact(M) for M in (a, c, q, r))
    Xi, Ki = fc.point(X), fc.point(K)
    pp, qq, _ = _prob(p)
    F = fc.add(A, fc.mul(Ki, C))
    AXA = fc.add(fc.mul(fc.mul(A, Xi), fc.transpose(A)), Q)
    FXF = fc.add(fc.add(fc.mul(fc.mul(F, Xi), fc.transpose(F)), Q),
                 fc.mul(fc.mul(Ki, R), fc.transpose(Ki)))
    phi = fc.add(fc.scale(qq, AXA), fc.scale(pp, FXF))
    return fc.verified_definite_margin(fc.add(Xi, phi, -1.0))


def lower_side(a, c, q, r, p: float, X: np.ndarray) -> float | None:
    """Verified margin of the Schur-complement block of g_p(X) − X ≻ 0 (None if not proven)."""
    A, C, Q, R = (fc.from_exact(M) for M in (a, c, q, r))
    Xi = fc.point(X)
    _, _, sp_ = _prob(p)
    AX = fc.mul(A, Xi)
    top = fc.add(fc.add(fc.mul(AX, fc.transpose(A)), Q), Xi, -1.0)
    off = fc.scale(sp_, fc.mul(AX, fc.transpose(C)))
    bottom = fc.add(fc.mul(fc.mul(C, Xi), fc.transpose(C)), R)
    mid = np.block([[top[0], off[0]], [off[0].T, bottom[0]]])
    rad = np.block([[top[1], off[1]], [off[1].T, bottom[1]]])
    return fc.verified_definite_margin((mid, rad))


def mare_enclosure(a: np.ndarray, c: np.ndarray, q: np.ndarray, r: np.ndarray, p: float,
                   V: np.ndarray) -> dict[str, Any] | None:
    """A verified enclosure (1 − ε) V ⪯ V̄ ⪯ (1 + ε) V of the MARE fixed point (module doc), or
    None when no width in :data:`ENCLOSURE_WIDTHS` is proven (e.g. Q singular, or V not close
    to V̄).

    Parameters
    ----------
    a, c, q, r : numpy.ndarray
        Float views of the exact system matrices (each entry rounded once).
    p : float
        The arrival probability (its exact value within one ulp).
    V : numpy.ndarray
        The computed fixed point.

    Returns
    -------
    dict or None
        ``{"relative_width": ε, "trace_interval": [lo, hi], "proves_p_above_p_up": True,
        "margins": [lower, upper], "method": ...}``.

    References
    ----------
    Sinopoli et al. (2004), Lemma 1(b), Lemma 2, Lemma 4, Theorem 1 and the corrected
    Theorem 6(b) constraint; docs/theory.md §2, §3.

    Examples
    --------
    >>> import numpy as np
    >>> from kfcrit.theory.covariance.mare import mare_enclosure
    >>> one = np.eye(1)
    >>> enc = mare_enclosure(1.25 * one, one, one, one, 0.5, np.array([[7.733944]]))
    >>> lo, hi = enc["trace_interval"]
    >>> bool(lo <= 7.7339437 <= hi), enc["relative_width"]
    (True, 1e-06)
    """
    V = symmetrize(np.asarray(V, dtype=float))
    if not (np.all(np.isfinite(V)) and 0.0 < p <= 1.0):
        return None
    try:
        K = optimal_gain(a, c, r, V)
    except np.linalg.LinAlgError:
        return None
    if not np.all(np.isfinite(K)):
        return None
    n = V.shape[0]
    tr = float(np.trace(V))
    slack = 4 * n * fc.U          # rounding of the float trace of (1 ± ε) V
    for eps in ENCLOSURE_WIDTHS:
        hi_m = upper_side(a, c, q, r, p, symmetrize((1.0 + eps) * V), K)
        if hi_m is None:
            continue
        lo_m = lower_side(a, c, q, r, p, symmetrize((1.0 - eps) * V))
        if lo_m is None:
            continue
        return {"relative_width": eps,
                "trace_interval": [(1.0 - eps) * tr * (1 - slack), (1.0 + eps) * tr * (1 + slack)],
                "proves_p_above_p_up": True, "margins": [lo_m, hi_m],
                "method": "verified float64 enclosure (1 − ε)V ⪯ V̄ ⪯ (1 + ε)V: X ≻ φ(K_V, X) "
                          "at X = (1 + ε)V and g_p(X) ≻ X at X = (1 − ε)V by its Schur "
                          "complement, with a priori rounding bounds (theory §3)"}
    return None
