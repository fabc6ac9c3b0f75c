"""The mesh in the analysis (theory §13): the ``mesh`` section, the operating point, the
covariance lower bound, the simulation and the per-hop link-policy reasons of a mesh file.

Raw forwarding (store-and-forward of measurements) is the operating point: its verdict is read
from the theory's :class:`~kfcrit.theory.mesh.stability.LawStability` facts by
:func:`kfcrit.analysis.verdict.verdict_of`. Estimate relaying (Gupta et al. 2009: p_cut·ρ(A)² < 1)
and smart sensors (critical value 1 − 1/ρ(A)²) are compared beside it, and the record says which
mode the design needs.
"""
from __future__ import annotations

import math
from fractions import Fraction
from typing import Any

import sympy as sp

from kfcrit.analysis import verdict as vd
from kfcrit.analysis.mesh.section import (
    MeshAllLost,
    MeshConstraint,
    MeshCutRow,
    MeshFacts,
    MeshFailure,
    MeshHopLinkRow,
    MeshHopRow,
    MeshLaw,
    MeshLawCell,
    MeshMode,
    MeshNodeRow,
    MeshRelaying,
    MeshRouteRow,
    MeshSection,
    MeshSimulation,
    MeshSmart,
    MeshSmartRow,
)
from kfcrit.analysis.network import lyapunov_only_bounds
from kfcrit.records.channel import MeshChannel
from kfcrit.records.contract import OperatingPoint, VerificationCheck
from kfcrit.records.covariance import CovarianceBounds
from kfcrit.records.simulation import NetworkMeanTrace, NetworkSimulation, Simulation
from kfcrit.theory.facts import StabilityFacts

RAW = "raw measurements (store-and-forward)"
RELAYING = "estimate relaying (Gupta et al. 2009)"
SMART = "smart sensors (each sends its own estimate)"
LAW_CELLS_SHOWN = 8


def _text(x: Any) -> str | None:
    """An exact value as text (None for a missing or float value)."""
    if x is None or isinstance(x, float):
        return None
    if isinstance(x, Fraction):
        x = sp.Rational(x.numerator, x.denominator)
    return sp.sstr(x)


# ---------------------------------------------------------------------------------------------
# rows
# ---------------------------------------------------------------------------------------------

def _hop_link(link: Any) -> MeshHopLinkRow | None:
    ch = getattr(link, "channel", None)
    if ch is None or getattr(ch, "model", None) != "link-budget":
        return None
    return MeshHopLinkRow(radio=str(ch.radio.name), distance_m=float(ch.distance_m),
                          sinr_db=float(ch.sinr_db), attempt_per=1.0 - float(ch.arrival_value),
                          tx_power_dbm=float(ch.tx_power_dbm))


def hop_rows(mfile: Any, analysis: Any) -> list[MeshHopRow]:
    """One row per hop: q_h, k_h, s_h = 1 − (1 − q_h)^{k_h+1}, σ*_h and the headroom."""
    out = []
    for h, head, link in zip(mfile.mesh.hops, analysis.hops, mfile.links):
        exact = h.period_success_exact()
        out.append(MeshHopRow(
            name=h.name, source=h.source, target=h.target, attempt_success=h.q,
            attempt_success_expression=_text(h.q_exact), retries=h.retries,
            period_success=h.period_success(), period_success_expression=_text(exact),
            origin=link.source, critical=head.critical,
            critical_attempt_success=head.critical_q, headroom=head.headroom,
            link=_hop_link(link), distance_m=link.distance_m))
    return out


def route_rows(mesh: Any) -> list[MeshRouteRow]:
    """One row per route: hops, each hop's success (per period; per attempt under a slot
    budget, where the slot DP decides) and the route's delivery probability."""
    from kfcrit.theory.mesh.law import route_arrival

    out = []
    for r in mesh.routes:
        idx = mesh.route_hops(r)
        value = route_arrival(mesh, r)
        slots = mesh.slots_per_period is not None
        out.append(MeshRouteRow(
            sensor=r.sensor, nodes=list(r.nodes), hops=[mesh.hops[k].name for k in idx],
            hop_success=[mesh.hops[k].q if slots else mesh.hops[k].period_success()
                         for k in idx],
            arrival_probability=float(value),
            arrival_expression=_text(value),
            origin=r.origin))
    return out


