"""Facts about mean stability, as the theory establishes them — never verdicts.

A theorem gives a *necessary* condition for bounded E[P_t] (it holds, fails, or cannot be
decided at the precision available) and a *sufficient* one (a checked certificate proves it or
nothing is proven). Where the two surfaces are proven to meet, the necessary condition alone
decides (``exact_region``). Only :mod:`kfcrit.analysis.verdict` turns these facts into the
words *mean-stable*, *mean-unstable* and *undetermined* (docs/theory.md §16), so that every
verdict of one record is derived by the same rule.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class StabilityFacts:
    r"""What is proven about mean stability at one point of the parameter space.

    Parameters
    ----------
    necessary : bool or None
        The necessary condition holds (True), fails (False: decided exactly or certified), or
        is at equality within the precision available (None).
    sufficient : bool
        A sufficient condition is proven (a certificate checked in ball arithmetic, a closed
        form, or ρ(A) < 1).
    exact_region : bool
        The necessary condition is also sufficient here (the surfaces meet, proven), so
        ``necessary is True`` alone proves mean stability.
    necessary_basis, sufficient_basis : str
        The argument behind each fact, in words.

    Notes
    -----
    The rule that reads these facts (docs/theory.md §16):

    .. math::

        \text{unstable} \iff \neg\,\text{necessary}, \qquad
        \text{stable} \iff \text{sufficient} \lor (\text{exact} \land \text{necessary}).
    """

    necessary: bool | None
    sufficient: bool
    exact_region: bool = False
    necessary_basis: str = ""
    sufficient_basis: str = ""

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON data (the ``facts`` key of a record section)."""
        return {"necessary": self.necessary, "sufficient": self.sufficient,
                "exact_region": self.exact_region, "necessary_basis": self.necessary_basis,
                "sufficient_basis": self.sufficient_basis}
