"""Stability region of a sensor network in (p_1, …, p_N) (docs/theory.md §9 [beyond]).

N sensors, independent Bernoulli links with arrival probabilities p = (p_1..p_N). The region
𝓢 = {p : E[P_t] bounded} is an up-set (docs/theory.md §9: g_p is non-increasing in each p_i). It is
enclosed between two surfaces:

* **necessary** (closed form): for every sensor set T, ρ_T = the largest |λ| among the
  eigenvalues of A not observable through C_T (PBH); p ∈ 𝓢 requires
  Π_{i∉T}(1 − p_i)·ρ_T² < 1. Only the *maximal* unobservable sets matter (a larger T has fewer
  factors), and for an eigenvalue λ with eigenspace V they are the blind sensors (C_i V = 0)
  together with a hyperplane of the sensors' row spaces C_i V — enumerated from at most g − 1
  sensors (g = dim V), never from all 2^N subsets (:func:`necessary_constraints`).
* **sufficient** (numerical, certified): gains K_S and X ≻ 0 with
  X ≻ Σ_S π(S)(A + K_S C_S) X (A + K_S C_S)' (kernels in :mod:`kfcrit.theory.links.netkernels`),
  found by Newton on the threshold of the noise-free expected map along a path and checked in
  ball arithmetic.

Where they meet the region is exact. One case is proven here and in docs/theory.md §15.6
(Theorem E, with product-form gains; Lemma D reduces the test to single sensors):
**modal one-step observability**. Let the modes with |λ| ≥ 1 be
diagonalizable with eigenvectors w_1..w_k, and suppose that for every received set S the
vectors {C_S w_j : C_S w_j ≠ 0} are linearly independent. Then for every S a real gain K_S
with K_S C_S w_j = −λ_j w_j for the seen modes and K_S = 0 on a complement exists; the unstable
subspace U is invariant under every F_S = A + K_S C_S, F_S acts on U as diag(λ_j·[C_S w_j = 0])
in the w-basis, and K_S C_S maps everything into U, so on the quotient every F_S acts as A
(stable). With X diagonal in the w-basis, Σ_S π(S) F_S X F_S' has diagonal entries
|λ_j|² Π_{i∉B_j}(1 − p_i) x_j, B_j = {i : C_i w_j = 0}; the block-triangular jump system is
mean-square stable iff every |λ_j|² Π_{i∉B_j}(1 − p_i) < 1, and each of these is implied by a
necessary constraint (B_j is unobservable for λ_j). So 𝓢 is exactly the necessary region.
Scalar plants seen by several sensors and decoupled modes are such cases.

For one sensor the single-link theory (Sinopoli, Mo–Sinopoli: :mod:`kfcrit.theory.critical.section`,
:mod:`kfcrit.theory.upper.bracket`) gives the critical value, exactly where it is known.
"""
from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from fractions import Fraction
from typing import Any

import numpy as np
import sympy as sp

from kfcrit.errors import InputError
from kfcrit.io.typed import to_json
from kfcrit.model.exprparse import exact_text
from kfcrit.model.network import Network
from kfcrit.records.bursty import facts_record
from kfcrit.records.network import (
    ExactRegion,
    NecessaryConstraint,
    NecessarySurfacePoint,
    NetworkBottleneck,
    NetworkCertificate,
    NetworkMethod,
    NetworkNMinus1,
    NetworkSection,
    NetworkSensor,
    SensorCriticalValue,
    SensorMargin,
    SensorNMinus1,
    SensorSurfaces,
    SufficientSurface,
    UniformMargin,
)
from kfcrit.theory.critical.compare import compare_probability
from kfcrit.theory.critical.section import critical_value, structure_of
from kfcrit.theory.facts import StabilityFacts
from kfcrit.theory.links import netkernels as nk
from kfcrit.theory.links.netmargins import exact_margin, network_bottleneck, uniform_necessary_bracket
from kfcrit.theory.links.netnecessary import (  # noqa: F401 - Constraint, RANK_TOL re-exported
    RANK_TOL,
    Constraint,
    factor_sign,
    modal_one_step,
    necessary_along,
    necessary_constraints,
    necessary_coordinate,
    necessary_holds,
)
from kfcrit.theory.links.netsearch import Boundary, SeqContext, modal_gains
from kfcrit.theory.upper.bracket import upper_bound

CERT_STEPS = (0.5, 1.0, 10.0, 100.0, 1e3, 1e4, 1e5, 1e6)
"""Certificates are tried at the Newton root + step·tol for these steps."""
CERT_MAX_STATES = 24
"""Where the region is exact (modal one-step observability), numerical certificates are only
sought up to this many states (N operators of size n(n+1)/2 squared); beyond, the exact-region
proof decides alone."""
BALL_BRACKET_BUDGET = 200000
"""Most (constraints × sensors) whose uniform-margin crossing is enclosed in ball arithmetic;
beyond, the float bisection's crossing is reported."""


def _owner(network: Network) -> np.ndarray:
    return np.concatenate([np.full(s.m, i) for i, s in enumerate(network.sensors)])


# ---- boundaries along paths

