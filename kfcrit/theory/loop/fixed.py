"""Fixed linear designs over lossy sensing and actuation links: stability, second moment, cost.

theory §12 (UDP-like loops, and any deployed design): with the jump-linear form
z_{t+1} = Φ_m z_t + G_m n_t of :mod:`kfcrit.theory.loop.stack`, modes m = (γ, ν), the loop is
mean-square stable iff

.. math::

    \\rho\\Bigl(\\sum_m \\pi_m \\Phi_m \\otimes \\Phi_m\\Bigr) < 1 \\quad (\\text{i.i.d. links}),
    \\qquad
    \\rho\\bigl((T' \\otimes I)\\operatorname{diag}(\\Phi_i \\otimes \\Phi_i)\\bigr) < 1
    \\quad (\\text{Gilbert–Elliott links}),

decided exactly by :mod:`kfcrit.theory.loop.msstab`. When it holds, the stationary second
moment solves the Lyapunov-type equation (i.i.d.)

.. math::

    Z = \\sum_m \\pi_m \\bigl(\\Phi_m Z \\Phi_m' + G_m N G_m'\\bigr), \\qquad N = Q \\oplus R,

or, for Markov modes, Z_j = Σ_i T_ij (Φ_i Z_i Φ_i' + π_i G_i N G_i'), and the average cost is

.. math::

    J = \\operatorname{tr}(W Z_{xx}) + \\sum_m \\operatorname{tr}\\bigl(U (H_m Z_m H_m'
        + \\pi_m J_m R J_m')\\bigr)

(Z_m = π_m Z for i.i.d. modes). Sources: Costa, Fragoso & Marques 2005; Schenato et al. 2007.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from kfcrit.theory.covariance.riccati import symmetrize, unvech, vech
from kfcrit.theory.loop.links import LossLink, joint_chain
from kfcrit.theory.loop.msstab import StabilityFact, mss_decision, operator_matrix
from kfcrit.theory.loop.stack import FixedDesign, ModeMatrices, mode_matrices
from kfcrit.theory.loop.tcp import LoopCost

__all__ = ["FixedLoop", "as_link", "fixed_loop", "mean_square_stability", "second_moment"]


@dataclass(frozen=True)
class FixedLoop:
    """Facts about a fixed design over two links.

    Attributes
    ----------
    stability : StabilityFact
        Mean-square stability (certified or not decided) and the float spectral radius.
    cost : LoopCost
        The stationary average cost (``inf`` when stability fails, ``nan`` when undecided and
        the second moment could not be formed).
    second_moment : ndarray or None
        Stationary E[z z'] (z = (x, x̂[, a][, â])).
    sizes : dict
        Block sizes of z.
    markov : bool
        Whether the Markov-jump (Gilbert–Elliott) form was used.
    """

    stability: StabilityFact
    cost: LoopCost
    second_moment: np.ndarray | None
    sizes: dict[str, int]
    markov: bool


def as_link(link: Any) -> LossLink:
    """A :class:`LossLink` from a link or an arrival probability (i.i.d.)."""
    return link if isinstance(link, LossLink) else LossLink.bernoulli(link)


def _operator(mm: ModeMatrices, sensing: LossLink, actuation: LossLink, exact: bool
              ) -> tuple[np.ndarray, list, list | None]:
    modes, T, pi = joint_chain(sensing, actuation)
    iid = sensing.iid and actuation.iid
    conv = (lambda x: x) if exact else float
    w = [conv(p) for p in pi]
    Tm = None if iid else [[conv(t) for t in row] for row in T]
    return operator_matrix(mm.Phi, w, Tm), w, Tm


def mean_square_stability(design: FixedDesign, sensing: Any, actuation: Any,
                          certified: bool = True) -> StabilityFact:
    """Mean-square stability of ``design`` over the two links (exact where possible).

    .. math::

        \\rho\\Bigl(\\sum_m \\pi_m \\Phi_m \\otimes \\Phi_m\\Bigr) < 1

    Parameters
    ----------
    design : FixedDesign
    sensing, actuation : LossLink or number
        Links, or i.i.d. arrival probabilities γ̄, ν̄ (floats are taken as the binary numbers
        they are; pass fractions.Fraction for exact decimal values).
    certified : bool
        Decide exactly (False: float spectral radius only, status "not decided").

    Returns
    -------
    StabilityFact
        ``status`` ("holds (certified)", "fails (certified)" or "not decided"), ``holds``, the
        spectral radius ``rho`` and the method.

    Raises
    ------
    ValueError
        An arrival probability outside [0, 1].

    References
    ----------
    Costa, Fragoso & Marques (2005), "Discrete-time Markov jump linear systems";
    Schenato, Sinopoli, Franceschetti, Poolla & Sastry (2007), "Foundations of control and
    estimation over lossy networks", Proc. IEEE 95(1); docs/theory.md §12 (UDP-like loops).

    Examples
    --------
    >>> from kfcrit.theory.loop.stack import fixed_design
    >>> design = fixed_design([[1.25]], [[1]], [[1]], 1, 1, 1, 1)   # steady Kalman gain and LQR
    >>> from fractions import Fraction
    >>> from kfcrit.theory.loop.fixed import mean_square_stability
    >>> mean_square_stability(design, 0.8, 0.8).status
    'holds (certified)'
    >>> mean_square_stability(design, Fraction(3, 10), Fraction(3, 10)).status
    'fails (certified)'
    """
    s, a = as_link(sensing), as_link(actuation)
    nu = a.arrival()
    mm_f = mode_matrices(design, float(nu))
    M, _, _ = _operator(mm_f, s, a, False)
    blocks = 1 if (s.iid and a.iid) else 4
    N = mm_f.Phi[0].shape[0]
    M_exact = None
    if certified:
        mm_e = mode_matrices(design, nu, exact=True)
        M_exact, _, _ = _operator(mm_e, s, a, True)
    return mss_decision(M_exact, M, N, blocks)


def second_moment(mm: ModeMatrices, design: FixedDesign, sensing: LossLink,
                  actuation: LossLink) -> tuple[list[np.ndarray], list[float]]:
    """Stationary Z_m = E[z z' 1{mode m}] per mode (i.i.d.: Z_m = π_m Z) and the π_m.

    .. math::

        Z_j = \\sum_i T_{ij}\\bigl(\\Phi_i Z_i \\Phi_i' + \\pi_i G_i N G_i'\\bigr)

    Raises ``np.linalg.LinAlgError`` when the linear system is singular (ρ = 1).
    """
    modes, T, pi = joint_chain(sensing, actuation)
    pf = [float(p) for p in pi]
    n, m = design.A.shape[0], design.C.shape[0]
    Nn = np.zeros((n + m, n + m))
    Nn[:n, :n], Nn[n:, n:] = design.Q, design.R
    forcing = [symmetrize(G @ Nn @ G.T) for G in mm.G]
    N = mm.Phi[0].shape[0]
    if sensing.iid and actuation.iid:
        M = operator_matrix(mm.Phi, pf)
        rhs = vech(sum(p * F for p, F in zip(pf, forcing)))
        Z = unvech(np.linalg.solve(np.eye(M.shape[0]) - M, rhs), N)
        return [p * Z for p in pf], pf
    Tf = [[float(t) for t in row] for row in T]
    M = operator_matrix(mm.Phi, pf, Tf)
    rhs = np.concatenate([vech(sum(Tf[i][j] * pf[i] * forcing[i] for i in range(4)))
                          for j in range(4)])
    z = np.linalg.solve(np.eye(M.shape[0]) - M, rhs)
    d = N * (N + 1) // 2
    return [unvech(z[j * d:(j + 1) * d], N) for j in range(4)], pf


def _cost(mm: ModeMatrices, design: FixedDesign, Zm: list[np.ndarray], pf: list[float]
          ) -> float:
    n = design.A.shape[0]
    Z = sum(Zm)
    J = float(np.trace(design.W @ Z[:n, :n]))
    for H, Jv, Zi, p in zip(mm.H, mm.J, Zm, pf):
        J += float(np.trace(design.U @ (H @ Zi @ H.T + p * Jv @ design.R @ Jv.T)))
    return J


def fixed_loop(design: FixedDesign, sensing: Any, actuation: Any,
               certified: bool = True) -> FixedLoop:
    """Stability, stationary second moment and average cost of a fixed design.

    .. math::

        J = \\lim_{T\\to\\infty} \\frac{1}{T} E \\sum_t (x_t' W x_t + a_t' U a_t)

    Parameters
    ----------
    design : FixedDesign
    sensing, actuation : LossLink or number
        The links (numbers are i.i.d. arrival probabilities).
    certified : bool
        Decide stability exactly (see :func:`mean_square_stability`).

    Returns
    -------
    FixedLoop
        ``cost.value`` is inf when stability fails (certified), the Lyapunov value when it
        holds; when undecided the value is computed if ρ̂ < 1 and flagged ``finite=None``.

    Raises
    ------
    ValueError
        An arrival probability outside [0, 1].

    References
    ----------
    Costa, Fragoso & Marques (2005);
    Schenato, Sinopoli, Franceschetti, Poolla & Sastry (2007), "Foundations of control and
    estimation over lossy networks", Proc. IEEE 95(1); docs/theory.md §12.

    Examples
    --------
    >>> from kfcrit.theory.loop.stack import fixed_design
    >>> design = fixed_design([[1.25]], [[1]], [[1]], 1, 1, 1, 1)   # steady Kalman gain and LQR
    >>> from kfcrit.theory.loop.fixed import fixed_loop
    >>> loop = fixed_loop(design, 0.8, 0.8)
    >>> loop.stability.status, round(loop.cost.value, 6)
    ('holds (certified)', 5.949977)
    >>> fixed_loop(design, 0.3, 0.3).cost.value
    inf
    """
    s, a = as_link(sensing), as_link(actuation)
    fact = mean_square_stability(design, s, a, certified)
    mm = mode_matrices(design, float(a.arrival()))
    markov = not (s.iid and a.iid)
    inf = math.inf
    if fact.holds is False or (fact.holds is None and fact.rho >= 1):
        cost = LoopCost(inf, inf, inf, False if fact.holds is False else None,
                        "none: not mean-square stable", None, fact.status)
        return FixedLoop(fact, cost, None, design.sizes, markov)
    try:
        Zm, pf = second_moment(mm, design, s, a)
    except np.linalg.LinAlgError:
        cost = LoopCost(math.nan, 0.0, inf, None, "singular second-moment equation", None,
                        fact.status)
        return FixedLoop(fact, cost, None, design.sizes, markov)
    J = _cost(mm, design, Zm, pf)
    how = "Markov-jump Lyapunov equation" if markov else "Lyapunov equation (i.i.d. modes)"
    cost = LoopCost(J, J, J, True if fact.holds else None, how, None,
                    f"mean-square stability {fact.status} ({fact.method})")
    return FixedLoop(fact, cost, symmetrize(sum(Zm)), design.sizes, markov)

