"""What ns-3 is asked to simulate: sensors, sink, propagation, noise and shadowing draws.

Built from the link budgets of a file (one link, or every sensor of a ``sensors:`` network) and
checked without ns-3, so everything here is testable on a machine without the wheel.

Mapping of a link budget onto ns-3's lr-wpan model (IEEE 802.15.4 2.4 GHz O-QPSK, the same
error model as ``ieee802154-oqpsk-2450``, applied to the whole PPDU; the traces it gives are
measured links in the sense of theory §14):

* path loss: ns-3's ``LogDistancePropagationLossModel`` with the first sensor's exponent,
  reference distance and reference loss (free space: exponent 2 and the Friis loss at 1 m).
  A sensor whose path loss differs, or whose distance lies below the reference distance (where
  ns-3 clamps the loss to the reference loss and kfcrit extrapolates), gets the difference as a
  fixed ``offset_db`` on its link to the sink;
* noise: every receiver's noise power over the channel is the least *effective* noise of the
  sensors' links, N_eff = N ⊕ I + ΔL (ΔL the implementation loss of a datasheet-calibrated
  radio, which shifts the same O-QPSK curve); a sensor with more gets the excess as offset;
* transmit power: ``tx_power_dbm + antenna_gain_db``; the sink answers (acknowledgements) with
  the largest of these;
* shadowing (``path_loss.shadowing``, σ = ``shadowing_sigma_db``), on sensor–sink links only,
  independent between sensors, drawn here with NumPy from the seed: ``per-link`` one value per
  sensor for the whole run; ``per-packet`` one value per period shared by the period's attempts,
  or (``fading_per_attempt: independent``) one per transmission, drawn by ns-3; and
  ``time-correlated`` an AR(1) series X_{k+1} = ρ X_k + √(1 − ρ²) σ Z_k with ρ for the
  simulated period (bursty losses, theory §7 and §10);
* retries: ``max_retries`` = ns-3's ``macMaxFrameRetries``, with acknowledgements requested
  when it is positive (without retries, no acknowledgement, as the analytic model assumes);
* sensors without ``position_m`` sit at their ``distance_m`` from the sink, spread evenly on a
  circle (their mutual distances then decide whether they hear each other's carrier).
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from kfcrit.errors import InputError
from kfcrit.link.linkbudget import LinkBudget
from kfcrit.link.propagation import SPEED_OF_LIGHT
from kfcrit.link.radios import CalibratedOqpsk, Ieee802154Oqpsk

MAX_NS3_SENSORS = 64
"""Most sensors simulated together (short addresses 1..64)."""
MAX_NS3_PERIODS = 10_000_000
"""Most sample periods of one run."""
MAX_TABLE_VALUES = 50_000_000
"""Most shadowing values handed to ns-3 (sensors with per-period shadowing × periods)."""
DEFAULT_PERIOD_S = 0.1
"""Sample period when neither the command line nor the file gives one."""


@dataclass(frozen=True)
class Ns3Sensor:
    """One sensor as ns-3 sees it.

    Attributes
    ----------
    name : str
        The sensor's name (``sensor`` for a single-link file).
    link : LinkBudget
        Its link budget (the analytic side).
    position_m : tuple of float
        (x, y, z) in metres.
    tx_power_dbm : float
        Transmit power plus antenna gain.
    offset_db : float
        Extra loss on its link to the sink (module docstring).
    shadowing_db : numpy.ndarray
        Shadowing values in dB: empty (none, or drawn per transmission by ns-3), one (per link)
        or one per period.
    attempt_sigma_db : float
        σ of a normal value drawn by ns-3 per transmission (0: none).
    """

    name: str
    link: LinkBudget
    position_m: tuple[float, float, float]
    tx_power_dbm: float
    offset_db: float
    shadowing_db: np.ndarray
    attempt_sigma_db: float

    @property
    def shadowing_mode(self) -> str:
        """``none``, or the link's ``path_loss.shadowing`` with ``/attempt`` when redrawn per
        transmission."""
        if self.link.sigma_db == 0:
            return "none"
        if self.attempt_sigma_db > 0:
            return "per-packet/attempt"
        return self.link.path_loss.shadowing


@dataclass(frozen=True)
class Ns3Plan:
    """Everything one ns-3 run needs (see the module docstring for the mapping).

    Attributes
    ----------
    sensors : tuple of Ns3Sensor
        In file order; sensor i has short address i + 1.
    sink_position_m : tuple of float
        (x, y, z).
    period_s : float
        Sample period T; sensor i asks its MAC to send period k's frame at k·T (+ jitter).
    periods : int
        Number of periods simulated.
    jitter_s : float
        Each request is delayed by a uniform value in [0, jitter_s) (0: synchronous sampling).
    nakagami_m : float or None
        Nakagami-m fading per transmission (None: none).
    seed : int
        ns-3 ``RngSeedManager::SetSeed(seed + 1)``, ``SetRun(1)``; NumPy shadowing draws.
    exponent, reference_distance_m, reference_loss_db : float
        ns-3's ``LogDistancePropagationLossModel``.
    noise_dbm : float
        Noise power of every receiver over the channel (dBm).
    sink_tx_power_dbm : float
        Transmit power of the sink's acknowledgements.
    """

    sensors: tuple[Ns3Sensor, ...]
    sink_position_m: tuple[float, float, float]
    period_s: float
    periods: int
    jitter_s: float
    nakagami_m: float | None
    seed: int
    exponent: float
    reference_distance_m: float
    reference_loss_db: float
    noise_dbm: float
    sink_tx_power_dbm: float

    @property
    def names(self) -> tuple[str, ...]:
        """Sensor names in order."""
        return tuple(s.name for s in self.sensors)

    def to_dict(self) -> dict[str, Any]:
        """The plan as plain JSON data (shadowing tables summarised, not listed)."""
        return {
            "period_s": self.period_s, "periods": self.periods, "jitter_s": self.jitter_s,
            "nakagami_m": self.nakagami_m, "seed": self.seed,
            "sink_position_m": list(self.sink_position_m),
            "propagation": {"model": "LogDistancePropagationLossModel",
                            "exponent": self.exponent,
                            "reference_distance_m": self.reference_distance_m,
                            "reference_loss_db": self.reference_loss_db},
            "noise_dbm": self.noise_dbm, "sink_tx_power_dbm": self.sink_tx_power_dbm,
            "sensors": [{"name": s.name, "position_m": list(s.position_m),
                         "distance_m": s.link.distance_m, "tx_power_dbm": s.tx_power_dbm,
                         "packet_bytes": s.link.packet_bytes,
                         "max_retries": s.link.max_retries, "offset_db": s.offset_db,
                         "shadowing": s.shadowing_mode,
                         "shadowing_sigma_db": s.link.sigma_db,
                         "shadowing_values": int(s.shadowing_db.size)}
                        for s in self.sensors]}


def ns3_log_distance_db(distance_m: float, exponent: float, reference_distance_m: float,
                        reference_loss_db: float) -> float:
    """The loss ns-3's ``LogDistancePropagationLossModel`` applies (dB).

    PL0 + 10 n log10(d/d0) for d > d0, and PL0 for d ≤ d0 (ns-3 does not extrapolate).
    """
    if distance_m <= reference_distance_m:
        return reference_loss_db
    return reference_loss_db + 10.0 * exponent * math.log10(distance_m / reference_distance_m)


def log_distance_parameters(link: LinkBudget) -> tuple[float, float, float]:
    """(exponent, reference distance, reference loss) of a link's median path loss.

    Free space is log-distance with n = 2, d0 = 1 m and the Friis loss 20 log10(4π f / c).
    """
    pl = link.path_loss
    if pl.model == "log-distance":
        return pl.exponent, pl.reference_distance_m, pl.reference_loss_db
    return 2.0, 1.0, 20.0 * math.log10(4.0 * math.pi * float(pl.frequency_hz) / SPEED_OF_LIGHT)


def effective_noise_dbm(link: LinkBudget) -> float:
    """N ⊕ I plus the radio's implementation loss (what the ideal O-QPSK curve must see)."""
    loss = link.radio.implementation_loss_db if isinstance(link.radio, CalibratedOqpsk) else 0.0
    return link.noise.total_dbm + loss


