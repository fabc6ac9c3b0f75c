"""Loss links of a closed loop: i.i.d. Bernoulli or Gilbert–Elliott (two-state Markov) links.

A link is received (state 1) or lost (state 0). Gilbert–Elliott (theory §7): failure rate
f = P(lost next | received now), recovery rate r = P(received next | lost now), transition
matrix over (lost, received)

.. math::

    T = \\begin{pmatrix} 1 - r & r \\\\ f & 1 - f \\end{pmatrix}, \\qquad
    \\pi_{received} = \\frac{r}{f + r}.

An i.i.d. link with arrival probability p is the case f = 1 − p, r = p (f + r = 1).
Probabilities are kept as given; :meth:`LossLink.exact` returns them as exact fractions (a
binary float is the rational it is).
"""
from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import numpy as np

__all__ = ["LossLink", "as_fraction", "joint_chain"]


def as_fraction(x: Any) -> Fraction:
    """An exact fraction of a number (float: its binary value; sympy Rational: exact)."""
    if isinstance(x, Fraction):
        return x
    if isinstance(x, (int, np.integer)):
        return Fraction(int(x))
    if isinstance(x, (float, np.floating)):
        return Fraction(float(x))
    p, q = getattr(x, "p", None), getattr(x, "q", None)
    if p is not None and q is not None:
        return Fraction(int(p), int(q))
    return Fraction(str(x))


@dataclass(frozen=True)
class LossLink:
    """A lossy link (Gilbert–Elliott; i.i.d. when failure + recovery = 1).

    Attributes
    ----------
    failure : number
        f = P(lost next | received now).
    recovery : number
        r = P(received next | lost now).
    """

    failure: Any
    recovery: Any

    def __post_init__(self) -> None:
        f, r = float(self.failure), float(self.recovery)
        if not (0 <= f <= 1 and 0 <= r <= 1 and f + r > 0):
            raise ValueError(f"need 0 ≤ f, r ≤ 1 and f + r > 0, got f={f}, r={r}")

    @classmethod
    def bernoulli(cls, p: Any) -> LossLink:
        """The i.i.d. link with arrival probability p (f = 1 − p, r = p)."""
        pf = as_fraction(p)
        if not 0 <= pf <= 1:
            raise ValueError(f"arrival probability must be in [0, 1], got {p}")
        if isinstance(p, float):
            return cls(1.0 - p if Fraction(1.0 - p) == 1 - pf else 1 - pf, p)
        return cls(1 - pf, pf)

    @property
    def iid(self) -> bool:
        """Whether the link is memoryless (f + r = 1 exactly)."""
        return as_fraction(self.failure) + as_fraction(self.recovery) == 1

    def exact(self) -> tuple[Fraction, Fraction]:
        """(f, r) as exact fractions."""
        return as_fraction(self.failure), as_fraction(self.recovery)

    def arrival(self) -> Fraction:
        """Stationary arrival probability r/(f + r), exactly."""
        f, r = self.exact()
        return r / (f + r)

    def transition(self) -> list[list[Fraction]]:
        """T over states (0 = lost, 1 = received), exactly."""
        f, r = self.exact()
        return [[1 - r, r], [f, 1 - f]]

    def sample(self, rng: np.random.Generator, steps: int, paths: int) -> np.ndarray:
        """Arrivals (steps × paths, bool), started from the stationary law."""
        f, r = float(self.failure), float(self.recovery)
        if self.iid:
            return rng.random((steps, paths)) < float(self.arrival())
        out = np.empty((steps, paths), dtype=bool)
        state = rng.random(paths) < float(self.arrival())
        for t in range(steps):
            out[t] = state
            u = rng.random(paths)
            state = np.where(state, u >= f, u < r)
        return out


def joint_chain(sensing: LossLink, actuation: LossLink
                ) -> tuple[list[tuple[int, int]], list[list[Fraction]], list[Fraction]]:
    """The joint mode chain of two independent links: modes m = (γ, ν), T = T_γ ⊗ T_ν.

    .. math::

        T_{(\\gamma,\\nu),(\\gamma',\\nu')} = T^{s}_{\\gamma\\gamma'} T^{a}_{\\nu\\nu'}, \\qquad
        \\pi_{(\\gamma,\\nu)} = \\pi^{s}_\\gamma \\pi^{a}_\\nu

    Returns
    -------
    (modes, T, pi)
        modes in the order (0,0), (0,1), (1,0), (1,1); T and π exact.
    """
    Ts, Ta = sensing.transition(), actuation.transition()
    ps = [1 - sensing.arrival(), sensing.arrival()]
    pa = [1 - actuation.arrival(), actuation.arrival()]
    modes = [(g, v) for g in (0, 1) for v in (0, 1)]
    T = [[Ts[g][g2] * Ta[v][v2] for (g2, v2) in modes] for (g, v) in modes]
    pi = [ps[g] * pa[v] for (g, v) in modes]
    return modes, T, pi
