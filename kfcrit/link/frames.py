"""Frames and MAC retransmissions: what a packet is on the air and how retries combine.

Frame of IEEE 802.15.4 (2.4 GHz O-QPSK PHY), in bytes::

    PPDU = SHR (preamble 4 + SFD 1) + PHR 1 + PSDU
    PSDU = MPDU = MAC header + application payload + FCS 2   (at most aMaxPHYPacketSize = 127)

``packet_bytes`` in a system file is the *application payload*. The MAC overhead of a data frame
with short addresses and PAN-ID compression is 11 bytes (frame control 2, sequence number 1,
destination PAN 2, destination address 2, source address 2; FCS 2); with 64-bit addresses it is
23 (give ``mac_overhead_bytes`` for other frame formats).

Bits the packet error rate covers (``per_over``, :data:`PER_OVER`):

* ``ppdu`` (default): the whole PPDU, PHY header (SHR + PHR, 6 bytes for 802.15.4) + PSDU,
  L_PER = phy_header + PSDU. A receiver that loses the preamble, the SFD or the length byte
  loses the frame as surely as one that fails the FCS; ns-3's lr-wpan model applies its O-QPSK
  error model to every bit received between the start and the end of the PPDU
  (``LrWpanPhy::CheckInterference``: chunk = duration × bit rate), so this convention
  reproduces ns-3's analytic packet success rate;
* ``psdu``: the PSDU only (MAC header + payload + FCS), L_PER = PSDU — the bits the FCS
  protects; the convention of many textbook link budgets.

Both give PER(s) = 1 − (1 − BER(s))^{8 L_PER}; the PHY header always counts in the airtime.

Retransmissions: with ``k`` retries an update is lost only when all k + 1 attempts fail, so

.. math:: p = 1 - \\mathrm{PER}^{k+1}

if the attempts fail independently given the channel state of the sample period. The model
assumes that every attempt fits in the sample period and that the attempts of one period see the
*same* shadowing value (retries are milliseconds apart, far below a shadowing coherence time):
under per-link shadowing the formula holds conditionally on the link's shadowing value; under
per-packet shadowing the average is E_X[1 − PER(s + X)^{k+1}] (correlated attempts gain less
than 1 − E[PER]^{k+1}); under time-correlated shadowing a period in a deep fade loses all its
attempts. A link with ``fading_per_attempt: independent`` (per-packet shadowing only) redraws the
shadowing value for every attempt instead, so the attempts fail independently with the
shadowing-averaged PER and p = 1 − (E_X[PER(s + X)])^{k+1} (Jensen: never below the shared
value). A lost acknowledgement causes a needless retry, not a lost update, so acknowledgement
errors do not enter p.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from kfcrit.errors import InputError
from kfcrit.io.typed import to_json
from kfcrit.records.channel import RadioFrameRecord

PER_OVER = ("ppdu", "psdu")
"""Conventions for the bits the packet error rate covers (default first)."""


@dataclass(frozen=True)
class FrameFormat:
    """PHY and MAC framing of a radio standard (sizes in bytes).

    Attributes
    ----------
    standard : str
        Name of the PHY/MAC standard.
    mac_overhead_bytes : int
        MAC header + FCS of a data frame (default when the link gives none).
    phy_header_bytes : int
        SHR + PHR, sent before the PSDU (airtime; and the PER with ``per_over: ppdu``).
    max_psdu_bytes : int or None
        The PHY's largest PSDU (None: no limit).
    bit_rate_bps : float or None
        PSDU bit rate (for the airtime).
    max_retries : int
        Largest number of MAC retransmissions the standard allows.
    ack_wait_s : float or None
        Time a sender waits for an acknowledgement before retrying.
    """

    standard: str
    mac_overhead_bytes: int
    phy_header_bytes: int
    max_psdu_bytes: int | None
    bit_rate_bps: float | None
    max_retries: int
    ack_wait_s: float | None = None

    def psdu_bytes(self, payload_bytes: int, mac_overhead_bytes: int | None = None) -> int:
        """PSDU length: MAC overhead + payload (the bytes the packet error rate covers)."""
        overhead = self.mac_overhead_bytes if mac_overhead_bytes is None else mac_overhead_bytes
        return int(payload_bytes) + int(overhead)

    def per_bytes(self, payload_bytes: int, mac_overhead_bytes: int | None = None,
                  per_over: str = "ppdu") -> int:
        r"""Bytes the packet error rate covers: PHY header + PSDU (``ppdu``) or PSDU (``psdu``).

        .. math:: L_{PER} = H_{PHY} + L_{PSDU}\ \text{(ppdu)},\qquad
                  L_{PER} = L_{PSDU}\ \text{(psdu)}
        """
        if per_over not in PER_OVER:
            raise ValueError(f"per_over must be one of {PER_OVER}, got {per_over!r}")
        psdu = self.psdu_bytes(payload_bytes, mac_overhead_bytes)
        return psdu + (self.phy_header_bytes if per_over == "ppdu" else 0)

    def max_payload_bytes(self, mac_overhead_bytes: int | None = None) -> int | None:
        """Largest application payload that fits the PHY (None: no limit)."""
        if self.max_psdu_bytes is None:
            return None
        overhead = self.mac_overhead_bytes if mac_overhead_bytes is None else mac_overhead_bytes
        return self.max_psdu_bytes - overhead

    def check_payload(self, payload_bytes: int, mac_overhead_bytes: int | None,
                      field: str) -> None:
        """One-line error naming ``field`` when the frame exceeds the PHY limit."""
        psdu = self.psdu_bytes(payload_bytes, mac_overhead_bytes)
        if self.max_psdu_bytes is not None and psdu > self.max_psdu_bytes:
            overhead = psdu - int(payload_bytes)
            raise InputError(f"payload {payload_bytes} + MAC overhead {overhead} = {psdu} bytes "
                             f"exceeds the {self.standard} PHY limit of {self.max_psdu_bytes} "
                             f"bytes (largest payload {self.max_psdu_bytes - overhead})",
                             field=field)

    def check_retries(self, retries: int, field: str) -> None:
        """One-line error naming ``field`` when ``retries`` exceeds the standard's maximum."""
        if not 0 <= retries <= self.max_retries:
            raise InputError(f"must be between 0 and {self.max_retries} ({self.standard}), "
                             f"got {retries}", field=field)

    def airtime_s(self, psdu_bytes: int) -> float | None:
        """Time on air of one attempt: 8 (PHY header + PSDU) / bit rate."""
        if self.bit_rate_bps is None:
            return None
        return 8.0 * (self.phy_header_bytes + psdu_bytes) / self.bit_rate_bps

    def attempts_duration_s(self, psdu_bytes: int, retries: int) -> float | None:
        """Worst case for k + 1 unacknowledged attempts: (k + 1)(airtime + ack wait).

        CSMA-CA backoffs are not included (they are random and configuration-dependent).
        """
        air = self.airtime_s(psdu_bytes)
        if air is None or self.ack_wait_s is None:
            return None
        return (retries + 1) * (air + self.ack_wait_s)

    def record(self) -> RadioFrameRecord:
        """The framing as the record states it (``radio.frame``)."""
        return RadioFrameRecord(standard=self.standard, mac_overhead_bytes=self.mac_overhead_bytes,
                                phy_header_bytes=self.phy_header_bytes,
                                max_psdu_bytes=self.max_psdu_bytes, bit_rate_bps=self.bit_rate_bps,
                                max_retries=self.max_retries, ack_wait_s=self.ack_wait_s)

    def to_dict(self) -> dict[str, Any]:
        return to_json(self.record())


