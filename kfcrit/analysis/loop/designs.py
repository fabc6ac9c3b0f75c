"""The designs a closed-loop record compares, and their curves (theory §12).

Helpers of :mod:`kfcrit.analysis.loop.section`: the links as the theory's
:class:`~kfcrit.theory.loop.links.LossLink`, the TCP-like optimal cost at one point, the stable
region's boundary of each design in the (γ̄, ν̄) plane, the TCP-like/UDP-like comparison rows,
the cost against each link's arrival probability and the seeded closed-loop Monte Carlo. Facts
only: the verdict words are the analysis's (:mod:`kfcrit.analysis.verdict`).
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import numpy as np
import sympy as sp

from kfcrit.analysis.loop.schema import (
    LoopCostCurve,
    LoopCostSummary,
    LoopCurve,
    LoopDesignRow,
    LoopSimulationSummary,
    LoopThreshold,
)
from kfcrit.records.contract import VerificationCheck
from kfcrit.theory.covariance.riccati import symmetrize
from kfcrit.theory.loop.curve import loop_critical_curve
from kfcrit.theory.loop.filter_mean import FilterMoments, filter_moments, rre_mean_monte_carlo
from kfcrit.theory.loop.fixed import fixed_loop
from kfcrit.theory.loop.links import LossLink
from kfcrit.theory.loop.stack import FixedDesign, fixed_design
from kfcrit.theory.loop.tcp import LoopCost, control_gain, control_mare, tcp_cost

SIM_SIZE = {"full": (1000, 1500), "quick": (300, 600)}
"""Closed-loop Monte Carlo (paths, steps) of ``kfcrit analyze`` and of ``--quick``."""
FILTER_MC = {"full": (1000, 3000), "quick": (300, 1000), "curve": (200, 600)}
"""Monte Carlo size of lim E[P_{t|t}] (n > 1) at the operating point and on the cost curves."""
MC_Z = 3.0
"""Standard errors a Monte Carlo cost may differ from the theory's before the check fails."""


@dataclass(frozen=True)
class LoopPoint:
    """What the designs read of a loop at its operating point: the design judged
    (``tcp-optimal`` or ``fixed``), the sensing γ̄ and actuation ν̄, the two thresholds, the
    judged design's cost and (a fixed design) its spectral radius."""

    design: str
    gamma: float
    nu: float
    sensing: LoopThreshold
    actuation: LoopThreshold
    cost: LoopCostSummary
    spectral_radius: float | None = None


@dataclass(frozen=True)
class TcpParts:
    """The TCP-like optimal loop at one (γ̄, ν̄): its cost, S of the control MARE (None when
    it has no fixed point), the gain L as lists of floats and lim E[P_{t|t}] (reusable at this
    γ̄)."""

    cost: LoopCost
    S: np.ndarray | None
    L: list[list[float]] | None
    moments: FilterMoments | None


def optional_float(x: Any) -> float | None:
    """A number as a Python float, None when missing or not finite (JSON has no infinity)."""
    if x is None:
        return None
    f = float(x)
    return f if math.isfinite(f) else None


def cost_summary(cost: LoopCost) -> LoopCostSummary:
    """A :class:`~kfcrit.theory.loop.tcp.LoopCost` as the record's summary (an infinite bound
    or value is ``None``; ``finite`` says which case it is)."""
    return LoopCostSummary(value=optional_float(cost.value), lower=optional_float(cost.lower),
                           upper=optional_float(cost.upper),
                           finite=None if cost.finite is None else bool(cost.finite),
                           method=str(cost.method), error=optional_float(cost.error),
                           reason=str(cost.reason))


def probability_fraction(p: Any) -> Fraction:
    """An arrival probability as an exact fraction (a float or sympy Float: its binary value)."""
    if isinstance(p, sp.Rational):
        return Fraction(int(p.p), int(p.q))
    return Fraction(float(p))


