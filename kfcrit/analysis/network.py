"""Sensor networks in the analysis (theory §9): the network section, its operating point, each
link's policy, the network's Lyapunov bound, its simulation and the burst condition."""
from __future__ import annotations

from dataclasses import replace
from typing import Any

import sympy as sp

from kfcrit.analysis import verdict as vd
from kfcrit.analysis.links import bursty_channel
from kfcrit.io.systemfile import SystemSpec
from kfcrit.records.bursty import StabilityFactsRecord, facts_record
from kfcrit.records.channel import NetworkChannel, NetworkChannelSensor, channel_record
from kfcrit.records.contract import CriticalValueRecord, OperatingPoint, UpperBoundRecord
from kfcrit.records.covariance import CovarianceBounds
from kfcrit.records.network import (
    DeadLinkBurst,
    ExactRegion,
    NetworkBurstCondition,
    NetworkSection,
    SensorCriticalValue,
    SensorLink,
    SensorMargin,
    SensorSurfaces,
    UniformMargin,
)
from kfcrit.records.simulation import NetworkMeanTrace, NetworkSimulation, Simulation
from kfcrit.theory.facts import StabilityFacts


def network_sections(spec: SystemSpec, opts: Any, warnings: list[str],
                     single: tuple[vd.Verdict, str] | None = None,
                     stacked: tuple[CriticalValueRecord | None, UpperBoundRecord | None]
                     | None = None, timings: dict[str, float] | None = None
                     ) -> tuple[NetworkSection, OperatingPoint]:
    """The ``network`` section (theory §9: per-sensor critical values, uniform margin, N − 1
    verdicts, bottleneck) and the operating point of a ``sensors:`` file.

    The top-level critical value and p_up of such a record are those of the stacked system —
    every sensor's packet arriving together, as over one joint link; the network's own values
    are in ``network``. ``single`` is the operating-point verdict of a one-sensor network,
    decided by the single-link theory: the network section states that same verdict.
    ``stacked`` holds the stacked system's ``critical_value`` and ``upper_bound`` sections,
    repeated under clearly named keys (``stacked_critical_value``, ``stacked_upper_bound``).

    Every verdict of the section (the network's, each N − 1 case's) is read from the theory's
    facts by :mod:`kfcrit.analysis.verdict`; with bursty links the burst condition joins in.
    The theory builds the section with those verdicts
    (:meth:`~kfcrit.theory.links.network.NetworkResult.record`); the burst condition, the
    links and the stacked sections join it here.
    """
    from kfcrit.theory.links.network import network_analysis

    result = network_analysis(spec.network, tol=opts.tolerance)
    if timings is not None:
        timings["network.seconds"] = round(result.seconds, 4)
    one_link = (bursty_channel(spec.network.sensors[0].channel)
                if single is not None and spec.network.size == 1 else None)
    notes = list(result.warnings)
    if one_link is not None:
        notes = one_bursty_link_warnings(notes, spec.network.names[0])
    warnings.extend(notes)
    if spec.network.size > 1:
        warnings.append("sensor network: the top-level critical value and p_up are those of the "
                        "stacked system (all sensors' packets arriving together); per-sensor "
                        "critical values, the uniform margin and N − 1 verdicts are in "
                        "`network`")
    verdict, basis = vd.verdict_of(result.facts)
    burst = network_burst_condition(spec.network)
    iid = all(s.channel is None or s.channel.iid for s in spec.network.sensors)
    if burst is not None:
        verdict, basis = vd.network_burst_verdict(verdict, basis, burst.holds,
                                                  burst.statement, burst.facts)
    if single is not None:
        verdict, basis = single
    holds = burst.holds if burst is not None else None
    dead_burst = burst.n_minus_1 or {} if burst is not None else {}
    burst_facts = {name: dead.facts for name, dead in dead_burst.items()}
    dead_verdicts = [vd.dead_link_verdict(row.n_minus_1, iid=iid, burst_holds=holds,
                                          burst_facts=burst_facts.get(row.name)).value
                     for row in result.sensors]
    section = replace(result.record(verdict.value, basis, dead_verdicts), warnings=notes)
    if burst is not None:
        section = replace(section, burst_condition=burst)
    if stacked is not None:
        section = replace(section, stacked_critical_value=stacked[0],
                          stacked_upper_bound=stacked[1],
                          stacked_meaning=("the top-level critical_value and upper_bound: the "
                                           "stacked system, every sensor's packet arriving "
                                           "together as over one link (not any one sensor's "
                                           "critical value)"))
    links = network_link_designs(spec.network, section, warnings, timings)
    section = replace(section, sensors=[
        replace(row, link=links.get(row.name, row.link), n_minus_1=replace(
            row.n_minus_1, burst_facts=burst_facts.get(row.name, row.n_minus_1.burst_facts)))
        for row in section.sensors], n_minus_1=[
        replace(row, burst_facts=burst_facts.get(row.name, row.burst_facts))
        for row in section.n_minus_1])
    if one_link is not None:
        section = one_bursty_link(section, spec.network, one_link, result.single_lower,
                                  verdict, basis)
    sensors = section.sensors
    bottleneck = section.bottleneck.name
    row = next((s for s in sensors if s.name == bottleneck), sensors[0] if sensors else None)
    op = OperatingPoint(
        arrival_probability=row.arrival_probability if row is not None else None,
        channel=NetworkChannel(model="network", sensors=[
            NetworkChannelSensor(name=s.name, channel=channel_record(s.channel))
            for s in spec.network.sensors]),
        iid=iid, margin=section.uniform_margin.value, margin_robust=None,
        bracket=section.uniform_margin.interval,
        arrival_probabilities={s.name: s.arrival_probability for s in sensors},
        bottleneck=bottleneck,
        note="network: the operating-point arrival probability is the bottleneck sensor's; the "
             "margin is the uniform margin δ (every link degraded by δ reaches the stability "
             "boundary)",
        verdict=verdict, basis=basis)
    return section, op


