"""The one verdict and the one review decision.

Everything that says whether a design is acceptable is decided here, once, from the sections of
the analysis record; ``analyze``, ``sweep`` and ``report`` all call these functions and every
view renders what they return.

* :func:`operating_verdict` — mean stability at the operating point of the channel
  (``operating_point.verdict``): the arrival probability against p_c, its robust value or the
  bracket [lower, upper]; bursty and measured channels by their own rules (docs/theory.md §7, §10).
* :func:`review` — the review decision, combining in this order: stability at the operating
  point (mean-unstable → fail), each requirement (not met → fail, not demonstrated →
  undetermined), the link policy (margin or outage not met → fail).
* :func:`exit_code` — the documented exit code of a record (README, "Exit codes").

Invariant: a decision is ``fail`` if any reason fails, else ``undetermined`` if any reason is
undetermined, else ``pass``; the exit code is a function of the decision (and of failed
verification checks) only.
"""
from __future__ import annotations

import enum
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any, Protocol

from kfcrit.errors import ExitCode
from kfcrit.io.typed import ABSENT
from kfcrit.records.contract import Verdict
from kfcrit.theory.critical.compare import compare_probability
from kfcrit.theory.facts import StabilityFacts
from kfcrit.theory.links.markov import near_one_text


def mean_bounded(verdict: Verdict | None) -> bool | None:
    """Whether sup_t E[P_t] is finite, as the estimator's verdict decides it (None when it
    does not decide): what every section that states the mean's existence follows."""
    return {Verdict.MEAN_STABLE: True, Verdict.MEAN_UNSTABLE: False}.get(verdict)


class LoopVerdict(str, enum.Enum):
    """Mean-square stability of a closed loop at the operating point (theory §12, §16.5)."""

    MEAN_SQUARE_STABLE = "mean-square-stable"
    MEAN_SQUARE_UNSTABLE = "mean-square-unstable"
    UNDETERMINED = "undetermined"


class Decision(str, enum.Enum):
    """The review decision a CI gate uses."""

    PASS = "pass"
    FAIL = "fail"
    UNDETERMINED = "undetermined"


class CheckStatus(str, enum.Enum):
    """Outcome of one reason of the review."""

    PASS = "pass"
    FAIL = "fail"
    UNDETERMINED = "undetermined"
    NOT_APPLICABLE = "not applicable"


@dataclass(frozen=True)
class Reason:
    """One check of the review decision: what was checked, its outcome, and why."""

    check: str
    status: CheckStatus
    detail: str


@dataclass(frozen=True)
class Review:
    """The review decision and the reasons it combines (stability, requirements, link)."""

    decision: Decision
    reasons: tuple[Reason, ...]


STABILITY_CHECK = "stability at the operating point"
NOT_DETECTABLE_BASIS = ("(C, A) is not detectable (PBH test): a mode with |λ| ≥ 1 is "
                        "unobservable, so the expected error covariance diverges for every "
                        "arrival probability, even p = 1 (no losses); there is no critical "
                        "value, and p_up and the covariance bounds do not apply")
LINK_MARGIN_CHECK = "link policy: margin"
LINK_OUTAGE_CHECK = "link policy: outage"


# ----------------------------------------------------------------------------- comparisons

def exceeds(p: Any, value: Any) -> bool | None:
    r"""Whether the arrival probability ``p`` is strictly above ``value``, decided exactly.

    Parameters
    ----------
    p, value : sympy number, int, Fraction, float, str or None
        A float is the binary rational it holds; exact numbers are compared exactly
        (:func:`kfcrit.theory.critical.compare.compare_probability`, the package's one exact
        comparison): ``9/25 + 10**-40`` is above ``9/25`` although both round to one double.

    Returns
    -------
    bool or None
        ``None`` when either side is unknown; ``False`` when the sign cannot be decided (the
        conservative side: p does not exceed).

    Examples
    --------
    >>> import sympy as sp
    >>> exceeds(sp.Rational(9, 25) + sp.Rational(1, 10**40), sp.Rational(9, 25))
    True
    >>> exceeds(0.36, sp.Rational(9, 25))
    False

    .. math:: \operatorname{exceeds}(p, v) = [\,p - v > 0\,]
    """
    if value is None or p is None:
        return None
    try:
        return compare_probability(p, value) > 0
    except ArithmeticError:
        return False