def check_ns3_link(link: Any, field: str) -> LinkBudget:
    """The link budget, if ns-3's lr-wpan model can simulate it (else an InputError)."""
    if not isinstance(link, LinkBudget):
        model = getattr(link, "model", type(link).__name__)
        raise InputError(f"is {model!s}; 'kfcrit link simulate' needs a link-budget channel "
                         "(ns-3 simulates radio links only)", field=f"{field}.model")
    if not isinstance(link.radio, (Ieee802154Oqpsk, CalibratedOqpsk)):
        raise InputError(f"is {link.radio.name}; ns-3's lr-wpan model simulates IEEE 802.15.4 "
                         "2.4 GHz O-QPSK radios only (ieee802154-oqpsk-2450 or a calibrated "
                         "802.15.4 profile)", field=f"{field}.radio")
    if link.per_over != "ppdu":
        raise InputError("ns-3's error model covers the whole PPDU; use per_over: ppdu to "
                         "compare with it", field=f"{field}.per_over")
    return link


def _placement(count: int, index: int, distance: float) -> tuple[float, float, float]:
    angle = 2.0 * math.pi * index / count
    return distance * math.cos(angle), distance * math.sin(angle), 0.0


def _point(values: Sequence[float] | None) -> tuple[float, float, float] | None:
    if values is None:
        return None
    xs = [float(v) for v in values] + [0.0] * (3 - len(values))
    return xs[0], xs[1], xs[2]