ONE_BURSTY_LINK = ("one sensor over a bursty link: its burst facts decide (theory §7, §10), as "
                   "for the same link without the network; the i.i.d. critical value, "
                   "surfaces and received-set certificate at the stationary arrival "
                   "probability do not apply to losses in bursts (null)")
"""``network.reason`` of a one-sensor network over a bursty link."""


def one_bursty_link_warnings(theory: list[str], name: str) -> list[str]:
    """The network theory's warnings for one sensor over a bursty link: its note that the
    link is analysed at its stationary arrival probability (i.i.d.) becomes what the section
    states instead."""
    from kfcrit.theory.links.network import bursty_iid_warning

    iid = bursty_iid_warning([name])
    return [w for w in theory if w != iid] + [
        f"sensor {name} has a bursty (Markov) link: the network section states the link's "
        "burst facts and its margin r − r_nec (theory §10), as the operating point does; the "
        "per-sensor i.i.d. quantities (critical value, surfaces, certificate) are null"]


def one_bursty_link(section: NetworkSection, network: Any, ge: Any, lower: Any,
                    verdict: vd.Verdict, basis: str) -> NetworkSection:
    r"""The network section of one sensor over a bursty link, stating what the record states
    for that link (theory §7, §10): its facts (the necessary burst condition, and the
    sufficient condition the link section proved, read from the operating point's
    ``verdict`` and ``basis``) and the operating point's margin

    .. math:: \delta = r - r_{nec}, \qquad r_{nec} = \max(1 - \rho(A)^{-2}, 0),

    as the sensor's margin, the uniform margin and the bottleneck's. The i.i.d. quantities of
    theory §9 at the stationary arrival probability (critical value, surfaces, received-set
    certificate) mean nothing for losses in bursts: null, ``reason`` says why. ``lower`` is the
    single-link lower bound max(1 − 1/ρ(A)², 0) of the network theory (value and exact form).
    """
    from kfcrit.theory.links.markov import (
        burst_necessary,
        recovery_margin,
        scalar_theorem_applies,
    )

    system = network.stacked_system()
    r_nec = lower.value if lower is not None else None
    margin = recovery_margin(ge.recovery_rate, r_nec, lower.expr if lower is not None else None)
    exact = scalar_theorem_applies(system)
    interval: list[float | None] = [margin, margin] if exact else [None, margin]
    nec = burst_necessary(system, ge.recovery_rate)
    nec_basis = "necessary burst condition: " + nec.statement
    if verdict is vd.Verdict.MEAN_UNSTABLE:
        facts = StabilityFacts(False, False, exact, basis, "")
    elif verdict is vd.Verdict.MEAN_STABLE:
        facts = StabilityFacts(True, True, exact, nec_basis, basis)
    else:
        facts = StabilityFacts(nec.holds, False, False, nec_basis, "")
    threshold = (f"r_nec = {r_nec:.6g}" if r_nec is not None else "r_nec")
    rule = ("r − r_nec: the bursty link's recovery rate against the necessary threshold r_nec = "
            "max(1 − 1/ρ(A)², 0) of the burst condition (1 − r)ρ(A)² < 1 (theory §10), the "
            "operating point's margin; positive iff the necessary burst condition holds")
    row = section.sensors[0]
    row = replace(row, critical_value=SensorCriticalValue(
        value=None, interval=None, exact=False, expression=None,
        basis=(f"bursty link: mean stability depends on the recovery rate r, not on the "
               f"arrival probability alone; the link's threshold is {threshold} (necessary "
               "burst condition, theory §10) and its margin r − r_nec")),
        surfaces=SensorSurfaces(necessary=None, sufficient=None),
        margin=SensorMargin(value=margin, interval=list(interval)))
    return replace(
        section, reason=ONE_BURSTY_LINK, sensors=[row],
        uniform_margin=UniformMargin(
            value=margin, interval=list(interval), unbounded=None, rule=rule,
            reason=("one sensor over a bursty link: δ = r − r_nec, the operating point's margin"
                    + ("" if exact else "; only the necessary end is exact (theory §10)"))),
        bottleneck=replace(section.bottleneck, name=row.name, margin=margin,
                           margin_interval=list(interval)),
        necessary_constraints=[replace(c, condition=(
            "prod over sensors not blind of (1 - r_i) * modulus2 < 1 (bursty link: the burst "
            "condition, c_i = 1 - r_i, theory §10)")) for c in section.necessary_constraints],
        exact_region=ExactRegion(
            holds=exact,
            reason=("scalar plant seen by the sensor: (1 − r)a² < 1 is necessary and "
                    "sufficient (theory §7)" if exact else
                    "bursty link on a vector plant: only the necessary burst condition "
                    "(1 − r)ρ(A)² < 1 is exact; sufficiency needs the coupled certificate of "
                    "the link section (theory §10)"),
            basis="scalar Gilbert–Elliott theorem (theory §7)" if exact else
                  "necessary burst condition (theory §10)"),
        certificate=None, facts=facts_record(facts))