# ----------------------------------------------------------------------------- verdict

@dataclass(frozen=True)
class CriticalInputs:
    """What the verdict needs of the theory sections (plain numbers, exact where available).

    ``critical`` is p_c (None when it has no closed form), ``critical_exact`` its exact value
    (a sympy number) when known, ``robust`` the robust critical value (None when no nearby
    system is worse), ``lower`` the best lower bound (block lower bound or p_low), ``upper``
    the upper end of p_up, ``classification`` the structure class.
    """

    classification: str | None
    critical: float | None
    critical_exact: Any = None
    robust: float | None = None
    lower: float | None = None
    upper: float | None = None
    p_low: float | None = None
    p_low_exact: Any = None


@dataclass(frozen=True)
class BurstInputs:
    """A Gilbert–Elliott channel as the verdict sees it (docs/theory.md §7, §10).

    ``recovery`` is r; ``sufficient`` is True when a coupled fixed-gain certificate (or, for a
    scalar plant, the exact condition (1 − r)a² < 1) proves mean stability, None when nothing
    sufficient was evaluated; ``basis`` names that sufficient argument.
    """

    recovery: float
    failure: float
    sufficient: bool | None = None
    basis: str | None = None


def burst_factor(recovery: float, spectral_radius: float) -> float:
    r"""The burst growth factor of docs/theory.md §10.

    .. math:: \beta = (1 - r)\,\rho(A)^2

    A loss burst lasts j steps with probability (1 − r)^{j−1} r and the dominant mode grows by
    ρ^{2j} over it, so E[P_t] is unbounded when β ≥ 1, for any system.
    """
    return (1.0 - recovery) * spectral_radius ** 2


@dataclass(frozen=True)
class MeasuredInputs:
    r"""A measured trace's confidence region as the verdict sees it (docs/theory.md §14).

    ``model`` is the fitted model the likelihood-ratio test chose. Bernoulli: the corners are
    the ends of the Clopper–Pearson interval of p (``worst_p`` the lower, ``best_p`` the upper
    end). Gilbert–Elliott: the corners of the Bonferroni rectangle, with what the theory proved
    at each (``worst_burst`` at (f_hi, r_lo) with its sufficient condition, ``best_burst`` at
    (f_lo, r_hi)). ``length_to_decide`` is the trace length at which the interval at the fitted
    values would exclude the threshold ``threshold_text`` (None: no length decides).
    """

    model: str
    confidence: float
    worst_p: Any = None
    best_p: Any = None
    worst_burst: BurstInputs | None = None
    best_burst: BurstInputs | None = None
    length_to_decide: int | None = None
    threshold_text: str = ""


@dataclass(frozen=True)
class JointLawInputs:
    """A network's empirical joint law of the received set as the verdict sees it (§13, §14).

    ``point`` are the stability facts under the point estimate π̂;
    ``necessary_fails`` / ``necessary_holds``: the necessary condition P(S ⊆ T)·ρ_T² < 1 fails
    for some T at the lower ends / holds for every T at the upper ends of simultaneous
    (Bonferroni) Clopper–Pearson intervals at ``confidence``; ``exact_region``: the necessary
    condition is also sufficient for this network (so the upper ends decide stability).
    """

    confidence: float
    point: StabilityFacts
    necessary_fails: bool
    necessary_holds: bool
    exact_region: bool
    fails_basis: str = ""
    holds_basis: str = ""
    length_to_decide: int | None = None


def confidence_text(confidence: float) -> str:
    """``95 %`` for 0.95 (the way a review states its confidence)."""
    return f"{100 * float(confidence):.6g} %"


