r"""Radio models: bit error rate as a function of SINR, and packet error rate from it.

A radio turns the signal-to-interference-plus-noise ratio at the receiver (linear, not dB) into a
bit error rate; every radio shares the uncoded packet error rate

    PER(SINR, L) = 1 − (1 − BER(SINR))^{8 L}        (L bytes, independent bit errors)

and the arrival probability 1 − PER, with L the bytes the PER covers (the PPDU by default, or the
PSDU: ``per_over``, see :mod:`kfcrit.link.frames`). Adding
a radio never touches the others: write a frozen dataclass with ``ber``, ``from_mapping`` and
``to_dict`` and add one line to ``_RADIOS``.

Datasheet profiles (:func:`radio_profiles`) are the ideal O-QPSK formula shifted by an
implementation loss ΔL (dB), calibrated so that the datasheet sensitivity S (dBm, at the stated
PER and PSDU length) is reproduced against the thermal noise of the 2 MHz channel at 290 K:

.. math:: \Delta L = S - N_{ref} - s_{ideal}(1 - \mathrm{PER}_{ref}, L_{ref}),
          \qquad N_{ref} = 10\log_{10}(k_B \cdot 290 \cdot 2\,\mathrm{MHz}/1\,\mathrm{mW}),

and BER(SINR) = BER_ideal(SINR / 10^{ΔL/10}). ΔL contains the receiver's noise figure and its
demodulator loss; a link using a profile should give its noise floor without a noise figure.
s_ideal is solved over the reference PPDU, L_ref + 6 bytes (PHY header + the datasheet's PSDU):
the bits a link's PER covers by default (``per_over: ppdu``, :mod:`kfcrit.link.frames`), so a
default link at the sensitivity has exactly the datasheet PER; a ``per_over: psdu`` link there
has a slightly lower PER (its PER covers 6 bytes fewer).

Numerics: ``PER`` and ``arrival`` are computed as ``−expm1(8L·log1p(−BER))`` and
``exp(8L·log1p(−BER))`` so that tiny error rates (PER ~ 1e-12) keep full relative accuracy.
"""
from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from kfcrit.errors import InputError
from kfcrit.link.fields import integer_field, real_field
from kfcrit.link.frames import IEEE802154_2450, UNFRAMED, FrameFormat
from kfcrit.link.propagation import db_to_linear, thermal_noise_dbm
from kfcrit.records.channel import RadioRecord

SINR_SEARCH_DB = (-40.0, 60.0)
"""Interval (dB) searched when inverting PER(SINR); error rates outside it are reported as edges."""