@dataclass
class _Context:
    network: Network
    plant: nk.Plant
    col: nk.Collection
    tol: float
    ball: bool
    stats: dict[str, Any] = field(default_factory=lambda: {"newton": 0, "bisection": 0,
                                                          "certificates": 0})

    def certify(self, p: np.ndarray, X: np.ndarray, gains: np.ndarray | None = None):
        self.stats["certificates"] += 1
        st = self.network.stacked_system()
        return nk.certify_at(self.plant, st.A, st.C, self.col, p, X, gains, ball=self.ball)

    def try_at(self, p: np.ndarray, X0: np.ndarray | None = None):
        # a short power iteration suffices: its X only seeds the gains, and the certificate
        # (Stein solve, policy iteration, ball check) is decided independently
        r, X = nk.network_cone_radius(self.plant, self.col, p, X0, iterations=60, eps=1e-10)
        if not (np.isfinite(r) and r < 1.0):
            return None, X
        chk, Xc, _ = self.certify(p, X)
        return (chk if chk is not None and chk.ok else None), X

    def coordinate_boundary(self, i: int, p: np.ndarray, s_nec: float | None) -> Boundary:
        """Certified crossing along p_i = s ∈ [0, 1], the others at p."""
        return _boundary(self, coordinate_path(p, i), 0.0, 1.0, s_nec)

    def path_boundary(self, path: nk.Path, lo: float, hi: float,
                      s_nec: float | None) -> Boundary:
        """Certified crossing along a general path on [lo, hi]."""
        return _boundary(self, path, lo, hi, s_nec)


def _boundary(ctx: _Context, path: nk.Path, lo: float, hi: float,
              s_nec: float | None) -> Boundary:
    """Certified crossing of the sufficient surface along ``path`` on [lo, hi]."""
    if s_nec is None:
        return Boundary(None, None, None, "the necessary surface is not crossed on the path")
    if s_nec <= lo:
        chk, _ = ctx.try_at(path(lo)[0])
        if chk is not None:
            return Boundary(lo, lo, chk.to_dict(), "certified at the start of the path")
    start = min(max(s_nec, lo), hi)
    for frac in (0.0, 0.05, 0.25, 0.5):
        # Newton from the necessary end first, then from points further into the path
        s0 = start + frac * (hi - start)
        _, X0 = nk.network_cone_radius(ctx.plant, ctx.col, path(s0)[0], iterations=80, eps=1e-10)
        ctx.stats["newton"] += 1
        th = nk.network_threshold_newton(ctx.plant, ctx.col, path, X0, s0)
        if not (th.converged and th.s >= s_nec - 1e-7 and th.s <= hi
                and np.linalg.eigvalsh(th.X).min() > 0):
            continue
        for step in CERT_STEPS:
            s = max(th.s + step * ctx.tol, s_nec)
            if s > hi:
                break
            chk, _, _ = ctx.certify(path(s)[0], th.X, th.gains)
            if chk is not None and chk.ok:
                return Boundary(s_nec, s, chk.to_dict(), "threshold Newton, certified")
    return _bisection(ctx, path, max(s_nec, lo), hi)


def _bisection(ctx: _Context, path: nk.Path, a: float, b: float) -> Boundary:
    """Fallback: bisection with a certificate attempt at every point (slow, robust)."""
    ctx.stats["bisection"] += 1
    chk, X = ctx.try_at(path(b)[0])
    if chk is None:
        return Boundary(a, None, None, "no certificate at the end of the path")
    best = (b, chk)
    lo = a
    while best[0] - lo > max(ctx.tol, 1e-7):
        mid = 0.5 * (lo + best[0])
        c, X = ctx.try_at(path(mid)[0], X)
        if c is not None:
            best = (mid, c)
        else:
            lo = mid
    return Boundary(a, best[0], best[1].to_dict(), "bisection with certificates")


def coordinate_path(p: np.ndarray, i: int) -> nk.Path:
    """p(s) = p with p_i = s, s ∈ [0, 1]."""
    d = np.zeros(p.size)
    d[i] = 1.0

    def path(s: float) -> tuple[np.ndarray, np.ndarray]:
        q = p.copy()
        q[i] = min(max(s, 0.0), 1.0)
        return q, d
    return path


def uniform_path(p: np.ndarray) -> nk.Path:
    """p(s) = clip(p + s·1, 0, 1), s ∈ [−1, 1] (s = −δ, δ the uniform degradation)."""
    def path(s: float) -> tuple[np.ndarray, np.ndarray]:
        raw = p + s
        return np.clip(raw, 0.0, 1.0), ((raw > 0) & (raw < 1)).astype(float)
    return path


# ---- the result

@dataclass(frozen=True)
class SensorResult:
    """One sensor's row of the network analysis."""

    name: str
    arrival_probability: float
    arrival_expression: str | None
    critical: dict[str, Any]
    surfaces: dict[str, Any]
    margin: dict[str, Any]
    n_minus_1: StabilityFacts
    n_minus_1_reason: str
    margin_exact: sp.Expr | None = None
    """p_i − p_i* exactly where both are exact (ranks the bottleneck; not in the record)."""

    def record(self, dead_verdict: str) -> NetworkSensor:
        """The row of ``network.sensors``, its N − 1 case judged ``dead_verdict`` (the
        verdict is read from :attr:`n_minus_1` by the analysis)."""
        crit, surf = self.critical, self.surfaces
        nec, suf = surf.get("necessary"), surf.get("sufficient")
        return NetworkSensor(
            name=self.name, arrival_probability=_real(self.arrival_probability),
            arrival_probability_expression=self.arrival_expression,
            critical_value=SensorCriticalValue(
                value=_real(crit["value"]), interval=_reals(crit["interval"]),
                exact=bool(crit["exact"]), expression=crit["expression"], basis=crit["basis"]),
            surfaces=SensorSurfaces(
                necessary=None if nec is None else NecessarySurfacePoint(
                    value=_real(nec["value"]), expression=nec["expression"]),
                sufficient=None if suf is None else SufficientSurface(
                    value=_real(suf["value"]), certificate=certificate_record(suf["certificate"]),
                    note=suf["note"])),
            margin=SensorMargin(value=_real(self.margin["value"]),
                                interval=_reals(self.margin["interval"])),
            n_minus_1=SensorNMinus1(verdict=dead_verdict, reason=self.n_minus_1_reason,
                                    facts=facts_record(self.n_minus_1)))

    def dead_record(self, dead_verdict: str) -> NetworkNMinus1:
        """The row of ``network.n_minus_1``: this sensor's link dead, judged ``dead_verdict``."""
        return NetworkNMinus1(name=self.name, verdict=dead_verdict, reason=self.n_minus_1_reason,
                              facts=facts_record(self.n_minus_1))

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "arrival_probability": self.arrival_probability,
                "arrival_probability_expression": self.arrival_expression,
                "critical_value": dict(self.critical), "surfaces": dict(self.surfaces),
                "margin": dict(self.margin), "n_minus_1": {"facts": self.n_minus_1.to_dict(),
                                                         "reason": self.n_minus_1_reason}}


