"""Propagation and receiver noise (with the physical constants and decibel conversions the link
modules share): median path loss with log-normal shadowing, noise floor.

::

    path loss     PL(d) = PL0 + 10·n·log10(d/d0) + X          (log-distance, X ~ N(0, σ²) dB)
                  PL(d) = 20·log10(4π d f / c) + X             (free space, Friis)
    noise floor   N = 10·log10(k_B T B / 1 mW) + NF            (≈ −174 dBm/Hz + 10·log10 B + NF)
    N ⊕ I         10·log10(10^{N/10} + 10^{I/10})               (I: interference, optional)

Shadowing modes (``path_loss.shadowing``): ``per-link`` (one draw of X per deployed link),
``per-packet`` (a fresh draw every sample period) and ``time-correlated`` (an AR(1) process over
the sample periods, see :mod:`kfcrit.link.shadowing`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from kfcrit.errors import InputError
from kfcrit.link.fields import mapping_field, real_field
from kfcrit.model.channels import check_keys
from kfcrit.records.channel import NoiseRecord, PathLossRecord

SHADOWING_MODES = ("per-link", "per-packet", "time-correlated")
MAX_SIGMA_DB = 30.0

BOLTZMANN = 1.380649e-23
"""Boltzmann constant k_B in J/K (exact in the 2019 SI)."""
SPEED_OF_LIGHT = 299_792_458.0
"""c in m/s (exact)."""
REFERENCE_TEMPERATURE_K = 290.0
"""The standard noise temperature T0 (IEEE definition of the noise figure)."""


def db_to_linear(x_db: Any) -> Any:
    """10^(x/10)."""
    return np.power(10.0, np.asarray(x_db, dtype=float) / 10.0)


def linear_to_db(x: Any) -> Any:
    """10·log10(x)."""
    return 10.0 * np.log10(np.asarray(x, dtype=float))


def thermal_noise_dbm(bandwidth_hz: float, noise_figure_db: float = 0.0,
                      temperature_k: float = REFERENCE_TEMPERATURE_K) -> float:
    r"""Noise floor in dBm.

    .. math:: N = 10 \log_{10}(k_B T B / 1\,\mathrm{mW}) + NF

    (−173.98 dBm/Hz at 290 K).
    """
    return float(10.0 * math.log10(BOLTZMANN * temperature_k * bandwidth_hz * 1e3)
                 + noise_figure_db)


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
        data = mapping_field(data, prefix)
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

    def record(self) -> PathLossRecord:
        """The path-loss model as the record states it (``channel.path_loss``)."""
        if self.model == "log-distance":
            return PathLossRecord(model=self.model, exponent=self.exponent,
                                  reference_distance_m=self.reference_distance_m,
                                  reference_loss_db=self.reference_loss_db,
                                  formula="PL(d) = PL0 + 10 n log10(d/d0) + X",
                                  shadowing_sigma_db=self.shadowing_sigma_db,
                                  shadowing=self.shadowing)
        return PathLossRecord(model=self.model, frequency_hz=self.frequency_hz,
                              formula="PL(d) = 20 log10(4 pi d f / c) + X",
                              shadowing_sigma_db=self.shadowing_sigma_db,
                              shadowing=self.shadowing)


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
        data = mapping_field(data, prefix)
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

    def record(self) -> NoiseRecord:
        """The noise as the record states it (``channel.noise``)."""
        return NoiseRecord(noise_floor_dbm=self.floor_dbm, bandwidth_hz=self.bandwidth_hz,
                           noise_figure_db=self.noise_figure_db,
                           temperature_k=self.temperature_k,
                           interference_dbm=self.interference_dbm,
                           noise_plus_interference_dbm=self.total_dbm)
