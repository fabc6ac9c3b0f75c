"""Link budgets: from transmit power, distance and packet size to the arrival probability.

The chain, in dB and dBm (every step is a stated formula, tested against independent values)::

    path loss     PL(d) = PL0 + 10·n·log10(d/d0) + X          (log-distance, X ~ N(0, σ²) dB)
                  PL(d) = 20·log10(4π d f / c) + X             (free space, Friis)
    received      Pr = Pt + G − PL(d)                          (G: total antenna gain, dB)
    noise floor   N = 10·log10(k_B T B / 1 mW) + NF            (≈ −174 dBm/Hz + 10·log10 B + NF)
    SINR          SINR_dB = Pr − 10·log10(10^{N/10} + 10^{I/10})   (I: interference, optional)
    arrival       p = 1 − PER(SINR, L) = (1 − BER(SINR))^{8L}  (radio model: kfcrit.link.radios)

Shadowing X is *per link* by default (slow fading: a deployed link has one fixed X, so its
arrival process is i.i.d. with p(X); the channel's arrival probability is the median link's,
X = 0, and shadowing enters the design through outage probabilities P(p(X) < p_c) and the margin
policy) or *per packet* (X drawn afresh for every packet: arrivals are i.i.d. with
p̄ = E_X[p(X)], which is then the channel's arrival probability).

Design outputs (``design_section``): for each required arrival probability (p_c, the robust
value, the bracket ends, p_up) the required SINR and received power, the link margin of the
configured link in dB, the largest distance that still meets it under the margin policy, and
the outage probabilities. ``gilbert_elliott_section`` states the bursty-loss condition.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import sympy as sp
from scipy.special import ndtr, ndtri

from kfcrit.model.channels import Channel, GilbertElliott, check_keys
from kfcrit.errors import InputError
from kfcrit.link.radios import Radio, db_to_linear, radio_from_mapping

BOLTZMANN = 1.380649e-23
"""Boltzmann constant k_B in J/K (exact in the 2019 SI)."""
SPEED_OF_LIGHT = 299_792_458.0
"""c in m/s (exact)."""
SHADOWING_MODES = ("per-link", "per-packet")
MAX_SIGMA_DB = 30.0
Z_RANGE = 9.0
"""Shadowing averages integrate the standard normal over [−9, 9] (mass outside < 1e-18)."""


# ---------------------------------------------------------------------------------------------
# Reading numbers exactly from their text
# ---------------------------------------------------------------------------------------------

def exact_number(value: Any, field: str) -> sp.Expr:
    """Exact real number of a system-file value (text, int or sympy); never ``eval``."""
    from kfcrit.model.exprparse import number_from_text, parse_expression

    if isinstance(value, bool) or value is None:
        raise InputError("must be a number", field=field)
    if isinstance(value, sp.Basic):
        if not value.is_number:
            raise InputError("must be a number", field=field)
        return value
    if isinstance(value, int):
        return sp.Integer(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            raise InputError("must be a finite number", field=field)
        return number_from_text(repr(value), field)
    if isinstance(value, str):
        try:
            return _parsed_text(value)
        except InputError:  # parse again to name the caller's field in the message
            return parse_expression(value, field)
    raise InputError(f"must be a number, got {type(value).__name__}", field=field)


@functools.lru_cache(maxsize=8192)
def _parsed_text(text: str) -> sp.Expr:
    """``parse_expression`` memoised by text (pure; sympy numbers are immutable; errors are
    not cached). A sweep re-reads the same channel texts at every point."""
    from kfcrit.model.exprparse import parse_expression

    return parse_expression(text, "value")


def real_field(data: dict, key: str, prefix: str, *, low: float | None = None,
               high: float | None = None, low_open: bool = False) -> float:
    """Read ``data[key]`` exactly; check ``low ≤ x ≤ high`` (``low < x`` if ``low_open``)."""
    where = f"{prefix}.{key}"
    x = exact_number(data[key], where)
    if low is not None and (bool(x <= low) if low_open else bool(x < low)):
        raise InputError(f"must be {'>' if low_open else '>='} {low:g}, got {sp.sstr(x)[:30]}",
                         field=where)
    if high is not None and bool(x > high):
        raise InputError(f"must be <= {high:g}, got {sp.sstr(x)[:30]}", field=where)
    return float(sp.N(x, 20)) if not x.is_Rational else float(x)


def integer_field(data: dict, key: str, prefix: str, *, low: int, high: int) -> int:
    """Read an integer exactly and check ``low ≤ x ≤ high``."""
    where = f"{prefix}.{key}"
    x = exact_number(data[key], where)
    if not x.is_Integer:
        raise InputError(f"must be an integer, got {sp.sstr(x)[:30]}", field=where)
    if not low <= int(x) <= high:
        raise InputError(f"must be between {low} and {high}, got {int(x)}", field=where)
    return int(x)


def _mapping(value: Any, field: str) -> dict:
    if not isinstance(value, dict):
        raise InputError("must be a mapping", field=field)
    return value


# ---------------------------------------------------------------------------------------------
# Path loss and noise
# ---------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class PathLoss:
    """Median path loss (log-distance or free space) plus log-normal shadowing σ (dB).

    ``loss_db(d)`` is the median; ``distance_m(loss)`` its inverse.
    """

    model: str
    exponent: float = 2.0
    reference_distance_m: float = 1.0
    reference_loss_db: float = 0.0
    frequency_hz: float | None = None
    shadowing_sigma_db: float = 0.0
    shadowing: str = "per-link"
    MODELS: ClassVar[tuple[str, ...]] = ("log-distance", "free-space")

    @classmethod
    def from_mapping(cls, data: Any, prefix: str) -> PathLoss:
        data = _mapping(data, prefix)
        model = data.get("model")
        if model not in cls.MODELS:
            raise InputError(f"must be one of: {', '.join(cls.MODELS)}", field=f"{prefix}.model")
        common = {"model", "shadowing_sigma_db", "shadowing"}
        if model == "log-distance":
            check_keys(data, common | {"exponent", "reference_distance_m", "reference_loss_db"},
                       {"exponent", "reference_loss_db"}, prefix)
            kw: dict[str, Any] = {
                "exponent": real_field(data, "exponent", prefix, low=0, high=10, low_open=True),
                "reference_loss_db": real_field(data, "reference_loss_db", prefix, low=-100,
                                                high=300),
                "reference_distance_m": (real_field(data, "reference_distance_m", prefix, low=0,
                                                    high=1e7, low_open=True)
                                         if "reference_distance_m" in data else 1.0)}
        else:
            check_keys(data, common | {"frequency_hz"}, {"frequency_hz"}, prefix)
            kw = {"frequency_hz": real_field(data, "frequency_hz", prefix, low=0, high=1e15,
                                             low_open=True)}
        if "shadowing_sigma_db" in data:
            kw["shadowing_sigma_db"] = real_field(data, "shadowing_sigma_db", prefix, low=0,
                                                  high=MAX_SIGMA_DB)
        if "shadowing" in data:
            if data["shadowing"] not in SHADOWING_MODES:
                raise InputError(f"must be one of: {', '.join(SHADOWING_MODES)}",
                                 field=f"{prefix}.shadowing")
            kw["shadowing"] = data["shadowing"]
        return cls(model=model, **kw)

    def loss_db(self, distance_m: Any) -> Any:
        """Median path loss: PL0 + 10 n log10(d/d0), or Friis 20 log10(4π d f / c)."""
        d = np.asarray(distance_m, dtype=float)
        if self.model == "log-distance":
            return self.reference_loss_db + 10.0 * self.exponent * np.log10(
                d / self.reference_distance_m)
        return 20.0 * np.log10(4.0 * math.pi * d * self.frequency_hz / SPEED_OF_LIGHT)

    def distance_m(self, loss_db: float) -> float | None:
        """Inverse of :meth:`loss_db`; None when the distance overflows a float."""
        if self.model == "log-distance":
            expo = (loss_db - self.reference_loss_db) / (10.0 * self.exponent)
            scale = self.reference_distance_m
        else:
            expo = loss_db / 20.0
            scale = SPEED_OF_LIGHT / (4.0 * math.pi * self.frequency_hz)
        if expo > 300:
            return None
        return float(scale * 10.0 ** expo)

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"model": self.model}
        if self.model == "log-distance":
            out.update(exponent=self.exponent, reference_distance_m=self.reference_distance_m,
                       reference_loss_db=self.reference_loss_db,
                       formula="PL(d) = PL0 + 10 n log10(d/d0) + X")
        else:
            out.update(frequency_hz=self.frequency_hz,
                       formula="PL(d) = 20 log10(4 pi d f / c) + X")
        out.update(shadowing_sigma_db=self.shadowing_sigma_db, shadowing=self.shadowing)
        return out


def thermal_noise_dbm(bandwidth_hz: float, noise_figure_db: float = 0.0,
                      temperature_k: float = 290.0) -> float:
    """Noise floor N = 10·log10(k_B·T·B / 1 mW) + NF in dBm (−173.98 dBm/Hz at 290 K)."""
    return float(10.0 * math.log10(BOLTZMANN * temperature_k * bandwidth_hz * 1e3)
                 + noise_figure_db)


@dataclass(frozen=True)
class Noise:
    """Receiver noise floor (thermal, or given) and optional interference power, in dBm."""

    floor_dbm: float
    bandwidth_hz: float | None = None
    noise_figure_db: float | None = None
    temperature_k: float | None = None
    interference_dbm: float | None = None

    @classmethod
    def from_mapping(cls, data: Any, prefix: str) -> Noise:
        data = _mapping(data, prefix)
        thermal = {"noise_figure_db", "bandwidth_hz", "temperature_k"}
        check_keys(data, thermal | {"noise_floor_dbm", "interference_dbm"}, set(), prefix)
        interference = (real_field(data, "interference_dbm", prefix, low=-300, high=100)
                        if "interference_dbm" in data else None)
        if "noise_floor_dbm" in data:
            extra = sorted(thermal & set(data))
            if extra:
                raise InputError("give either noise_floor_dbm or the thermal parameters, "
                                 "not both", field=f"{prefix}.{extra[0]}")
            return cls(real_field(data, "noise_floor_dbm", prefix, low=-300, high=100),
                       interference_dbm=interference)
        if "bandwidth_hz" not in data:
            raise InputError("is required (or give noise_floor_dbm)",
                             field=f"{prefix}.bandwidth_hz")
        b = real_field(data, "bandwidth_hz", prefix, low=0, high=1e15, low_open=True)
        nf = (real_field(data, "noise_figure_db", prefix, low=0, high=100)
              if "noise_figure_db" in data else 0.0)
        t = (real_field(data, "temperature_k", prefix, low=0, high=1e6, low_open=True)
             if "temperature_k" in data else 290.0)
        return cls(thermal_noise_dbm(b, nf, t), b, nf, t, interference)

    @property
    def total_dbm(self) -> float:
        """Noise plus interference: 10·log10(10^{N/10} + 10^{I/10})."""
        if self.interference_dbm is None:
            return self.floor_dbm
        return float(np.logaddexp(self.floor_dbm * math.log(10) / 10,
                                  self.interference_dbm * math.log(10) / 10) * 10 / math.log(10))

    def to_dict(self) -> dict[str, Any]:
        return {"noise_floor_dbm": self.floor_dbm, "bandwidth_hz": self.bandwidth_hz,
                "noise_figure_db": self.noise_figure_db, "temperature_k": self.temperature_k,
                "interference_dbm": self.interference_dbm,
                "noise_plus_interference_dbm": self.total_dbm}


# ---------------------------------------------------------------------------------------------
# The channel
# ---------------------------------------------------------------------------------------------

LINK_KEYS = {"model", "radio", "tx_power_dbm", "distance_m", "packet_bytes", "path_loss",
             "noise", "antenna_gain_db", "margin_db", "max_outage"}
LINK_REQUIRED = {"radio", "tx_power_dbm", "distance_m", "packet_bytes", "path_loss", "noise"}


@dataclass(frozen=True, eq=False)
class LinkBudget(Channel):
    """A radio link: i.i.d. packet arrivals with p = 1 − PER(SINR(d), L) (see module docstring).

    Margin policy: a design must keep ``margin_db`` dB of SINR in reserve; with ``max_outage``
    the reserve is at least σ·Φ^{-1}(1 − max_outage) (per-link shadowing: at most that fraction
    of links fall below the requirement).
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
    model: ClassVar[str] = "link-budget"
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    @classmethod
    def from_mapping(cls, data: dict, prefix: str, base_dir: Path | None = None) -> LinkBudget:
        check_keys(data, LINK_KEYS, LINK_REQUIRED, prefix)
        kw: dict[str, Any] = {
            "radio": radio_from_mapping(data["radio"], f"{prefix}.radio"),
            "tx_power_dbm": real_field(data, "tx_power_dbm", prefix, low=-100, high=100),
            "distance_m": real_field(data, "distance_m", prefix, low=0, high=1e9, low_open=True),
            "packet_bytes": integer_field(data, "packet_bytes", prefix, low=1, high=65535),
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
        return cls(**kw)

    # -- the chain -----------------------------------------------------------------------------
    @property
    def path_loss_db(self) -> float:
        """Median path loss at the configured distance."""
        return float(self.path_loss.loss_db(self.distance_m))

    @property
    def rx_power_dbm(self) -> float:
        """Median received power Pr = Pt + G − PL(d)."""
        return self.tx_power_dbm + self.antenna_gain_db - self.path_loss_db

    @property
    def sinr_db(self) -> float:
        """Median SINR = Pr − (N ⊕ I)."""
        return self.rx_power_dbm - self.noise.total_dbm

    @property
    def sigma_db(self) -> float:
        return self.path_loss.shadowing_sigma_db

    @property
    def per_packet_shadowing(self) -> bool:
        return self.sigma_db > 0 and self.path_loss.shadowing == "per-packet"

    def nominal_arrival(self, sinr_db: float) -> float:
        """1 − PER at a given SINR, without shadowing."""
        return float(self.radio.arrival(sinr_db, self.packet_bytes))

    def mean_arrival(self, sinr_db: float) -> float:
        """Shadowing average p̄(s) = ∫ p(s + σz) φ(z) dz (trapezoid rule on z ∈ [−9, 9]).

        The integrand is smooth and decays like φ(z), so the trapezoid rule converges
        geometrically; the step keeps σ·h ≤ 0.02 dB, far finer than the width of any PER curve.
        """
        sigma = self.sigma_db
        if sigma == 0:
            return self.nominal_arrival(sinr_db)
        h = min(0.01, 0.02 / sigma)
        count = 2 * math.ceil(Z_RANGE / h) + 1
        z = np.linspace(-Z_RANGE, Z_RANGE, count)
        weights = np.exp(-0.5 * z * z) / math.sqrt(2 * math.pi)
        values = self.radio.arrival(sinr_db + sigma * z, self.packet_bytes)
        return float(min(1.0, np.trapezoid(values * weights, z)))

    def effective_arrival(self, sinr_db: float) -> float:
        """The i.i.d. arrival probability at median SINR ``sinr_db`` (mean if per-packet)."""
        return self.mean_arrival(sinr_db) if self.per_packet_shadowing \
            else self.nominal_arrival(sinr_db)

    @property
    def arrival_value(self) -> float:
        """The arrival probability as a float (cached)."""
        if "p" not in self._cache:
            self._cache["p"] = self.effective_arrival(self.sinr_db)
        return self._cache["p"]

    @property
    def arrival_probability(self) -> sp.Expr:
        """Median link's 1 − PER (per-link shadowing) or its shadowing average (per-packet)."""
        return sp.Float(self.arrival_value, 17)

    @property
    def iid(self) -> bool:
        return True

    # -- design --------------------------------------------------------------------------------
    @property
    def effective_margin_db(self) -> float:
        """max(margin_db, σ·Φ^{-1}(1 − max_outage)) — the SINR reserve the design keeps."""
        margin = self.margin_db
        if self.max_outage is not None and self.sigma_db > 0 \
                and not self.per_packet_shadowing:
            margin = max(margin, float(self.sigma_db * ndtri(1.0 - self.max_outage)))
        return margin

    def required_sinr_db(self, p: float) -> float | None:
        """Least median SINR (dB) whose arrival probability is ≥ p; None if none is needed."""
        if not self.per_packet_shadowing:
            return self.radio.required_sinr_db(p, self.packet_bytes)
        from scipy.optimize import brentq

        lo, hi = -60.0, 100.0
        if p <= self.mean_arrival(lo):
            return None
        if p >= self.mean_arrival(hi):
            raise ValueError(f"arrival probability {p!r} is not reached")
        return float(brentq(lambda s: self.mean_arrival(s) - p, lo, hi, xtol=1e-9))

    def outage_probability(self, p: float) -> float:
        """P(p_link < p) over per-link shadowing: Φ((s_req(p) − s0)/σ) (0 or 1 when σ = 0)."""
        s_req = self.radio.required_sinr_db(p, self.packet_bytes) if p < 1 else math.inf
        if s_req is None:
            return 0.0
        if self.sigma_db == 0:
            return 1.0 if self.sinr_db < s_req else 0.0
        return float(ndtr((s_req - self.sinr_db) / self.sigma_db))

    def max_distance_m(self, sinr_required_db: float, margin_db: float) -> float | None:
        """Largest d with Pt + G − PL(d) − N − margin ≥ SINR_req (None if it overflows)."""
        allowed = self.tx_power_dbm + self.antenna_gain_db - self.noise.total_dbm \
            - sinr_required_db - margin_db
        return self.path_loss.distance_m(allowed)

    def link_dict(self) -> dict[str, Any]:
        """The configured link, step by step."""
        sinr = self.sinr_db
        ber = float(self.radio.ber(db_to_linear(sinr)))
        return {"tx_power_dbm": self.tx_power_dbm, "antenna_gain_db": self.antenna_gain_db,
                "distance_m": self.distance_m, "packet_bytes": self.packet_bytes,
                "path_loss_db": self.path_loss_db, "rx_power_dbm": self.rx_power_dbm,
                **self.noise.to_dict(), "sinr_db": sinr,
                "sinr_linear": float(db_to_linear(sinr)), "bit_error_rate": ber,
                "packet_error_rate": float(self.radio.per(sinr, self.packet_bytes)),
                "arrival_probability_nominal": self.nominal_arrival(sinr),
                "arrival_probability_mean": self.mean_arrival(sinr),
                "arrival_probability": self.arrival_value}

    def to_dict(self) -> dict[str, Any]:
        return {"model": self.model, "radio": self.radio.to_dict(),
                "tx_power_dbm": self.tx_power_dbm, "distance_m": self.distance_m,
                "packet_bytes": self.packet_bytes, "antenna_gain_db": self.antenna_gain_db,
                "path_loss": self.path_loss.to_dict(), "noise": self.noise.to_dict(),
                "margin_db": self.margin_db, "max_outage": self.max_outage,
                "sinr_db": self.sinr_db, "arrival_probability": self.arrival_value,
                "arrival_probability_expression": repr(self.arrival_value),
                "arrival_probability_basis": ("shadowing average (per-packet shadowing)"
                                              if self.per_packet_shadowing else
                                              "median link (no shadowing draw)")}


# ---------------------------------------------------------------------------------------------
# Design outputs for the analysis record
# ---------------------------------------------------------------------------------------------

def _threshold_row(channel: LinkBudget, label: str, p: float) -> dict[str, Any]:
    """Required SINR / received power / distance and the link margin for one requirement p."""
    row: dict[str, Any] = {"label": label, "arrival_probability": p, "required_sinr_db": None,
                           "required_rx_power_dbm": None, "link_margin_db": None,
                           "max_distance_m": None, "max_distance_unbounded": False,
                           "outage_probability": None, "reachable": True}
    if p >= 1.0:
        row["reachable"] = False
        row["outage_probability"] = 1.0
        return row
    try:
        s_req = channel.required_sinr_db(p)
    except ValueError:
        row["reachable"] = False
        return row
    row["outage_probability"] = channel.outage_probability(p)
    if s_req is None:
        row["max_distance_unbounded"] = True
        return row
    d = channel.max_distance_m(s_req, channel.effective_margin_db)
    row.update(required_sinr_db=s_req, required_rx_power_dbm=s_req + channel.noise.total_dbm,
               link_margin_db=channel.sinr_db - s_req, max_distance_m=d,
               max_distance_unbounded=d is None)
    return row


def _design_requirement(critical_value: float | None, robust_value: float | None,
                        bracket: tuple[float | None, float | None],
                        upper_bound: float | None) -> tuple[float | None, str]:
    """The arrival probability a design must exceed, and why.

    max(p_c, robust value) when p_c is known; otherwise the upper end of the bracket (or p_up):
    exceeding it is sufficient for mean stability.
    """
    if critical_value is not None:
        if robust_value is not None and robust_value > critical_value:
            return robust_value, "robust critical value"
        return critical_value, "critical value p_c"
    high = bracket[1] if bracket and bracket[1] is not None else upper_bound
    if high is not None:
        return high, "upper end of the bracket (sufficient; p_c unknown)"
    return None, "no requirement known"


def design_section(channel: Channel, *, critical_value: float | None,
                   robust_value: float | None,
                   bracket: tuple[float | None, float | None],
                   upper_bound: float | None) -> dict[str, Any]:
    """The ``link_budget`` section of the analysis record.

    Parameters
    ----------
    channel : Channel
        The configured channel; anything but a :class:`LinkBudget` gives ``{"applicable": False}``.
    critical_value, robust_value : float or None
        p_c and the robust critical value (None when unknown).
    bracket : (float or None, float or None)
        Lower and upper ends bracketing p_c when it is unknown.
    upper_bound : float or None
        p_up.

    Returns
    -------
    dict
        ``applicable, radio, link, margin_policy, required_arrival_probability {critical_value,
        robust_value, bracket, design_value, basis}, required_sinr_db, required_rx_power_dbm,
        link_margin_db, max_distance_m, max_distance_unbounded, mean_stable_at_distance,
        shadowing {sigma_db, mode, mean_arrival_probability, outage_below_critical,
        outage_below_upper}, thresholds [rows], notes``.
    """
    if not isinstance(channel, LinkBudget):
        return {"applicable": False, "reason": "the channel is not a link-budget model"}
    bracket = tuple(bracket) if bracket is not None else (None, None)
    p_design, basis = _design_requirement(critical_value, robust_value, bracket, upper_bound)
    rows = []
    for label, value in (("critical_value", critical_value), ("robust_critical_value",
                                                              robust_value),
                         ("bracket_low", bracket[0] if critical_value is None else None),
                         ("bracket_high", bracket[1] if critical_value is None else None),
                         ("upper_bound", upper_bound)):
        if value is not None:
            rows.append(_threshold_row(channel, label, float(value)))
    design = _threshold_row(channel, "design", p_design) if p_design is not None else None
    sinr = channel.sinr_db
    p_link = channel.arrival_value
    notes = []
    if channel.sigma_db > 0 and not channel.per_packet_shadowing:
        notes.append("per-link shadowing: the arrival probability is the median link's; a "
                     "deployed link falls below a requirement with the outage probability")
    if channel.per_packet_shadowing:
        notes.append("per-packet shadowing: arrivals are i.i.d. with the shadowing-averaged "
                     "probability; outage probabilities describe per-link shadowing and are "
                     "given for comparison")
    if channel.path_loss.model == "log-distance" \
            and channel.distance_m < channel.path_loss.reference_distance_m:
        notes.append("the distance is below the reference distance of the log-distance model")
    return {
        "applicable": True,
        "radio": channel.radio.to_dict(),
        "link": channel.link_dict(),
        "margin_policy": {"margin_db": channel.margin_db, "max_outage": channel.max_outage,
                          "effective_margin_db": channel.effective_margin_db,
                          "rule": "keep max(margin_db, sigma * Phi^-1(1 - max_outage)) dB of "
                                  "SINR above the requirement"},
        "required_arrival_probability": {"critical_value": critical_value,
                                         "robust_value": robust_value,
                                         "bracket": list(bracket), "design_value": p_design,
                                         "basis": basis},
        "required_sinr_db": design["required_sinr_db"] if design else None,
        "required_rx_power_dbm": design["required_rx_power_dbm"] if design else None,
        "link_margin_db": design["link_margin_db"] if design else None,
        "max_distance_m": design["max_distance_m"] if design else None,
        "max_distance_unbounded": bool(design["max_distance_unbounded"]) if design else False,
        "mean_stable_at_distance": (p_link > p_design) if p_design is not None else None,
        "shadowing": {
            "sigma_db": channel.sigma_db, "mode": channel.path_loss.shadowing,
            "mean_arrival_probability": channel.mean_arrival(sinr),
            "outage_below_critical": (channel.outage_probability(float(critical_value))
                                      if critical_value is not None else None),
            "outage_below_upper": (channel.outage_probability(float(upper_bound))
                                   if upper_bound is not None else None)},
        "thresholds": rows,
        "notes": notes,
    }


# ---------------------------------------------------------------------------------------------
# Gilbert–Elliott (bursty) links
# ---------------------------------------------------------------------------------------------

GE_CLAIMS = [
    {"statement": "Kalman filtering with Markovian (Gilbert-Elliott) packet losses: conditions "
                  "for the stability of the peak covariance (sufficient in general, necessary "
                  "and sufficient for some classes of systems).",
     "source": "M. Huang, S. Dey, Stability of Kalman filtering with Markovian packet losses, "
               "Automatica 43(4), 2007",
     "status": "claim from the literature (not verified by kfcrit)"},
    {"statement": "For non-degenerate systems the mean error covariance is bounded iff "
                  "(1 - r) |lambda_1|^2 < 1, whatever the failure rate f; for second-order "
                  "systems the condition depends on the structure of (A, C) and reduces to the "
                  "i.i.d. critical value when f + r = 1.",
     "source": "K. You, M. Fu, L. Xie, Mean square stability for Kalman filtering with "
               "Markovian packet losses, Automatica 47(12), 2011",
     "status": "claim from the literature (not verified by kfcrit)"},
]
"""Literature results beyond the scalar case, labelled as claims (MATH §7)."""

GE_SIM_PATHS = 4000
GE_SIM_MIN_LOST = 100
"""The horizon keeps about this many paths that have lost every packet since t = 0."""
GE_SIM_STEPS = (8, 400)
GE_SIM_BOUNDED_STEPS = 40
"""Least horizon when the condition holds (E[P_t] must have settled to show that it is bounded)."""
GE_GROWTH_FACTOR = 2.0
"""E[P_T] / E[P_{T/2}] above this reads as growing, below as bounded."""


def ge_horizon(a: float, failure: float, recovery: float, paths: int = GE_SIM_PATHS) -> int:
    """Horizon T of :func:`ge_scalar_simulation` for the scalar system ``a``.

    When (1 − r)a² > 1, E[P_t] grows like ((1 − r)a²)^t through the paths that have lost every
    packet since the start; a sample of ``paths`` paths estimates it only while about
    :data:`GE_SIM_MIN_LOST` such paths remain: paths·π_loss·(1 − r)^T ≈ 100 with π_loss =
    f/(f + r). Beyond that horizon the sample mean saturates (it is a mean of a heavy-tailed
    variable) and would wrongly look bounded. When the condition holds the horizon is at least
    :data:`GE_SIM_BOUNDED_STEPS`, so that the mean has settled.
    """
    lo, hi = GE_SIM_STEPS
    if recovery >= 1:
        steps = hi
    else:
        pi_loss = failure / (failure + recovery)
        steps = int(math.floor(math.log(GE_SIM_MIN_LOST / (paths * pi_loss))
                               / math.log1p(-recovery)))
    if (1 - recovery) * a * a < 1:
        steps = max(steps, GE_SIM_BOUNDED_STEPS)
    return max(lo, min(hi, steps))


def ge_scalar_simulation(a: float, c: float, q: float, r_noise: float, failure: float,
                         recovery: float, *, paths: int = GE_SIM_PATHS, steps: int | None = None,
                         seed: int = 0) -> dict[str, Any]:
    """Monte Carlo of the scalar random Riccati equation driven by a Gilbert–Elliott chain.

    P ← a²P + q on a loss, P ← a²P + q − a²c²P²/(c²P + r) on an arrival; P_0 = 1 and the chain
    starts in its stationary law. Reports the sample means of P at T/2 and T (T from
    :func:`ge_horizon` unless given) and their ratio: near 1 when E[P_t] is bounded, about
    ((1 − r)a²)^{T/2} when it grows.

    Parameters
    ----------
    a, c, q, r_noise : float
        The scalar system (A, C, Q, R).
    failure, recovery : float
        f = P(lost next | received now) and r = P(received next | lost now).
    paths : int
        Number of simulated paths.
    steps : int, optional
        Horizon T (default :func:`ge_horizon`).
    seed : int
        Seed of the NumPy generator.

    Returns
    -------
    dict
        ``paths, steps, seed, horizon_rule, mean_half, mean_end, growth_ratio,
        expected_growth_if_unbounded, capped``.
    """
    if steps is None:
        steps = ge_horizon(a, failure, recovery, paths)
    rng = np.random.default_rng(seed)
    received = rng.random(paths) < recovery / (failure + recovery)
    P = np.ones(paths)
    a2, c2 = a * a, c * c
    means = np.empty(steps + 1)
    means[0] = 1.0
    with np.errstate(over="ignore", invalid="ignore"):
        for t in range(1, steps + 1):
            u = rng.random(paths)
            received = np.where(received, u >= failure, u < recovery)
            pred = a2 * P + q
            upd = pred - a2 * c2 * P * P / (c2 * P + r_noise)
            P = np.minimum(np.where(received, upd, pred), 1e300)
            means[t] = P.mean()
    half, end = float(means[steps // 2]), float(means[steps])
    value = (1 - recovery) * a2
    return {"paths": paths, "steps": steps, "seed": seed,
            "horizon_rule": f"about {GE_SIM_MIN_LOST} paths lose every packet up to T "
                            f"(T in [{GE_SIM_STEPS[0]}, {GE_SIM_STEPS[1]}], at least "
                            f"{GE_SIM_BOUNDED_STEPS} when the condition holds)",
            "mean_half": half, "mean_end": end,
            "growth_ratio": end / half if half > 0 else None,
            "expected_growth_if_unbounded": (float(value ** (steps - steps // 2))
                                             if value > 1 else None),
            "capped": bool(np.max(P) >= 1e300)}


def _ge_status(system: Any, classification: str, c_nonzero: bool) -> tuple[str, bool]:
    """(label of the condition, whether it is a theorem that decides mean stability)."""
    if classification == "stable":
        return ("theorem: rho(A) < 1, so E[P_t] is bounded for every loss process "
                "(the condition holds trivially)", True)
    if classification == "not-detectable":
        return ("not applicable: (C, A) is not detectable, E[P_t] diverges for every loss "
                "process", False)
    if system.n == 1 and c_nonzero:
        return ("theorem (scalar case, MATH §7: a loss burst lasts j steps with probability "
                "(1 - r)^(j-1) r and multiplies P by about a^(2j))", True)
    if classification == "non-degenerate":
        return ("claim: necessary and sufficient for non-degenerate systems (You-Fu-Xie 2011, "
                "see claims); not verified by kfcrit", False)
    return (f"necessary condition only (claim, loss-burst argument of MATH §7 applied to "
            f"lambda_1); no sufficient condition is implemented for a {classification} system "
            "(You-Fu-Xie 2011 give structure-dependent conditions for second-order systems)",
            False)


def gilbert_elliott_fit(arrivals: Any, system: Any = None) -> dict[str, Any]:
    """Maximum-likelihood two-state Markov (Gilbert–Elliott) fit of a 0/1 arrival sequence.

    f̂ = #(1 → 0) / #(1 → ·) and r̂ = #(0 → 1) / #(0 → ·) over consecutive pairs (the transition
    counts of the chain). For information only: a fit to a finite recording is an estimate, not
    the channel, so no theorem is applied to it. With ``system`` the value (1 − r̂)·ρ(A)² of the
    MATH §7 condition is added (again for information). ``available`` is False when the trace
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


def gilbert_elliott_section(system: Any, channel: Channel, *, seed: int = 0,
                            simulate: bool = True) -> dict[str, Any]:
    """Mean stability under Gilbert–Elliott losses (MATH §7).

    Scalar case (theorem): losses arrive in bursts of length j with probability
    (1 − r)^{j−1} r, and P grows like a^{2j} during a burst (while after an arrival it is at most
    R/c²), so E[P] is bounded iff (1 − r)·a² < 1, i.e. the recovery rate r exceeds 1 − 1/a²
    (the i.i.d. critical value; f does not enter). It is checked by :func:`ge_scalar_simulation`.
    For n > 1 the same test with a = ρ(A) is labelled as what it is: a claim from the literature
    for non-degenerate systems, a necessary condition only otherwise.

    Parameters
    ----------
    system : System
        The system.
    channel : Channel
        The configured channel; anything but :class:`GilbertElliott` gives
        ``{"applicable": False}``.
    seed : int
        Seed of the simulation check.
    simulate : bool
        Run the simulation check (scalar case only).

    Returns
    -------
    dict
        ``applicable, failure_rate, recovery_rate, stationary_arrival_probability,
        mean_burst_length, spectral_radius, classification, condition {expression, value, holds,
        status, decides}, required_recovery_rate, max_mean_burst_length, simulation | null,
        simulation_consistent | null, simulation_note, claims``.
    """
    from kfcrit.theory.critical import critical_value

    if not isinstance(channel, GilbertElliott):
        return {"applicable": False, "reason": "the channel is not a Gilbert-Elliott model"}
    f = float(channel.failure_rate)
    r = float(channel.recovery_rate)
    a = float(max(abs(np.linalg.eigvals(system.a))))
    value = (1 - r) * a * a
    classification = critical_value(system).classification
    scalar = system.n == 1
    c_nonzero = bool(np.any(system.c != 0))
    status, decides = _ge_status(system, classification, c_nonzero)
    r_min = max(0.0, 1 - 1 / (a * a)) if a > 0 else 0.0
    out: dict[str, Any] = {
        "applicable": True, "failure_rate": f, "recovery_rate": r,
        "stationary_arrival_probability": r / (f + r), "mean_burst_length": 1 / r,
        "spectral_radius": a, "classification": classification,
        "condition": {"expression": "(1 - r) a^2 < 1", "value": value, "holds": value < 1,
                      "status": status, "decides": decides},
        "required_recovery_rate": r_min,
        "max_mean_burst_length": (1 / r_min) if r_min > 0 else None,
        "simulation": None, "simulation_consistent": None, "simulation_note": None,
        "claims": GE_CLAIMS}
    if simulate and scalar and decides and classification != "stable":
        sim = ge_scalar_simulation(float(system.a[0, 0]), float(system.c[0, 0]),
                                   float(system.q[0, 0]), float(system.r[0, 0]), f, r,
                                   seed=seed)
        out["simulation"] = sim
        expected = sim["expected_growth_if_unbounded"]
        if abs(value - 1) < 0.15:
            out["simulation_note"] = ("(1 - r) a^2 is within 0.15 of 1: a simulation of this "
                                      "size cannot tell bounded from growing; not compared")
        elif value > 1 and (expected is None or expected < 2 * GE_GROWTH_FACTOR):
            out["simulation_note"] = ("the horizon a simulation can resolve is too short for "
                                      "the predicted growth to show; not compared")
        elif sim["growth_ratio"] is not None:
            out["simulation_consistent"] = (sim["growth_ratio"] < GE_GROWTH_FACTOR) == \
                (value < 1)
            reading = "bounded" if sim["growth_ratio"] < GE_GROWTH_FACTOR else "growing"
            out["simulation_note"] = (f"E[P_T]/E[P_T/2] = {sim['growth_ratio']:.4g} at T = "
                                      f"{sim['steps']}; read as {reading} (threshold "
                                      f"{GE_GROWTH_FACTOR:g})")
    return out