def network_lower_bound(network: Any, all_lost: float | None = None,
                        p_low_exact: Any = None) -> CovarianceBounds:
    r"""The Lyapunov lower bound of a network's error covariance (theory §9).

    .. math:: \bar S = \pi(\emptyset)\, A \bar S A' + Q, \qquad
              \pi(\emptyset) = \prod_i (1 - p_i)

    (E[P_{t+1}] ⪰ π(∅) A E[P_t] A' + Q: with every packet lost the filter only predicts), so
    lim E[P_t] ⪰ S̄; V̄ of the network is not computed (``upper.computed`` False, so
    ``upper.exists`` False says nothing about existence). ``p = 1 − π(∅)`` is the probability
    that at least one sensor's packet arrives. ``all_lost`` is a measured π̂(∅) (time-aligned
    traces, theory §14) that replaces the independence product.

    S̄ exists iff π(∅)·ρ(A)² < 1, i.e. 1 − π(∅) > p_low = 1 − 1/ρ(A)²; with exact arrival
    probabilities and ``p_low_exact`` that is decided exactly (a product that rounds onto
    1/ρ(A)² in float64 finds no bounded S̄ there, yet S̄ exists, beyond float64).
    """
    import numpy as np

    product = all_lost is None
    lost = float(np.prod([1.0 - float(s.channel.arrival_probability)
                          for s in network.sensors if s.channel is not None])) if product \
        else float(all_lost)
    bounds = lyapunov_only_bounds(network.stacked_system(), lost, "not computed for a network", (
        "sensor network: S̄ solves S = Π(1 − p_i) A S A' + Q (all packets lost together); p is "
        "1 − Π(1 − p_i); V̄ is not computed" if product else
        "sensor network of time-aligned traces: S̄ solves S = π̂(∅) A S A' + Q with the "
        "measured probability π̂(∅) that every packet is lost; p is 1 − π̂(∅); V̄ is not "
        "computed"))
    if product and bounds.lower.exists is False:
        from kfcrit.theory.covariance.bounds import lower_exists_exactly

        at_least_one = 1 - sp.Mul(*[1 - s.channel.arrival_probability
                                    for s in network.sensors if s.channel is not None])
        bounds = replace(bounds, lower=lower_exists_exactly(bounds.lower, at_least_one,
                                                            p_low_exact))
    return bounds