def measured_verdict(crit: CriticalInputs, measured: MeasuredInputs) -> tuple[Verdict, str]:
    r"""The verdict on the whole confidence region of a trace fit (docs/theory.md §14).

    The stable set is an up-set in p (i.i.d.) and in r, a down-set in f (Gilbert–Elliott), so

    .. math::

        \text{mean-stable with confidence } c \iff \text{stable at the worst corner},\qquad
        \text{mean-unstable with confidence } c \iff \text{unstable at the best corner},

    each corner judged by the rules of :func:`operating_verdict` (i.i.d.: p against p_c or its
    bracket, compared exactly; Gilbert–Elliott: the burst condition (1 − r)ρ² < 1 and the
    sufficient condition proven at that corner); otherwise undetermined, with the trace length
    that would decide at the fitted values.
    """
    if crit.classification == "not-detectable":
        return Verdict.MEAN_UNSTABLE, NOT_DETECTABLE_BASIS
    c = confidence_text(measured.confidence)
    if measured.model == "bernoulli":
        at_worst = _iid_verdict(measured.worst_p, crit)
        at_best = _iid_verdict(measured.best_p, crit)
        worst = f"lower end p = {float(measured.worst_p):.6g}"
        best = f"upper end p = {float(measured.best_p):.6g}"
        region = (f"the {c} Clopper–Pearson interval of p (i.i.d. losses: the likelihood-ratio "
                  "test does not reject them)")
    else:
        at_worst = _burst_verdict(crit, measured.worst_burst)
        at_best = _burst_verdict(crit, measured.best_burst)
        wb, bb = measured.worst_burst, measured.best_burst
        worst = f"worst corner (f, r) = ({float(wb.failure):.6g}, {float(wb.recovery):.6g})"
        best = f"best corner (f, r) = ({float(bb.failure):.6g}, {float(bb.recovery):.6g})"
        region = (f"the {c} Bonferroni rectangle of the Gilbert–Elliott fit (bursty losses: the "
                  "likelihood-ratio test rejects i.i.d. losses)")
    if at_worst[0] is Verdict.MEAN_STABLE and at_best[0] is not Verdict.MEAN_UNSTABLE:
        return (Verdict.MEAN_STABLE, f"with confidence {c}: mean-stable on the whole of "
                f"{region}; at its {worst}: {at_worst[1]}")
    if at_best[0] is Verdict.MEAN_UNSTABLE and at_worst[0] is not Verdict.MEAN_STABLE:
        return (Verdict.MEAN_UNSTABLE, f"with confidence {c}: mean-unstable on the whole of "
                f"{region}; at its {best}: {at_best[1]}")
    if measured.length_to_decide is not None:
        length = (f"; a trace of about {measured.length_to_decide} periods would decide at the "
                  f"fitted values ({measured.threshold_text})")
    else:
        length = ("; no trace length decides at the fitted values"
                  + (f" ({measured.threshold_text})" if measured.threshold_text else ""))
    return (Verdict.UNDETERMINED, f"{region} is not decided at confidence {c}: at its {worst} "
            f"{at_worst[0].value}, at its {best} {at_best[0].value}{length}")


def joint_law_verdict(joint: JointLawInputs) -> tuple[Verdict, str]:
    r"""The verdict of a network whose sensors' traces were recorded together (§13, §14).

    .. math::

        \text{mean-unstable} \iff \exists T:\ \underline{P}(S \subseteq T)\,\rho_T^2 \ge 1,
        \qquad
        \text{mean-stable} \iff E \land \forall T:\ \overline{P}(S \subseteq T)\,\rho_T^2 < 1,

    with the under/over-lined probabilities the ends of simultaneous intervals at the
    confidence c and E the exact-region proof; otherwise undetermined, stating the point
    estimate's verdict (the joint law's confidence region is then not covered).
    """
    c = confidence_text(joint.confidence)
    if joint.necessary_fails:
        return Verdict.MEAN_UNSTABLE, f"with confidence {c}: {joint.fails_basis}"
    if joint.necessary_holds and joint.exact_region:
        return Verdict.MEAN_STABLE, f"with confidence {c}: {joint.holds_basis}"
    point, why = verdict_of(joint.point)
    length = (f"; a trace of about {joint.length_to_decide} periods would decide at the "
              "estimated law" if joint.length_to_decide is not None else "")
    return (Verdict.UNDETERMINED, f"not decided at confidence {c}: the point estimate of the "
            f"joint law gives {point.value} ({why}), but the joint law's confidence region is "
            "not covered (the sufficient certificate is checked at the point estimate only)"
            + length)