def loss_link(channel: Any) -> tuple[LossLink, str | None]:
    r"""The channel as a two-state link (i.i.d. when f + r = 1) and a note when approximated.

    .. math:: \pi_{received} = r / (f + r)
    """
    if channel.model == "gilbert-elliott":
        return LossLink(probability_fraction(channel.failure_rate),
                        probability_fraction(channel.recovery_rate)), None
    if channel.model == "link-budget" and not channel.iid:
        ge = channel.gilbert_elliott()
        return (LossLink(probability_fraction(ge.failure_rate),
                         probability_fraction(ge.recovery_rate)),
                "a link budget with time-correlated shadowing is judged by its two-state "
                "(Gilbert–Elliott) approximation")
    link = LossLink.bernoulli(probability_fraction(channel.arrival_probability))
    if channel.model == "trace":
        return link, ("a measured trace is taken as i.i.d. at its empirical arrival rate "
                      "(for information only)")
    return link, None


# ----------------------------------------------------------------------------- TCP-like

def tcp_cost_at(m: dict[str, np.ndarray], system: Any, gamma: float, nu: float,
                finite: bool | None, seed: int = 0, size: str = "full",
                moments: FilterMoments | None = None, quick: bool = False) -> TcpParts:
    r"""The TCP-like optimal cost at (γ̄, ν̄) with its bounds (theory §12).

    .. math::

        J = \operatorname{tr}(SQ) + \bar\nu\,\operatorname{tr}\bigl(L'(B'SB+U)L\,
            \lim E[P_{t|t}]\bigr)

    ``finite`` is the fact "γ̄ > γ_c and ν̄ > ν_c" (True/False/None); ``moments`` reuses
    lim E[P_{t|t}] at this γ̄.
    """
    A, B, Q, W, U = m["A"], m["B"], m["Q"], m["W"], m["U"]
    S = None if finite is False and nu <= 0 else control_mare(A, B, W, U, nu)
    L = None if S is None else control_gain(A, B, U, S)
    inf = math.inf
    if finite is False or S is None:
        why = ("γ̄ ≤ γ_c or ν̄ ≤ ν_c: the cost is infinite (theory §12)" if finite is False
               else "the control MARE has no fixed point at this ν̄")
        return TcpParts(LoopCost(inf, inf, inf, False if finite is False else None, "none",
                                 None, why), S, _list(L), moments)
    if moments is None:
        paths, steps = FILTER_MC["quick" if quick else size]
        M = symmetrize(L.T @ (B.T @ S @ B + U) @ L)
        moments = filter_moments(system, gamma, mc_paths=paths, mc_steps=steps, seed=seed,
                                 weight=M, value=size != "curve" or system.n > 1)
        if moments.mean_filt is None and moments.lower_filt is not None:
            # a curve point of a scalar plant: the exact atom propagation settles slowly near
            # γ_c, so the figure's points use the (seeded) Monte Carlo instead
            mp, mf, se = rre_mean_monte_carlo(system.a, system.c, system.q, system.r, gamma,
                                              paths=paths, steps=steps, burn=steps // 5,
                                              seed=seed, weight=M)
            moments = FilterMoments(gamma, mp, mf, f"monte-carlo ({paths} paths × {steps} "
                                    f"steps, seed {seed})", se, moments.lower_filt,
                                    moments.upper_filt)
    why = "γ̄ > γ_c and ν̄ > ν_c" if finite else "finiteness undecided"
    cost = tcp_cost(A, B, Q, W, U, S, nu, moments, finite, why)
    return TcpParts(cost, S, _list(L), moments)


def _list(M: np.ndarray | None) -> list[list[float]] | None:
    return None if M is None else np.asarray(M, dtype=float).tolist()


def tcp_rectangle(sens: LoopThreshold, act: LoopThreshold) -> LoopCurve:
    """The TCP-like stable region {γ̄ > γ_c, ν̄ > ν_c}: its corner and two edges (the upper
    ends of the thresholds' intervals when only bracketed)."""
    def corner(th: LoopThreshold) -> float | None:
        if th.value is not None and th.exact:
            return float(th.value)
        return float(th.interval[1]) if th.interval else None

    g, v = corner(sens), corner(act)
    points = [] if g is None or v is None else [[g, 1.0], [g, v], [1.0, v]]
    return LoopCurve(design="TCP-like optimal", kind="thresholds", points=points,
                     region="γ̄ > γ_c and ν̄ > ν_c (i.i.d. links, theory §12)"
                     if points else "no threshold: an unstable mode is unobservable or "
                                    "unreachable")


