"""Link budgets: from transmit power, distance and payload size to the arrival probability.

The chain, in dB and dBm (every step is a stated formula, tested against independent values)::

    path loss     PL(d) = PL0 + 10·n·log10(d/d0) + X          (kfcrit.link.propagation)
    received      Pr = Pt + G − PL(d)                          (G: total antenna gain, dB)
    SINR          SINR_dB = Pr − (N ⊕ I)                       (noise floor and interference)
    frame         L = PHY header + payload + MAC overhead       (kfcrit.link.frames; per_over)
    one attempt   1 − PER(SINR, L) = (1 − BER(SINR))^{8L}      (radio model: kfcrit.link.radios)
    fast fading   PER → E_γ[PER(γ, L)], γ ~ Gamma(m, SINR/m)   (optional: kfcrit.link.fading)
    arrival       p = 1 − PER^{k+1}                            (k = max_retries MAC retries)

``packet_bytes`` is the application payload; the PSDU adds the radio's MAC header and FCS
(``mac_overhead_bytes``, 11 bytes for an 802.15.4 data frame with short addresses) and must fit
the PHY (127 bytes for 802.15.4). The PER covers the whole PPDU by default (``per_over: ppdu``:
the PHY header — preamble, SFD, PHR, 6 bytes for 802.15.4 — is received with the same bit error
rate, as in ns-3's lr-wpan model), or the PSDU only (``per_over: psdu``); the PHY header always
counts in the airtime.

Retries and shadowing (``fading_per_attempt``): ``shared`` (default) — the k + 1 attempts of a
period see the period's shadowing value, p̄ = E_X[1 − PER(s + X)^{k+1}]; ``independent`` (only
with per-packet shadowing) — each attempt draws its own value, so the attempts fail
independently with the averaged PER, p̄ = 1 − (E_X[PER(s + X)])^{k+1}.

Fast fading (``fading: {model: rayleigh | nakagami, m}``, default none): the SNR of every
attempt is redrawn from Gamma(m, γ̄/m) around the mean γ̄ (Rayleigh: m = 1), independently per
attempt, so one attempt fails with E_γ[PER(γ)] and p = 1 − E_γ[PER(γ)]^{k+1}; the shadowing
(below) sets γ̄ and the fading varies around it (:mod:`kfcrit.link.fading`).

Shadowing X (``path_loss.shadowing``):

* ``per-link`` (default; slow fading: a deployed link has one fixed X, so its arrival process is
  i.i.d. with p(X)); the channel's arrival probability is the median link's, X = 0, and
  shadowing enters the design through outage probabilities P(p(X) < p_c) and the margin policy;
* ``per-packet``: X drawn afresh every sample period; arrivals are i.i.d. with
  p̄ = E_X[p(X)], which is then the channel's arrival probability (the retries of one period
  share its X);
* ``time-correlated``: X an AR(1) process over the sample periods (``shadowing_correlation``);
  the arrivals are the two-state Markov (Gilbert–Elliott) approximation of
  :mod:`kfcrit.link.shadowing`, with stationary arrival probability p̄ — a bursty channel.

Design outputs: :func:`kfcrit.link.budgetsection.link_budget_record` (the ``link_budget`` section
of the record) and its JSON form :func:`design_section`.
"""
from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import sympy as sp

from kfcrit.errors import InputError
from kfcrit.io.typed import to_json
from kfcrit.link.budgetsection import frame_record, link_budget_record
from kfcrit.link.fading import NO_FADING, FastFading, correlated_all_fail
from kfcrit.link.fields import choice_field, exact_field_number, integer_field, real_field
from kfcrit.link.frames import PER_OVER, arrival_with_retries, attempt_probability
from kfcrit.link.propagation import (
    BOLTZMANN,
    MAX_SIGMA_DB,
    SHADOWING_MODES,
    SPEED_OF_LIGHT,
    Noise,
    PathLoss,
    thermal_noise_dbm,
)
from kfcrit.link.radios import (
    Radio,
    certain_arrival_sinr_db,
    db_to_linear,
    radio_from_mapping,
)
from kfcrit.link.shadowing import (
    Z_RANGE,
    ShadowingCorrelation,
    ShadowingMarkov,
    markov_from_mean_arrival,
    shadowing_averages,
    shadowing_grid,
)
from kfcrit.model.channels import ArrivalProcess, Channel, GilbertElliott, check_keys
from kfcrit.records.channel import ChannelRecord

__all__ = [
    "BOLTZMANN", "SPEED_OF_LIGHT", "MAX_SIGMA_DB", "SHADOWING_MODES", "Z_RANGE", "LinkBudget",
    "Noise", "PathLoss", "design_section", "exact_field_number", "gilbert_elliott_fit",
    "integer_field", "real_field", "thermal_noise_dbm", "warm_links",
]

# ---------------------------------------------------------------------------------------------
# The channel
# ---------------------------------------------------------------------------------------------