def probability_to_beat(crit: CriticalInputs) -> tuple[float | None, str | None]:
    """The arrival probability an i.i.d. link must exceed, and what that number is.

    .. math::

        p^\\star = \\begin{cases} \\max(p_c, p_c^{\\text{robust}}) & p_c \\text{ known}\\\\
        \\overline{p}_{up} & \\text{else (sufficient)}\\\\
        \\underline{p} & \\text{else (necessary only)} \\end{cases}

    The one "p to beat" of every view that shows a requirement column (the sweep table, the
    operating point); the verdict itself compares exactly (:func:`operating_verdict`).

    Parameters
    ----------
    crit : CriticalInputs
        The theory's critical value, robust value and bracket.

    Returns
    -------
    value : float or None
        The probability to beat (None when the record has no bound at all).
    basis : str or None
        ``"critical value"``, ``"robust critical value"``, ``"upper bound (sufficient)"`` or
        ``"lower bound (necessary only)"``.

    References
    ----------
    docs/theory.md §16 (verdict and review).

    Examples
    --------
    >>> probability_to_beat(CriticalInputs("general", 0.36, robust=0.37))
    (0.37, 'robust critical value')
    >>> probability_to_beat(CriticalInputs("general", None, lower=0.3, upper=0.4))
    (0.4, 'upper bound (sufficient)')
    """
    if crit.critical is not None:
        if crit.robust is not None and crit.robust > crit.critical:
            return crit.robust, "robust critical value"
        return crit.critical, "critical value"
    if crit.upper is not None:
        return crit.upper, "upper bound (sufficient)"
    if crit.lower is not None:
        return crit.lower, "lower bound (necessary only)"
    return None, None


def operating_verdict(p: Any, crit: CriticalInputs, *, iid: bool = True,
                      burst: BurstInputs | None = None, measured_trace: bool = False,
                      measured: MeasuredInputs | None = None) -> tuple[Verdict, str]:
    """Mean stability at arrival probability ``p`` and the basis of the verdict.

    Rules, in this order:

    1. not detectable → mean-unstable for every p (no p makes E[P_t] bounded);
    2. a measured trace → the verdict on its fit's whole confidence region
       (:func:`measured_verdict`); without a fit, undetermined;
    3. a Gilbert–Elliott channel → mean-unstable when (1 − r)ρ(A)² ≥ 1 (any system, docs/theory.md §10),
       mean-stable when a sufficient condition is proven, else undetermined;
    4. i.i.d. losses, ρ(A) < 1 → mean-stable unless a system within the tolerance has a
       critical value ≥ p (undetermined);
    5. i.i.d. losses with p_c known → mean-stable if p exceeds p_c and its robust value,
       mean-unstable if p ≤ p_c, undetermined between them;
    6. p_c bracketed → mean-stable above the upper end, mean-unstable at or below the lower end,
       undetermined inside.
    """
    if crit.classification == "not-detectable":
        return Verdict.MEAN_UNSTABLE, NOT_DETECTABLE_BASIS
    if measured is not None:
        return measured_verdict(crit, measured)
    if measured_trace:
        return (Verdict.UNDETERMINED, "measured trace: the mean-stability theorems assume i.i.d. "
                "(Sinopoli, Mo–Sinopoli) or Gilbert–Elliott arrivals, which a recorded sequence "
                "is not; the empirical arrival rate and a Gilbert–Elliott fit are given for "
                "information only")
    if burst is not None and not iid:
        return _burst_verdict(crit, burst)
    return _iid_verdict(p, crit)


def _iid_verdict(p: Any, crit: CriticalInputs) -> tuple[Verdict, str]:
    if crit.classification == "stable":
        if crit.robust is not None and not exceeds(p, crit.robust):
            return (Verdict.UNDETERMINED, "ρ(A) < 1 as entered, but a system within the "
                    f"tolerance has critical value {crit.robust:.6g} ≥ p")
        return Verdict.MEAN_STABLE, "ρ(A) < 1: E[P_t] is bounded for every arrival probability"
    if crit.critical is not None:
        pc = crit.critical_exact if crit.critical_exact is not None else crit.critical
        worst = max(crit.critical, crit.robust if crit.robust is not None else crit.critical)
        if not exceeds(p, pc):
            return Verdict.MEAN_UNSTABLE, f"p ≤ p_c = {crit.critical:.6g}"
        if crit.robust is not None and crit.robust > crit.critical and not exceeds(p, worst):
            return (Verdict.UNDETERMINED, f"p_c = {crit.critical:.6g} < p ≤ robust critical "
                    f"value {worst:.6g} (a system within the tolerance is unstable at p)")
        return Verdict.MEAN_STABLE, f"p > p_c = {crit.critical:.6g}"
    lo = crit.lower if crit.lower is not None else 0.0
    if not exceeds(p, lo):
        return Verdict.MEAN_UNSTABLE, f"p ≤ lower bound {lo:.6g} of p_c"
    if crit.upper is not None and exceeds(p, crit.upper):
        return Verdict.MEAN_STABLE, f"p > upper bound p_up = {crit.upper:.6g} of p_c"
    up = f"{crit.upper:.6g}" if crit.upper is not None else "unknown"
    return Verdict.UNDETERMINED, f"p inside the bracket [{lo:.6g}, {up}] of p_c"