def lyapunov_only_bounds(system: Any, lost: float, method: str, reason: str
                         ) -> CovarianceBounds:
    r"""Covariance bounds with the Lyapunov lower bound only (a network or a mesh, theory §9,
    §13): S̄ at ``p = 1 − lost``,

    .. math:: \bar S = \text{lost}\cdot A \bar S A' + Q,

    and V̄ not computed (``method`` says why)."""
    from kfcrit.theory.covariance import bounds

    S = bounds.lower_covariance(system.a, system.q, 1.0 - lost)
    lower = bounds.covariance_summary(S)
    upper = replace(bounds.covariance_summary(None), computed=False, method=method)
    return CovarianceBounds(p=1.0 - lost, lower=lower, upper=upper, ordered=None,
                            applicable=True, reason=reason)


def network_link_designs(network: Any, net: NetworkSection, warnings: list[str],
                         timings: dict[str, float] | None = None) -> dict[str, SensorLink]:
    """Each link-budget sensor's link against its own margin policy (``link`` of its row in
    ``network.sensors``), by sensor name: the arrival probability it must exceed is its critical
    value with the other links at their operating values (the upper end of its interval when
    only bracketed)."""
    from kfcrit.link.budgetsection import link_budget_record

    out: dict[str, SensorLink] = {}
    for row, sensor in zip(net.sensors, network.sensors):
        ch = sensor.channel
        if ch is None or ch.model != "link-budget":
            continue
        value, interval = row.critical_value.value, row.critical_value.interval
        bracket = (None, None) if value is not None or not interval else tuple(interval)
        try:
            lb = link_budget_record(ch, critical_value=value, robust_value=None,
                                    bracket=bracket, upper_bound=None)
        except (ValueError, ArithmeticError) as exc:
            warnings.append(f"link design of sensor {sensor.name} not computed: {exc}")
            continue
        out[row.name] = SensorLink(link=lb.link, link_margin_db=lb.link_margin_db,
                                   required_sinr_db=lb.required_sinr_db,
                                   max_distance_m=lb.max_distance_m,
                                   margin_policy=lb.margin_policy,
                                   design_check=lb.design_check, shadowing=lb.shadowing)
    return out


STACKED_MIN_PATHS = 64
"""Fewest paths of a network's Monte Carlo, however many rows the sensors stack."""


def stacked_paths(paths: int, n: int, m: int) -> int:
    """Paths of a network's Monte Carlo: the single-link budget for n states (sized for a step
    of cost c(max(n, 6), 6)), divided by how much more a step of the stacked filter costs.

    .. math::

        \\text{paths} = \\max\\Bigl(64,\\ \\Bigl\\lfloor \\text{paths}_n\\,
        \\frac{\\max(c(6, 6),\\, c(n, \\min(m, n)))}{c(n, m)} \\Bigr\\rfloor\\Bigr),\\qquad
        c(n, m) = n^3 + m^3 + n^2 m + n m^2

    (a step forms the m×m innovation covariance, factors it and applies the gain). Three
    scalar sensors keep the full budget; 100 sensors on a scalar plant run 64 paths, and the
    record states the paths used.
    """
    def cost(states: int, rows: int) -> int:
        return states ** 3 + rows ** 3 + states * states * rows + states * rows * rows

    factor = cost(n, m) / max(cost(6, 6), cost(n, min(m, n)))
    return max(min(paths, STACKED_MIN_PATHS), int(paths / factor)) if factor > 1 else paths


def network_simulation(spec: SystemSpec, opts: Any, op: OperatingPoint) -> Simulation:
    """Monte Carlo of the random Riccati equation with each sensor over its own link (the rows
    of C that arrived update the filter, theory §9): E[tr P_t] at the horizon, or — when the
    network is mean-unstable — the sample statistics labelled as not estimating a mean."""
    from kfcrit.sim.montecarlo import Budget, simulate

    net = spec.network
    budget = Budget.for_system(spec.system.n, opts.quick)
    paths = stacked_paths(budget.paths, spec.system.n, spec.system.m)
    sensors = [(list(range(sl.start, sl.stop)), s.channel)
               for sl, s in zip(net.row_slices(), net.sensors)]
    res = simulate(spec.system, paths, budget.steps, opts.seed, sensors=sensors,
                   track_lambda_max=False)
    mt = res.mean_trace_statistics()
    horizon = res.horizon_distribution()
    summary = NetworkSimulation(
        paths=paths, steps=budget.steps, seed=opts.seed, sensors=[s.name for s in net.sensors],
        mean_exists=None, diverged_paths=res.diverged_paths,
        horizon_quantiles=horizon.quantiles, horizon_levels=horizon.levels)
    mean = NetworkMeanTrace(mean=mt.mean[-1], lower=mt.lower[-1], upper=mt.upper[-1])
    if op.verdict is vd.Verdict.MEAN_UNSTABLE:
        summary = replace(summary, mean_exists=False, sample_mean_trace=mean.mean,
                          statement="E[tr P_t] diverges (the network is mean-unstable): the "
                                    "sample mean estimates nothing")
    else:
        summary = replace(summary, mean_exists=None if op.verdict is not vd.Verdict.MEAN_STABLE
                          else True, mean_trace=mean)
    return Simulation(seed=opts.seed, quick=opts.quick, network=summary,
                      reason="per-sensor arrivals, each sensor over its own link")


