"""Critical arrival probability p_c: which theorem applies, its exact value, and how robust it is.

The decision tree (docs/theory.md §3–§4, Mo–Sinopoli; the eigen-structure comes from
:mod:`kfcrit.theory.structure.eigen`):

1. some eigenvector with |λ| ≥ 1 is invisible to C  → ``not-detectable`` (no p_c: E[P_t]
   diverges for every p, even with no losses);
2. ρ(A) < 1                                            → ``stable``, p_c = 0;
3. A not diagonalizable                                → ``non-diagonalizable``: no closed form,
   except Sinopoli Section IV (C invertible, or a single unstable eigenvalue), where p_c = p_low;
4. every equi-block with |λ| ≥ 1 one-step observable   → ``non-degenerate`` (Thm 4),
   p_c = max(1 − |λ_1|^{−2}, 0);
5. the |λ| ≥ 1 part is one degenerate equal-modulus pair → ``degenerate-second-order``
   (Thm 5, 9, 10; with Thm 3 and Thm 8 when stable eigenvalues are present),
   p_c = max(1 − |λ_1|^{−2/(1 − D_M(φ/2π))}, 0) = max(1 − |λ_1|^{−2q/(q−1)}, 0);
6. otherwise                                          → ``degenerate``: no closed form; the block
   lower bound (Thm 3 over single eigenvalues and equal-modulus pairs) is reported instead.

The robust value (issue item 3) looks at every decision a relative perturbation of size ``tol``
could flip *upwards*: moduli within ``tol`` of each other (a pair that could become an equi-block),
C-columns within ``tol``·‖C‖ of rank deficiency, an angle φ/2π within ``tol`` of a rational r/q with
a smaller q (q ≤ ``MAX_DENOMINATOR``; larger q change p_c by at most 0.37/(q − 1)), and eigenvectors
within ``tol``·‖C‖ of being unobservable. The continuous drift of p_c with |λ_1| (O(tol)) is not a
flip and is not reported.
"""
from __future__ import annotations

from typing import Any

import sympy as sp

from kfcrit.defaults import DEFAULT_TOLERANCE
from kfcrit.errors import InputError
from kfcrit.model.system import System
from kfcrit.records.structure import MomentThreshold, Theory
from kfcrit.theory.critical.classify import block_lower, c_full_rank, classify_structure, lower_of
from kfcrit.theory.critical.numtext import (
    p_c_text,
    superscript,
)
from kfcrit.theory.critical.robust import headline_structure, robust_value
from kfcrit.theory.critical.values import (
    CriticalValue,
    Num,
    eig_above,
    nondegenerate_value,
    num_of,
    on_circle,
)
from kfcrit.theory.structure.eigen import (
    Structure,
    cmp_exact,
    structure_at,
    structure_of,
)

# --------------------------------------------------------------------------- theory

def _theory(system: System, st: Structure, classification: str, pc: Num | None,
            channel: Any) -> Theory:
    """The ``theory`` section: the moment thresholds (Mo–Sinopoli Cor. 2), stochastic
    boundedness (Kar–Sinopoli–Moura Thm 9) and the almost-sure statements (§6)."""
    top = st.eigen[0]
    all_unstable = all(st.relevant(i) for i in range(len(st.eigen))) and not any(
        on_circle(e, st) for e in st.eigen)
    applies = classification == "non-degenerate" and all_unstable
    moments = []
    for q in (1, 2):
        if not nondegenerate_value(top.mod2, top.mod2_expr, eig_above(top, st)).value > 0:
            v = Num(0.0, sp.Integer(0) if top.mod2_expr is not None else None)
        elif top.mod2_expr is not None:
            v = num_of(1 - top.mod2_expr ** (-q))
        else:
            v = Num(1 - top.mod2 ** (-q))
        moments.append(MomentThreshold(q=q, value=float(v.value), expression=v.expression,
                                       applies=bool(applies)))
    pc_text = "p_c (not known in closed form)" if pc is None else p_c_text(
        pc.value, pc.expression if pc.expr is not None else None, system.exact)
    if st.detectable:
        sb = ("Kar–Sinopoli–Moura Thm 9: for every arrival probability p > 0 the random Riccati "
              "sequence Pₜ is stochastically bounded and converges weakly to a unique invariant "
              f"distribution from every P_0; that distribution has a finite mean iff p > "
              f"{pc_text}.")
        if not st.controllable_Q:
            sb += (" (Their hypothesis (A, Q^(1/2)) stabilizable is assumed here: kfcrit checked "
                   "controllability, which failed.)")
    else:
        sb = ("Kar–Sinopoli–Moura Thm 9 needs (C, A) detectable, which fails: no statement.")
    io = st.observability_index
    return Theory(moment_thresholds=moments,
                  moment_thresholds_note=("Mo–Sinopoli Cor. 2: supₖ E[Pₖ^q] < ∞ iff "
                                          "p > 1 − |λ₁|^(−2q); applies to non-degenerate "
                                          "systems whose eigenvalues are all unstable"),
                  stochastic_boundedness=sb, almost_sure=_almost_sure(st, channel),
                  observability_index=int(io) if io is not None else None)


