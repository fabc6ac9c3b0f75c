"""Curves of the link layer for the figures: arrays computed here, drawn in kfcrit.views.

Every curve is a frozen dataclass of NumPy arrays with the formula it evaluates; the views only
plot them. ``record()`` states a curve as its section of the record (``link_budget.curves``).
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from kfcrit.io.typed import to_json
from kfcrit.link.linkbudget import LinkBudget
from kfcrit.link.radios import SINR_SEARCH_DB, Radio
from kfcrit.records.link import ArrivalVsDistance, OutageVsDistance, PerVsSinr


@dataclass(frozen=True)
class ArrivalCurve:
    """p(d) of a link against distance: the median link's and the shadowing average."""

    distance_m: np.ndarray = field(repr=False)
    arrival: np.ndarray = field(repr=False)
    mean_arrival: np.ndarray | None = field(repr=False)
    configured_distance_m: float
    max_retries: int
    psdu_bytes: int

    def record(self) -> ArrivalVsDistance:
        return ArrivalVsDistance(
            distance_m=self.distance_m.tolist(), arrival=self.arrival.tolist(),
            mean_arrival=None if self.mean_arrival is None else self.mean_arrival.tolist(),
            configured_distance_m=self.configured_distance_m, max_retries=self.max_retries,
            psdu_bytes=self.psdu_bytes)

    def to_dict(self) -> dict[str, Any]:
        return to_json(self.record())


@dataclass(frozen=True)
class PerCurve:
    """PER(SINR) of one attempt for several PSDU lengths: 1 − (1 − BER(SINR))^{8(H + L)}.

    H = ``header_bytes`` is the PHY header the PER also covers (``per_over: ppdu``), 0 for a
    PSDU-only PER.
    """

    radio: str
    sinr_db: np.ndarray = field(repr=False)
    psdu_bytes: tuple[int, ...]
    per: np.ndarray = field(repr=False)
    """Shape (len(psdu_bytes), len(sinr_db))."""
    header_bytes: int = 0

    def record(self) -> PerVsSinr:
        return PerVsSinr(radio=self.radio, sinr_db=self.sinr_db.tolist(),
                         psdu_bytes=list(self.psdu_bytes), per=self.per.tolist(),
                         header_bytes=self.header_bytes)

    def to_dict(self) -> dict[str, Any]:
        return to_json(self.record())


@dataclass(frozen=True)
class OutageCurve:
    """P(p_link(X) < p) over per-link shadowing, against distance, for each requirement p."""

    distance_m: np.ndarray = field(repr=False)
    requirements: tuple[tuple[str, float], ...]
    outage: np.ndarray = field(repr=False)
    """Shape (len(requirements), len(distance_m))."""
    sigma_db: float
    max_outage: float | None
    configured_distance_m: float

    def record(self) -> OutageVsDistance:
        return OutageVsDistance(distance_m=self.distance_m.tolist(),
                                requirements=[list(r) for r in self.requirements],
                                outage=self.outage.tolist(), sigma_db=self.sigma_db,
                                max_outage=self.max_outage,
                                configured_distance_m=self.configured_distance_m)

    def to_dict(self) -> dict[str, Any]:
        return to_json(self.record())


def distance_grid(link: LinkBudget, factor: float = 4.0, points: int = 200) -> np.ndarray:
    """Log-spaced distances from d/factor to d·factor around the configured distance."""
    d = link.distance_m
    return np.geomspace(d / factor, d * factor, points)


def arrival_vs_distance(link: LinkBudget, distance_m: Any = None) -> ArrivalCurve:
    """p(d) = 1 − PER(s_0(d), L)^{k+1} and, with shadowing, its average p̄(d)."""
    d = distance_grid(link) if distance_m is None else np.asarray(distance_m, dtype=float)
    sinr = (link.tx_power_dbm + link.antenna_gain_db - link.path_loss.loss_db(d)
            - link.noise.total_dbm)
    arrival = np.asarray(link.link_arrival(sinr), dtype=float)
    mean = (np.array([link.mean_arrival(float(s)) for s in sinr]) if link.sigma_db > 0
            else None)
    return ArrivalCurve(d, arrival, mean, link.distance_m, link.max_retries, link.psdu_bytes)