def shadowing_draws(link: LinkBudget, periods: int, period_s: float,
                    rng: np.random.Generator) -> tuple[np.ndarray, float]:
    """Shadowing values (dB) of one sensor and the σ ns-3 draws per transmission.

    Parameters
    ----------
    link : LinkBudget
        Its ``path_loss.shadowing`` and σ decide the draws (module docstring).
    periods : int
        Periods simulated.
    period_s : float
        The simulated period (sets ρ of time-correlated shadowing).
    rng : numpy.random.Generator
        The sensor's generator.

    Returns
    -------
    (numpy.ndarray, float)
        The table (empty, one value, or one per period) and the per-transmission σ (or 0).
    """
    sigma = link.sigma_db
    empty = np.zeros(0)
    if sigma == 0:
        return empty, 0.0
    mode = link.path_loss.shadowing
    if mode == "per-link":
        return sigma * rng.standard_normal(1), 0.0
    if mode == "per-packet":
        if link.fading_per_attempt == "independent":
            return empty, sigma
        return sigma * rng.standard_normal(periods), 0.0
    corr = link.shadowing_correlation
    rho = dataclasses.replace(corr, sample_period_s=period_s).correlation if corr else 0.0
    z = rng.standard_normal(periods)
    x = np.empty(periods)
    x[0] = sigma * z[0]
    scale = sigma * math.sqrt(max(0.0, 1.0 - rho * rho))
    for k in range(1, periods):
        x[k] = rho * x[k - 1] + scale * z[k]
    return x, 0.0


def _fading_shape(links: Sequence[Any], nakagami_m: float | None, single: bool) -> float | None:
    """The Nakagami m ns-3 applies: ``--nakagami-m``, else the links' own ``fading`` (one m for all
    transmissions, so the links must agree, and the option must not contradict them)."""
    shapes = {link.fading.shape for link in links}
    if shapes == {None}:
        return nakagami_m
    field = "channel.fading" if single else "sensors[].channel.fading"
    if len(shapes) > 1:
        raise InputError("ns-3 applies one Nakagami m to every transmission: give every link "
                         "the same fading (or use --nakagami-m)", field=field)
    shape = shapes.pop()
    if nakagami_m is not None and nakagami_m != shape:
        raise InputError(f"--nakagami-m {nakagami_m:g} contradicts the file's fading "
                         f"(m = {shape:g})", field=field)
    return shape