def network_burst_condition(network: Any) -> NetworkBurstCondition | None:
    r"""The burst facts of a network with bursty links (theory §9 and §10).

    *Necessary.* A run of k steps in which every sensor outside T loses its packets has
    probability of order Π_{j∉T} c_j^k, c_j = 1 − r_j for a Gilbert–Elliott link (the chance a
    lost link stays lost) and 1 − p_j for an i.i.d. one (independent links: the all-lost run
    of the joint chain decays like the product), while the modes unobservable through C_T grow
    like ρ_T^{2k}: E[P_t] is unbounded unless Π_{j∉T} c_j·ρ_T² < 1 for every T — the necessary
    surface of :func:`kfcrit.theory.links.network.necessary_constraints` at p_j' = 1 − c_j.

    *Sufficient for a scalar plant.* Any arrival from a sensor with C_j ≠ 0 resets the error:
    P⁺ ≤ 1/(C_j'R_j⁻¹C_j), so P_t ≤ a^{2τ}M + q Σ_{i<τ} a^{2i} with τ the time since the last
    useful arrival, and P(τ ≥ k) ≤ Π_j c_j^{k−1} over the seeing sensors. Hence E[P_t] is
    bounded iff Π_{j seeing} c_j·a² < 1 — exactly the necessary constraint with T the blind
    sensors: the burst condition decides both ways (``facts.exact_region``).

    ``n_minus_1`` gives the same facts with each link dead (c_i = 1). None when every link is
    memoryless.
    """
    import numpy as np
    import sympy as sp

    from kfcrit.theory.links.network import necessary_constraints, necessary_holds

    chains = [bursty_channel(s.channel) for s in network.sensors]
    if all(c is None for c in chains):
        return None
    q_exact = [c.recovery_rate if c is not None else
               (s.channel.arrival_probability if s.channel is not None else None)
               for s, c in zip(network.sensors, chains)]
    q = np.array([float(v) if v is not None else 0.0 for v in q_exact])
    cons = necessary_constraints(network)
    scalar = network.n == 1

    def facts(holds: bool | None, what: str) -> StabilityFactsRecord:
        nec = (f"burst condition {what}: Π_(j∉T) c_j·ρ_T² < 1 for every sensor set T "
               + ("holds" if holds else "fails: loss bursts make E[P_t] diverge"
                  if holds is False else "undecided at float precision"))
        suff = ("scalar plant: any useful arrival resets the error, so E[P_t] is bounded iff the "
                "all-lost runs decay faster than a^(-2k), i.e. the burst condition (theory §10)"
                if scalar and holds is True else "")
        return facts_record(StabilityFacts(holds, bool(scalar and holds is True), scalar, nec,
                                           suff))

    holds = necessary_holds(cons, q, q_exact)
    dead: dict[str, DeadLinkBurst] = {}
    for i, s in enumerate(network.sensors):
        qd, qde = q.copy(), list(q_exact)
        qd[i], qde[i] = 0.0, sp.Integer(0)
        hd = necessary_holds(cons, qd, qde)
        dead[s.name] = DeadLinkBurst(holds=_bool(hd), facts=facts(hd, f"with {s.name} dead"))
    names = ", ".join(s.name for s, c in zip(network.sensors, chains) if c is not None)
    statement = (f"burst condition for the bursty links ({names}): Π_(j∉T) c_j·ρ_T² < 1 for "
                 "every sensor set T, c_j = 1 − r_j (Gilbert–Elliott) or 1 − p_j (i.i.d.) — "
                 + ("holds" if holds else "fails: loss bursts make E[P_t] diverge"
                    if holds is False else "undecided at float precision"))
    return NetworkBurstCondition(
        holds=_bool(holds), statement=statement,
        continuation={s.name: 1 - float(v) for s, v in zip(network.sensors, q)},
        facts=facts(holds, "at the operating point"), n_minus_1=dead)


def _bool(value: Any) -> bool | None:
    """A decided fact as a bool (None stays undecided)."""
    return None if value is None else bool(value)