def _burst_value_text(recovery: Any, crit: CriticalInputs) -> str:
    r"""(1 − r)·ρ(A)² = (1 − r)/(1 − p_low) as text: exact where r and p_low are (a value
    within 10⁻⁹ of 1 is written 1 ± ε, never a bare 1 that a float would print).

    .. math::  (1 - r)\,\rho(A)^2 = \frac{1 - r}{1 - p_{low}}
    """
    import sympy as sp

    if isinstance(recovery, sp.Basic) and isinstance(crit.p_low_exact, sp.Basic):
        return near_one_text((1 - recovery) / (1 - crit.p_low_exact) - 1)
    return f"{(1.0 - float(recovery)) / (1.0 - crit.p_low):.6g}"


def _burst_verdict(crit: CriticalInputs, burst: BurstInputs) -> tuple[Verdict, str]:
    """Gilbert–Elliott verdict. With ρ(A) > 1, (1 − r)ρ² ≥ 1 ⇔ r ≤ 1 − 1/ρ² = p_low, which is
    compared exactly when p_low and r are exact."""
    if crit.classification == "stable" and crit.robust is None:
        return Verdict.MEAN_STABLE, "ρ(A) < 1: E[P_t] is bounded for every arrival process"
    p_low = crit.p_low_exact if crit.p_low_exact is not None else crit.p_low
    if p_low is not None and crit.p_low is not None and crit.p_low > 0 \
            and not exceeds(burst.recovery, p_low):
        return (Verdict.MEAN_UNSTABLE, f"burst condition (1 − r)·ρ(A)² = "
                f"{_burst_value_text(burst.recovery, crit)} ≥ 1 "
                f"(r = {float(burst.recovery):.6g} ≤ 1 − 1/ρ(A)² = {crit.p_low:.6g}; necessary "
                "for bounded E[P_t] for any system, docs/theory.md §10): loss bursts make E[P_t] diverge")
    if burst.sufficient is True:
        return Verdict.MEAN_STABLE, burst.basis or "a sufficient condition holds"
    return (Verdict.UNDETERMINED, "bursty losses: the necessary burst condition (1 − r)·ρ(A)² < 1 "
            "holds, and no sufficient condition was proven at this operating point"
            + (f" ({burst.basis})" if burst.basis else ""))


def verdict_of(facts: StabilityFacts) -> tuple[Verdict, str]:
    r"""The verdict that a set of stability facts supports (docs/theory.md §16).

    .. math::

        \text{mean-unstable} \iff \neg N, \qquad
        \text{mean-stable} \iff S \lor (E \land N), \qquad
        \text{else undetermined},

    with N the necessary condition (``False`` only when it fails, decided), S a proven
    sufficient condition and E the proof that the two surfaces meet.

    Examples
    --------
    >>> verdict_of(StabilityFacts(necessary=True, sufficient=False))[0].value
    'undetermined'
    >>> verdict_of(StabilityFacts(necessary=True, sufficient=False, exact_region=True))[0].value
    'mean-stable'
    """
    if facts.necessary is False:
        return Verdict.MEAN_UNSTABLE, facts.necessary_basis or "a necessary condition fails"
    if facts.sufficient:
        return Verdict.MEAN_STABLE, facts.sufficient_basis or "a sufficient condition holds"
    if facts.exact_region and facts.necessary is True:
        return Verdict.MEAN_STABLE, (facts.sufficient_basis or facts.necessary_basis
                                     or "exact region: the necessary condition holds")
    if facts.necessary is None:
        return Verdict.UNDETERMINED, "the necessary condition is at equality"
    return Verdict.UNDETERMINED, "the necessary condition holds, no sufficient one is proven"