def build_plan(links: Sequence[tuple[str, Any, Sequence[float] | None]], *,
               sink_position_m: Sequence[float] | None, periods: int, period_s: float,
               seed: int, jitter_s: float = 0.0,
               nakagami_m: float | None = None) -> Ns3Plan:
    """The ns-3 plan of a file's links.

    Parameters
    ----------
    links : sequence of (name, channel, position or None)
        Each sensor's name, channel (must be an 802.15.4 link budget) and position in metres.
    sink_position_m : sequence of float or None
        The sink's position (origin when None).
    periods : int
        Periods to simulate, 1..:data:`MAX_NS3_PERIODS`.
    period_s : float
        Sample period (s), > 0.
    seed : int
        Seed of ns-3 and of the shadowing draws.
    jitter_s : float
        Uniform sampling jitter in [0, period_s).
    nakagami_m : float or None
        Nakagami m ≥ 0.5, or None (then the links' ``fading``, if they have one).

    Returns
    -------
    Ns3Plan

    Raises
    ------
    InputError
        A channel ns-3 cannot simulate (naming its field), or an option out of range.
    """
    if not links:
        raise InputError("the file has no link to simulate", field="channel")
    if len(links) > MAX_NS3_SENSORS:
        raise InputError(f"has {len(links)} sensors; ns-3 simulates at most {MAX_NS3_SENSORS}",
                         field="sensors")
    if not 1 <= periods <= MAX_NS3_PERIODS:
        raise InputError(f"must be in 1..{MAX_NS3_PERIODS}", field="--periods")
    if not (math.isfinite(period_s) and period_s > 0):
        raise InputError("must be a positive number of seconds", field="--period-ms")
    if not (math.isfinite(jitter_s) and 0 <= jitter_s < period_s):
        raise InputError("must be in [0, the sample period)", field="--jitter-ms")
    if nakagami_m is not None and not (math.isfinite(nakagami_m) and nakagami_m >= 0.5):
        raise InputError("must be at least 0.5 (1 is Rayleigh fading)", field="--nakagami-m")
    single = len(links) == 1 and links[0][2] is None
    checked = [check_ns3_link(ch, "channel" if single else f"sensors[{i}].channel")
               for i, (_, ch, _) in enumerate(links)]
    nakagami_m = _fading_shape(checked, nakagami_m, single)
    exponent, d0, pl0 = log_distance_parameters(checked[0])
    sink = _point(sink_position_m) or (0.0, 0.0, 0.0)
    noise = min(effective_noise_dbm(link) for link in checked)
    table = 0
    rngs = np.random.default_rng([seed, 0x6E73]).spawn(len(links))
    sensors = []
    for i, ((name, _, position), link) in enumerate(zip(links, checked, strict=True)):
        pos = _point(position)
        if pos is None:
            x, y, z = _placement(len(links), i, link.distance_m)
            pos = (sink[0] + x, sink[1] + y, sink[2] + z)
        distance = math.dist(pos, sink)
        offset = (link.path_loss_db - ns3_log_distance_db(distance, exponent, d0, pl0)
                  + effective_noise_dbm(link) - noise)
        shadow, attempt_sigma = shadowing_draws(link, periods, period_s, rngs[i])
        table += shadow.size
        if table > MAX_TABLE_VALUES:
            raise InputError(f"too many shadowing values for ns-3 (more than "
                             f"{MAX_TABLE_VALUES:,}); simulate fewer periods", field="--periods")
        shadow.setflags(write=False)
        sensors.append(Ns3Sensor(name, link, pos, link.tx_power_dbm + link.antenna_gain_db,
                                 float(offset), shadow, attempt_sigma))
    return Ns3Plan(tuple(sensors), sink, float(period_s), int(periods), float(jitter_s),
                   nakagami_m, int(seed), float(exponent), float(d0), float(pl0), float(noise),
                   max(s.tx_power_dbm for s in sensors))


def file_links(spec: Any) -> tuple[list[tuple[str, Any, Sequence[float] | None]],
                                    Sequence[float] | None]:
    """(name, channel, position) of every link of a loaded system file, and the sink position.

    A single-channel file gives one sensor named ``sensor``; a ``sensors:`` network gives its
    sensors in order. A file without a channel is an InputError naming ``channel``.
    """
    net = getattr(spec, "network", None)
    if net is not None:
        out = []
        for i, s in enumerate(net.sensors):
            if s.channel is None:
                raise InputError("is required: every sensor needs a link-budget channel to "
                                 "simulate", field=f"sensors[{i}].channel")
            out.append((s.name, s.channel,
                        [float(v) for v in s.position] if s.position is not None else None))
        sink = [float(v) for v in net.sink_position] if net.sink_position is not None else None
        return out, sink
    if getattr(spec, "channel", None) is None:
        raise InputError("is required: the file has no link to simulate", field="channel")
    return [("sensor", spec.channel, None)], None


def default_period_s(spec: Any) -> float:
    """The sample period the file implies: a link's ``shadowing_correlation.sample_period_s``,
    else the ``sampling_time`` of a continuous-time model, else 0.1 s."""
    links, _ = file_links(spec)
    for _, channel, _ in links:
        corr = getattr(channel, "shadowing_correlation", None)
        if corr is not None:
            return float(corr.sample_period_s)
    continuous = getattr(spec, "continuous", None)
    if continuous is not None:
        return float(continuous.sampling_time)
    return DEFAULT_PERIOD_S
