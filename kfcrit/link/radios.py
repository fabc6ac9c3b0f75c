"""Radio models: bit error rate as a function of SINR, and packet error rate from it.

A radio turns the signal-to-interference-plus-noise ratio at the receiver (linear, not dB) into a
bit error rate; every radio shares the uncoded packet error rate

    PER(SINR, L) = 1 − (1 − BER(SINR))^{8 L}        (L bytes, independent bit errors)

and the arrival probability 1 − PER. Adding a radio never touches the others: write a frozen
dataclass with ``ber``, ``from_mapping`` and ``to_dict`` and add one line to ``_RADIOS``.

Numerics: ``PER`` and ``arrival`` are computed as ``−expm1(8L·log1p(−BER))`` and
``exp(8L·log1p(−BER))`` so that tiny error rates (PER ~ 1e-12) keep full relative accuracy.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from scipy.optimize import brentq
from scipy.special import comb, erfc

from kfcrit.errors import InputError

SINR_SEARCH_DB = (-40.0, 60.0)
"""Interval (dB) searched when inverting PER(SINR); error rates outside it are reported as edges."""


def db_to_linear(x_db: Any) -> Any:
    """10^(x/10)."""
    return np.power(10.0, np.asarray(x_db, dtype=float) / 10.0)


def linear_to_db(x: Any) -> Any:
    """10·log10(x)."""
    return 10.0 * np.log10(np.asarray(x, dtype=float))


class Radio:
    """Base class: subclasses define :meth:`ber` (vectorised over linear SINR)."""

    name: ClassVar[str]
    formula: ClassVar[str]
    source: ClassVar[str]

    def ber(self, sinr: Any) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError

    def log_arrival(self, sinr_db: Any, packet_bytes: int) -> np.ndarray:
        """log(1 − PER) = 8L·log1p(−BER) at SINR given in dB."""
        ber = np.clip(self.ber(db_to_linear(sinr_db)), 0.0, 1.0)
        with np.errstate(divide="ignore"):
            return 8 * packet_bytes * np.log1p(-ber)

    def arrival(self, sinr_db: Any, packet_bytes: int) -> np.ndarray:
        """Packet arrival probability 1 − PER at SINR given in dB."""
        return np.exp(self.log_arrival(sinr_db, packet_bytes))

    def per(self, sinr_db: Any, packet_bytes: int) -> np.ndarray:
        """Packet error rate 1 − (1 − BER)^{8L} at SINR given in dB."""
        return -np.expm1(self.log_arrival(sinr_db, packet_bytes))

    def required_sinr_db(self, arrival_probability: float, packet_bytes: int) -> float | None:
        """Least SINR (dB) with 1 − PER ≥ ``arrival_probability`` (memoised, see below).

        The result depends only on (radio, p, L) — not on distance, power or noise — so a
        sweep over those asks the same question many times; the answers are memoised per
        process (:func:`functools.lru_cache`; errors are not cached, and a cached answer is
        the same float the computation gives).
        """
        return _required_sinr_cached(self, float(arrival_probability), int(packet_bytes))

    def _required_sinr_db(self, arrival_probability: float, packet_bytes: int) -> float | None:
        """Least SINR (dB) with 1 − PER ≥ ``arrival_probability`` (the computation).

        Returns None when no SINR is needed (``arrival_probability`` ≤ the arrival probability at
        the bottom of :data:`SINR_SEARCH_DB`, e.g. 0). Raises :class:`ValueError` for 1 or more
        (never reached at finite SINR). The root is found by Brent's method on
        log PER(s) − log(1 − p) (p > 1/2) or log(1 − PER(s)) − log p, both increasing/decreasing
        monotonically in s, so the result keeps relative accuracy for p near 0 and near 1.
        """
        p = float(arrival_probability)
        if not p < 1.0:
            raise ValueError("an arrival probability of 1 is not reached at finite SINR")
        lo, hi = SINR_SEARCH_DB
        if p <= float(self.arrival(lo, packet_bytes)):
            return None

        if p > 0.5:
            target = math.log1p(-p)

            def fn(s: float) -> float:
                return math.log(max(float(self.per(s, packet_bytes)), 1e-300)) - target
        else:
            target = math.log(p)

            def fn(s: float) -> float:
                return float(self.log_arrival(s, packet_bytes)) - target
        unreachable = fn(hi) > 0 if p > 0.5 else fn(hi) < 0
        if unreachable:
            raise ValueError(f"arrival probability {p!r} needs more than {hi} dB SINR")
        return float(brentq(fn, lo, hi, xtol=1e-12, rtol=4 * np.finfo(float).eps, maxiter=200))


@functools.lru_cache(maxsize=4096)
def _required_sinr_cached(radio: Radio, p: float, packet_bytes: int) -> float | None:
    return radio._required_sinr_db(p, packet_bytes)


@dataclass(frozen=True)
class Ieee802154Oqpsk(Radio):
    """IEEE 802.15.4-2006 O-QPSK at 2450 MHz (DSSS, 16-ary quasi-orthogonal), as in ns-3.

    BER(SINR) = (8/15)·(1/16)·Σ_{k=2}^{16} (−1)^k C(16,k) exp(20·SINR·(1/k − 1)),

    SINR linear (IEEE 802.15.4-2006 Annex E; ns-3 ``LrWpanErrorModel::GetChunkSuccessRate``).
    It is the bit error rate of non-coherent 16-ary orthogonal signalling,
    (M/2)/(M − 1)·P_s with M = 16, at Es/N0 = 20·SINR.
    """

    name: ClassVar[str] = "ieee802154-oqpsk-2450"
    formula: ClassVar[str] = ("BER = (8/15)(1/16) sum_{k=2}^{16} (-1)^k C(16,k) "
                              "exp(20 SINR (1/k - 1))")
    source: ClassVar[str] = "IEEE 802.15.4-2006 Annex E; ns-3 LrWpanErrorModel"

    @classmethod
    def from_mapping(cls, data: dict, prefix: str) -> Ieee802154Oqpsk:
        _check_radio_keys(data, set(), prefix)
        return cls()

    def ber(self, sinr: Any) -> np.ndarray:
        s = np.asarray(sinr, dtype=float)
        k = np.arange(2, 17, dtype=float)
        coeff = (-1.0) ** k * comb(16, k, exact=False)
        terms = coeff * np.exp(20.0 * s[..., None] * (1.0 / k - 1.0))
        return np.clip(terms.sum(axis=-1) * (8.0 / 15.0) / 16.0, 0.0, 0.5)

    def to_dict(self) -> dict[str, Any]:
        return {"model": self.name, "formula": self.formula, "source": self.source}


@dataclass(frozen=True)
class CoherentBpsk(Radio):
    """Coherent BPSK over AWGN.

    BER = Q(√(2·Eb/N0)) = ½·erfc(√(Eb/N0)),   Eb/N0 [dB] = SINR [dB] + G,

    with G = ``processing_gain_db`` = 10·log10(B_noise / R_bit) (0 dB for a matched filter whose
    noise bandwidth equals the bit rate).
    """

    processing_gain_db: float = 0.0
    name: ClassVar[str] = "bpsk"
    formula: ClassVar[str] = ("BER = Q(sqrt(2 Eb/N0)) = erfc(sqrt(Eb/N0))/2, "
                              "Eb/N0 = SINR * 10^(G/10)")
    source: ClassVar[str] = "Proakis, Digital Communications, coherent BPSK in AWGN"

    @classmethod
    def from_mapping(cls, data: dict, prefix: str) -> CoherentBpsk:
        from kfcrit.link.linkbudget import real_field

        _check_radio_keys(data, {"processing_gain_db"}, prefix)
        gain = 0.0
        if "processing_gain_db" in data:
            gain = real_field(data, "processing_gain_db", prefix, low=-60, high=60)
        return cls(gain)

    def ber(self, sinr: Any) -> np.ndarray:
        ebn0 = np.asarray(sinr, dtype=float) * 10.0 ** (self.processing_gain_db / 10.0)
        return 0.5 * erfc(np.sqrt(ebn0))

    def to_dict(self) -> dict[str, Any]:
        return {"model": self.name, "processing_gain_db": self.processing_gain_db,
                "formula": self.formula, "source": self.source}


_RADIOS: dict[str, type[Radio]] = {
    Ieee802154Oqpsk.name: Ieee802154Oqpsk,
    CoherentBpsk.name: CoherentBpsk,
}


def radio_models() -> list[str]:
    """Names of the registered radios."""
    return sorted(_RADIOS)


def _check_radio_keys(data: dict, allowed: set[str], prefix: str) -> None:
    for key in data:
        if key != "model" and key not in allowed:
            raise InputError(f"unknown key (allowed: {', '.join(sorted(allowed | {'model'}))})",
                             field=f"{prefix}.{key}")


def radio_from_mapping(value: Any, prefix: str) -> Radio:
    """A radio from ``radio: NAME`` or ``radio: {model: NAME, ...parameters}``."""
    data = {"model": value} if isinstance(value, str) else value
    if not isinstance(data, dict) or not isinstance(data.get("model"), str):
        raise InputError(f"must be a radio name or a mapping with 'model' (one of: "
                         f"{', '.join(radio_models())})", field=prefix)
    name = data["model"]
    if name not in _RADIOS:
        raise InputError(f"unknown radio {name[:40]!r} (known: {', '.join(radio_models())})",
                         field=prefix if isinstance(value, str) else f"{prefix}.model")
    return _RADIOS[name].from_mapping(data, prefix)