def fixed_curve(design: FixedDesign, label: str, quick: bool = False) -> LoopCurve:
    r"""The boundary of a fixed design's stable region in the (γ̄, ν̄) plane (i.i.d. links).

    .. math:: \nu^*(\bar\gamma) = \min\{\bar\nu : \rho(\textstyle\sum_m \pi_m \Phi_m \otimes
              \Phi_m) < 1\}
    """
    gammas = np.linspace(0.0, 1.0, 11 if quick else 21)
    nus = np.linspace(0.0, 1.0, 21 if quick else 41)
    cc = loop_critical_curve(design, gammas, nu_grid=nus, tol=1e-3)
    points = [[float(g), float(v)] for g, v in zip(cc.gammas, cc.nu_star) if v is not None]
    rho = [[float(r) if math.isfinite(r) else None for r in row] for row in cc.rho]
    return LoopCurve(design=label, kind="spectral-radius scan", points=points,
                     region="ρ(Σ π_m Φ_m ⊗ Φ_m) < 1 (i.i.d. links): above the curve where the "
                            "scan shows an up-set in ν̄",
                     gamma=[float(g) for g in cc.gammas],
                     nu_star=[None if v is None else float(v) for v in cc.nu_star],
                     monotone=[bool(b) for b in cc.monotone_at_grid],
                     nu_grid=[float(v) for v in cc.nu_grid], rho=rho)


def critical_nu(design: FixedDesign, gamma: float) -> tuple[float | None, list[float] | None]:
    """The least ν̄ (a bracket of width 10⁻⁴) that stabilises ``design`` at the sensing γ̄."""
    cc = loop_critical_curve(design, [gamma], nu_grid=np.linspace(0.0, 1.0, 41), tol=1e-4)
    br = cc.bracket[0]
    return optional_float(cc.nu_star[0]), (None if br is None else [float(br[0]), float(br[1])])


# ----------------------------------------------------------------------------- comparison

def _fixed_row(label: str, d: FixedDesign, s_link: LossLink, a_link: LossLink,
               gamma: float) -> LoopDesignRow:
    res = fixed_loop(d, s_link, a_link)
    star, br = critical_nu(d, gamma)
    return LoopDesignRow(design=label, acknowledged=bool(d.acked), on_loss=d.on_loss,
                         stability=f"ρ(Σ π_m Φ_m ⊗ Φ_m) < 1: {res.stability.status}",
                         spectral_radius=optional_float(res.stability.rho),
                         cost=cost_summary(res.cost), critical_nu=star,
                         critical_nu_interval=br)


def default_design(m: dict[str, np.ndarray], acked: bool, on_loss: str) -> FixedDesign:
    """Steady-state Kalman and LQR gains over the links (acknowledged or not)."""
    return fixed_design(m["A"], m["B"], m["C"], m["Q"], m["R"], m["W"], m["U"], acked=acked,
                        on_loss=on_loss)


def comparison_rows(spec: Any, m: dict[str, np.ndarray], point: LoopPoint,
                    design: FixedDesign | None, tcp_parts: TcpParts | None,
                    s_link: LossLink, a_link: LossLink, judged: Callable[..., FixedDesign],
                    *, tcp_finite: bool | None, quick: bool = False, seed: int = 0
                    ) -> tuple[list[LoopDesignRow], FixedDesign | None]:
    """TCP-like against UDP-like side by side at the operating point: the TCP-like optimal loop
    (``zero`` only), the Kalman + LQR design acknowledged and not, and the file's design."""
    lp = spec.loop
    g, v = point.gamma, point.nu
    rows: list[LoopDesignRow] = []
    if lp.on_loss == "zero":
        parts = tcp_parts or tcp_cost_at(m, spec.system, g, v, tcp_finite, seed=seed,
                                         quick=quick)
        act = point.actuation
        state = {True: "holds", False: "fails", None: "undecided"}[tcp_finite]
        rows.append(LoopDesignRow(design="TCP-like optimal", acknowledged=True, on_loss="zero",
                                  stability=f"γ̄ > γ_c and ν̄ > ν_c: {state}",
                                  spectral_radius=None, cost=cost_summary(parts.cost),
                                  critical_nu=act.value, critical_nu_interval=act.interval))
    udp = None
    for acked, label in ((True, "TCP-like (Kalman + LQR)"), (False, "UDP-like (Kalman + LQR)")):
        try:
            d = default_design(m, acked, lp.on_loss)
        except (ValueError, np.linalg.LinAlgError):
            continue
        if not acked:
            udp = d
        if design is not None and not lp.fixed and lp.acknowledged == acked:
            continue            # the judged design itself: its row follows
        rows.append(_fixed_row(label, d, s_link, a_link, g))
    if design is not None:
        rows.append(_fixed_row("this design", design, s_link, a_link, g))
    return rows, udp