def _constraint(c: Any) -> MeshConstraint:
    return MeshConstraint(within=list(c.unobservable), eigenvalue=str(c.eigenvalue),
                          modulus2=float(c.modulus2), probability=float(c.probability),
                          value=float(c.value), value_expression=_text(c.value_exact),
                          holds=c.holds)


def facts_row(law_stability: Any) -> MeshFacts:
    """The facts of a :class:`~kfcrit.theory.mesh.stability.LawStability` with evidence."""
    f, nec = law_stability.facts, law_stability.necessary
    return MeshFacts(
        necessary=f.necessary, sufficient=f.sufficient, exact_region=f.exact_region,
        necessary_basis=f.necessary_basis, sufficient_basis=f.sufficient_basis,
        decided=law_stability.exact, reason=law_stability.reason,
        binding=_constraint(nec.binding) if nec.binding is not None else None,
        constraints=[_constraint(c) for c in nec.constraints],
        certificate=law_stability.sufficient.reason,
        exact_region_reason=str(law_stability.exact_region_reason or ""))


def all_lost_row(analysis: Any) -> MeshAllLost:
    r"""π(∅) against Π(1 − a_i); ratio = π(∅)/Π(1 − a_i) (None when the product is 0)."""
    prod = analysis.product_of_losses
    return MeshAllLost(value=analysis.all_lost, expression=_text(analysis.all_lost_exact),
                       product_of_marginals=prod,
                       product_expression=_text(analysis.product_of_losses_exact),
                       ratio=analysis.all_lost / prod if prod > 0 else None)


def law_row(law: Any) -> MeshLaw:
    """The law's method and its most probable received sets."""
    cells = sorted(range(len(law.probabilities)), key=lambda k: -float(law.probabilities[k]))
    top = [MeshLawCell(list(law.members(k)), float(law.probabilities[k]))
           for k in cells[:LAW_CELLS_SHOWN]]
    return MeshLaw(method=law.method, exact=law.exact, cells=len(law.probabilities), largest=top)


# ---------------------------------------------------------------------------------------------
# forwarding modes
# ---------------------------------------------------------------------------------------------

def relaying_row(network: Any, mesh: Any) -> MeshRelaying:
    """Estimate relaying: per sensor p_cut·ρ(A)² against 1 (necessary and sufficient for one
    sensor; for several the network statement is sufficient only)."""
    from kfcrit.theory.mesh.relaying import estimate_relaying

    res = estimate_relaying(network, mesh)
    rows = [MeshCutRow(sensor=r.sensor, p_cut=r.cut.p_cut, p_cut_expression=_text(
        r.cut.p_cut_exact), cut_hops=list(r.cut.hops), source_side=list(r.cut.source_side),
        value=r.value, value_expression=_text(r.value_exact), detectable=r.detectable,
        holds=r.stable) for r in res.sensors]
    detecting = [r for r in rows if r.detectable] or rows
    best = min(detecting, key=lambda r: r.p_cut)
    verdict = vd.condition_verdict(res.network_stable, necessary=len(rows) == 1)
    return MeshRelaying(p_cut=best.p_cut, verdict=verdict, basis=res.basis,
                        rho2=float(res.rho2.rho2), sensors=rows)


def smart_summary(smart: MeshSmart) -> str:
    """The smart-sensor comparison as a result: the best detecting sensor's a_i against
    1 − 1/ρ(A)² (not the condition alone)."""
    if smart.critical_value is None:
        return smart.basis
    seen = [r for r in smart.sensors if r.detectable]
    if not seen:
        return f"no single sensor detects the plant (needed: a_i > {smart.critical_value:.6g})"
    best = max(seen, key=lambda r: r.arrival_probability)
    rel = ">" if best.above else "≤"
    return (f"best a_i = {best.arrival_probability:.6g} ({best.sensor}) {rel} 1 − 1/ρ(A)² = "
            f"{smart.critical_value:.6g}")