def with_verdict(section: dict[str, Any]) -> dict[str, Any]:
    """A theory section with ``facts`` (and a literature ``claim``) given its ``verdict`` key:
    the verdict its facts support, and the claim's ``verdict_if_true``."""
    out = dict(section)
    out["verdict"] = verdict_of(facts_from_dict(out.get("facts") or {}))[0].value
    claim = out.get("claim")
    if isinstance(claim, dict) and "stable_if_true" in claim:
        out["claim"] = {**claim, "verdict_if_true": (Verdict.MEAN_STABLE if claim["stable_if_true"]
                                                     else Verdict.MEAN_UNSTABLE).value}
    return out


def stamp_operating_verdict(sections: dict[str, Any]) -> None:
    """Give every section that states the stability of the operating point (a bursty link's
    certificate, with or without a link budget) the operating point's one verdict, keeping
    the section's own ``facts`` beside it."""
    op = sections.get("operating_point")
    verdict = op.verdict.value if op is not None else None
    link = sections.get("link_budget")
    if verdict is None or link is None:
        return
    bursty = getattr(link, "bursty", None)
    if bursty and bursty.certificate:   # a link budget's time-correlated shadowing
        link = replace(link, bursty=replace(bursty, certificate=replace(
            bursty.certificate, verdict=verdict)))
    certificate = getattr(link, "certificate", None)
    if certificate:                     # a Gilbert–Elliott channel
        link = replace(link, certificate=replace(certificate, verdict=verdict))
    sections["link_budget"] = link


def condition_verdict(holds: bool | None, *, necessary: bool) -> Verdict:
    """The verdict of one stated condition (theory §13: estimate relaying's p_cut·ρ(A)² < 1):
    it holding proves mean stability; it failing proves instability only when the condition is
    also ``necessary`` (one sensor, Gupta et al. 2009); otherwise, or undecided, undetermined."""
    if holds is True:
        return Verdict.MEAN_STABLE
    if holds is False and necessary:
        return Verdict.MEAN_UNSTABLE
    return Verdict.UNDETERMINED


def facts_from_dict(data: Any) -> StabilityFacts:
    """:class:`StabilityFacts` from its JSON form (a mapping) or its record
    (:class:`kfcrit.records.bursty.StabilityFactsRecord`)."""
    if not isinstance(data, Mapping):
        data = {k: getattr(data, k, None) for k in ("necessary", "sufficient", "exact_region",
                                                     "necessary_basis", "sufficient_basis")}
    return StabilityFacts(necessary=data.get("necessary"),
                          sufficient=bool(data.get("sufficient")),
                          exact_region=bool(data.get("exact_region")),
                          necessary_basis=str(data.get("necessary_basis") or ""),
                          sufficient_basis=str(data.get("sufficient_basis") or ""))


def dead_link_verdict(facts: Mapping[str, Any], *, iid: bool, burst_holds: bool | None,
                      burst_facts: Any = None) -> Verdict:
    """The N − 1 verdict of one dead link: the facts with that link dead. With bursty links the
    i.i.d. surfaces decide nothing (the sufficient one assumes independence in time, and the
    necessary one at the stationary arrival probabilities is weaker than the burst condition
    only when f + r ≤ 1): the burst facts with that link dead (``burst_facts``) decide; a
    failing burst condition of the whole network makes every case mean-unstable."""
    if burst_holds is False:
        return Verdict.MEAN_UNSTABLE
    if not iid:
        if burst_facts is not None:
            return verdict_of(facts_from_dict(burst_facts))[0]
        f = facts_from_dict(facts)
        return verdict_of(StabilityFacts(f.necessary, False, False, f.necessary_basis, ""))[0]
    return verdict_of(facts_from_dict(facts))[0]


def network_burst_verdict(verdict: Verdict, basis: str, holds: bool | None,
                          statement: str, facts: Any = None) -> tuple[Verdict, str]:
    """A network with bursty links (theory §10): the burst facts decide (``facts``: the
    burst condition as the necessary fact, the scalar renewal bound as the sufficient one);
    the i.i.d. surfaces at the stationary arrival probabilities prove nothing either way."""
    if facts is not None:
        v, why = verdict_of(facts_from_dict(facts))
        if v is Verdict.UNDETERMINED:
            return v, (f"{statement}; the i.i.d. surfaces of theory §9 at the stationary "
                       "arrival probabilities decide nothing for links with memory")
        return v, why
    if holds is False:
        return Verdict.MEAN_UNSTABLE, statement
    if verdict is Verdict.MEAN_STABLE:
        return (Verdict.UNDETERMINED, f"{statement}; the sufficient surface (theory §9) assumes "
                "independent Bernoulli links, so with bursty links it proves nothing")
    return verdict, f"{basis}; {statement}"