def _almost_sure(st: Structure, channel: Any) -> list[str]:
    """Plain sentences from docs/theory.md §6 (Wu–Shi–Anderson–Johansson) for the configured channel."""
    label = ("Consequence (Borel–Cantelli argument on Wu–Shi–Anderson–Johansson Lemma 4, "
             "docs/theory.md §6), not a theorem of the papers: ")
    if not st.detectable:
        return ["(C, A) is not detectable: tr Pₖ diverges almost surely on every channel."]
    if st.stable:
        return ["A is stable: tr Pₖ stays bounded by a deterministic constant for every arrival "
                "sequence (absolutely upper and lower almost-surely stable)."]
    io = st.observability_index
    critical = not any(eig_above(e, st) for e in st.eigen)
    if io is not None:
        m_text = f"liminf tr Pₖ ≤ tr M with M = h{superscript(io)}(M₀) (Iₒ = {io})"
    elif st.observable:
        m_text = ("liminf tr Pₖ ≤ tr M with M = h^(Iₒ)(M₀) ((C, A) is observable by the PBH "
                  "test; Iₒ itself is not determined in floating point at this size)")
    else:
        m_text = "a liminf bound (Lemma 4 needs (C, A) observable, which fails here)"
    if critical:
        general = (label + "A is critically stable (ρ(A) = 1, no |λ| > 1), not unstable: the "
                   "upper a.s. instability consequence of docs/theory.md §6 is stated for unstable A and is "
                   "not claimed here. For an arrival process in which every run of Iₒ arrivals "
                   f"recurs infinitely often, {m_text} (absolutely lower a.s. stable). Mean "
                   "stability is a different, stronger notion.")
    else:
        general = (label + "for unstable A and an arrival process in which every finite loss "
                   "burst and every run of Iₒ arrivals recur infinitely often, limsup tr Pₖ = ∞ "
                   f"almost surely (upper a.s. unstable) while {m_text} (absolutely lower a.s. "
                   "stable). Mean stability is a different, stronger notion.")
    if channel is None:
        return [general]
    model = getattr(channel, "model", None)
    if model == "bernoulli":
        p = channel.arrival_probability
        if p == 1:
            return ["Every packet arrives (p = 1): the standard Kalman filter; Pₖ converges "
                    "to the Riccati fixed point (detectable system), so tr Pₖ is bounded."]
        if p == 0 and not critical:
            return ["No packet arrives (p = 0): open-loop prediction of an unstable system; "
                    "tr Pₖ → ∞ surely."]
        if p == 0:
            return ["No packet arrives (p = 0): open-loop prediction of a critically stable "
                    "system (ρ(A) = 1); no almost-sure statement of docs/theory.md §6 applies."]
        return [f"i.i.d. losses with 0 < p = {sp.sstr(p)} < 1 satisfy the recurrence condition. "
                + general]
    if model == "gilbert-elliott":
        f, r = channel.failure_rate, channel.recovery_rate
        if 0 < f < 1 and 0 < r < 1:
            return [f"Gilbert–Elliott losses with both rates in (0, 1) (failure {sp.sstr(f)}, "
                    f"recovery {sp.sstr(r)}) are a *-mixing Markov chain satisfying the "
                    "recurrence condition. " + general]
        return ["Gilbert–Elliott losses with a rate equal to 1: some loss bursts or arrival runs "
                "never occur, so the recurrence condition of docs/theory.md §6 does not hold; no "
                "statement."]
    if model == "trace":
        return ["A recorded trace is finite: the almost-sure statements concern infinite "
                "arrival sequences and are not evaluated for it."]
    return [f"Channel model {model!r}: the recurrence condition of docs/theory.md §6 is not checked "
            "for it. " + general]


# --------------------------------------------------------------------------- entry points

def _hypothesis_warnings(system: System, st: Structure) -> list[str]:
    out = []
    if st.path == "numeric":
        out.append(f"eigen-structure decided in floating point ({st.path_reason})")
    out.extend(f"float64 could not resolve the spectrum: {u}" for u in st.unresolved)
    if not st.controllable_Q:
        out.append("(A, Q^(1/2)) is not controllable: Sinopoli's existence theorem for p_c "
                   "assumes it")
    # exact for exact input, scale-aware for floats: Q = 1e-250·I is positive definite
    if not system.is_positive_definite("Q"):
        out.append("Q is not positive definite: Mo–Sinopoli (H3) assumes Q ≻ 0 (Thm 2, "
                   "independence of Q, R, Σ0)")
    if not system.is_positive_definite("Sigma0"):
        out.append("Σ0 is not positive definite: Mo–Sinopoli (H3) assumes Σ0 ≻ 0")
    return out