@dataclass(frozen=True)
class NetworkResult:
    """The stability analysis of a sensor network at arrival probabilities p (a plain record).

    ``to_dict()`` keys: facts {necessary, sufficient, exact_region, ...}, reason, sensors
    [SensorResult], uniform_margin {value, interval, unbounded, basis}, n_minus_1 [{name,
    facts, reason}], bottleneck {name, margin, rule}, necessary_constraints [...], exact_region
    {holds, reason, basis}, certificate, method, claims [str], warnings [str], seconds. The
    verdicts that read these facts are given by :mod:`kfcrit.analysis.verdict` to
    :meth:`record`, which builds the record's ``network`` section.
    """

    facts: StabilityFacts
    reason: str
    sensors: tuple[SensorResult, ...]
    uniform_margin: dict[str, Any]
    bottleneck: dict[str, Any]
    constraints: tuple[NecessaryConstraint, ...]
    exact_region: dict[str, Any]
    certificate: dict[str, Any] | None
    method: dict[str, Any]
    claims: tuple[str, ...]
    warnings: tuple[str, ...] = ()
    seconds: float = 0.0
    single_lower: Any = None
    """One sensor: the single-link lower bound p_low = max(1 − 1/ρ(A)², 0) (a
    :class:`~kfcrit.theory.critical.values.Num`), the necessary recovery threshold r_nec of a
    bursty link (not in the record)."""

    def sensor(self, name: str) -> SensorResult:
        """The row of the named sensor."""
        for s in self.sensors:
            if s.name == name:
                return s
        raise KeyError(name)

    def record(self, verdict: str, basis: str, dead_verdicts: Sequence[str]) -> NetworkSection:
        """The ``network`` section of the record: judged ``verdict`` on ``basis``, the N − 1
        case of sensor k judged ``dead_verdicts[k]`` (the verdicts are read from the facts by
        :mod:`kfcrit.analysis.verdict`)."""
        um, bn, ex, me = self.uniform_margin, self.bottleneck, self.exact_region, self.method
        return NetworkSection(
            verdict=verdict, reason=self.reason, basis=basis,
            sensors=[s.record(v) for s, v in zip(self.sensors, dead_verdicts)],
            uniform_margin=UniformMargin(value=_real(um["value"]), interval=_reals(um["interval"]),
                                         unbounded=um["unbounded"], rule=um["rule"],
                                         reason=um["reason"]),
            n_minus_1=[s.dead_record(v) for s, v in zip(self.sensors, dead_verdicts)],
            bottleneck=bottleneck_record(bn),
            necessary_constraints=list(self.constraints),
            exact_region=ExactRegion(holds=bool(ex["holds"]), reason=ex["reason"],
                                     basis=ex["basis"]),
            certificate=certificate_record(self.certificate),
            method=NetworkMethod(received_sets=int(me["received_sets"]),
                                 all_received_sets=bool(me["all_received_sets"]),
                                 tolerance=_real(me["tolerance"]),
                                 ball_checked=bool(me["ball_checked"]),
                                 newton=int(me["newton"]), bisection=int(me["bisection"]),
                                 certificates=int(me["certificates"]),
                                 decided_by=me["decided_by"]),
            claims=list(self.claims), warnings=list(self.warnings),
            facts=facts_record(self.facts))

    def to_dict(self) -> dict[str, Any]:
        return {"facts": self.facts.to_dict(), "reason": self.reason,
                "sensors": [s.to_dict() for s in self.sensors],
                "uniform_margin": dict(self.uniform_margin),
                "n_minus_1": [{"name": s.name, "facts": s.n_minus_1.to_dict(),
                               "reason": s.n_minus_1_reason} for s in self.sensors],
                "bottleneck": dict(self.bottleneck),
                "necessary_constraints": [to_json(c) for c in self.constraints],
                "exact_region": dict(self.exact_region), "certificate": self.certificate,
                "method": dict(self.method), "claims": list(self.claims),
                "warnings": list(self.warnings), "seconds": round(self.seconds, 4)}