# ----------------------------------------------------------------------------- cost curves

def _grid(quick: bool) -> list[float]:
    return [round(k / (10 if quick else 20), 6) for k in range(1, (10 if quick else 20) + 1)]


def _fixed_costs(d: FixedDesign, links: list[tuple[LossLink, LossLink]]) -> list[float | None]:
    out: list[float | None] = []
    for s, a in links:
        try:
            c = fixed_loop(d, s, a, certified=False).cost
        except (ValueError, np.linalg.LinAlgError):
            c = None
        out.append(float(c.value) if c is not None and c.finite is not False
                   and math.isfinite(c.value) else None)
    return out


def cost_curves(spec: Any, m: dict[str, np.ndarray], point: LoopPoint,
                design: FixedDesign | None, tcp_parts: TcpParts | None,
                udp: FixedDesign | None, *, quick: bool = False, seed: int = 0
                ) -> list[LoopCostCurve]:
    """The cost against the sensing γ̄ (ν̄ at its operating value) and against the actuation
    ν̄ (γ̄ at its operating value), for each design of the comparison."""
    g0, v0 = point.gamma, point.nu
    s_link, _ = loss_link(spec.channel)
    a_link, _ = loss_link(spec.loop.channel)
    grid = _grid(quick)
    curves = []
    for link, op in (("sensing", g0), ("actuation", v0)):
        pairs = [(LossLink.bernoulli(Fraction(p)), a_link) if link == "sensing"
                 else (s_link, LossLink.bernoulli(Fraction(p))) for p in grid]
        costs: dict[str, list[float | None]] = {}
        if spec.loop.on_loss == "zero":
            costs["TCP-like optimal"] = _tcp_series(spec, m, point, link, grid, tcp_parts,
                                                    seed)
        if design is not None:
            costs["this design"] = _fixed_costs(design, pairs)
        if udp is not None and not (design is not None and not spec.loop.fixed
                                    and not spec.loop.acknowledged):
            costs["UDP-like (Kalman + LQR)"] = _fixed_costs(udp, pairs)
        curves.append(LoopCostCurve(link=link, probability=grid, costs=costs,
                                    operating=float(op)))
    return curves


def _tcp_series(spec: Any, m: dict[str, np.ndarray], point: LoopPoint, link: str,
                grid: list[float], tcp_parts: TcpParts | None, seed: int
                ) -> list[float | None]:
    """TCP-like optimal cost along one link (finite where both thresholds' upper ends are
    exceeded, float comparison: a curve for the figure, not a decision)."""
    def upper(th: LoopThreshold) -> float | None:
        iv = th.interval
        return th.value if th.exact else (iv[1] if iv else None)

    gc, vc = upper(point.sensing), upper(point.actuation)
    g0, v0 = point.gamma, point.nu
    moments = tcp_parts.moments if link == "actuation" and tcp_parts is not None else None
    series: list[float | None] = []
    for p in grid:
        g, v = (p, v0) if link == "sensing" else (g0, p)
        if None in (gc, vc) or g <= gc or v <= vc:
            series.append(None)
            continue
        parts = tcp_cost_at(m, spec.system, g, v, True, seed=seed, size="curve",
                            moments=moments)
        if link == "actuation" and moments is None:
            moments = parts.moments
        c = parts.cost.value
        series.append(float(c) if math.isfinite(c) else None)
    return series


# ----------------------------------------------------------------------------- Monte Carlo

