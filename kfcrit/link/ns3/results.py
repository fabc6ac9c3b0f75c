"""Statistics of an ns-3 run: arrival traces, loss causes, cross-sensor dependence, analytics.

Pure NumPy/SciPy on the raw outcome of :func:`kfcrit.link.ns3.driver.run_plan` (an
:class:`Ns3Run`), so all of it is testable without ns-3.

Per sensor and period k the trace value is 1 iff the sink's MAC indicated sensor i's frame of
period k before the period ended (t < (k + 1)·T: a measurement must reach the filter before
its next update). A lost period is attributed to one cause, in this order:

``late``
    the frame arrived after its period (queued behind an earlier one, or slow backoffs);
``channel_access``
    the MAC gave up: CSMA-CA found the channel busy ``macMaxCSMABackoffs + 1`` times in a row
    (MCPS-DATA.confirm ``CHANNEL_ACCESS_FAILURE``);
``collision``
    the frame was sent and never received, and at least one of its transmissions overlapped on
    the air with another node's (a sensor's frame, or the sink's acknowledgement) — measured
    from every node's ``PhyTxBegin`` and the PPDU airtime, not from the receiver's SINR, so an
    overlap with a weak interferer is still counted here;
``noise``
    the frame was sent, never received, and none of its transmissions overlapped: lost to noise
    (with shadowing and fading);
``not_sent``
    no transmission of it happened before the run ended (still queued).

The simulated arrival ratio comes with its exact Clopper–Pearson interval (trace statistics,
theory §14). Cross-sensor dependence: P(all lost) with its interval against Π(1 − p̂_i), and
the pairwise (Pearson, "phi") correlation of the loss indicators (theory §9, §13).
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from kfcrit.link.linkbudget import LinkBudget
from kfcrit.link.ns3.topology import Ns3Plan, Ns3Sensor
from kfcrit.link.tracefit import clopper_pearson

CHANNEL_ACCESS_FAILURE = 0xE1
"""ns-3 ``MacStatus::CHANNEL_ACCESS_FAILURE``."""
NO_ACK = 0xE9
"""ns-3 ``MacStatus::NO_ACK`` (every retry went unacknowledged)."""
LOSS_CAUSES = ("late", "channel_access", "collision", "noise", "not_sent")
"""The causes a lost period is attributed to, in the order they are tested."""
CONFIDENCE = 0.95


@dataclass(frozen=True)
class Ns3Run:
    """The raw outcome of one ns-3 run.

    Attributes
    ----------
    delivered : numpy.ndarray
        (sensors, periods) int8: 0 never received, 1 received within its period, 2 late.
    status : numpy.ndarray
        (sensors, periods) int: the MCPS-DATA.confirm status of the period's frame, −1 none.
    tx_node, tx_period : numpy.ndarray
        Per PHY transmission: the node (sensor index; the sink is ``sensors``) and, for a
        sensor, the period of the frame (−1 otherwise).
    tx_start, tx_end : numpy.ndarray
        Start and end of each transmission (s).
    base_noise_dbm, noise_dbm : float
        ns-3's thermal noise over the channel, and the noise set on every receiver.
    duplicates : int
        Frames the sink received again (a retry after a lost acknowledgement).
    ns3_version : str
        Version of the ns-3 wheel.
    """

    delivered: np.ndarray
    status: np.ndarray
    tx_node: np.ndarray
    tx_period: np.ndarray
    tx_start: np.ndarray
    tx_end: np.ndarray
    base_noise_dbm: float
    noise_dbm: float
    duplicates: int
    ns3_version: str

    @property
    def traces(self) -> np.ndarray:
        """(sensors, periods) uint8: 1 iff received within its period."""
        return (self.delivered == 1).astype(np.uint8)


def overlapping(node: np.ndarray, start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """Whether each transmission overlaps in time with another node's.

    A node's own transmissions never overlap (its radio sends one frame at a time), so any
    overlap found is with another node. Touching intervals (end = start) do not overlap.
    """
    n = start.size
    if n == 0:
        return np.zeros(0, dtype=bool)
    order = np.argsort(start, kind="stable")
    s, e, who = start[order], end[order], node[order]
    prev_end = np.maximum.accumulate(e)
    before = np.zeros(n, dtype=bool)
    before[1:] = prev_end[:-1] > s[1:]
    after = np.zeros(n, dtype=bool)
    after[:-1] = s[1:] < e[:-1]
    hit = before | after
    # a node never overlaps itself; guard anyway against equal-node neighbours
    if n > 1:
        same_next = np.zeros(n, dtype=bool)
        same_next[:-1] = (who[1:] == who[:-1]) & (s[1:] < e[:-1])
        hit &= ~(same_next & ~before)
    out = np.empty(n, dtype=bool)
    out[order] = hit
    return out


def loss_causes(run: Ns3Run) -> dict[str, np.ndarray]:
    """Boolean (sensors, periods) masks: ``delivered`` and every cause of :data:`LOSS_CAUSES`."""
    sensors, periods = run.delivered.shape
    attempts = np.zeros((sensors, periods), dtype=np.int64)
    overlapped = np.zeros((sensors, periods), dtype=np.int64)
    hit = overlapping(run.tx_node, run.tx_start, run.tx_end)
    own = (run.tx_node < sensors) & (run.tx_period >= 0) & (run.tx_period < periods)
    idx = (run.tx_node[own], run.tx_period[own])
    np.add.at(attempts, idx, 1)
    np.add.at(overlapped, idx, hit[own].astype(np.int64))
    ok = run.delivered == 1
    late = run.delivered == 2
    left = ~ok & ~late
    access = left & (run.status == CHANNEL_ACCESS_FAILURE)
    left &= ~access
    collision = left & (overlapped > 0)
    left &= ~collision
    noise = left & (attempts > 0)
    return {"delivered": ok, "late": late, "channel_access": access, "collision": collision,
            "noise": noise, "not_sent": left & ~noise, "attempts": attempts,
            "overlapped": overlapped}


def _nakagami_grid(m: float) -> tuple[np.ndarray, np.ndarray]:
    """Nodes 10·log10(g) (dB) and weights of E[h(g)], g ~ Gamma(m, 1/m) (unit mean power).

    In u = ln g the density is m^m / Γ(m) · exp(m u − m e^u); trapezoid rule on [−40/m', 4].
    """
    lo = -40.0 / min(1.0, m) if m < 1 else -25.0
    u = np.linspace(lo, 4.0, 6001)
    log_f = m * math.log(m) - math.lgamma(m) + m * u - m * np.exp(u)
    w = np.exp(log_f) * (u[1] - u[0])
    w[0] *= 0.5
    w[-1] *= 0.5
    return 10.0 * u / math.log(10.0), w / w.sum()


def _attempt_success(link: LinkBudget, sinr_db: np.ndarray, nakagami_m: float | None) -> np.ndarray:
    """1 − PER of one attempt at median SINR ``sinr_db`` (averaged over Nakagami fading)."""
    if nakagami_m is None:
        return np.exp(link.radio.log_arrival(sinr_db, link.per_bytes))
    g_db, w = _nakagami_grid(nakagami_m)
    vals = np.exp(link.radio.log_arrival(sinr_db[:, None] + g_db[None, :], link.per_bytes))
    return vals @ w


def analytic_arrival(sensor: Ns3Sensor, nakagami_m: float | None = None) -> float:
    """The arrival probability kfcrit predicts for the conditions simulated for ``sensor``.

    Without fading and per-link shadowing this is the link budget's own value; with per-link
    shadowing it is p at the drawn value, p(s − X); with Nakagami-m fading (independent per
    transmission) each attempt succeeds with a = E_g[1 − PER(s + 10 log10 g)], the retries give
    1 − (1 − a)^{k+1}, and shadowing is averaged over N(0, σ²) (shared per period: average of
    p; per transmission: 1 − (1 − E[a])^{k+1}).
    """
    link = sensor.link
    s = link.sinr_db
    k1 = link.max_retries + 1
    sigma = link.sigma_db
    mode = sensor.shadowing_mode
    if mode == "per-link":
        s = s - float(sensor.shadowing_db[0])
    if nakagami_m is None:
        if mode == "per-link":
            return link.nominal_arrival(s)
        return link.arrival_value
    if mode in ("none", "per-link"):
        a = float(_attempt_success(link, np.array([s]), nakagami_m)[0])
        return 1.0 - (1.0 - a) ** k1
    z, wz = np.polynomial.hermite_e.hermegauss(80)
    wz = wz / wz.sum()
    a = _attempt_success(link, s + sigma * z, nakagami_m)
    if mode == "per-packet/attempt":
        return float(1.0 - (1.0 - float(a @ wz)) ** k1)
    return float((1.0 - (1.0 - a) ** k1) @ wz)


def _interval(k: int, n: int) -> list[float]:
    lo, hi = clopper_pearson(int(k), int(n), CONFIDENCE)
    return [float(lo), float(hi)]


def loss_correlation(traces: np.ndarray) -> list[list[float | None]]:
    """Pairwise Pearson correlation of the loss indicators 1 − trace (None where a sensor never,
    or always, lost its frame: the correlation is undefined)."""
    loss = 1.0 - np.asarray(traces, dtype=float)
    n = loss.shape[0]
    centred = loss - loss.mean(axis=1, keepdims=True)
    norms = np.sqrt((centred * centred).sum(axis=1))
    out: list[list[float | None]] = []
    for i in range(n):
        row: list[float | None] = []
        for j in range(n):
            if norms[i] == 0 or norms[j] == 0:
                row.append(None)
            else:
                row.append(float(centred[i] @ centred[j] / (norms[i] * norms[j])))
        out.append(row)
    return out


def cross_sensor_statistics(traces: np.ndarray) -> dict[str, Any]:
    """P(all lost) (with its 95 % Clopper–Pearson interval) against the product of the marginal
    loss ratios, their ratio, and the pairwise loss correlation."""
    arr = np.asarray(traces, dtype=np.uint8)
    n_sensors, periods = arr.shape
    lost_all = int((arr.sum(axis=0) == 0).sum())
    marginal_loss = 1.0 - arr.mean(axis=1)
    product = float(np.prod(marginal_loss))
    p_all = lost_all / periods
    corr = loss_correlation(arr)
    pairs = [c for i, row in enumerate(corr) for j, c in enumerate(row) if j > i and c is not None]
    return {"sensors": n_sensors, "periods": periods, "all_lost_periods": lost_all,
            "p_all_lost": p_all, "p_all_lost_ci95": _interval(lost_all, periods),
            "product_of_marginal_losses": product,
            "ratio": (p_all / product) if product > 0 else None,
            "independence_in_ci95": bool(_interval(lost_all, periods)[0] <= product
                                         <= _interval(lost_all, periods)[1]),
            "loss_correlation": corr,
            "max_abs_pairwise_correlation": max((abs(c) for c in pairs), default=None)}


def simulation_summary(plan: Ns3Plan, run: Ns3Run) -> dict[str, Any]:
    """The report of one run: per-sensor simulated vs analytic arrival, loss causes, attempts,
    and (two or more sensors) the cross-sensor statistics."""
    causes = loss_causes(run)
    traces = run.traces
    periods = plan.periods
    rows = []
    for i, sensor in enumerate(plan.sensors):
        k = int(traces[i].sum())
        ci = _interval(k, periods)
        analytic_file = float(sensor.link.arrival_value)
        analytic_sim = analytic_arrival(sensor, plan.nakagami_m)
        lost = {c: int(causes[c][i].sum()) for c in LOSS_CAUSES}
        attempts = int(causes["attempts"][i].sum())
        rows.append({
            "name": sensor.name, "distance_m": math.dist(sensor.position_m, plan.sink_position_m),
            "periods": periods, "received": k, "arrival_simulated": k / periods,
            "arrival_simulated_ci95": ci,
            "arrival_analytic": analytic_file,
            "arrival_analytic_simulated_conditions": analytic_sim,
            "analytic_in_ci95": bool(ci[0] <= analytic_sim <= ci[1]),
            "lost": lost, "lost_total": periods - k,
            "transmissions": attempts,
            "transmissions_overlapped": int(causes["overlapped"][i].sum()),
            "mean_transmissions_per_period": attempts / periods,
            "shadowing": sensor.shadowing_mode,
            "shadowing_drawn_db": (float(sensor.shadowing_db[0])
                                   if sensor.shadowing_mode == "per-link" else None)})
    out: dict[str, Any] = {
        "backend": "ns-3 lr-wpan", "ns3_version": run.ns3_version,
        "plan": plan.to_dict(), "ns3_noise_dbm": run.noise_dbm,
        "ns3_thermal_noise_dbm": run.base_noise_dbm, "duplicates": run.duplicates,
        "sensors": rows,
        "loss_causes": {
            "measured": "per lost period, the first of: late (received after its period), "
                        "channel_access (CSMA-CA CHANNEL_ACCESS_FAILURE confirm), collision "
                        "(a transmission of the frame overlapped another node's on the air, "
                        "from PhyTxBegin and the PPDU airtime), noise (transmitted, no overlap, "
                        "not received), not_sent (still queued at the end)"},
        "cross_sensor": cross_sensor_statistics(traces) if len(plan.sensors) > 1 else None,
        "notes": [
            "analytic: the link budget's arrival probability, which ignores "
            "contention; arrival_analytic_simulated_conditions adds the drawn per-link "
            "shadowing value and Nakagami fading when present",
            "CSMA-CA: ns-3 defaults (macMinBE 3, macMaxBE 5, macMaxCSMABackoffs 4); "
            "acknowledgements requested iff max_retries > 0",
        ]}
    return out


def trace_file_text(name: str, trace: np.ndarray, header: dict[str, Any]) -> str:
    """A ``binary`` trace file (:mod:`kfcrit.io.traceformats`): ``#`` comment lines with the
    provenance, then one 0 or 1 per line (period 0 first)."""
    lines = [f"# kfcrit link simulate (ns-3 lr-wpan): sensor {name}"]
    lines += [f"# {k}: {v}" for k, v in header.items()]
    body = "\n".join("1" if v else "0" for v in np.asarray(trace).tolist())
    return "\n".join(lines) + "\n" + body + "\n"


def analytic_arrival_curve(sensor: Ns3Sensor, distances_m: Sequence[float]) -> list[float]:
    r"""The link budget's arrival probability of ``sensor``'s link at each distance,

    .. math:: p(d) = 1 - \mathrm{PER}(s(d))^{k+1}

    (with the file's shadowing and fading models, :attr:`LinkBudget.arrival_value`), for the
    figure of the analytic against the simulated arrival by distance. Nakagami fading added on
    the command line is not in it (the markers at the simulated conditions include it)."""
    return [float(sensor.link.with_changes(distance_m=float(d)).arrival_value)
            for d in distances_m]


def simulated_distance_grid(summary: dict[str, Any], points: int = 60) -> list[float]:
    """Distances spanning the simulated sensors': from half the nearest to 1.5 × the farthest."""
    ds = [float(r["distance_m"]) for r in summary["sensors"]]
    lo, hi = max(min(ds) * 0.5, 0.1), max(ds) * 1.5
    return [float(v) for v in np.geomspace(lo, hi, points)]