LINK_KEYS = {"model", "radio", "tx_power_dbm", "distance_m", "packet_bytes", "path_loss",
             "noise", "antenna_gain_db", "margin_db", "max_outage", "max_retries",
             "mac_overhead_bytes", "shadowing_correlation", "per_over", "fading_per_attempt",
             "fading", "coherence_time_s"}
LINK_REQUIRED = {"radio", "tx_power_dbm", "distance_m", "packet_bytes", "path_loss", "noise"}
MAX_PAYLOAD_BYTES = 65535
FADING_PER_ATTEMPT = ("shared", "independent", "correlated")
"""How the retries of one period see the shadowing: one value per period, one per attempt, or
a Gauss–Markov value per attempt correlated by exp(−Δ/T_c) (``coherence_time_s`` T_c)."""
FRAME_KEYS = ("payload_bytes", "mac_overhead_bytes", "psdu_bytes", "phy_header_bytes",
              "ppdu_bytes", "max_psdu_bytes", "max_payload_bytes", "standard", "per_over",
              "per_bytes", "per_covers", "definition", "airtime_s", "max_retries",
              "max_retries_allowed", "attempts_duration_s", "retry_formula", "fading_per_attempt",
              "retry_assumption")
"""The keys of a channel's ``frame`` (:meth:`LinkBudget.frame_dict`), in their order."""