def _exact_p_up(system: System, st: Structure, low: Num) -> list[tuple[Num, str, bool]]:
    """Cases where the upper bound p_up is known exactly: (value, why, theorem?).

    * C invertible: p_up = p_low (Sinopoli et al. 2004 Section IV, a theorem);
    * a single output (m = 1, exact path, every |λ|² of the unstable eigenvalues an explicit
      algebraic number): p_up = 1 − 1/Π_{|λ_i| > 1} |λ_i|² (with multiplicity) — docs/theory.md §3
      **[beyond]**: the dual of Elia's rank-one result, checked numerically on the paper
      examples and random single-output systems, *not* a theorem of the papers.
    """
    out: list[tuple[Num, str, bool]] = []
    if c_full_rank(system, st):
        out.append((low, "C invertible: p_up = p_low (Sinopoli et al. 2004 Section IV, theorem)", True))
    if system.m == 1 and st.path == "exact":
        unstable = [e for e in st.eigen if e.unit_cmp is not None and e.unit_cmp > 0]
        if all(e.mod2_expr is not None for e in unstable):
            prod = sp.Integer(1)
            for e in unstable:
                prod = prod * e.mod2_expr ** e.multiplicity
            up = num_of(sp.expand(1 - 1 / prod)) if unstable else Num(0.0, sp.Integer(0))
            out.append((up, (f"single output: p_up = 1 − 1/Π|λ_u|² = {up.expression} over the "
                             "eigenvalues with |λ| > 1 — a claim (docs/theory.md §3 [beyond]: the dual of "
                             "Elia's rank-one result, checked numerically, not a theorem of the "
                             "papers)"), False))
    return out


def _coinciding(system: System, st: Structure, low: Num, blow: Num, bwhy: str
                ) -> tuple[Num, str, bool] | None:
    """The value when the block lower bound equals an exactly known p_up (exact comparison)."""
    if blow is None or blow.expr is None:
        return None
    for up, why, theorem in _exact_p_up(system, st, low):
        if up.expr is not None and cmp_exact(sp.expand(blow.expr - up.expr), 0) == 0:
            return (blow, f"the bounds coincide: block lower bound {blow.expression} ({bwhy}) = "
                          f"upper bound p_up = {up.expression} ({why}), so p_c = "
                          f"{blow.expression}", theorem)
    return None


