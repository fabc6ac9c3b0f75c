"""The critical curve of a fixed design in the (γ̄, ν̄) plane (i.i.d. links).

For each γ̄ of a grid, the least ν̄ with

.. math::

    \\rho(\\bar\\gamma, \\bar\\nu) = \\rho\\Bigl(\\sum_m \\pi_m(\\bar\\gamma, \\bar\\nu)\\,
    \\Phi_m \\otimes \\Phi_m\\Bigr) < 1 .

Monotonicity in ν̄ is **not** guaranteed for a general fixed design (the operator is affine in
ν̄, (1 − ν̄)𝓛_lost + ν̄𝓛_received, and for UDP-like designs Φ_m itself depends on ν̄; nothing
orders 𝓛_lost and 𝓛_received). So the ν̄ axis is scanned on a grid first; only where the
stable grid points form an up-set {ν̄ ≥ ν*} is the boundary refined by bisection between the
last unstable and the first stable grid point, and ``monotone_at_grid`` says so. Elsewhere the
stable grid intervals are reported and no single boundary is claimed. Optionally both ends of
each refined bracket are decided exactly (:mod:`kfcrit.theory.loop.msstab`).
"""
from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from kfcrit.theory.loop.fixed import mean_square_stability
from kfcrit.theory.loop.msstab import operator_matrix
from kfcrit.theory.loop.stack import FixedDesign, mode_matrices

__all__ = ["LoopCriticalCurve", "loop_critical_curve", "spectral_radius"]


@dataclass(frozen=True)
class LoopCriticalCurve:
    """The critical ν̄ of a fixed design for each γ̄ of a grid.

    Attributes
    ----------
    gammas : ndarray
        The γ̄ grid.
    nu_grid : ndarray
        The scanned ν̄ grid.
    rho : ndarray
        Float spectral radius, shape (len(gammas), len(nu_grid)).
    nu_star : list of float or None
        Refined boundary (midpoint of ``bracket``) where the stable grid set is an up-set and
        some grid point is stable; None otherwise.
    bracket : list of (float, float) or None
        ν̄ interval of width ≤ tol containing the crossing (float spectral radius).
    monotone_at_grid : list of bool
        Whether the stable grid points form an up-set {ν̄ ≥ ν*} along ν̄.
    stable_intervals : list of list of (float, float)
        Maximal runs of stable grid points, [first, last] ν̄ of each run.
    certified : list of bool or None
        Both bracket ends decided exactly (lower end fails, upper end holds); None when not
        asked or no bracket.
    """

    gammas: np.ndarray
    nu_grid: np.ndarray
    rho: np.ndarray
    nu_star: list[float | None]
    bracket: list[tuple[float, float] | None]
    monotone_at_grid: list[bool]
    stable_intervals: list[list[tuple[float, float]]]
    certified: list[bool | None]


def spectral_radius(design: FixedDesign, gamma: float, nu: float) -> float:
    """Float ρ(Σ_m π_m Φ_m ⊗ Φ_m) for i.i.d. links with arrival probabilities γ̄, ν̄.

    .. math::

        \\pi_{(\\gamma,\\nu)} = \\bar\\gamma^{\\gamma}(1-\\bar\\gamma)^{1-\\gamma}
        \\bar\\nu^{\\nu}(1-\\bar\\nu)^{1-\\nu}
    """
    mm = mode_matrices(design, nu)
    w = [(gamma if g else 1 - gamma) * (nu if v else 1 - nu) for g, v in mm.modes]
    M = operator_matrix(mm.Phi, w)
    with np.errstate(all="ignore"):
        ev = np.linalg.eigvals(M)
    return float(np.max(np.abs(ev)))


def _runs(nus: np.ndarray, stable: np.ndarray) -> list[tuple[float, float]]:
    out, start = [], None
    for i, s in enumerate(stable):
        if s and start is None:
            start = i
        if start is not None and (not s or i == len(stable) - 1):
            end = i if s else i - 1
            out.append((float(nus[start]), float(nus[end])))
            start = None
    return out


def _bisect(design: FixedDesign, gamma: float, lo: float, hi: float, tol: float
            ) -> tuple[float, float]:
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        if spectral_radius(design, gamma, mid) < 1:
            hi = mid
        else:
            lo = mid
    return lo, hi


def loop_critical_curve(design: FixedDesign, gammas: np.ndarray | list[float],
                   nu_grid: np.ndarray | None = None, tol: float = 1e-4,
                   certify_ends: bool = False) -> LoopCriticalCurve:
    """Scan ν̄ for each γ̄; refine the boundary only where the grid shows an up-set.

    Parameters
    ----------
    design : FixedDesign
    gammas : array_like
        γ̄ values (sensing arrival probabilities).
    nu_grid : array_like, optional
        ν̄ values scanned (default 0, 0.025, …, 1).
    tol : float
        Width of the refined bracket.
    certify_ends : bool
        Decide both ends of each bracket exactly (the operator is affine in ν̄ but ρ need not
        be monotone *between* grid points either: a certified bracket proves a sign change of
        ρ − 1 inside it, not that it is the only one).

    Returns
    -------
    LoopCriticalCurve

        ``gammas``, ``nu_grid``, ``rho`` (spectral radius on the grid), ``nu_star`` (the
        boundary ν̄ for each γ̄), ``bracket``, ``stable_intervals`` and ``certified``.

    Raises
    ------
    ValueError
        An arrival probability outside [0, 1].

    References
    ----------
    Schenato, Sinopoli, Franceschetti, Poolla & Sastry (2007), "Foundations of control and
    estimation over lossy networks", Proc. IEEE 95(1); docs/theory.md §12
    (critical curve of a fixed design); Costa, Fragoso & Marques (2005).

    Examples
    --------
    >>> from kfcrit.theory.loop.stack import fixed_design
    >>> design = fixed_design([[1.25]], [[1]], [[1]], 1, 1, 1, 1)   # steady Kalman gain and LQR
    >>> from kfcrit.theory.loop.curve import loop_critical_curve
    >>> curve = loop_critical_curve(design, [0.8])
    >>> lo, hi = curve.bracket[0]
    >>> round(lo, 4), round(hi, 4), curve.stable_intervals[0][0][1]
    (0.4033, 0.4034, 1.0)
    """
    gam = np.asarray(gammas, dtype=float)
    nus = np.linspace(0.0, 1.0, 41) if nu_grid is None else np.asarray(nu_grid, dtype=float)
    rho = np.array([[spectral_radius(design, g, v) for v in nus] for g in gam])
    stars, brackets, mono, runs, certs = [], [], [], [], []
    for i, g in enumerate(gam):
        stable = rho[i] < 1
        runs.append(_runs(nus, stable))
        first = int(np.argmax(stable)) if stable.any() else None
        up = first is not None and bool(stable[first:].all())
        mono.append(up or not stable.any())
        if not up or first is None:
            stars.append(None)
            brackets.append(None)
            certs.append(None)
            continue
        if first == 0:
            br = (float(nus[0]), float(nus[0]))
        else:
            br = _bisect(design, float(g), float(nus[first - 1]), float(nus[first]), tol)
        brackets.append(br)
        stars.append(0.5 * (br[0] + br[1]))
        if certify_ends and br[0] < br[1]:
            gf = Fraction(float(g))
            lo_fact = mean_square_stability(design, gf, Fraction(br[0]))
            hi_fact = mean_square_stability(design, gf, Fraction(br[1]))
            certs.append(lo_fact.holds is False and hi_fact.holds is True)
        else:
            certs.append(None)
    return LoopCriticalCurve(gam, nus, rho, stars, brackets, mono, runs, certs)