@dataclass(frozen=True, eq=False)
class LinkBudget(Channel):
    r"""A radio link: arrivals with p = 1 − PER(SINR(d), L)^{k+1} (see module docstring).

    .. math::

        p = 1 - \mathrm{PER}\bigl(\mathrm{SINR}(d), L\bigr)^{k+1},\qquad
        1 - \mathrm{PER} = (1 - \mathrm{BER}(\mathrm{SINR}))^{8L}.

    Margin policy: a design must keep ``margin_db`` dB of SINR in reserve; with ``max_outage``
    the reserve is at least σ·Φ^{-1}(1 − max_outage) (per-link shadowing: at most that fraction
    of links fall below the requirement).

    ``packet_bytes`` is the application payload; ``mac_overhead_bytes`` (None: the radio's
    default) is added to it to form the PSDU; the PER covers the PHY header + PSDU
    (``per_over = "ppdu"``, default) or the PSDU (``"psdu"``). ``fading_per_attempt`` is
    ``"shared"`` (the attempts of a period share its shadowing value) or ``"independent"``
    (redrawn per attempt; per-packet shadowing only).

    Parameters
    ----------
    radio : Radio
        The radio model (e.g. ``ieee802154-oqpsk-2450``); in a system file, its name.
    tx_power_dbm, distance_m : float
        Transmit power and link distance.
    packet_bytes : int
        Application payload per packet.
    path_loss : PathLoss
        Log-distance path loss and its shadowing.
    noise : Noise
        Noise floor (noise figure, bandwidth, temperature) and interference.
    antenna_gain_db, margin_db : float
        Total antenna gain, and the SINR reserve of the margin policy.
    max_outage : float, optional
        Largest allowed shadowing outage probability.
    max_retries : int
        MAC retries k.
    mac_overhead_bytes : int, optional
        MAC header and FCS (default: the radio's).
    shadowing_correlation : ShadowingCorrelation, optional
        AR(1) correlation of time-correlated shadowing.
    per_over : {"ppdu", "psdu"}
        What the packet error rate covers.
    fading_per_attempt : {"shared", "independent"}
        Whether the attempts of a period share their shadowing value.
    fading : FastFading
        Fast fading redrawn per attempt (default none): the attempt PER is E_γ[PER(γ)].

    Attributes
    ----------
    arrival_probability : sympy.Expr
        The arrival probability of the median link (per-link shadowing) or the average one.
    model : str
        ``"link-budget"``.

    Raises
    ------
    kfcrit.errors.InputError
        An invalid or missing field (``from_mapping`` names it with its prefix), a payload that
        does not fit the PHY, or inconsistent shadowing options.

    References
    ----------
    docs/theory.md §11 (link design from the required arrival probability, retries
    1 − PER^{k+1}), §11.1 (fast fading) and §16.3 (the margin and outage policy in the review).

    Examples
    --------
    >>> from kfcrit import LinkBudget
    >>> link = LinkBudget.from_mapping({
    ...     "radio": "ieee802154-oqpsk-2450", "tx_power_dbm": 0, "distance_m": 105,
    ...     "packet_bytes": 40,
    ...     "path_loss": {"model": "log-distance", "exponent": 3.0,
    ...                   "reference_distance_m": 1, "reference_loss_db": 40.2},
    ...     "noise": {"noise_figure_db": 10, "bandwidth_hz": 2.0e6, "temperature_k": 290}},
    ...     "channel")
    >>> round(float(link.arrival_probability), 4), link.iid
    (0.9465, True)
    >>> LinkBudget.from_mapping({"radio": "ieee802154-oqpsk-2450"}, "channel")
    Traceback (most recent call last):
        ...
    kfcrit.errors.InputError: channel.distance_m: is required
    """

    radio: Radio
    tx_power_dbm: float
    distance_m: float
    packet_bytes: int
    path_loss: PathLoss
    noise: Noise
    antenna_gain_db: float = 0.0
    margin_db: float = 0.0
    max_outage: float | None = None
    max_retries: int = 0
    mac_overhead_bytes: int | None = None
    shadowing_correlation: ShadowingCorrelation | None = None
    per_over: str = "ppdu"
    fading_per_attempt: str = "shared"
    fading: FastFading = NO_FADING
    coherence_time_s: float | None = None
    model: ClassVar[str] = "link-budget"

    def __post_init__(self) -> None:
        frame = self.radio.frame
        frame.check_payload(self.packet_bytes, self.mac_overhead_bytes, "packet_bytes")
        frame.check_retries(self.max_retries, "max_retries")
        correlated = self.path_loss.shadowing == "time-correlated"
        if correlated and (self.shadowing_correlation is None or self.sigma_db <= 0):
            raise InputError("time-correlated shadowing needs shadowing_sigma_db > 0 and the "
                             "link's shadowing_correlation", field="path_loss.shadowing")
        if self.shadowing_correlation is not None and not correlated:
            raise InputError("only with path_loss.shadowing: time-correlated",
                             field="shadowing_correlation")
        if self.per_over not in PER_OVER:
            raise InputError(f"must be one of: {', '.join(PER_OVER)}", field="per_over")
        if self.fading_per_attempt not in FADING_PER_ATTEMPT:
            raise InputError(f"must be one of: {', '.join(FADING_PER_ATTEMPT)}",
                             field="fading_per_attempt")
        if self.fading_per_attempt in ("independent", "correlated") \
                and self.path_loss.shadowing != "per-packet":
            raise InputError(f"{self.fading_per_attempt} needs a shadowing value that can be "
                             "redrawn per attempt (path_loss.shadowing: per-packet); per-link and "
                             "time-correlated shadowing are shared by the attempts of a period",
                             field="fading_per_attempt")
        if (self.fading_per_attempt == "correlated") != (self.coherence_time_s is not None):
            raise InputError("is required with fading_per_attempt: correlated, and only then",
                             field="coherence_time_s")
        if self.fading_per_attempt == "correlated" and self.attempt_spacing_s is None:
            raise InputError("correlated needs the radio's airtime and acknowledgement wait "
                             "(the attempt spacing)", field="fading_per_attempt")

    @classmethod
    def from_mapping(cls, data: dict, prefix: str, base_dir: Path | None = None) -> LinkBudget:
        check_keys(data, LINK_KEYS, LINK_REQUIRED, prefix)
        radio = radio_from_mapping(data["radio"], f"{prefix}.radio")
        frame = radio.frame
        kw: dict[str, Any] = {
            "radio": radio,
            "tx_power_dbm": real_field(data, "tx_power_dbm", prefix, low=-100, high=100),
            "distance_m": real_field(data, "distance_m", prefix, low=0, high=1e9, low_open=True),
            "packet_bytes": integer_field(data, "packet_bytes", prefix, low=1,
                                          high=MAX_PAYLOAD_BYTES),
            "path_loss": PathLoss.from_mapping(data["path_loss"], f"{prefix}.path_loss"),
            "noise": Noise.from_mapping(data["noise"], f"{prefix}.noise"),
        }
        if "antenna_gain_db" in data:
            kw["antenna_gain_db"] = real_field(data, "antenna_gain_db", prefix, low=-100,
                                               high=100)
        if "margin_db" in data:
            kw["margin_db"] = real_field(data, "margin_db", prefix, low=0, high=100)
        if "max_outage" in data:
            kw["max_outage"] = real_field(data, "max_outage", prefix, low=0, high=0.5,
                                          low_open=True)
        if "max_retries" in data:
            kw["max_retries"] = integer_field(data, "max_retries", prefix, low=0,
                                              high=frame.max_retries)
        if "mac_overhead_bytes" in data:
            kw["mac_overhead_bytes"] = integer_field(
                data, "mac_overhead_bytes", prefix, low=0,
                high=(frame.max_psdu_bytes - 1) if frame.max_psdu_bytes else MAX_PAYLOAD_BYTES)
        if "shadowing_correlation" in data:
            kw["shadowing_correlation"] = ShadowingCorrelation.from_mapping(
                data["shadowing_correlation"], f"{prefix}.shadowing_correlation")
        if "per_over" in data:
            kw["per_over"] = choice_field(data, "per_over", prefix, PER_OVER)
        if "fading_per_attempt" in data:
            kw["fading_per_attempt"] = choice_field(data, "fading_per_attempt", prefix,
                                                    FADING_PER_ATTEMPT)
        if "fading" in data:
            kw["fading"] = FastFading.from_mapping(data["fading"], f"{prefix}.fading")
        if "coherence_time_s" in data:
            kw["coherence_time_s"] = real_field(data, "coherence_time_s", prefix, low=0,
                                                high=1e6, low_open=True)
        try:
            return cls(**kw)
        except InputError as exc:  # name the field with the caller's prefix
            raise InputError(str(exc).split(": ", 1)[-1],
                             field=f"{prefix}.{exc.field}" if exc.field else prefix) from None

    # -- the chain -----------------------------------------------------------------------------
    @property
    def path_loss_db(self) -> float:
        """Median path loss at the configured distance."""
        return float(self.path_loss.loss_db(self.distance_m))

    @property
    def rx_power_dbm(self) -> float:
        """Median received power Pr = Pt + G − PL(d)."""
        return self.tx_power_dbm + self.antenna_gain_db - self.path_loss_db

    @cached_property
    def sinr_db(self) -> float:
        """Median SINR = Pr − (N ⊕ I) (computed once per link)."""
        return self.rx_power_dbm - self.noise.total_dbm

    @property
    def sigma_db(self) -> float:
        return self.path_loss.shadowing_sigma_db

    @property
    def per_packet_shadowing(self) -> bool:
        """Shadowing redrawn per sample period (independently, or as a correlated process)."""
        return self.sigma_db > 0 and self.path_loss.shadowing in ("per-packet",
                                                                  "time-correlated")

    @property
    def time_correlated(self) -> bool:
        return self.path_loss.shadowing == "time-correlated"

    @property
    def psdu_bytes(self) -> int:
        """PSDU length: payload + MAC header + FCS."""
        return self.radio.frame.psdu_bytes(self.packet_bytes, self.mac_overhead_bytes)

    @property
    def per_bytes(self) -> int:
        """Bytes the packet error rate covers: PHY header + PSDU (ppdu) or the PSDU (psdu)."""
        return self.radio.frame.per_bytes(self.packet_bytes, self.mac_overhead_bytes,
                                          self.per_over)

    @property
    def attempt_spacing_s(self) -> float | None:
        """Δ = airtime + acknowledgement wait: the time between two attempts of a period."""
        return self.radio.frame.attempts_duration_s(self.psdu_bytes, 0)

    @property
    def attempt_correlation(self) -> float | None:
        r"""ρ = exp(−Δ/T_c) between consecutive attempts (``correlated`` only)."""
        if self.fading_per_attempt != "correlated" or self.coherence_time_s is None:
            return None
        return math.exp(-self.attempt_spacing_s / self.coherence_time_s)

    @property
    def independent_attempts(self) -> bool:
        """The attempts of a period draw their own shadowing value (``independent``)."""
        return self.fading_per_attempt == "independent" and self.sigma_db > 0

    def with_changes(self, **changes: Any) -> LinkBudget:
        """A copy with some parameters changed (validated like the original)."""
        fields = {k: getattr(self, k) for k in (
            "radio", "tx_power_dbm", "distance_m", "packet_bytes", "path_loss", "noise",
            "antenna_gain_db", "margin_db", "max_outage", "max_retries", "mac_overhead_bytes",
            "shadowing_correlation", "per_over", "fading_per_attempt", "fading",
            "coherence_time_s")}
        fields.update(changes)
        return LinkBudget(**fields)

    def instantaneous_per(self, snr: Any) -> np.ndarray:
        """PER at the *linear* instantaneous SNR ``snr``: 1 − (1 − BER)^{8L}."""
        ber = np.clip(self.radio.ber(np.asarray(snr, dtype=float)), 0.0, 1.0)
        with np.errstate(divide="ignore"):
            return -np.expm1(8 * self.per_bytes * np.log1p(-ber))

    def attempt_per(self, sinr_db: Any) -> np.ndarray:
        r"""PER of one attempt at mean SINR ``sinr_db``, L = :attr:`per_bytes`.

        .. math:: \mathrm{PER}(s) = 1 - (1 - \mathrm{BER}(s))^{8L}

        and with fast fading its average E_γ[PER(γ)], γ ~ Gamma(m, 10^{s/10}/m)
        (:meth:`kfcrit.link.fading.FastFading.mean_per`).
        """
        if not self.fading.active:
            return self.radio.per(sinr_db, self.per_bytes)
        return self.fading.mean_per(self.instantaneous_per, db_to_linear(sinr_db))

    def attempt_log_arrival(self, sinr_db: Any) -> np.ndarray:
        """log(1 − PER) of one attempt (faded: log1p(−E_γ[PER]), accurate for PER near 0)."""
        if not self.fading.active:
            return self.radio.log_arrival(sinr_db, self.per_bytes)
        with np.errstate(divide="ignore"):
            return np.log1p(-self.attempt_per(sinr_db))

    def link_arrival(self, sinr_db: Any) -> np.ndarray:
        r"""Arrival probability within a sample period at SINR ``sinr_db`` (no shadowing draw).

        .. math:: p(s) = 1 - \mathrm{PER}(s, L)^{k+1}
        """
        return arrival_with_retries(self.attempt_log_arrival(sinr_db), self.max_retries)

    def nominal_arrival(self, sinr_db: float) -> float:
        """p(s) of :meth:`link_arrival` as a float."""
        return float(self.link_arrival(sinr_db))

    def mean_arrival(self, sinr_db: float) -> float:
        r"""Shadowing average (trapezoid rule on z ∈ [−9, 9]).

        Shared shadowing (the attempts of a period see one value):

        .. math:: \bar p(s) = \int p(s + \sigma z)\,\varphi(z)\,dz,\qquad
                  p(s) = 1 - \mathrm{PER}(s)^{k+1}

        independent per attempt (``fading_per_attempt: independent``), with the averaged
        one-attempt success :math:`\bar a = \int (1 - \mathrm{PER}(s + \sigma z))\,
        \varphi(z)\,dz`:

        .. math:: \bar p(s) = 1 - (1 - \bar a)^{k+1}

        The integrand is smooth and decays like φ(z), so the trapezoid rule converges
        geometrically; the step keeps σ·h ≤ 0.02 dB, far finer than the width of any PER curve
        (with fast fading, a twentieth of the fading spread, at most 0.25 dB: the faded PER is
        smooth on that scale).
        """
        sigma = self.sigma_db
        if sigma == 0:
            return self.nominal_arrival(sinr_db)
        z, weights = shadowing_grid(self.shadowing_step)
        if self.attempt_correlation is not None:
            fail = correlated_all_fail(lambda x: self.attempt_per(sinr_db + sigma * x), z,
                                       weights, self.attempt_correlation, self.max_retries + 1)
            return float(1.0 - fail)
        if self.independent_attempts:
            one = np.exp(self.attempt_log_arrival(sinr_db + sigma * z))
            a = float(min(1.0, np.trapezoid(one * weights, z)))
            if a >= 1.0:
                return 1.0
            return float(-math.expm1((self.max_retries + 1) * math.log1p(-a)))
        s = sinr_db + sigma * z
        if self.fading.active:
            values = self.link_arrival(s)
        else:
            values, mid = self._certain_values(s)
            values[mid] = self.link_arrival(s[mid])
        return shadowing_averages(values, self.shadowing_step)[0]

    @property
    def shadowing_step(self) -> float:
        """The step h in z of :meth:`mean_arrival`'s grid: σ·h ≤ 0.02 dB (with fast fading a
        twentieth of the fading spread), h ≤ 0.01 (σ > 0)."""
        return min(0.01, self.fading.shadowing_step_db() / self.sigma_db)

    def _certain_values(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """p at the SINRs ``s`` where it is exactly 0.0 or 1.0 in double precision
        (:func:`kfcrit.link.radios.certain_arrival_sinr_db`), and the mask of the others (the
        transition, where p must be computed; their entries are left 0.0)."""
        s0, s1 = certain_arrival_sinr_db(self.radio, self.per_bytes, self.max_retries)
        return (s >= s1).astype(float), (s > s0) & (s < s1)

    @property
    def shared_shadowing_average(self) -> bool:
        """:meth:`mean_arrival` is the plain average of p(s + σz) (σ > 0, no fast fading, the
        attempts of a period share the shadowing value): the case :func:`warm_links`
        batches."""
        return (self.sigma_db > 0 and not self.fading.active
                and self.attempt_correlation is None and not self.independent_attempts)

    def effective_arrival(self, sinr_db: float) -> float:
        """The stationary arrival probability at median SINR ``sinr_db`` (mean if redrawn)."""
        return self.mean_arrival(sinr_db) if self.per_packet_shadowing \
            else self.nominal_arrival(sinr_db)

    @cached_property
    def median_mean_arrival(self) -> float:
        """:meth:`mean_arrival` at the configured median SINR (computed once per link: the
        record reads it three times, and it is the costly shadowing average)."""
        return self.mean_arrival(self.sinr_db)

    @cached_property
    def median_log_arrival(self) -> float:
        """log(1 − PER) of one attempt at the configured median SINR (computed once per link:
        the PER, the attempt and the nominal arrival probabilities are read from it)."""
        return self.attempt_log_arrival(self.sinr_db)

    @cached_property
    def median_ber(self) -> float:
        """The radio's bit error rate at the configured median SINR (computed once per link)."""
        return float(self.radio.ber(db_to_linear(self.sinr_db)))

    @cached_property
    def median_nominal_arrival(self) -> float:
        """:meth:`nominal_arrival` at the configured median SINR (computed once per link)."""
        return float(arrival_with_retries(self.median_log_arrival, self.max_retries))

    @cached_property
    def arrival_value(self) -> float:
        """The arrival probability as a float (computed once per link)."""
        return self.median_mean_arrival if self.per_packet_shadowing \
            else self.median_nominal_arrival

    @property
    def arrival_probability(self) -> sp.Expr:
        """Median link's p (per-link shadowing) or its shadowing average (redrawn shadowing)."""
        return sp.Float(self.arrival_value, 17)

    @property
    def iid(self) -> bool:
        return not self.time_correlated

    def shadowing_markov(self) -> ShadowingMarkov | None:
        """The Gilbert–Elliott approximation of time-correlated shadowing (None otherwise)."""
        if not self.time_correlated or self.shadowing_correlation is None:
            return None
        return markov_from_mean_arrival(self.shadowing_correlation.correlation,
                                        self.arrival_value)

    def gilbert_elliott(self) -> GilbertElliott | None:
        """The equivalent :class:`GilbertElliott` channel of time-correlated shadowing.

        None when the shadowing is not time-correlated, or when a rate underflows to 0 (a link
        that practically never fails or never recovers; its arrival probability decides).
        """
        chain = self.shadowing_markov()
        if chain is None or not (chain.failure_rate > 0 and chain.recovery_rate > 0):
            return None
        return GilbertElliott(sp.Float(chain.failure_rate, 17),
                              sp.Float(chain.recovery_rate, 17))

    def arrival_process(self) -> ArrivalProcess:
        """I.i.d. arrivals, or the Markov chain of time-correlated shadowing."""
        chain = self.shadowing_markov()
        if chain is None:
            return ArrivalProcess("iid", p=self.arrival_value)
        return ArrivalProcess("markov", failure_rate=chain.failure_rate,
                              recovery_rate=chain.recovery_rate)

    # -- design --------------------------------------------------------------------------------
    @cached_property
    def effective_margin_db(self) -> float:
        """max(margin_db, σ·Φ^{-1}(1 − max_outage)) — the SINR reserve the design keeps.

        The outage term applies where an outage exists: per-link shadowing (a fraction of
        deployed links) and time-correlated shadowing (a fraction of the time); shadowing redrawn
        i.i.d. per packet is averaged into the arrival probability instead. Computed once per
        link (the design reads it for every threshold).
        """
        margin = self.margin_db
        if self.max_outage is not None and self.sigma_db > 0 \
                and (not self.per_packet_shadowing or self.time_correlated):
            from scipy.special import ndtri

            margin = max(margin, float(self.sigma_db * ndtri(1.0 - self.max_outage)))
        return margin

    def link_required_sinr_db(self, p: float) -> float | None:
        """Least SINR (dB) with p(s) ≥ p without a shadowing draw (retries included).

        Solved on one attempt: PER(s)^{k+1} ≤ 1 − p ⇔ 1 − PER(s) ≥ 1 − (1 − p)^{1/(k+1)}
        (with fast fading on the averaged PER, by Brent's method on log E[PER] over
        [−40, 160] dB).
        """
        if self.fading.active:
            return self.faded_required_sinr_db(attempt_probability(p, self.max_retries))
        return self.radio.required_sinr_db(attempt_probability(p, self.max_retries),
                                           self.per_bytes)

    def faded_required_sinr_db(self, q: float) -> float | None:
        """Least mean SINR (dB) whose faded attempt success 1 − E_γ[PER] is ≥ ``q``."""
        if not q < 1.0:
            raise ValueError("an arrival probability of 1 is not reached at finite SINR")
        lo, hi = -40.0, 160.0
        if q <= float(np.exp(self.attempt_log_arrival(lo))):
            return None
        target = math.log1p(-q)

        def fn(s: float) -> float:
            return math.log(max(float(self.attempt_per(s)), 1e-300)) - target
        if fn(hi) > 0:
            raise ValueError(f"arrival probability {q!r} needs more than {hi} dB SINR")
        from scipy.optimize import brentq

        return float(brentq(fn, lo, hi, xtol=1e-10, maxiter=200))

    def required_sinr_db(self, p: float) -> float | None:
        """Least median SINR (dB) whose arrival probability is ≥ p; None if none is needed."""
        if not self.per_packet_shadowing:
            return self.link_required_sinr_db(p)
        lo, hi = -60.0, 100.0
        if p <= self.mean_arrival(lo):
            return None
        if p >= self.mean_arrival(hi):
            raise ValueError(f"arrival probability {p!r} is not reached")
        from scipy.optimize import brentq

        return float(brentq(lambda s: self.mean_arrival(s) - p, lo, hi, xtol=1e-9))

    def outage_probability(self, p: float) -> float:
        """P(p_link < p) over per-link shadowing: Φ((s_req(p) − s0)/σ) (0 or 1 when σ = 0)."""
        s_req = self.link_required_sinr_db(p) if p < 1 else math.inf
        if s_req is None:
            return 0.0
        if self.sigma_db == 0:
            return 1.0 if self.sinr_db < s_req else 0.0
        from scipy.special import ndtr

        return float(ndtr((s_req - self.sinr_db) / self.sigma_db))

    def max_distance_m(self, sinr_required_db: float, margin_db: float) -> float | None:
        """Largest d with Pt + G − PL(d) − N − margin ≥ SINR_req (None if it overflows)."""
        allowed = self.tx_power_dbm + self.antenna_gain_db - self.noise.total_dbm \
            - sinr_required_db - margin_db
        return self.path_loss.distance_m(allowed)

    def frame_dict(self) -> dict[str, Any]:
        """The frame on the air (:func:`~kfcrit.link.budgetsection.frame_record`) as plain data,
        in the key order of the channel's ``frame``."""
        frame = to_json(frame_record(self))
        return {k: frame[k] for k in FRAME_KEYS}

    def to_dict(self) -> dict[str, Any]:
        chain = self.shadowing_markov()
        return {"model": self.model, "radio": self.radio.to_dict(),
                "tx_power_dbm": self.tx_power_dbm, "distance_m": self.distance_m,
                "packet_bytes": self.packet_bytes, "antenna_gain_db": self.antenna_gain_db,
                "path_loss": self.path_loss.to_dict(), "noise": self.noise.to_dict(),
                "margin_db": self.margin_db, "max_outage": self.max_outage,
                "max_retries": self.max_retries, "per_over": self.per_over,
                "fading_per_attempt": self.fading_per_attempt,
                "coherence_time_s": self.coherence_time_s,
                "fading": self.fading.to_dict(), "frame": self.frame_dict(),
                "shadowing_correlation": (self.shadowing_correlation.to_dict()
                                          if self.shadowing_correlation else None),
                "gilbert_elliott": chain.to_dict() if chain else None,
                "sinr_db": self.sinr_db, "arrival_probability": self.arrival_value,
                "arrival_probability_expression": repr(self.arrival_value),
                "arrival_probability_basis": self.arrival_basis}

    def record(self) -> ChannelRecord:
        """The link as the record states it (``system.channel``, ``operating_point.channel``),
        built field by field."""
        chain = self.shadowing_markov()
        return ChannelRecord(
            model=self.model, arrival_probability=self.arrival_value,
            arrival_probability_expression=repr(self.arrival_value),
            radio=self.radio.record(), tx_power_dbm=self.tx_power_dbm,
            distance_m=self.distance_m, packet_bytes=self.packet_bytes,
            antenna_gain_db=self.antenna_gain_db, path_loss=self.path_loss.record(),
            noise=self.noise.record(), margin_db=self.margin_db, max_outage=self.max_outage,
            max_retries=self.max_retries, frame=frame_record(self),
            shadowing_correlation=(self.shadowing_correlation.record()
                                   if self.shadowing_correlation else None),
            gilbert_elliott=chain.record() if chain else None, sinr_db=self.sinr_db,
            arrival_probability_basis=self.arrival_basis, per_over=self.per_over,
            fading_per_attempt=self.fading_per_attempt, fading=self.fading.record(),
            coherence_time_s=self.coherence_time_s)

    @property
    def arrival_basis(self) -> str:
        """Which arrival probability the link states: the shadowing average (per packet or of
        the Gilbert–Elliott approximation of time-correlated shadowing) or the median link."""
        if self.shadowing_markov() is not None:
            return ("stationary arrival probability of the Gilbert-Elliott approximation of "
                    "time-correlated shadowing (= the shadowing average)")
        return ("shadowing average (per-packet shadowing)" if self.per_packet_shadowing
                else "median link (no shadowing draw)")


def warm_links(links: Iterable[Any]) -> int:
    r"""Compute the median-SINR values of many links in a few NumPy calls (a sweep's chunk).

    The links are grouped by (radio, PER bytes, retries), the arguments of their arrival
    probability p(s). For each group of two or more links without fast fading, one call of
    the radio over all their median SINRs gives :attr:`LinkBudget.median_ber` and
    :attr:`LinkBudget.median_log_arrival`, and, for shared shadowing
    (:attr:`LinkBudget.shared_shadowing_average`), :meth:`LinkBudget.link_arrival` over the
    transition SINRs of all of them, in blocks of :data:`WARM_BLOCK`, gives every link's
    shadowing average

    .. math:: \bar p(s) = \int p(s + \sigma z)\,\varphi(z)\,dz

    (:meth:`LinkBudget.mean_arrival`; each link's trapezoid sum is its own,
    :func:`shadowing_averages`). The values are
    stored where the cached properties keep them and are bit for bit those the link computes
    alone: every step of p(s) is elementwise, the same floating-point operations on each SINR
    whatever array it is in (:func:`kfcrit.link.radios.oqpsk_ber` sums its terms in one fixed
    order for any length). A group whose evaluation fails is left to compute lazily, so its
    error stays that of its own link.

    Parameters
    ----------
    links : iterable
        Channels; anything but a :class:`LinkBudget` is skipped.

    Returns
    -------
    int
        How many links were warmed.
    """
    groups: dict[tuple[Any, int, int], list[LinkBudget]] = {}
    for link in links:
        if isinstance(link, LinkBudget) and not link.fading.active \
                and "median_log_arrival" not in link.__dict__:
            groups.setdefault((link.radio, link.per_bytes, link.max_retries), []).append(link)
    warmed = 0
    for group in groups.values():
        if len(group) < 2:
            continue
        try:
            _warm_group(group)
        except (ValueError, ArithmeticError, FloatingPointError):
            continue
        warmed += len(group)
    return warmed


WARM_BLOCK = 8192
"""Most SINRs per call of the radio when links are warmed together: a block that stays in
the CPU cache (several times faster per SINR than one call over a whole chunk; the same
values, every step being elementwise)."""
WARM_GRID_VALUES = 32768
"""Most grid values (links × grid points) of one block of shadowing averages."""


def _warm_group(group: list[LinkBudget]) -> None:
    """:func:`warm_links` for links that share (radio, PER bytes, retries)."""
    head = group[0]
    sinr = np.array([link.sinr_db for link in group])
    ber = head.radio.ber(db_to_linear(sinr))
    log_arrival = head.attempt_log_arrival(sinr)
    by_grid: dict[tuple[float, float], list[LinkBudget]] = {}
    for link in group:
        if link.shared_shadowing_average:
            by_grid.setdefault((link.sigma_db, link.shadowing_step), []).append(link)
    means: list[tuple[LinkBudget, float]] = []
    for (sigma, step), links in by_grid.items():
        z, _ = shadowing_grid(step)
        rows = max(1, WARM_GRID_VALUES // z.size)
        for start in range(0, len(links), rows):
            block = links[start:start + rows]
            # one row per link: s = s_link + σz, as in LinkBudget.mean_arrival
            s = np.array([link.sinr_db for link in block])[:, None] + sigma * z
            values, mid = head._certain_values(s)
            transition = s[mid]
            for lo in range(0, transition.size, WARM_BLOCK):
                transition[lo:lo + WARM_BLOCK] = head.link_arrival(
                    transition[lo:lo + WARM_BLOCK])
            values[mid] = transition
            means.extend(zip(block, shadowing_averages(values, step)))
    for link, b, la in zip(group, ber, log_arrival):
        link.__dict__["median_ber"] = float(b)
        link.__dict__["median_log_arrival"] = la
    for link, mean in means:
        link.__dict__["median_mean_arrival"] = mean


# ---------------------------------------------------------------------------------------------
# Design outputs for the analysis record
# ---------------------------------------------------------------------------------------------

def design_section(channel: Channel, *, critical_value: float | None,
                   robust_value: float | None,
                   bracket: tuple[float | None, float | None],
                   upper_bound: float | None,
                   accuracy: Any = None) -> dict[str, Any]:
    """The ``link_budget`` section in its JSON form (the typed section:
    :func:`kfcrit.link.budgetsection.link_budget_record`, parameters as there).

    Returns
    -------
    dict
        ``to_json`` of the section; ``{"applicable": False, "reason": ...}`` for a channel that
        is not a :class:`LinkBudget`.
    """
    if not isinstance(channel, LinkBudget):
        return {"applicable": False, "reason": "the channel is not a link-budget model"}
    return to_json(link_budget_record(channel, critical_value=critical_value,
                                      robust_value=robust_value, bracket=bracket,
                                      upper_bound=upper_bound, accuracy=accuracy))


# ---------------------------------------------------------------------------------------------
# Recorded arrival traces
# ---------------------------------------------------------------------------------------------

def gilbert_elliott_fit(arrivals: Any, system: Any = None) -> dict[str, Any]:
    """Maximum-likelihood two-state Markov (Gilbert–Elliott) fit of a 0/1 arrival sequence.

    f̂ = #(1 → 0) / #(1 → ·) and r̂ = #(0 → 1) / #(0 → ·) over consecutive pairs (the transition
    counts of the chain). For information only: a fit to a finite recording is an estimate, not
    the channel, so no theorem is applied to it. With ``system`` the value (1 − r̂)·ρ(A)² of the
    theory §7 condition is added (again for information). ``available`` is False when the trace
    has no received or no lost packet before its last value (a rate is then undefined).
    """
    g = np.asarray(arrivals, dtype=bool)
    prev, nxt = g[:-1], g[1:]
    n1, n0 = int(prev.sum()), int((~prev).sum())
    n10, n01 = int((prev & ~nxt).sum()), int((~prev & nxt).sum())
    out: dict[str, Any] = {"transitions": {"received_to_lost": n10, "received": n1,
                                           "lost_to_received": n01, "lost": n0},
                           "method": "maximum likelihood (transition counts)",
                           "status": "for information: an estimate from the recording, "
                                     "no theorem is applied to it"}
    if n1 == 0 or n0 == 0 or n01 == 0:
        return {"available": False, **out,
                "reason": "the trace has no loss, no arrival, or no recovery from a loss"}
    f, r = n10 / n1, n01 / n0
    out = {"available": True, "failure_rate": f, "recovery_rate": r,
           "stationary_arrival_probability": r / (f + r) if f + r > 0 else None,
           "mean_burst_length": 1 / r, **out}
    if system is not None:
        a = float(max(abs(np.linalg.eigvals(system.a)))) if system.n else 0.0
        out["condition"] = {"expression": "(1 - r) a^2 < 1", "value": (1 - r) * a * a,
                            "holds": bool((1 - r) * a * a < 1)}
    return out