def critical_value(system: System, tolerance: float = DEFAULT_TOLERANCE, channel: Any = None,
                   structure: Structure | None = None, robust: bool = True) -> CriticalValue:
    r"""Classify (A, C), give p_c exactly where a theorem applies, and its robust value.

    The critical arrival probability of Sinopoli et al. (2004), Theorem 2: for i.i.d. arrivals
    with probability p, sup_t E[P_t] < ∞ iff p > p_c. Where every equi-block with |λ| ≥ 1 is
    one-step observable (Mo & Sinopoli, Theorem 4)

    .. math::

        p_c = \max\bigl(1 - |\lambda_1(A)|^{-2},\ 0\bigr),

    and for a degenerate second-order block (Theorems 5, 9, 10)
    p_c = max(1 − |λ_1|^{−2q/(q−1)}, 0).

    Parameters
    ----------
    system : System
        The system (Q, R, Σ0 only enter the hypothesis checks: Mo–Sinopoli Thm 2).
    tolerance : float
        Relative perturbation size for the robust critical value (default 1e-9); on the numeric
        path also the decision tolerance of the eigen-structure.
    channel : Channel, optional
        The configured channel, for the almost-sure statements in ``theory``.
    structure : Structure, optional
        The eigen-structure of ``system`` from
        :func:`kfcrit.theory.structure.eigen.structure_of` (computed here when omitted). A numeric-path
        structure decided at another tolerance is re-decided at ``tolerance``.
    robust : bool
        Compute the robust critical value (the systems within ``tolerance``); when False the
        record says it was not computed (a draft of a large system: each eigenvalue group
        costs a Sylvester separation of order k(n − k)).

    Returns
    -------
    CriticalValue
        Record; ``.sections()`` gives the record's sections as their classes,
        ``.to_dict()`` their plain JSON data (see :class:`CriticalValue`).
        ``classification`` is one of ``not-detectable``, ``stable``, ``non-diagonalizable``,
        ``non-degenerate``, ``degenerate-second-order``, ``degenerate``; ``value`` is p_c as a
        ``Num`` (``.value`` float, ``.expr`` exact) or None where no closed form applies.

    Raises
    ------
    kfcrit.errors.InputError
        ``tolerance`` not a number in [0, 0.1].

    References
    ----------
    Sinopoli et al. (2004), Theorems 2 and 3; Mo & Sinopoli, "Towards finding the critical value
    for Kalman filtering with intermittent observations", Theorems 3, 4, 5, 9 and 10;
    docs/theory.md §3 and §4.

    Examples
    --------
    >>> from kfcrit import System, critical_value
    >>> critical_value(System(A=[[2.0]], C=[[1.0]], Q=[[1.0]], R=[[1.0]])).value.value
    0.75
    >>> cv = critical_value(System(A=[[1.25, 0], [1, 1.1]], C=[[1, 1]], Q=20, R=2.5))
    >>> cv.classification, cv.value.expr
    ('non-degenerate', 9/25)
    >>> critical_value(System(A=[[0, -2], [2, 0]], C=[[1, 0]], Q=1, R=1)).value.expr
    15/16
    >>> critical_value(System(A=[[2]], C=[[1]], Q=1, R=1), tolerance=1)
    Traceback (most recent call last):
        ...
    kfcrit.errors.InputError: tolerance: must be a number in [0, 0.1], got 1
    """
    if not (isinstance(tolerance, (int, float)) and 0 <= tolerance <= 0.1):
        raise InputError(f"must be a number in [0, 0.1], got {tolerance!r}", field="tolerance")
    st_in = (structure_at(structure, system, tolerance) if structure is not None
             else structure_of(system, tolerance))
    st, st_tol = headline_structure(system, st_in)
    low = lower_of(st)
    classification, value, reason = classify_structure(system, st, low)
    reason = reason.replace("= ≈", "≈").replace("|≈ ", "|")
    if st.unresolved:
        reason += ("; RESOLUTION FAILED: float64 cannot resolve some eigenvalues of A (their "
                   "error bounds 64·ε·‖A‖·κ overlap), so this rests on the computed values: "
                   + "; ".join(st.unresolved))
    warnings = _hypothesis_warnings(system, st)
    if classification == "not-detectable":
        blow, bwhy = None, "not detectable: no finite critical value"
    else:
        blow, bwhy = block_lower(st, low)
        if value is not None and value.value > blow.value:
            blow, bwhy = value, "equals p_c"
    basis = None
    if value is None and classification in ("degenerate", "non-diagonalizable"):
        hit = _coinciding(system, st, low, blow, bwhy)
        if hit is not None:
            value, why, theorem = hit
            reason += "; " + why
            basis = "theorem" if theorem else "claim"
            if not theorem:
                warnings.append("p_c rests on the single-output identity p_up = 1 − 1/Π|λ_u|², "
                                "a claim checked numerically (docs/theory.md §3 [beyond]), not a theorem")
    robust_entry = None
    if classification != "not-detectable" and robust:
        robust_entry = robust_value(system, st, st_tol, tolerance, value, blow, classification,
                                     warnings)
    elif classification != "not-detectable":
        warnings.append(f"robust critical value not computed (a --quick draft of n = "
                        f"{system.n} states): the verdict does not consider systems within the "
                        f"tolerance {tolerance:g}; run without --quick for it")
    theory = _theory(system, st, classification, value, channel)
    return CriticalValue(classification=classification, value=value, reason=reason, lower=low,
                         block_lower=blow, block_reason=bwhy, robust=robust_entry, structure=st,
                         theory=theory, warnings=tuple(warnings), basis=basis)


def critical_section(system: System, tolerance: float = DEFAULT_TOLERANCE, channel: Any = None,
                     structure: Structure | None = None) -> dict[str, Any]:
    """``critical_value(system, tolerance, channel, structure).to_dict()``.

    The record sections of the critical value, as plain JSON data.

    Parameters
    ----------
    system : System
        The system.
    tolerance : float
        Relative perturbation size of the robust critical value.
    channel : Channel, optional
        The configured channel (for the almost-sure statements).
    structure : Structure, optional
        The eigen-structure of ``system``, when already computed.

    Returns
    -------
    dict
        Keys ``classification``, ``critical_value`` (``value``, ``exact``, ``expression``,
        ``latex``, ``reason``), ``lower_bound``, ``block_lower_bound``, ``robust_critical_value``,
        ``structure``, ``theory`` and ``warnings``.

    Raises
    ------
    kfcrit.errors.InputError
        As :func:`critical_value`.

    References
    ----------
    Mo & Sinopoli, Theorem 4; docs/theory.md §4.

    Examples
    --------
    >>> from kfcrit import System
    >>> from kfcrit.theory.critical.section import critical_section
    >>> d = critical_section(System(A=[["5/4"]], C=[[1]], Q=1, R=1))
    >>> d["classification"], d["critical_value"]["expression"], d["critical_value"]["value"]
    ('non-degenerate', '9/25', 0.36)
    """
    return critical_value(system, tolerance, channel, structure).to_dict()