def _probabilities(network: Network, p: Sequence[Any] | None
                   ) -> tuple[np.ndarray, list[sp.Expr | None]]:
    """Float and exact arrival probabilities (from the sensors' channels when ``p`` is None)."""
    if p is None:
        p = network.arrival_probabilities()
        if any(v is None for v in p):
            missing = [s.name for s, v in zip(network.sensors, p) if v is None]
            raise InputError("is missing: every sensor of a network needs its own link (e.g. "
                             "channel: {model: bernoulli, arrival_probability: 0.9})",
                             field=f"sensors.{missing[0]}.channel")
    p = list(p)
    if len(p) != network.size:
        raise InputError(f"must have {network.size} entries (one per sensor), got {len(p)}",
                         field="p")
    exact: list[sp.Expr | None] = []
    flt = np.zeros(len(p))
    for i, v in enumerate(p):
        if isinstance(v, bool):
            raise InputError("must be a number", field=f"p[{i}]")
        if isinstance(v, sp.Basic):
            e = v
        elif isinstance(v, (int, np.integer)):
            e = sp.Integer(int(v))
        elif isinstance(v, Fraction):
            e = sp.Rational(v.numerator, v.denominator)
        elif isinstance(v, (float, np.floating)):
            e = sp.Rational(float(v)) if math.isfinite(float(v)) else None
        else:
            raise InputError(f"must be a number, got {type(v).__name__}", field=f"p[{i}]")
        if e is None or not e.is_number:
            raise InputError("must be a finite number", field=f"p[{i}]")
        f = float(sp.N(e, 20)) if not e.is_Rational else float(e)
        if not 0.0 <= f <= 1.0:
            raise InputError(f"must be in [0, 1], got {f:g}", field=f"p[{i}]")
        exact.append(e)
        flt[i] = f
    return flt, exact


def _expr_text(e: sp.Expr | None) -> str | None:
    return exact_text(e) if e is not None else None


def bursty_iid_warning(names: Sequence[str]) -> str:
    """The warning that the sensors ``names`` have bursty links, analysed here at their
    stationary arrival probabilities (the i.i.d. theory of §9)."""
    return (f"sensors {', '.join(names)} have bursty (Markov) links: the analysis uses their "
            "stationary arrival probabilities (i.i.d. theory)")


SEQUENTIAL = "sequential"
"""``network.method.decided_by`` of the one-sensor maps (docs/theory.md §15)."""
RECEIVED_SETS = "received-sets"
"""``network.method.decided_by`` of the received-set certificate (docs/theory.md §9.3)."""
AUTO_EXACT_MAX = 8
"""``method="auto"`` enumerates every received set up to this many sensors (2^N is cheap
there and tighter); beyond it the one-sensor maps decide."""


def _choose_method(method: str, N: int) -> str:
    """``received-sets`` or ``sequential`` for ``method`` in {auto, received-sets, sequential}."""
    if method == "auto":
        return RECEIVED_SETS if N <= AUTO_EXACT_MAX else SEQUENTIAL
    if method in (RECEIVED_SETS, SEQUENTIAL):
        return method
    raise InputError(f"must be auto, {RECEIVED_SETS} or {SEQUENTIAL}, got {method!r}",
                     field="method")