# ----------------------------------------------------------------------------- closed loops

LOOP_CHECK = "closed loop: mean-square stability over both links"


def loop_verdict(facts: StabilityFacts) -> tuple[LoopVerdict, str]:
    r"""The closed loop's verdict from its facts (theory §12, §16.5), by the rule of
    :func:`verdict_of`: for the TCP-like optimal loop N is "γ̄ > γ_c and ν̄ > ν_c" and the
    region is exact; for a fixed design N = S = "ρ(Σ π_m Φ_m ⊗ Φ_m) < 1", decided exactly.

    .. math:: \text{ms-unstable} \iff \neg N, \qquad
              \text{ms-stable} \iff S \lor (E \land N)
    """
    verdict, basis = verdict_of(facts)
    return {Verdict.MEAN_STABLE: LoopVerdict.MEAN_SQUARE_STABLE,
            Verdict.MEAN_UNSTABLE: LoopVerdict.MEAN_SQUARE_UNSTABLE,
            Verdict.UNDETERMINED: LoopVerdict.UNDETERMINED}[verdict], basis


def loop_operating_verdict(estimator: tuple[Verdict | str, str],
                           loop: tuple[LoopVerdict | str, str]) -> tuple[Verdict, str]:
    """``operating_point.verdict`` of a file with a loop: the estimator's mean stability AND
    the loop's mean-square stability (theory §16.5).

    mean-unstable if either is unstable; mean-stable if both are stable; else undetermined.
    """
    est, est_basis = Verdict(estimator[0]), estimator[1]
    lv, loop_basis = LoopVerdict(loop[0]), loop[1]
    both = f"estimator {est.value} ({est_basis}); closed loop {lv.value} ({loop_basis})"
    if lv is LoopVerdict.MEAN_SQUARE_UNSTABLE or est is Verdict.MEAN_UNSTABLE:
        return Verdict.MEAN_UNSTABLE, both
    if lv is LoopVerdict.MEAN_SQUARE_STABLE and est is Verdict.MEAN_STABLE:
        return Verdict.MEAN_STABLE, both
    return Verdict.UNDETERMINED, both


def loop_reasons(verdict: LoopVerdict | str | None, basis: str,
                 actuation_check: Mapping[str, Any] | None) -> list[Reason]:
    """The review's reasons of a loop: its mean-square stability, and the actuation link's
    margin and outage policy (of a link budget)."""
    if verdict is None:
        return []
    lv = LoopVerdict(verdict)
    status = {LoopVerdict.MEAN_SQUARE_STABLE: CheckStatus.PASS,
              LoopVerdict.MEAN_SQUARE_UNSTABLE: CheckStatus.FAIL,
              LoopVerdict.UNDETERMINED: CheckStatus.UNDETERMINED}[lv]
    return [Reason(LOOP_CHECK, status, f"{lv.value}: {basis}"),
            *link_reasons(actuation_check, "actuation link")]


# ----------------------------------------------------------------------------- review

def stability_reason(verdict: Verdict | str | None, basis: str | None) -> Reason:
    """The review's first reason: mean stability at the operating point."""
    if verdict is None:
        return Reason(STABILITY_CHECK, CheckStatus.NOT_APPLICABLE,
                      "no channel in the file: no operating point to review")
    verdict = Verdict(verdict)
    status = {Verdict.MEAN_STABLE: CheckStatus.PASS, Verdict.MEAN_UNSTABLE: CheckStatus.FAIL,
              Verdict.UNDETERMINED: CheckStatus.UNDETERMINED}[verdict]
    return Reason(STABILITY_CHECK, status, f"{verdict.value}: {basis or ''}".rstrip(": "))


class Assessed(Protocol):
    """One assessed requirement (the record's ``RequirementAssessment``)."""

    requirement: str
    status: str | None
    basis: str