def sinr_transition_db(radio: Radio, psdu_bytes: tuple[int, ...],
                       per_high: float = 0.999, per_low: float = 1e-4,
                       header_bytes: int = 0) -> tuple[float, float]:
    r"""SINR range (dB) where the radio's PER falls from ``per_high`` to ``per_low``.

    The lower end is where the longest frame still has PER = ``per_high``, the upper end where
    the shortest frame reaches PER = ``per_low``; both solve 1 − PER(s, L) = p with the radio's
    own PER (so a calibrated radio's implementation loss moves the range):

    .. math:: s_{lo} = s : \mathrm{PER}(s, L_{max}) = \mathrm{per}_{high},\quad
              s_{hi} = s : \mathrm{PER}(s, L_{min}) = \mathrm{per}_{low}.
    """
    lo = radio.required_sinr_db(1.0 - per_high, int(max(psdu_bytes)) + header_bytes)
    hi = radio.required_sinr_db(1.0 - per_low, int(min(psdu_bytes)) + header_bytes)
    lo = float(SINR_SEARCH_DB[0]) if lo is None else float(lo)
    hi = lo + 1.0 if hi is None else float(hi)
    return lo, max(hi, lo + 1.0)


def sinr_grid(radio: Radio, psdu_bytes: tuple[int, ...], include_db: Sequence[float] = (),
              pad_db: float = 2.0, step_db: float = 0.05, header_bytes: int = 0) -> np.ndarray:
    """Evenly spaced SINR values (dB) over the radio's transition region
    (:func:`sinr_transition_db`) widened by ``pad_db`` and to every finite value of
    ``include_db`` (the configured and required SINR the figure marks)."""
    lo, hi = sinr_transition_db(radio, psdu_bytes, header_bytes=header_bytes)
    extra = [float(v) for v in include_db if v is not None and np.isfinite(v)]
    lo, hi = min([lo, *extra]) - pad_db, max([hi, *extra]) + pad_db
    points = int(min(2001, max(121, round((hi - lo) / step_db) + 1)))
    return np.linspace(lo, hi, points)


def per_vs_sinr(radio: Radio, psdu_bytes: tuple[int, ...] = (20, 60, 127),
                sinr_db: Any = None, include_db: Sequence[float] = (),
                header_bytes: int = 0) -> PerCurve:
    r"""PER of one attempt against SINR (dB) for each PSDU length, with the radio's own PER
    (implementation loss included) over the PHY header H (``header_bytes``) and the PSDU:

    .. math:: \mathrm{PER}(s, L) = 1 - (1 - \mathrm{BER}(s))^{8(H + L)}.

    Without ``sinr_db`` the grid is :func:`sinr_grid` (the transition region of these frame
    sizes, widened to the SINR values in ``include_db``).
    """
    s = (sinr_grid(radio, psdu_bytes, include_db, header_bytes=header_bytes) if sinr_db is None
         else np.asarray(sinr_db, dtype=float))
    per = np.vstack([radio.per(s, int(L) + header_bytes) for L in psdu_bytes])
    return PerCurve(radio.record().model, s, tuple(int(L) for L in psdu_bytes),
                    per, int(header_bytes))


def outage_vs_distance(link: LinkBudget, requirements: dict[str, float],
                       distance_m: Any = None) -> OutageCurve:
    """Φ((s(p) − s_0(d))/σ) for each requirement p (per-link shadowing)."""
    d = distance_grid(link) if distance_m is None else np.asarray(distance_m, dtype=float)
    rows = []
    for _, p in requirements.items():
        rows.append([link.with_changes(distance_m=float(x)).outage_probability(float(p))
                     for x in d])
    return OutageCurve(d, tuple((k, float(v)) for k, v in requirements.items()),
                       np.array(rows, dtype=float), link.sigma_db, link.max_outage,
                       link.distance_m)