def smart_row(network: Any, analysis: Any, relaying: MeshRelaying) -> MeshSmart:
    r"""Smart sensors: sensor i's estimate arrives with its arrival probability a_i; one
    detecting sensor is mean-stable iff a_i > 1 − 1/ρ(A)² (theory §13). With several:
    sufficient if some detecting sensor's a_i exceeds it; necessary P(all lost)·ρ(A)² < 1
    (nothing arrives: the gateway only predicts).

    .. math:: p_s = 1 - 1/\rho(A)^2
    """
    from kfcrit.theory.mesh.relaying import smart_sensor_critical_value

    smart = smart_sensor_critical_value(network.stacked_system())
    detect = {r.sensor: r.detectable for r in relaying.sensors}
    p_s = smart.exact if smart.exact is not None else smart.value
    rows = []
    for m in analysis.marginals:
        a = m.exact if m.exact is not None else m.value
        above = vd.exceeds(a, p_s) if p_s is not None else None
        rows.append(MeshSmartRow(m.sensor, m.value, detect.get(m.sensor, False), above))
    if p_s is None:
        return MeshSmart(None, None, vd.Verdict.MEAN_UNSTABLE, smart.reason, rows)
    good = any(r.detectable and r.above for r in rows)
    lost = analysis.all_lost_exact if analysis.all_lost_exact is not None else analysis.all_lost
    nothing = vd.exceeds(1 - p_s, lost) if lost != 0 else True
    if len(rows) == 1:
        ok = rows[0].detectable and bool(rows[0].above)
        facts = StabilityFacts(ok, ok, True, f"a > 1 − 1/ρ(A)² = {float(p_s):.6g} "
                               "(smart sensor, theory §13)", "")
    else:
        facts = StabilityFacts(nothing, good, False,
                               "P(all lost)·ρ(A)² < 1 (with no estimate the gateway predicts)",
                               "a detecting sensor's estimate arrives with a_i > 1 − 1/ρ(A)²"
                               if good else "")
    verdict, basis = vd.verdict_of(facts)
    return MeshSmart(float(smart.value), _text(smart.exact), verdict, basis, rows)


def recommendation(raw: vd.Verdict, relaying: vd.Verdict, smart: vd.Verdict,
                   bottleneck: str | None) -> str:
    """Which forwarding mode the design needs, in one sentence."""
    stable = vd.Verdict.MEAN_STABLE
    if raw is stable:
        return ("raw forwarding is mean-stable: forwarding measurements suffices (estimate "
                "relaying and smart sensors only add margin)")
    head = f"raw forwarding is {raw.value}"
    if relaying is stable:
        return f"{head}; estimate relaying is mean-stable: relay estimates, not measurements"
    if smart is stable:
        return (f"{head}; smart sensors are mean-stable: run the filter on the sensors and send "
                "estimates")
    fix = f" (start with the bottleneck hop {bottleneck})" if bottleneck else ""
    return f"{head}, and no other forwarding mode is proven mean-stable: improve the hops{fix}"


# ---------------------------------------------------------------------------------------------
# simulation
# ---------------------------------------------------------------------------------------------

def theory_tail_exponent(facts: MeshFacts) -> float | None:
    r"""α = min over constraints of log(1/P(S ⊆ T))/log ρ_T² (None without a growing mode)."""
    vals = [math.log(1.0 / c.probability) / math.log(c.modulus2) for c in facts.constraints
            if c.modulus2 > 1 and 0 < c.probability < 1]
    zero = any(c.modulus2 > 1 and c.probability >= 1 for c in facts.constraints)
    return 0.0 if zero else (min(vals) if vals else None)


def simulation_row(mfile: Any, opts: Any, verdict: vd.Verdict, facts: MeshFacts,
                   all_lost: float) -> MeshSimulation:
    """Monte Carlo over the hop outcomes (:func:`kfcrit.sim.meshsim.simulate_mesh`) and its
    agreement with the verdict: the Hill tail exponent α̂ of tr P_T (3σ band) above 1 for a
    mean-stable verdict, below 1 for a mean-unstable one."""
    from kfcrit.sim.meshsim import simulate_mesh

    paths, steps = (800, 100) if opts.quick else (4000, 200)
    run = simulate_mesh(mfile.network, mfile.mesh, paths, steps, opts.seed)
    band = run.tail_exponent_band
    consistent = None
    if band is not None and verdict is vd.Verdict.MEAN_STABLE:
        consistent = True if band[0] > 1 else False if band[1] < 1 else None
    elif band is not None and verdict is vd.Verdict.MEAN_UNSTABLE:
        consistent = True if band[1] < 1 else False if band[0] > 1 else None
    alpha = theory_tail_exponent(facts)
    a_text = "—" if run.tail_exponent is None else f"{run.tail_exponent:.3g}"
    statement = (f"tail exponent of tr P_T across paths: Hill estimate {a_text}"
                 + (f" (3σ band {band[0]:.3g}–{band[1]:.3g})" if band else "")
                 + (f", theory {alpha:.3g}" if alpha is not None else "")
                 + "; E[tr P] is finite only when it exceeds 1")
    stable = verdict is vd.Verdict.MEAN_STABLE
    return MeshSimulation(
        paths=run.paths, steps=run.steps, seed=run.seed,
        mean_trace=run.mean_trace if stable and math.isfinite(run.mean_trace) else None,
        mean_trace_band=list(run.mean_trace_band) if stable else None,
        tail_exponent=run.tail_exponent, tail_exponent_band=list(band) if band else None,
        tail_exponent_theory=alpha, empirical_all_lost=run.empirical_all_lost,
        all_lost=all_lost, consistent=consistent, statement=statement)