def requirement_reasons(assessments: Iterable[Assessed]) -> list[Reason]:
    """One reason per requirement of the system file, from its assessment.

    ``met`` → pass, ``not met`` → fail, ``not demonstrated`` (or no assessment) → undetermined.
    """
    out: list[Reason] = []
    for item in assessments:
        status = {"met": CheckStatus.PASS, "not met": CheckStatus.FAIL}.get(
            item.status, CheckStatus.UNDETERMINED)
        out.append(Reason(f"requirement: {item.requirement}", status,
                          item.basis or "not assessed"))
    return out


def link_reasons(design_check: Any, link: str | None = None) -> list[Reason]:
    """The link policy of a link-budget channel: the margin and the shadowing outage (of the
    named sensor's link in a network). ``design_check`` is the typed
    :class:`~kfcrit.records.link.DesignCheck` (None: no link budget)."""
    if not design_check:
        return []
    suffix = f" ({link})" if link else ""
    out = []
    met = design_check.margin_policy_met
    design = None if design_check.design_value is ABSENT else design_check.design_value
    basis = None if design_check.basis is ABSENT else design_check.basis
    against = (f" above the required p = {design:.6g} ({basis})"
               if design is not None and basis else "")
    if design_check.requirement_reachable is False:
        out.append(Reason(LINK_MARGIN_CHECK + suffix, CheckStatus.FAIL,
                          "no link margin: the radio reaches no arrival probability that meets "
                          f"the binding requirement ({basis})"))
    elif design_check.margin_unbounded:
        out.append(Reason(LINK_MARGIN_CHECK + suffix, CheckStatus.PASS,
                          "link margin unbounded: the requirement is p > 0 (p_c = 0), which "
                          "every SINR meets"))
    elif met is not None:
        margin, needed = design_check.link_margin_db, design_check.required_margin_db
        out.append(Reason(LINK_MARGIN_CHECK + suffix,
                          CheckStatus.PASS if met else CheckStatus.FAIL,
                          f"link margin {margin:.3g} dB {'≥' if met else '<'} the policy's "
                          f"{needed:.3g} dB{against}"))
    ok = design_check.outage_within_policy
    if ok is not None:
        outage, allowed = design_check.outage_probability, design_check.max_outage
        out.append(Reason(LINK_OUTAGE_CHECK + suffix,
                          CheckStatus.PASS if ok else CheckStatus.FAIL,
                          f"shadowing outage {100 * outage:.3g} % {'≤' if ok else '>'} the "
                          f"allowed {100 * allowed:.3g} %"))
    return out


def decide(reasons: Sequence[Reason]) -> Decision:
    """fail if any reason fails, else undetermined if any is undetermined, else pass."""
    statuses = {r.status for r in reasons}
    if CheckStatus.FAIL in statuses:
        return Decision.FAIL
    if CheckStatus.UNDETERMINED in statuses:
        return Decision.UNDETERMINED
    return Decision.PASS


def review(verdict: Verdict | str | None, basis: str | None,
           assessments: Iterable[Assessed],
           design_check: Any,
           extra: Sequence[Reason] = ()) -> Review:
    """The review decision: stability, then each requirement, then the link policy."""
    reasons = [stability_reason(verdict, basis), *requirement_reasons(assessments),
               *link_reasons(design_check), *extra]
    return Review(decide(reasons), tuple(reasons))


def exit_code_of(verification_failed: bool, decision: str | None) -> int:
    """The documented exit code: 1 when a verification check failed; else 5 when the review
    fails, 3 when it is undetermined, 0 when it passes (the one place of this rule)."""
    if verification_failed:
        return int(ExitCode.VERIFICATION_FAILED)
    if decision == Decision.FAIL.value:
        return int(ExitCode.REVIEW_FAILED)
    if decision == Decision.UNDETERMINED.value:
        return int(ExitCode.INCONCLUSIVE)
    return int(ExitCode.OK)


def exit_code(record: Mapping[str, Any]) -> int:
    """The documented exit code of a record's plain JSON form (:func:`exit_code_of`; the typed
    record has :attr:`~kfcrit.analysis.sections.AnalysisRecord.exit_code`)."""
    return exit_code_of(any(c.get("passed") is False for c in record.get("verification") or []),
                        (record.get("review") or {}).get("decision"))