IEEE802154_2450 = FrameFormat(
    standard="IEEE 802.15.4 O-QPSK 2450 MHz", mac_overhead_bytes=11, phy_header_bytes=6,
    max_psdu_bytes=127, bit_rate_bps=250e3, max_retries=7, ack_wait_s=864e-6)
"""aMaxPHYPacketSize 127, macMaxFrameRetries ≤ 7, macAckWaitDuration 54 symbols of 16 µs."""

UNFRAMED = FrameFormat(standard="unframed (payload only)", mac_overhead_bytes=0,
                       phy_header_bytes=0, max_psdu_bytes=None, bit_rate_bps=None,
                       max_retries=15)
"""A generic modulation without a MAC: the packet is the payload."""


def log_per(log_arrival: Any) -> np.ndarray:
    """log PER = log(−expm1(log(1 − PER))), accurate for PER near 0 and near 1."""
    la = np.asarray(log_arrival, dtype=float)
    with np.errstate(divide="ignore"):
        return np.log(-np.expm1(la))


def arrival_with_retries(log_arrival: Any, retries: int) -> np.ndarray:
    r"""Arrival probability within a sample period with ``retries`` retransmissions.

    .. math:: p = 1 - \mathrm{PER}^{k+1} = -\operatorname{expm1}((k+1) \log \mathrm{PER})

    Parameters
    ----------
    log_arrival : array_like
        log(1 − PER) of one attempt.
    retries : int
        k ≥ 0.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        return 0.0 - np.expm1((retries + 1) * log_per(log_arrival))  # 0.0 −: no −0.0


def attempt_probability(arrival_probability: float, retries: int) -> float:
    r"""Per-attempt success probability that gives ``arrival_probability`` with k retries.

    .. math:: p_1 = 1 - (1 - p)^{1/(k+1)}
    """
    p = float(arrival_probability)
    if p >= 1.0:
        return 1.0
    return float(-math.expm1(math.log1p(-p) / (retries + 1)))