def loop_monte_carlo(point: LoopPoint, design: FixedDesign | None, m: dict[str, np.ndarray],
                     s_link: LossLink, a_link: LossLink, *, seed: int = 0, quick: bool = False,
                     L: Any = None) -> LoopSimulationSummary | None:
    r"""A seeded closed-loop Monte Carlo at the operating point, checking the cost.

    .. math:: |\hat J - J| \le 3\sqrt{\mathrm{se}(\hat J)^2 + \mathrm{err}(J)^2}

    An unstable loop is checked by the growth of the simulated second moment instead.
    """
    from kfcrit.sim.loop import simulate_fixed, simulate_tcp

    paths, steps = SIM_SIZE["quick" if quick else "full"]
    burn = steps // 5
    if point.design == "tcp-optimal":
        if L is None:
            return None
        sim = simulate_tcp(m["A"], m["B"], m["C"], m["W"], m["U"], m["Q"], m["R"], s_link,
                           a_link, paths=paths, steps=steps, burn_in=burn, seed=seed,
                           L=np.asarray(L, dtype=float))
        label = "TCP-like optimal (time-varying Kalman filter, L from the control MARE)"
    elif design is not None:
        sim = simulate_fixed(design, s_link, a_link, paths=paths, steps=steps, burn_in=burn,
                             seed=seed)
        label = "the judged fixed design"
    else:
        return None
    status, detail = _mc_check(point, sim)
    finite = bool(sim.finite)
    return LoopSimulationSummary(
        design=label, cost=optional_float(sim.cost) if finite else None,
        ci=[optional_float(sim.ci[0]), optional_float(sim.ci[1])] if finite else [None, None],
        std_error=optional_float(sim.std_error) if finite else None,
        confidence=float(sim.confidence), growth_rate=optional_float(sim.growth_rate),
        finite=finite, paths=int(sim.paths), steps=int(sim.steps), burn_in=int(sim.burn_in),
        seed=int(sim.seed), status=status, detail=detail)


def _near_boundary(point: LoopPoint) -> bool:
    """Just inside the stable region the stage cost is heavy-tailed and the sample mean is
    unreliable: a miss there is inconclusive, not a failure."""
    if point.design != "tcp-optimal":
        return (point.spectral_radius or 0.0) > 0.9
    gaps = [p - th.interval[1] for th, p in ((point.sensing, point.gamma),
                                             (point.actuation, point.nu)) if th.interval]
    return any(gap < 0.1 for gap in gaps)


def _mc_check(point: LoopPoint, sim: Any) -> tuple[str, str]:
    cost = point.cost
    J, err = cost.value, cost.error or 0.0
    if cost.finite is False:
        if not sim.finite or sim.growth_rate > 0:
            return "passed", (f"the cost is infinite and the simulated second moment grows "
                              f"(rate {sim.growth_rate:.3g} per step)")
        return "inconclusive", (f"the cost is infinite but the simulated second moment does "
                                f"not grow within {sim.steps} steps (rate "
                                f"{sim.growth_rate:.3g}): too close to the boundary to show")
    if J is None or not sim.finite:
        return "inconclusive", "no finite cost to compare"
    tol = MC_Z * math.hypot(sim.std_error, err)
    detail = (f"simulated J = {sim.cost:.6g} (± {sim.std_error:.2g}, {sim.paths} paths × "
              f"{sim.steps} steps) against J = {J:.6g}" + (f" (± {err:.2g})" if err else ""))
    if abs(sim.cost - J) <= tol:
        return "passed", detail + f": within {MC_Z:g} standard errors"
    if _near_boundary(point):
        return "inconclusive", detail + ": outside the band, but the operating point is near " \
                                        "the stability boundary (heavy-tailed cost)"
    return "failed", detail + f": outside {MC_Z:g} standard errors"


def loop_check(loop: Any) -> VerificationCheck | None:
    """The verification entry of the closed-loop Monte Carlo (None when not run); ``loop`` is
    the typed :class:`~kfcrit.analysis.loop.schema.LoopSection`."""
    sim = loop.simulation if loop is not None else None
    if not sim:
        return None
    passed = {"passed": True, "failed": False}.get(sim.status)
    return VerificationCheck("closed loop: simulated cost against the theory's J (theory §12)",
                             passed, sim.status, detail=sim.detail,
                             **({"reason": sim.detail} if sim.status == "inconclusive" else {}))