def record_simulation(sim: MeshSimulation, opts: Any, sensors: Any) -> Simulation:
    """The record's ``simulation`` section of a mesh (the same run, in the network form)."""
    if sim.mean_trace is None:
        summary = NetworkSimulation(paths=sim.paths, steps=sim.steps, seed=sim.seed,
                                    sensors=list(sensors), mean_exists=False,
                                    sample_mean_trace=None, statement=sim.statement)
    else:
        band = sim.mean_trace_band or [None, None]
        summary = NetworkSimulation(paths=sim.paths, steps=sim.steps, seed=sim.seed,
                                    sensors=list(sensors), mean_exists=True,
                                    mean_trace=NetworkMeanTrace(mean=sim.mean_trace,
                                                                lower=band[0], upper=band[1]),
                                    statement=sim.statement)
    return Simulation(seed=opts.seed, quick=opts.quick, network=summary,
                      reason="mesh: received sets drawn from the hop outcomes (theory §13)",
                      checks=[simulation_check(sim)])


def simulation_check(sim: MeshSimulation) -> VerificationCheck:
    """The verification entry of the mesh Monte Carlo (inconclusive when the band holds 1)."""
    status = {True: "passed", False: "failed", None: "inconclusive"}[sim.consistent]
    return VerificationCheck("mesh Monte Carlo: tail exponent of tr P on the verdict's side of 1",
                             sim.consistent, status, detail=sim.statement)


# ---------------------------------------------------------------------------------------------
# the section and its hooks
# ---------------------------------------------------------------------------------------------

def failure_rows(analysis: Any) -> list[MeshFailure]:
    """N − 1 of every relay and hop: the sensors lost and the verdict with it dead."""
    out = []
    for case in analysis.n_minus_1:
        verdict, basis = vd.verdict_of(case.facts.facts)
        out.append(MeshFailure(case.kind, case.element, list(case.lost_sensors), verdict,
                               basis))
    return out


def mesh_section(mfile: Any, opts: Any) -> MeshSection:
    """The typed ``mesh`` section (every verdict from :mod:`kfcrit.analysis.verdict`)."""
    from kfcrit.theory.mesh.stability import mesh_analysis

    net, mesh = mfile.network, mfile.mesh
    ma = mesh_analysis(net, mesh)
    facts = facts_row(ma.facts)
    verdict, basis = vd.verdict_of(ma.facts.facts)
    relaying = relaying_row(net, mesh)
    smart = smart_row(net, ma, relaying)
    heads = {h.hop: h for h in ma.hops}
    bottleneck = ma.bottleneck
    rows_modes = [
        MeshMode(RAW, verdict, facts.binding and
                 f"P(S ⊆ T)·ρ_T² = {facts.binding.value:.6g} for T = "
                 f"{{{', '.join(facts.binding.within)}}}" or basis),
        MeshMode(RELAYING, relaying.verdict, f"p_cut·ρ(A)² = "
                 f"{(relaying.p_cut or 0) * relaying.rho2:.6g} (p_cut = {relaying.p_cut:.6g})"),
        MeshMode(SMART, smart.verdict, smart_summary(smart))]
    sim = None
    if opts.simulate and opts.details:
        sim = simulation_row(mfile, opts, verdict, facts, ma.all_lost)
    return MeshSection(
        routing=mesh.routing, relay_mode=mesh.relay_mode, slots_per_period=mesh.slots_per_period,
        nodes=[MeshNodeRow(n.name, n.role, n.mode,
                           list(mfile.positions[n.name]) if n.name in mfile.positions else None)
               for n in mesh.nodes],
        hops=hop_rows(mfile, ma), routes=route_rows(mesh),
        arrival_probability={m.sensor: m.value for m in ma.marginals},
        arrival_expression={m.sensor: _text(m.exact) for m in ma.marginals
                            if m.exact is not None},
        all_lost=all_lost_row(ma), law=law_row(ma.law), facts=facts, verdict=verdict,
        basis=basis, bottleneck=bottleneck,
        bottleneck_headroom=heads[bottleneck].headroom if bottleneck in heads else None,
        relaying=relaying, smart_sensor=smart, modes=rows_modes,
        recommendation=recommendation(verdict, relaying.verdict, smart.verdict, bottleneck),
        failures=failure_rows(ma), simulation=sim)