def network_analysis(network: Network, p: Sequence[Any] | None = None, *,
                     tol: float = 1e-9, certify: bool = True,
                     method: str = "auto") -> NetworkResult:
    r"""Stability of a sensor network at arrival probabilities ``p`` (docs/theory.md §9).

    N sensors, sensor i over an independent Bernoulli(p_i) link. The necessary surface (§9.2)
    and the sufficient jump-linear certificate (§9.3) bracket the stability region, an up-set:

    .. math::

        p \in \mathcal S \Rightarrow \prod_{i \notin T} (1 - p_i)\, \rho_T^2 < 1
        \quad \text{for every sensor set } T .

    Parameters
    ----------
    network : Network
        The plant and its sensors (:class:`kfcrit.model.network.Network`).
    p : sequence, optional
        Arrival probabilities in sensor order (exact sympy numbers, ints, fractions or floats);
        default: the sensors' channels' arrival probabilities.
    tol : float
        Target width of the certified intervals.
    certify : bool
        Check certificates in ball arithmetic (True) or in float64 only (for benchmarks).
    method : str
        ``"received-sets"``: the jump-linear certificate over received sets (docs/theory.md
        §9.3, 2^N sets up to ``EXACT_MAX_SENSORS`` sensors); ``"sequential"``: one-sensor maps
        with product-form gains (docs/theory.md §15, polynomial in N); ``"auto"`` (default):
        received sets up to ``AUTO_EXACT_MAX`` sensors, else sequential. The record's
        ``method.decided_by`` names the one used.

    Returns
    -------
    NetworkResult
        Verdict at p, per-sensor critical values (least p_i keeping mean stability with the
        others at p), uniform margin, N−1 verdicts, bottleneck (see :class:`NetworkResult`).

    Raises
    ------
    kfcrit.errors.InputError
        ``tol`` outside (0, 1e-3], or an arrival probability that is not a number in [0, 1].

    References
    ----------
    Sinopoli et al. (2004), Theorem 3 and Lemma 1 (applied to each received set); Liu &
    Goldsmith (2004) for two sensors; docs/theory.md §9 (§9.2 necessary, §9.3 sufficient,
    §9.4 exact cases).

    Examples
    --------
    A scalar plant a = 2 seen by two sensors: stable iff (1 − p_1)(1 − p_2)·4 < 1 (§9.4).

    >>> from fractions import Fraction
    >>> from kfcrit import network_analysis
    >>> from kfcrit.model.network import Network, Sensor
    >>> net = Network(A=[[2]], Q=1, sensors=[Sensor("a", [[1]], 1), Sensor("b", [[1]], 1)])
    >>> res = network_analysis(net, p=[Fraction(3, 4), Fraction(3, 4)])
    >>> res.facts.necessary, res.facts.exact_region
    (True, True)
    >>> round(res.uniform_margin["value"], 9)       # (1/4 + δ)² · 4 = 1
    0.25
    >>> network_analysis(net, p=[Fraction(3, 4), Fraction(3, 4)], tol=1)
    Traceback (most recent call last):
        ...
    kfcrit.errors.InputError: tol: must be a number in (0, 1e-3], got 1
    """
    if not (isinstance(tol, (int, float)) and 0 < tol <= 1e-3):
        raise InputError(f"must be a number in (0, 1e-3], got {tol!r}", field="tol")
    t0 = time.perf_counter()
    pf, pe = _probabilities(network, p)
    N = network.size
    cons = necessary_constraints(network)
    exact_region, why_exact = modal_one_step(network)
    decided_by = _choose_method(method, N)
    st = network.stacked_system()
    if decided_by == SEQUENTIAL:
        ctx: _Context | SeqContext = SeqContext(network, pf, tol, certify,
                                                seed=modal_gains(network) if exact_region
                                                else None)
        col = nk.Collection(np.zeros((0, N), dtype=bool), True)
    else:
        plant = nk.Plant(st.a, st.c, _owner(network))
        col = nk.collection_for(pf, N)
        ctx = _Context(network, plant, col, tol, certify)
    claims = ["docs/theory.md §9 [beyond]: the necessary and sufficient surfaces, and the up-set "
              "property of the region, are stated in docs/theory.md §9 as claims to test"]
    if exact_region:
        claims.append("exact region by modal one-step observability: proof in "
                      "kfcrit.theory.links.network (beyond docs/theory.md §9, a claim until reviewed)")
    warnings: list[str] = []
    if decided_by == SEQUENTIAL:
        claims.append("docs/theory.md §15: the sufficient surface uses one-sensor maps with "
                      "product-form gains (polynomial in N; never less conservative than every "
                      "received set)")
    elif not col.complete:
        warnings.append(f"{N} sensors: the sufficient surface uses the {col.size} most likely "
                        "received sets, the rest counted as total loss (a valid, more "
                        "conservative sufficient condition)")
    bursty = [s.name for s in network.sensors if s.channel is not None and not s.channel.iid]
    if bursty and p is None:
        warnings.append(bursty_iid_warning(bursty))
    if not structure_of(st).controllable_Q:
        warnings.append("(A, Q^1/2) is not controllable: the necessary surface assumes "
                        "every unobserved unstable mode is excited by the noise")

    # ---- per sensor: coordinate paths
    rows = []
    for i in range(len(network.sensors)):
        rows.append(_sensor_row(ctx, cons, exact_region, i, pf, pe))

    # ---- uniform margin
    upath = uniform_path(pf)
    s_nec_u = necessary_along(cons, upath, -1.0, 1.0)
    if exact_region:
        bu = Boundary(s_nec_u, s_nec_u, None, "exact region (modal one-step observability)")
    else:
        bu = ctx.path_boundary(upath, -1.0, 1.0, s_nec_u)
    bracket = (s_nec_u, s_nec_u) if s_nec_u is not None else None
    if len(cons) * N <= BALL_BRACKET_BUDGET:
        try:
            bracket = uniform_necessary_bracket(cons, pe)
        except ArithmeticError:
            warnings.append("uniform margin: the necessary surface's crossing is not decided "
                            "in ball arithmetic; the float bisection's crossing is reported")
    margin = _uniform_margin(bu, bracket, exact_region)

    # ---- facts at p (the verdict is read from them in kfcrit.analysis.verdict)
    nec = necessary_holds(cons, pf, pe)
    cert = bu.check
    sufficient, suff_basis = False, "no sufficient certificate at p"
    if nec is False:
        bad = next(c for c in cons if factor_sign(c.factor(pf), c.factor_expr(pe)) != -1)
        dead = [network.names[i] for i in range(N) if i not in bad.blind]
        reason = (f"necessary constraint fails: eigenvalue {bad.eigenvalue} (|λ|² = "
                  f"{bad.mod2:.6g}) is unobservable without sensors {{{', '.join(dead)}}}, and "
                  f"Π(1 − p_i)·|λ|² = {bad.factor(pf):.6g} ≥ 1")
    elif exact_region and nec is True:
        reason = ("every necessary constraint holds and the region is exactly the necessary "
                  "region (modal one-step observability)")
        if network.n > CERT_MAX_STATES:
            warnings.append(f"n = {network.n} states > {CERT_MAX_STATES}: no numerical "
                            "certificate attempted (the verdict rests on the exact-region proof)")
        elif N <= nk.EXACT_MAX_SENSORS or isinstance(ctx, SeqContext):
            chk, _ = ctx.try_at(pf)
            cert = chk.to_dict() if chk is not None else None
            if chk is not None:
                sufficient, suff_basis = True, "sufficient surface (checked certificate)"
            else:
                warnings.append("no numerical certificate found at the operating point "
                                "(the verdict rests on the exact-region proof)")
    elif bu.s_cert is not None and bu.s_cert <= 0.0:
        sufficient = True
        suff_basis = "sufficient surface (checked certificate)"
        reason = (f"certificate at clip(p − {-bu.s_cert:.3g}·1) ≤ p; the region is an up-set "
                  "(theory §9)")
    else:
        chk, _ = ctx.try_at(pf)
        if chk is not None:
            sufficient, cert = True, chk.to_dict()
            suff_basis, reason = "sufficient surface (checked certificate)", "certificate at p"
        elif nec is None:
            reason = "the necessary constraint is at equality to 1e-12"
        else:
            reason = "between the necessary and the sufficient surface"
    facts = StabilityFacts(
        necessary=nec, sufficient=sufficient, exact_region=exact_region,
        necessary_basis="necessary surface (closed form, theory §9)",
        sufficient_basis=(suff_basis if sufficient or not exact_region else
                          "necessary surface (closed form) + exact region (theory §15.6, "
                          "Theorem E)"))

    bottleneck = network_bottleneck(rows)
    result = NetworkResult(
        facts=facts, reason=reason, sensors=tuple(rows),
        uniform_margin=margin, bottleneck=bottleneck,
        constraints=tuple(constraint_record(network, c) for c in cons),
        exact_region={"holds": exact_region, "reason": why_exact,
                      "basis": "proof in kfcrit.theory.links.network (claim beyond docs/theory.md §9)"},
        certificate=cert,
        method={"received_sets": col.size, "all_received_sets": col.complete,
                "tolerance": tol, "ball_checked": certify, "decided_by": decided_by,
                **ctx.stats},
        claims=tuple(claims), warnings=tuple(warnings), seconds=time.perf_counter() - t0)
    if N == 1:
        result = _single_link_overlay(network, result, pf, pe, tol)
    return result