class Radio:
    """Base class: subclasses define :meth:`ber` (vectorised over linear SINR) and ``frame``."""

    name: ClassVar[str]
    formula: ClassVar[str]
    source: ClassVar[str]
    frame: ClassVar[FrameFormat] = UNFRAMED

    def ber(self, sinr: Any) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError

    def to_dict(self) -> dict[str, Any]:  # pragma: no cover - abstract
        raise NotImplementedError

    def record(self) -> RadioRecord:  # pragma: no cover - abstract
        """The radio as the record states it (``link_budget.radio``)."""
        raise NotImplementedError

    def log_arrival(self, sinr_db: Any, packet_bytes: int) -> np.ndarray:
        """log(1 − PER) = 8L·log1p(−BER) at SINR given in dB (L: bytes covered)."""
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
        """Least SINR (dB) with 1 − PER ≥ ``arrival_probability``.

        The answer depends only on (radio, p, L), not on distance, power or noise, so a sweep
        over those asks the same question many times; :func:`required_sinr_db` memoises it
        (a pure function of hashable arguments; errors are not cached).
        """
        return required_sinr_db(self, float(arrival_probability), int(packet_bytes))

    def solve_required_sinr_db(self, arrival_probability: float,
                               packet_bytes: int) -> float | None:
        """Least SINR (dB) with 1 − PER ≥ ``arrival_probability`` (the computation).

        Returns None when no SINR is needed (``arrival_probability`` ≤ the arrival probability at
        the bottom of :data:`SINR_SEARCH_DB`, e.g. 0). Raises :class:`ValueError` for 1 or more
        (never reached at finite SINR). The root is found by Brent's method on
        log PER(s) − log(1 − p) (p > 1/2) or log(1 − PER(s)) − log p, both monotone in s, so
        the result keeps relative accuracy for p near 0 and near 1.
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
        from scipy.optimize import brentq

        return float(brentq(fn, lo, hi, xtol=1e-12, rtol=4 * np.finfo(float).eps, maxiter=200))


@functools.lru_cache(maxsize=4096)
def required_sinr_db(radio: Radio, arrival_probability: float,
                     packet_bytes: int) -> float | None:
    """:meth:`Radio.solve_required_sinr_db`, memoised (frozen radios are hashable values)."""
    return radio.solve_required_sinr_db(arrival_probability, packet_bytes)


CERTAIN_EXPONENT = -40.0
"""Exponent below which e^x vanishes beside 1 in double precision with room to spare:
e^{−40} = 4·10^{−18}, under the 2^{−54} = 5.6·10^{−17} that rounds 1 − e^x to 1."""
CERTAIN_MARGIN_DB = 1.0
"""Extra SINR (dB) between a computed end of :func:`certain_arrival_sinr_db` and the SINRs it
is used for (the error rate falls by orders of magnitude per dB, so rounding never crosses it)."""


@functools.lru_cache(maxsize=256)
def certain_arrival_sinr_db(radio: Radio, packet_bytes: int,
                            retries: int) -> tuple[float, float]:
    r"""SINRs (dB) below which the arrival probability within a period is exactly 0.0 and
    above which it is exactly 1.0 in double precision, as :func:`kfcrit.link.frames.
    arrival_with_retries` computes it from :meth:`Radio.log_arrival`.

    .. math:: p(s) = -\operatorname{expm1}igl((k+1)\log(-\operatorname{expm1}(\ell(s)))igr),
              \qquad \ell(s) = 8L\log(1 - \mathrm{BER}(s))

    is 0.0 where ℓ(s) < −40 (−expm1(ℓ) rounds to 1, its log to 0) and 1.0 where
    (k+1)·log(−expm1(ℓ(s))) < −40 (expm1 rounds to −1). BER is non-increasing in s, so both
    sets are half-lines; their ends are found by bisection and moved outwards by
    :data:`CERTAIN_MARGIN_DB`. A shadowing average evaluates the radio only between them.
    Memoised (a pure function of hashable arguments).

    Returns
    -------
    (float, float)
        (s_0, s_1): p is 0.0 for s ≤ s_0 and 1.0 for s ≥ s_1 (−inf or +inf when the set is
        empty on [−100, 200] dB).
    """
    def log_arrival(s: float) -> float:
        return float(radio.log_arrival(s, packet_bytes))

    def zero(s: float) -> bool:
        return log_arrival(s) < CERTAIN_EXPONENT

    def one(s: float) -> bool:
        la = log_arrival(s)
        return la == 0.0 or (retries + 1) * math.log(-math.expm1(la)) < CERTAIN_EXPONENT

    def edge(pred: Callable[[float], bool], inside: float, outside: float) -> float:
        for _ in range(60):   # 300 dB / 2^60: far below the margin
            mid = 0.5 * (inside + outside)
            inside, outside = (mid, outside) if pred(mid) else (inside, mid)
        return inside

    lo, hi = -100.0, 200.0
    s0 = edge(zero, lo, hi) - CERTAIN_MARGIN_DB if zero(lo) else -math.inf
    s1 = edge(one, hi, lo) + CERTAIN_MARGIN_DB if one(hi) else math.inf
    return s0, s1


@functools.lru_cache(maxsize=1)
def _oqpsk_terms() -> tuple[np.ndarray, np.ndarray]:
    """k = 2..16 and (−1)^k C(16, k) of :func:`oqpsk_ber`, computed once (read-only)."""
    from scipy.special import comb

    k = np.arange(2, 17, dtype=float)
    coeff = (-1.0) ** k * comb(16, k, exact=False)
    k.setflags(write=False)
    coeff.setflags(write=False)
    return k, coeff


def oqpsk_ber(sinr: Any) -> np.ndarray:
    r"""Bit error rate of the IEEE 802.15.4 2450 MHz O-QPSK PHY at linear SINR.

    .. math:: \mathrm{BER} = \frac{8}{15}\cdot\frac{1}{16}\sum_{k=2}^{16} (-1)^k \binom{16}{k}
              e^{20\,\mathrm{SINR}\,(1/k - 1)}
    """
    s = np.asarray(sinr, dtype=float)
    k, coeff = _oqpsk_terms()
    if s.ndim == 0:
        return _oqpsk_sum(s[None], k, coeff)[0]
    # every term underflows to exactly 0 above OQPSK_ZERO_SINR: BER = 0 there, computed or not
    live = ~(s > OQPSK_ZERO_SINR)
    if live.all():
        return _oqpsk_sum(s, k, coeff)
    out = np.zeros(s.shape)
    out[live] = _oqpsk_sum(s[live], k, coeff)
    return out


OQPSK_ZERO_SINR = 75.0
"""Linear SINR above which every term of :func:`oqpsk_ber` underflows: e^{20·75·(1/2 − 1)} =
e^{−750} is below the least subnormal float (e^{−745.13}), and the other terms are smaller."""


def _oqpsk_sum(s: np.ndarray, k: np.ndarray, coeff: np.ndarray) -> np.ndarray:
    """The sum of :func:`oqpsk_ber` at every SINR of ``s`` (clipped to [0, 1/2]).

    The fifteen terms are laid out one row per k and added in the order of NumPy's pairwise
    sum over a row of fifteen (eight in a tree, then the other seven one by one): the same
    floating-point operations as ``terms.sum(axis=-1)`` on the (SINR, k) array, so the same
    bits, without NumPy's slow reduction over a short axis.
    """
    flat = s.ravel()
    if flat.size < 16:  # a few SINRs: fewer NumPy calls this way, the same sums
        terms = coeff * np.exp(20.0 * flat[:, None] * (1.0 / k - 1.0))
        return np.clip(terms.sum(axis=-1) * (8.0 / 15.0) / 16.0, 0.0, 0.5).reshape(s.shape)
    e = coeff[:, None] * np.exp((1.0 / k - 1.0)[:, None] * (20.0 * flat)[None, :])
    total = ((e[0] + e[1]) + (e[2] + e[3])) + ((e[4] + e[5]) + (e[6] + e[7]))
    for row in e[8:]:
        total += row
    return np.clip(total * (8.0 / 15.0) / 16.0, 0.0, 0.5).reshape(s.shape)


@dataclass(frozen=True)
class Ieee802154Oqpsk(Radio):
    """IEEE 802.15.4-2006 O-QPSK at 2450 MHz (DSSS, 16-ary quasi-orthogonal), as in ns-3.

    BER(SINR) = (8/15)·(1/16)·Σ_{k=2}^{16} (−1)^k C(16,k) exp(20·SINR·(1/k − 1)),

    SINR linear (IEEE 802.15.4-2006 Annex E; ns-3 ``LrWpanErrorModel::GetChunkSuccessRate``).
    It is the bit error rate of non-coherent 16-ary orthogonal signalling,
    (M/2)/(M − 1)·P_s with M = 16, at Es/N0 = 20·SINR. An ideal receiver: no implementation
    loss (see :class:`CalibratedOqpsk` for datasheet-calibrated transceivers).
    """

    name: ClassVar[str] = "ieee802154-oqpsk-2450"
    formula: ClassVar[str] = ("BER = (8/15)(1/16) sum_{k=2}^{16} (-1)^k C(16,k) "
                              "exp(20 SINR (1/k - 1))")
    source: ClassVar[str] = "IEEE 802.15.4-2006 Annex E; ns-3 LrWpanErrorModel"
    frame: ClassVar[FrameFormat] = IEEE802154_2450

    @classmethod
    def from_mapping(cls, data: dict, prefix: str) -> Ieee802154Oqpsk:
        check_radio_keys(data, set(), prefix)
        return cls()

    def ber(self, sinr: Any) -> np.ndarray:
        return oqpsk_ber(sinr)

    def to_dict(self) -> dict[str, Any]:
        return {"model": self.name, "formula": self.formula, "source": self.source,
                "implementation_loss_db": 0.0, "frame": self.frame.to_dict()}

    def record(self) -> RadioRecord:
        return RadioRecord(model=self.name, formula=self.formula, source=self.source,
                           implementation_loss_db=0.0, frame=self.frame.record())


OQPSK_REFERENCE_BANDWIDTH_HZ = 2.0e6
"""Noise bandwidth of a 2450 MHz 802.15.4 channel (2 Mchip/s) used for the calibration."""


@dataclass(frozen=True)
class CalibratedOqpsk(Radio):
    r"""An 802.15.4 O-QPSK transceiver: the ideal formula shifted by an implementation loss.

    .. math:: \mathrm{BER}(\mathrm{SINR}) = \mathrm{BER}_{ideal}(\mathrm{SINR}\cdot
              10^{-\Delta L/10})

    ΔL is calibrated from the sensitivity (see the module docstring, :func:`calibrate_oqpsk`).
    """

    model_name: str
    sensitivity_dbm: float
    reference_per: float
    reference_psdu_bytes: int
    implementation_loss_db: float
    datasheet: str
    formula: ClassVar[str] = ("BER = BER_oqpsk(SINR / 10^(dL/10)), dL = S - N_ref - "
                              "s_ideal(1 - PER_ref, L_ref + 6) (PER over the reference PPDU)")
    source: ClassVar[str] = "datasheet sensitivity; IEEE 802.15.4-2006 Annex E formula"
    frame: ClassVar[FrameFormat] = IEEE802154_2450

    @property
    def name(self) -> str:  # type: ignore[override]
        return self.model_name

    @classmethod
    def from_mapping(cls, data: dict, prefix: str) -> CalibratedOqpsk:
        check_radio_keys(data, {"sensitivity_dbm", "reference_per", "reference_psdu_bytes"},
                         prefix)
        for key in ("sensitivity_dbm",):
            if key not in data:
                raise InputError("is required", field=f"{prefix}.{key}")
        per = (real_field(data, "reference_per", prefix, low=0, high=0.5, low_open=True)
               if "reference_per" in data else 0.01)
        length = (integer_field(data, "reference_psdu_bytes", prefix, low=1,
                                high=IEEE802154_2450.max_psdu_bytes)
                  if "reference_psdu_bytes" in data else 20)
        return calibrate_oqpsk(CUSTOM_OQPSK, real_field(data, "sensitivity_dbm", prefix,
                                                        low=-150, high=0),
                               per, length, "given in the system file")

    def ber(self, sinr: Any) -> np.ndarray:
        shift = 10.0 ** (-self.implementation_loss_db / 10.0)
        return oqpsk_ber(np.asarray(sinr, dtype=float) * shift)

    def to_dict(self) -> dict[str, Any]:
        return {"model": self.model_name, "formula": self.formula, "source": self.source,
                "sensitivity_dbm": self.sensitivity_dbm, "reference_per": self.reference_per,
                "reference_psdu_bytes": self.reference_psdu_bytes,
                "reference_noise_dbm": oqpsk_reference_noise_dbm(),
                "implementation_loss_db": self.implementation_loss_db,
                "datasheet": self.datasheet, "frame": self.frame.to_dict()}

    def record(self) -> RadioRecord:
        return RadioRecord(model=self.model_name, formula=self.formula, source=self.source,
                           implementation_loss_db=self.implementation_loss_db,
                           frame=self.frame.record(), sensitivity_dbm=self.sensitivity_dbm,
                           reference_per=self.reference_per,
                           reference_psdu_bytes=self.reference_psdu_bytes,
                           reference_noise_dbm=oqpsk_reference_noise_dbm(),
                           datasheet=self.datasheet)


CUSTOM_OQPSK = "ieee802154-oqpsk-calibrated"
"""Radio name for an 802.15.4 transceiver calibrated from a sensitivity given in the file."""


def oqpsk_reference_noise_dbm() -> float:
    """N_ref = thermal noise of the 2 MHz channel at 290 K with no noise figure (≈ −110.98)."""
    return thermal_noise_dbm(OQPSK_REFERENCE_BANDWIDTH_HZ, 0.0, 290.0)


def calibrate_oqpsk(name: str, sensitivity_dbm: float, reference_per: float,
                    reference_psdu_bytes: int, datasheet: str) -> CalibratedOqpsk:
    r"""The transceiver whose sensitivity is ``sensitivity_dbm`` at the given PER and PSDU.

    .. math:: \Delta L = S - N_{ref} - s_{ideal}(1 - \mathrm{PER}_{ref}, L_{ref} + H_{PHY})

    with H_PHY = 6 bytes (SHR + PHR): the PER of the sensitivity test is that of whole frames,
    counted over the PPDU as a default link counts it.
    """
    ideal = Ieee802154Oqpsk().required_sinr_db(
        1.0 - reference_per, reference_psdu_bytes + IEEE802154_2450.phy_header_bytes)
    loss = float(sensitivity_dbm) - oqpsk_reference_noise_dbm() - float(ideal)
    return CalibratedOqpsk(name, float(sensitivity_dbm), float(reference_per),
                           int(reference_psdu_bytes), loss, datasheet)


DATASHEET_SENSITIVITY = (
    ("cc2420", -95.0, 0.01, 20,
     "TI/Chipcon CC2420 datasheet (SWRS041): receiver sensitivity -95 dBm typical, PER = 1 %, "
     "20-byte PSDU (the IEEE 802.15.4 sensitivity test)"),
    ("cc2520", -98.0, 0.01, 20,
     "TI CC2520 datasheet (SWRS068): receiver sensitivity -98 dBm typical, PER = 1 %, "
     "20-byte PSDU"),
    ("at86rf233", -101.0, 0.01, 20,
     "Atmel AT86RF233 datasheet (8351): receiver sensitivity -101 dBm typical at 250 kb/s, "
     "AWGN, PER <= 1 %, PSDU length 20 octets"),
    ("nrf52840", -100.0, 0.01, 20,
     "Nordic nRF52840 Product Specification: IEEE 802.15.4 receiver sensitivity -100 dBm "
     "typical, PER = 1 %, 20-byte PSDU"),
)
"""(name, sensitivity dBm, PER, PSDU bytes, source): typical values as the datasheets state them."""


@functools.lru_cache(maxsize=1)
def radio_profiles() -> dict[str, CalibratedOqpsk]:
    """The datasheet-calibrated 802.15.4 transceivers, by name (pure; computed once)."""
    return {name: calibrate_oqpsk(name, s, per, length, source)
            for name, s, per, length, source in DATASHEET_SENSITIVITY}


@dataclass(frozen=True)
class CoherentBpsk(Radio):
    """Coherent BPSK over AWGN.

    BER = Q(√(2·Eb/N0)) = ½·erfc(√(Eb/N0)),   Eb/N0 [dB] = SINR [dB] + G,

    with G = ``processing_gain_db`` = 10·log10(B_noise / R_bit) (0 dB for a matched filter whose
    noise bandwidth equals the bit rate). No framing: the packet is the payload.
    """

    processing_gain_db: float = 0.0
    name: ClassVar[str] = "bpsk"
    formula: ClassVar[str] = ("BER = Q(sqrt(2 Eb/N0)) = erfc(sqrt(Eb/N0))/2, "
                              "Eb/N0 = SINR * 10^(G/10)")
    source: ClassVar[str] = "Proakis, Digital Communications, coherent BPSK in AWGN"

    @classmethod
    def from_mapping(cls, data: dict, prefix: str) -> CoherentBpsk:
        check_radio_keys(data, {"processing_gain_db"}, prefix)
        gain = 0.0
        if "processing_gain_db" in data:
            gain = real_field(data, "processing_gain_db", prefix, low=-60, high=60)
        return cls(gain)

    def ber(self, sinr: Any) -> np.ndarray:
        ebn0 = np.asarray(sinr, dtype=float) * 10.0 ** (self.processing_gain_db / 10.0)
        from scipy.special import erfc

        return 0.5 * erfc(np.sqrt(ebn0))

    def to_dict(self) -> dict[str, Any]:
        return {"model": self.name, "processing_gain_db": self.processing_gain_db,
                "formula": self.formula, "source": self.source, "frame": self.frame.to_dict()}

    def record(self) -> RadioRecord:
        return RadioRecord(model=self.name, formula=self.formula, source=self.source,
                           frame=self.frame.record(), processing_gain_db=self.processing_gain_db)


_RADIOS: dict[str, type[Radio]] = {
    Ieee802154Oqpsk.name: Ieee802154Oqpsk,
    CoherentBpsk.name: CoherentBpsk,
    CUSTOM_OQPSK: CalibratedOqpsk,
}


def radio_models() -> list[str]:
    """Names accepted by ``radio:``: the formula radios and the datasheet profiles."""
    return sorted(set(_RADIOS) | set(radio_profiles()))


def check_radio_keys(data: dict, allowed: set[str], prefix: str) -> None:
    """Unknown radio parameters are errors naming the field."""
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
    profiles = radio_profiles()
    if name in profiles:
        check_radio_keys(data, set(), prefix)
        return profiles[name]
    if name not in _RADIOS:
        raise InputError(f"unknown radio {name[:40]!r} (known: {', '.join(radio_models())})",
                         field=prefix if isinstance(value, str) else f"{prefix}.model")
    return _RADIOS[name].from_mapping(data, prefix)


@dataclass(frozen=True)
class RadioInfo:
    """One entry of :func:`radio_catalogue`."""

    name: str
    kind: str
    description: str
    parameters: dict[str, Any]

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "kind": self.kind, "description": self.description,
                "parameters": dict(self.parameters)}


def radio_catalogue() -> tuple[RadioInfo, ...]:
    """Every radio a system file can name, with its parameters (for ``kfcrit radios``).

    ``kind`` is ``formula`` (an ideal receiver: a textbook BER), ``datasheet`` (an 802.15.4
    transceiver calibrated from its datasheet sensitivity; ``implementation_loss_db`` relative
    to the ideal O-QPSK formula) or ``calibrated`` (the same, with the sensitivity given in the
    file: ``radio: {model: ieee802154-oqpsk-calibrated, sensitivity_dbm: ...}``).
    """
    out = [RadioInfo(Ieee802154Oqpsk.name, "formula", "ideal IEEE 802.15.4 O-QPSK receiver",
                     Ieee802154Oqpsk().to_dict()),
           RadioInfo(CoherentBpsk.name, "formula", "coherent BPSK in AWGN (optional "
                     "processing_gain_db), unframed", CoherentBpsk().to_dict()),
           RadioInfo(CUSTOM_OQPSK, "calibrated", "802.15.4 O-QPSK with the implementation loss "
                     "of a given sensitivity_dbm (reference_per 0.01, reference_psdu_bytes 20 "
                     "by default)", {"sensitivity_dbm": "required", "reference_per": 0.01,
                                     "reference_psdu_bytes": 20,
                                     "frame": IEEE802154_2450.to_dict()})]
    for name, radio in sorted(radio_profiles().items()):
        out.append(RadioInfo(name, "datasheet", radio.datasheet, radio.to_dict()))
    return tuple(out)