def mesh_operating_point(section: MeshSection) -> OperatingPoint:
    """The operating point of a mesh file: the mesh under raw forwarding (its verdict is the
    mesh section's); ``arrival_probability`` is the weakest sensor's."""
    arr = section.arrival_probability
    weakest = min(arr, key=lambda k: arr[k])
    return OperatingPoint(
        arrival_probability=arr[weakest],
        channel=MeshChannel(model="mesh", relay_mode=section.relay_mode,
                            slots_per_period=section.slots_per_period, routing=section.routing),
        iid=True, margin=None, margin_robust=None, bracket=None,
        arrival_probabilities=dict(arr), bottleneck=section.bottleneck,
        note=f"mesh under raw forwarding: the operating-point arrival probability is the "
             f"weakest sensor's ({weakest}); the joint law of the received set, the forwarding "
             "modes and N − 1 are in the mesh section",
        verdict=section.verdict, basis=section.basis)


def mesh_lower_bound(mfile: Any, all_lost: float) -> CovarianceBounds:
    r"""Lyapunov lower bound of lim E[P_t] under the mesh's law (theory §13):

    .. math:: \bar S = \pi(\emptyset) A \bar S A' + Q

    (with every packet lost the filter only predicts)."""
    return lyapunov_only_bounds(
        mfile.network.stacked_system(), all_lost, "not computed for a mesh",
        "mesh: S̄ solves S = π(∅) A S A' + Q; p is 1 − π(∅), the probability that at least one "
        "packet arrives; V̄ is not computed")


def hop_link_reasons(mfile: Any, section: MeshSection) -> list[vd.Reason]:
    """The link policy of each critical link-budget hop: its SINR margin over the SINR that
    gives one attempt the critical success σ*_h, against the hop's ``margin_db``."""
    out = []
    for row, link in zip(section.hops, mfile.links):
        ch = link.channel
        if ch is None or not row.critical or row.critical_attempt_success is None:
            continue
        if getattr(ch, "margin_db", 0) <= 0 and getattr(ch, "max_outage", None) is None:
            continue
        need = ch.link_required_sinr_db(min(row.critical_attempt_success, 1 - 1e-15))
        if need is None:
            continue
        margin, policy = ch.sinr_db - need, ch.effective_margin_db
        out.append(vd.Reason(f"{vd.LINK_MARGIN_CHECK} (hop {row.name})",
                             vd.CheckStatus.PASS if margin >= policy else vd.CheckStatus.FAIL,
                             f"link margin {margin:.3g} dB {'≥' if margin >= policy else '<'} "
                             f"the policy's {policy:.3g} dB above the critical per-attempt "
                             f"success {row.critical_attempt_success:.6g}"))
    return out


def mesh_sections(spec: Any, opts: Any, sec: dict[str, Any], warnings: list[str]
                  ) -> list[vd.Reason]:
    """Fill ``mesh``, ``operating_point``, ``covariance_bounds`` and ``simulation`` of a mesh
    file's record; return the per-hop link-policy reasons for the review."""
    mfile = spec.mesh
    section = mesh_section(mfile, opts)
    sec["mesh"] = section
    sec["operating_point"] = mesh_operating_point(section)
    sec["covariance_bounds"] = mesh_lower_bound(mfile, section.all_lost.value)
    if section.simulation is not None:
        sec["simulation"] = record_simulation(section.simulation, opts, mfile.mesh.sensors)
    else:
        sec["simulation"] = Simulation(skipped=True, reason="simulation disabled")
    if len(mfile.mesh.sensors) > 1:
        warnings.append("mesh: the top-level critical value and p_up are those of the stacked "
                        "system (every packet arriving together); the mesh's joint law, facts "
                        "and forwarding modes are in the mesh section")
    return hop_link_reasons(mfile, section)