def _sensor_row(ctx: _Context, cons: Sequence[Constraint], exact_region: bool, i: int,
                pf: np.ndarray, pe: list[sp.Expr | None]) -> SensorResult:
    network = ctx.network
    name = network.names[i]
    possible, nval, nexpr = necessary_coordinate(cons, i, pf, pe)
    if not possible:
        crit = {"value": None, "interval": None, "exact": possible is False, "expression": None,
                "basis": "necessary surface: a constraint without this sensor fails, so no "
                         "p_i in [0, 1] gives mean stability" if possible is False else
                         "undecided: a necessary constraint without this sensor is at "
                         "equality to float precision"}
        surfaces = {"necessary": None, "sufficient": None}
        b = Boundary(None, None, None, "")
    else:
        if exact_region and not _searches_in_exact_region(ctx):
            b = Boundary(nval, nval, None, "exact region")
        else:
            b = ctx.coordinate_boundary(i, pf, nval)
        surfaces = {"necessary": {"value": nval, "expression": _expr_text(nexpr)},
                    "sufficient": ({"value": b.s_cert, "certificate": b.check, "note": b.note}
                                   if b.s_cert is not None else None)}
        if exact_region:
            crit = {"value": nval, "interval": [nval, nval], "exact": nexpr is not None,
                    "expression": _expr_text(nexpr),
                    "basis": "necessary surface, exact region (modal one-step observability)"}
        elif b.s_cert is not None:
            width = b.s_cert - nval
            crit = {"value": nval if width <= max(ctx.tol * 1e3, 1e-6) else None,
                    "interval": [nval, b.s_cert], "exact": False,
                    "expression": _expr_text(nexpr) if width <= 1e-6 else None,
                    "basis": ("necessary and sufficient surfaces meet (certified interval)"
                              if width <= 1e-6 else
                              "between the necessary and the sufficient surface")}
        else:
            crit = {"value": None, "interval": [nval, None], "exact": False, "expression": None,
                    "basis": "necessary surface only; no certificate up to p_i = 1"}
    margin = {"value": (pf[i] - crit["value"]) if crit["value"] is not None else None,
              "interval": ([pf[i] - crit["interval"][1] if crit["interval"][1] is not None
                            else None, pf[i] - crit["interval"][0]]
                           if crit["interval"] is not None else None)}
    margin_exact = exact_margin(pe[i], nexpr) if possible and exact_region else None
    if margin_exact is not None:
        # a float difference of two nearly equal values loses what the exact data decide
        m = float(sp.N(margin_exact, 30))
        margin = {"value": m, "interval": [m, m]}
    # N−1: this sensor's link dead, the others at p
    q = pf.copy()
    q[i] = 0.0
    qe = list(pe)
    qe[i] = sp.Integer(0)
    nec0 = necessary_holds(cons, q, qe)
    # only a checked certificate at p_i ≤ 0 proves stability with the link dead: the exact
    # region's boundary point is an infimum (the region is open), not a certificate
    suff0 = bool(b.s_cert is not None and b.s_cert <= 0.0 and b.check is not None)
    why = ("a necessary constraint fails with this link dead" if nec0 is False else
           "a necessary constraint is at equality with this link dead" if nec0 is None else
           "exact region: every necessary constraint holds" if exact_region else
           "certificate with this link dead" if suff0 else
           "between the surfaces with this link dead")
    dead = StabilityFacts(necessary=nec0, sufficient=suff0, exact_region=exact_region,
                          necessary_basis="necessary surface with this link dead",
                          sufficient_basis="certificate with this link dead" if suff0 else "")
    if network.size == 2 and not exact_region:
        dead, why = _lone_sensor_facts(ctx, 1 - i, pe, dead, why)
    return SensorResult(name, float(pf[i]), _expr_text(pe[i]), crit, surfaces, margin,
                        dead, why, margin_exact)



def _searches_in_exact_region(ctx: _Context | SeqContext) -> bool:
    """Whether the sufficient surface is searched on a sensor's coordinate where the region is
    exact: by the one-sensor maps (a certificate is cheap there), up to CERT_MAX_STATES."""
    return isinstance(ctx, SeqContext) and ctx.network.n <= CERT_MAX_STATES


def _lone_sensor_facts(ctx: _Context, j: int, pe: list[sp.Expr | None], dead: StabilityFacts,
                       why: str) -> tuple[StabilityFacts, str]:
    """N − 1 of a two-sensor network leaves sensor j alone: its single-link theory (exact p_c
    of Mo–Sinopoli where a theorem applies, else [block lower bound, certified p_up]) compared
    exactly with p_j (theory §3–§4, §9), combined with the network facts with the link dead
    (either necessary condition failing fails; either sufficient one suffices)."""
    network = ctx.network
    sub = network.received_system([j])
    klass, crit, pc_exact, _ = _single_link_critical(sub, ctx.tol)
    lone, _ = _single_link_facts(klass, crit, pe[j], pc_exact)
    nec = (False if False in (dead.necessary, lone.necessary) else
           None if None in (dead.necessary, lone.necessary) else True)
    suff = dead.sufficient or lone.sufficient
    name = network.names[j]
    what = (f"p_c = {crit['expression'] or crit['value']}" if crit.get("value") is not None else
            f"the bracket {crit['interval']}" if crit.get("interval") is not None else
            "(C, A) not detectable")
    basis = f"single-link theory of {name} alone ({what}) against p_{name}"
    facts = StabilityFacts(nec, suff, lone.exact_region and nec is not None,
                           basis if lone.necessary is False else dead.necessary_basis,
                           basis if lone.sufficient else dead.sufficient_basis)
    if nec is False:
        why = f"{name} alone: {basis}: p ≤ its critical value"
    elif lone.sufficient or (lone.exact_region and nec is True):
        why = f"{name} alone: {basis}: p above its critical value"
    return facts, why


def _uniform_margin(b: Boundary, bracket: tuple[float, float] | None,
                    exact_region: bool) -> dict[str, Any]:
    """δ with clip(p − δ·1) on the boundary; s = −δ on :func:`uniform_path`.

    ``bracket`` [a, b] encloses the necessary surface's crossing (ball arithmetic on the exact
    data, :func:`~kfcrit.theory.links.netmargins.uniform_necessary_bracket`), so δ ≤ −a; in the
    exact region δ ∈ [−b, −a]. Elsewhere the sufficient end −s_cert (certified) is the lower end.
    """
    rule = ("signed δ such that clip(p − δ·(1, …, 1), 0, 1) lies on the boundary: positive "
            "when stable, negative when every link must improve")
    if bracket is None:
        return {"value": None, "interval": None, "unbounded": "negative", "rule": rule,
                "reason": "a necessary constraint fails even with every link perfect (p = 1)"}
    a, b_nec = bracket
    if b_nec <= -1.0 and (exact_region or (b.s_cert is not None and b.s_cert <= -1.0)):
        return {"value": None, "interval": None, "unbounded": "positive", "rule": rule,
                "reason": "mean-stable with every link dead (ρ(A) < 1 on what matters)"}
    hi = -a + 0.0   # no −0.0
    if exact_region:
        lo: float | None = -b_nec
        value: float | None = -(0.5 * a + 0.5 * b_nec)
        value = min(max(value, lo), hi) + 0.0
    else:
        lo = -b.s_cert if b.s_cert is not None else None
        value = hi if (lo is not None and hi - lo <= 1e-6) else None
    return {"value": value, "interval": [lo, hi], "unbounded": None, "rule": rule,
            "reason": ("exact region (necessary surface enclosed in ball arithmetic)"
                       if exact_region else
                       "necessary end enclosed in ball arithmetic, sufficient end certified"
                       if lo is not None else "necessary end only")}


def constraint_record(network: Network, c: Constraint) -> NecessaryConstraint:
    r"""The record of one necessary constraint (theory §9.2):

    .. math:: \prod_{i \notin T} (1 - p_i)\, |\lambda|^2 < 1 .
    """
    return NecessaryConstraint(
        unobservable_without=[network.names[i] for i in range(network.size)
                              if i not in c.blind],
        blind_sensors=[network.names[i] for i in sorted(c.blind)],
        eigenvalue=str(c.eigenvalue), modulus2=_real(c.mod2),
        modulus2_expression=_expr_text(c.mod2_expr), decided=c.decided,
        condition="prod over sensors not blind of (1 - p_i) * modulus2 < 1")


def certificate_record(check: dict[str, Any] | None) -> NetworkCertificate | None:
    """The record of a received-set certificate (:meth:`netkernels.NetworkCheck.to_dict`)."""
    if check is None:
        return None
    return NetworkCertificate(
        ok=bool(check["ok"]), p=[_real(v) for v in check["p"]],
        received_sets=int(check["received_sets"]),
        all_received_sets=bool(check["all_received_sets"]),
        min_eig_x_lower=_real(check["min_eig_x_lower"]),
        margin_lower=_real(check["margin_lower"]), reason=check["reason"],
        kind=check["kind"], verified_by=check["verified_by"])


def bottleneck_record(bn: dict[str, Any]) -> NetworkBottleneck:
    """The record of the bottleneck (:func:`~kfcrit.theory.links.netmargins.network_bottleneck`;
    ``margin_interval``, ``reason`` and ``candidates`` only where stated)."""
    out = NetworkBottleneck(name=bn["name"], margin=_real(bn["margin"]), rule=bn["rule"])
    if "margin_interval" in bn:
        out = replace(out, margin_interval=_reals(bn["margin_interval"]))
    if "reason" in bn:
        out = replace(out, reason=bn["reason"])
    if "candidates" in bn:
        out = replace(out, candidates=[str(c) for c in bn["candidates"]])
    return out


def _real(v: Any) -> float | int | None:
    """A number of the record: an int stays an int, a float (NumPy's or sympy's) becomes a
    Python float, None where it is not finite."""
    if v is None:
        return None
    if isinstance(v, (bool, np.bool_)):
        raise TypeError(f"a number was expected, got {v!r}")
    if isinstance(v, (int, np.integer)):
        return int(v)
    if isinstance(v, sp.Basic):
        if v.is_Integer:
            return int(v)
        v = sp.N(v, 20)
    f = float(v)
    return f if math.isfinite(f) else None


def _reals(vs: Sequence[Any] | None) -> list[float | int | None] | None:
    """:func:`_real` of each entry (None stays None)."""
    return None if vs is None else [_real(v) for v in vs]


# ---- one sensor: the single-link theory

def _single_link_overlay(network: Network, res: NetworkResult, pf: np.ndarray,
                         pe: list[sp.Expr | None], tol: float) -> NetworkResult:
    """For N = 1 the critical value, verdict and margins of the single-link theory (exact
    Mo–Sinopoli values where a theorem applies; else the bracket [block lower bound, p_up])."""
    system = network.stacked_system()
    p = float(pf[0])
    row = res.sensors[0]
    klass, crit, pc_exact, cvo = _single_link_critical(system, tol)
    facts, reason = _single_link_facts(klass, crit, pe[0], pc_exact)
    iv = crit["interval"]
    margin = {"value": p - crit["value"] if crit["value"] is not None else None,
              "interval": ([p - iv[1] if iv[1] is not None else None, p - iv[0]]
                           if iv is not None else None)}
    margin_exact = exact_margin(pe[0], pc_exact)
    if margin_exact is not None:
        # p = 9/25 + 10⁻⁴⁰ rounds onto p_c: the float difference would say 0, the exact one
        # says what the verdict says
        m = float(sp.N(margin_exact, 30))
        margin = {"value": m, "interval": [m, m]}
    stable = klass == "stable"
    n1 = StabilityFacts(necessary=stable, sufficient=stable, exact_region=True,
                        necessary_basis="no measurement reaches the estimator",
                        sufficient_basis="ρ(A) < 1" if stable else "")
    n1_why = "ρ(A) < 1" if stable else "no measurement reaches the estimator and ρ(A) ≥ 1"
    new_row = SensorResult(row.name, row.arrival_probability, row.arrival_expression, crit,
                           row.surfaces, margin, n1, n1_why)
    um = dict(res.uniform_margin)
    if klass != "stable":
        um.update(value=margin["value"], interval=margin["interval"], unbounded=None
                  if iv is not None else "negative",
                  reason="one sensor: δ = p − p_c (single-link theory)")
    return NetworkResult(facts=facts, reason=reason, sensors=(new_row,),
                         uniform_margin=um, bottleneck={**res.bottleneck, "name": row.name,
                                                        "margin": margin["value"],
                                                        "margin_interval": margin["interval"]},
                         constraints=res.constraints,
                         exact_region=_single_exact_region(res.exact_region, facts),
                         certificate=res.certificate, method=res.method, claims=res.claims,
                         warnings=res.warnings + tuple(cvo.warnings),
                         seconds=res.seconds, single_lower=cvo.lower)


def _single_exact_region(region: dict[str, Any], facts: StabilityFacts) -> dict[str, Any]:
    """The ``exact_region`` entry of one sensor: where the single-link theory gives p_c exactly
    (facts ``exact_region``), the region {p > p_c} is exact whatever modal one-step
    observability says (the two entries state one fact)."""
    if not facts.exact_region or region.get("holds"):
        return region
    return {**region, "holds": True,
            "reason": "one sensor: the single-link theory gives p_c exactly, so p > p_c is the "
                      "exact stability region",
            "basis": "single-link critical value (docs/theory.md §3–§4)"}


def _single_link_critical(system: Any, tol: float
                          ) -> tuple[str, dict[str, Any], sp.Expr | None, Any]:
    """The single-link critical value of one system (theory §3–§4): (classification, the
    ``crit`` dict of a sensor row, the exact p_c or None, the theory's
    :class:`~kfcrit.theory.critical.values.CriticalValue`)."""
    cvo = critical_value(system)
    klass = cvo.classification
    value = cvo.value
    if klass == "stable":
        crit = {"value": 0.0, "interval": [0.0, 0.0], "exact": True, "expression": "0",
                "basis": "single link: ρ(A) < 1"}
    elif klass == "not-detectable":
        crit = {"value": None, "interval": None, "exact": True, "expression": None,
                "basis": "single link: (C, A) not detectable"}
    elif value is not None:
        exact = cvo.structure.path == "exact"
        reason = cvo.reason
        if exact and value.expr is None:
            reason += (" (every decision exact; |λ₁|² is an algebraic number of degree ≥ 3, "
                       "so the value is given in double precision)")
        crit = {"value": value.value, "interval": [value.value, value.value],
                "exact": exact and value.expr is not None, "expression": value.expression,
                "basis": f"single link: {reason}"}
    else:
        up = upper_bound(system, tol)
        lo = cvo.block_lower.value if cvo.block_lower is not None else None
        if lo is None:
            lo = cvo.lower.value
        hi = up.interval[1] if up.certified else None
        crit = {"value": None, "interval": [lo, hi], "exact": False, "expression": None,
                "basis": "single link: bracket [block lower bound, certified p_up]"}
    pc_exact = cvo.value.expr if cvo.value is not None and cvo.value.expr is not None else None
    return klass, crit, pc_exact, cvo


def _single_link_facts(klass: str, crit: dict[str, Any], p: sp.Expr | None,
                       pc_exact: sp.Expr | None) -> tuple[StabilityFacts, str]:
    """Facts of one sensor's link from the single-link theory, p compared exactly."""
    basis = "single-link theory (theory §3–§4)"
    if crit["interval"] is None:
        return (StabilityFacts(False, False, True, "(C, A) is not detectable", ""),
                "(C, A) is not detectable")
    if klass == "stable":
        return StabilityFacts(True, True, True, basis, "ρ(A) < 1"), "ρ(A) < 1"
    lo, hi = crit["interval"]
    exact_lo = pc_exact if pc_exact is not None else lo
    above_lo = compare_probability(p, exact_lo) > 0
    above_hi = hi is not None and compare_probability(p, exact_lo if crit["value"] is not None
                                                      else hi) > 0
    what = ("p_c" if crit["value"] is not None else
            "the bracket [block lower bound, certified p_up]")
    return (StabilityFacts(above_lo, above_hi, crit["value"] is not None, basis,
                           basis if above_hi else ""),
            f"p against {what} (single-link theory)")
