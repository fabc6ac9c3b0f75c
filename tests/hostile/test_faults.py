"""Tests of the tests: each key property check must fail on a deliberately broken implementation.

Every fault is injected with ``monkeypatch`` into the ``riccati`` or the critical-value module (the
check functions call the implementation through the module, so they see the fault). A fault test
runs one property check over a small fixed corpus of inputs (the papers' systems and a few
seeded ones) and asserts that at least one input raises :class:`PropertyViolation`. The control
test runs the same corpora on the real implementation and asserts that nothing is raised, so a
detection is due to the fault and not to a loose or broken check.
"""
from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np
import pytest
import sympy as sp

from kfcrit.model.system import System
from kfcrit.theory.covariance import bounds as _bounds
from kfcrit.theory.covariance import riccati
from kfcrit.theory.critical import classify as critical_classify
from kfcrit.theory.critical import robust as critical_robust
from kfcrit.theory.critical import section as critical
from kfcrit.theory.critical import values as critical_values
from kfcrit.theory.upper import bracket as _upper

from ..properties import test_lemmas as L
from ..properties import test_theory_properties as P
from ..strategies import (
    PAPER_CASES,
    PAPER_FLOAT_CASES,
    DegenerateCase,
    RiccatiInput,
    Spectrum,
    SystemCase,
    paper_riccati_input,
)

_SPECTRA = {  # eigenvalues of the papers' systems (triangular A: the diagonal)
    "sinopoli-scalar": Spectrum((-1.25,), ()),
    "sinopoli-general": Spectrum((1.25, 1.1), ()),
    "sinopoli-single-unstable": Spectrum((1.25, 0.9, 0.6), ()),
}

# --------------------------------------------------------------------------------------------
# corpora


def _seeded_inputs(count: int = 6) -> list[RiccatiInput]:
    """Seeded random inputs (NumPy randomness is fine here: these are fixed test data)."""
    rng = np.random.default_rng(2024)
    out = []
    for k in range(count):
        n, m = 1 + k % 3, 1 + k % 2 if k % 3 else 1
        A = rng.normal(size=(n, n))
        C = rng.normal(size=(m, n))
        Lq, Lr, Lx, Ld = (rng.normal(size=(s, s)) for s in (n, m, n, n))
        Q, R = Lq @ Lq.T + 0.1 * np.eye(n), Lr @ Lr.T + 0.5 * np.eye(m)
        X = Lx @ Lx.T
        case = SystemCase(A, C, 0.5 * (Q + Q.T), 0.5 * (R + R.T))
        out.append(RiccatiInput(case, X, X + Ld @ Ld.T, rng.normal(size=(n, m)),
                                float(rng.random()), 0.3, 0.8))
    return out


RICCATI_CORPUS = [paper_riccati_input(name) for name in
                  ("sinopoli-scalar", "sinopoli-general", "sinopoli-single-unstable",
                   "mo-nondegenerate-four")] + _seeded_inputs()


def _jensen(inp: RiccatiInput) -> None:
    L.check_lemma1h(inp, [inp.X, inp.Y, 3 * inp.X], [0.2, 0.5, 0.3])


def _lemma2(inp: RiccatiInput) -> None:
    L.check_lemma2(inp.case, np.zeros_like(inp.X), inp.Y, inp.p, steps=6)


RICCATI_CHECKS: dict[str, Callable[[RiccatiInput], None]] = {
    "symmetry": L.check_exact_symmetry,
    "mare_formula": L.check_mare_formula,
    "lemma1a": L.check_lemma1a,
    "lemma1b": L.check_lemma1b,
    "lemma1c": L.check_lemma1c,
    "lemma1d": L.check_lemma1d,
    "lemma1e": L.check_lemma1e,
    "lemma1f": L.check_lemma1f,
    "lemma1g": L.check_lemma1g,
    "lemma1h": _jensen,
    "lemma2": _lemma2,
}


def _dm(name: str, rho: sp.Expr, q: int | None) -> DegenerateCase:
    c = PAPER_CASES[name]
    return DegenerateCase(c["A"], c["C"], rho, q)


DEGENERATE_CORPUS = [
    _dm("mo-degenerate-diagonal", sp.Integer(2), 2),
    _dm("rotation-third-turn", sp.Integer(2), 3),
    DegenerateCase(sp.Matrix([[0, -3], [3, 0]]) / 2, sp.Matrix([[1, 1]]), sp.Rational(3, 2), 2),
    DegenerateCase(sp.Matrix([[1, -1], [1, 1]]), sp.Matrix([[1, 0]]), sp.sqrt(2), 4),
    DegenerateCase(sp.Matrix([[1, -2], [2, 1]]), sp.Matrix([[1, 0]]), sp.sqrt(5), None),
]


def _paper_ordering() -> None:
    rhos = {"sinopoli-scalar": 1.25, "sinopoli-general": 1.25, "sinopoli-single-unstable": 1.25,
            "mo-degenerate-diagonal": 2.0, "mo-nondegenerate-four": 3.0,
            "rotation-third-turn": 2.0, "kar-scalar-fractal": 2 ** 0.5}
    for name, rho in rhos.items():
        c = PAPER_FLOAT_CASES[name]
        P.check_bound_ordering(P.record(System(c.A, c.C, c.Q, c.R)), rho=rho)


def _each(items, check) -> Callable[[], None]:
    def run() -> None:
        _run_all([lambda x=x: check(x) for x in items])
    return run


def _run_all(calls: list[Callable[[], None]]) -> None:
    """Run every call; re-raise the first PropertyViolation after running them all."""
    first = None
    for call in calls:
        try:
            call()
        except L.PropertyViolation as exc:
            first = first or exc
    if first is not None:
        raise first


_GENERAL = PAPER_CASES["sinopoli-general"]
_DIAG = PAPER_CASES["mo-degenerate-diagonal"]

def _upper_paper_checks() -> None:
    calls = []
    for name in ("sinopoli-general", "mo-degenerate-diagonal", "mo-nondegenerate-four"):
        c = PAPER_CASES[name]
        system = System(c["A"], c["C"], c["Q"], c["R"])

        def run(system=system, name=name) -> None:
            rec = P.upper_record(system)
            P.check_bound_ordering(P.record(system), p_up=rec["interval"][1])
            P.check_upper_certificate_exact(system, rec)
            P.check_upper_mare_characterisation(PAPER_FLOAT_CASES[name], rec)
        calls.append(run)
    _run_all(calls)


def _covariance_paper_checks() -> None:
    from kfcrit.theory.covariance.bounds import covariance_bounds

    calls = []
    for name, p in (("sinopoli-scalar", 0.5), ("sinopoli-general", 0.8),
                    ("sinopoli-single-unstable", 0.2), ("sinopoli-general", 0.3)):
        c = PAPER_CASES[name]
        system = System(c["A"], c["C"], c["Q"], c["R"])
        case = dataclasses.replace(PAPER_FLOAT_CASES[name],
                                   spectrum=_SPECTRA[name])

        def run(system=system, case=case, p=p) -> None:
            up = P.upper_record(system)
            P.check_covariance_bounds(case, p, covariance_bounds(system, p, up),
                                      tuple(up["interval"]))
        calls.append(run)
    _run_all(calls)


CRITICAL_CHECKS: dict[str, Callable[[], None]] = {
    "pair_value_formula": _each([(sp.Integer(4), 2), (sp.Integer(4), 3), (sp.Integer(9), None),
                                 (sp.Rational(25, 4), 5)],
                                lambda mq: P.check_pair_value_formula(*mq)),
    "degenerate_pair": _each(DEGENERATE_CORPUS, P.check_degenerate_pair),
    "noise_independence": _each(
        [_GENERAL, _DIAG, PAPER_CASES["sinopoli-scalar"]],
        lambda c: P.check_noise_independence(c["A"], c["C"], [
            (c["Q"], c["R"], None),
            (3 * sp.eye(c["A"].shape[0]), 7 * sp.eye(c["C"].shape[0]), 2 * sp.eye(c["A"].shape[0]))
        ])),
    "similarity": _each([(_GENERAL, sp.Matrix([[1, 1], [0, 1]])),
                         (_DIAG, sp.Matrix([[1, 0], [2, 1]]))],
                        lambda ct: P.check_similarity_invariance(ct[0]["A"], ct[0]["C"], ct[1])),
    "scaling": _each([(_GENERAL, sp.Integer(2)), (_DIAG, sp.Rational(3, 2)),
                      (PAPER_CASES["sinopoli-scalar"], sp.Integer(2))],
                     lambda ca: P.check_scaling_monotonicity(ca[0]["A"], ca[0]["C"], ca[1])),
    "bound_ordering": _paper_ordering,
    "upper": _upper_paper_checks,
    "covariance": _covariance_paper_checks,
}


# --------------------------------------------------------------------------------------------
# faults


def _g_sign_error(A, C, Q, R, X, p):
    AXC = A @ X @ C.T
    return riccati.symmetrize(A @ X @ A.T + Q + p * AXC @ np.linalg.solve(C @ X @ C.T + R, AXC.T))


def _g_unsymmetrised(A, C, Q, R, X, p):
    AXC = A @ X @ C.T
    return A @ X @ A.T + Q - p * AXC @ np.linalg.solve(C @ X @ C.T + R, AXC.T)


def _g_without_r(A, C, Q, R, X, p):
    AXC = A @ X @ C.T
    S = C @ X @ C.T + 1e-9 * np.eye(C.shape[0])  # "forgot R" (kept invertible)
    return riccati.symmetrize(A @ X @ A.T + Q - p * AXC @ np.linalg.solve(S, AXC.T))


def _g_one_minus_p(A, C, Q, R, X, p):
    AXC = A @ X @ C.T
    return riccati.symmetrize(A @ X @ A.T + Q
                              - (1 - p) * AXC @ np.linalg.solve(C @ X @ C.T + R, AXC.T))


def _g_convex_term(A, C, Q, R, X, p):
    AXC = A @ X @ C.T
    G = A @ X @ A.T + Q - p * AXC @ np.linalg.solve(C @ X @ C.T + R, AXC.T)
    return riccati.symmetrize(G + 0.05 * X @ X)


def _g_without_q(A, C, Q, R, X, p):
    AXC = A @ X @ C.T
    return riccati.symmetrize(A @ X @ A.T - p * AXC @ np.linalg.solve(C @ X @ C.T + R, AXC.T))


def _g_overcorrected(A, C, Q, R, X, p):
    AXC = A @ X @ C.T  # correction term 4× too large: g_p is no longer monotone
    return riccati.symmetrize(A @ X @ A.T + Q
                              - 4 * p * AXC @ np.linalg.solve(C @ X @ C.T + R, AXC.T))


def _phi_printed_v(A, C, Q, R, K, X, p):
    F = A + K @ C
    return riccati.symmetrize((1 - p) * (A @ X @ A.T + Q) + p * (F @ X @ F.T + Q + K @ K.T))


def _gain_sign(A, C, R, X):
    S = C @ X @ C.T + R
    return np.linalg.solve(S.T, (A @ X @ C.T).T).T


def _arrival_is_loss(A, C, Q, R, X):
    return riccati.symmetrize(A @ X @ A.T + Q)


_REAL_UPPER = _upper.upper_bound
_REAL_LOWER_COV = _bounds.lower_covariance
_REAL_UPPER_COV = _bounds.upper_covariance
_REAL_PAIR_VALUE = critical_values.pair_value
_REAL_NONDEGENERATE = critical_values.nondegenerate_value
_REAL_CRITICAL_VALUE = critical.critical_value


def _pair_value_q_plus_1(mod2, q, *args, **kwargs):
    return _REAL_PAIR_VALUE(mod2, None if q is None else q + 1, *args, **kwargs)


def _pair_value_ignores_dm(mod2, q, *args, **kwargs):
    return _REAL_PAIR_VALUE(mod2, None, *args, **kwargs)


def _lower_one_over_rho(mod2, *args, **kwargs):
    real = _REAL_NONDEGENERATE(mod2, *args, **kwargs)
    if real.value == 0.0:
        return real
    return critical_values.Num(max(1.0 - 1.0 / float(mod2) ** 0.5, 0.0))


def _lower_decreasing(mod2, *args, **kwargs):
    real = _REAL_NONDEGENERATE(mod2, *args, **kwargs)
    if real.value == 0.0:
        return real
    return critical_values.Num(min(1.0 / float(mod2), 1.0))


def _critical_depends_on_q(system, tolerance=1e-9, channel=None):
    rec = _REAL_CRITICAL_VALUE(system, tolerance, channel)
    if rec.value is None:
        return rec
    shift = 1e-6 * float(np.trace(system.q))
    return dataclasses.replace(rec, value=critical_values.Num(min(1.0, rec.value.value + shift)))


def _critical_uses_diagonal(system, tolerance=1e-9, channel=None):
    rec = _REAL_CRITICAL_VALUE(system, tolerance, channel)
    rho = float(np.max(np.abs(np.diag(system.a))))
    return dataclasses.replace(rec, lower=critical_values.Num(max(0.0, 1 - 1 / rho ** 2)))


def _upper_shifted_down(system, tol=1e-9, method="auto"):
    rec = _REAL_UPPER(system, tol, method)
    lo, hi = rec.interval
    return dataclasses.replace(rec, value=hi - 0.05, interval=(lo - 0.05, hi - 0.05))


def _upper_gain_perturbed(system, tol=1e-9, method="auto"):
    rec = _REAL_UPPER(system, tol, method)
    if rec.certificate is None or not rec.certificate.K:
        return rec
    cert = rec.certificate
    for key in ("K", "K_basis"):
        if getattr(cert, key):
            cert = dataclasses.replace(cert, **{key: [[v + 0.05 for v in row]
                                                      for row in getattr(cert, key)]})
    return dataclasses.replace(rec, certificate=cert)


def _lower_covariance_wrong_p(A, Q, p):
    return _REAL_LOWER_COV(A, Q, min(1.0, p + 0.1))


def _upper_covariance_one_step_short(system, p, gains=None):
    res = dict(_REAL_UPPER_COV(system, p, gains))
    if res["V"] is not None:
        res["V"] = 0.98 * res["V"]
    return res


RICCATI_FAULTS = [
    # (fault, attribute patched, replacement, the checks that must catch it)
    ("sign error in g_p", "g", _g_sign_error, ["mare_formula", "lemma1a", "lemma1d", "lemma1e"]),
    ("missing symmetrisation in g_p", "g", _g_unsymmetrised, ["symmetry"]),
    ("R dropped from C X C' + R", "g", _g_without_r, ["mare_formula", "lemma1a"]),
    ("p replaced by 1 − p in g_p", "g", _g_one_minus_p, ["lemma1d", "lemma1a"]),
    ("Q dropped from g_p", "g", _g_without_q, ["lemma1f", "lemma1g", "lemma1h"]),
    ("correction term 4x too large", "g", _g_overcorrected, ["lemma1c", "lemma2"]),
    ("convex term added to g_p", "g", _g_convex_term, ["lemma1e", "lemma1h"]),
    ("φ with V = Q + K K' (R dropped)", "phi", _phi_printed_v, ["lemma1a", "lemma1b"]),
    ("sign error in the optimal gain", "optimal_gain", _gain_sign, ["lemma1a"]),
    ("arrival map equal to the loss map", "f_arrival", _arrival_is_loss, ["mare_formula"]),
]

CRITICAL_FAULTS = [
    ("D_M returns 1/(q+1)", "pair_value", _pair_value_q_plus_1,
     ["pair_value_formula", "degenerate_pair"]),
    ("D_M ignored (always 0)", "pair_value", _pair_value_ignores_dm,
     ["pair_value_formula", "degenerate_pair"]),
    ("p_low = 1 − 1/ρ instead of 1 − 1/ρ²", "nondegenerate_value", _lower_one_over_rho,
     ["bound_ordering"]),
    ("bound decreasing in |λ|", "nondegenerate_value", _lower_decreasing, ["scaling"]),
    ("p_c depends on Q", "critical_value", _critical_depends_on_q, ["noise_independence"]),
    ("ρ(A) read off the diagonal of A", "critical_value", _critical_uses_diagonal,
     ["similarity"]),
]


MODULE_FAULTS = [
    ("p_up reported 0.05 too low", _upper, "upper_bound", _upper_shifted_down, "upper"),
    ("certificate gain perturbed", _upper, "upper_bound", _upper_gain_perturbed, "upper"),
    ("S̄ with the wrong p", _bounds, "lower_covariance", _lower_covariance_wrong_p,
     "covariance"),
    ("V̄ scaled by 0.98", _bounds, "upper_covariance", _upper_covariance_one_step_short,
     "covariance"),
]


@pytest.mark.parametrize(("fault", "module", "attr", "replacement", "check"), MODULE_FAULTS,
                         ids=[f"{f} -> {c}" for f, _m, _a, _r, c in MODULE_FAULTS])
def test_upper_and_bounds_faults_are_caught(monkeypatch: pytest.MonkeyPatch, fault: str,
                                            module, attr: str, replacement: Callable,
                                            check: str) -> None:
    monkeypatch.setattr(module, attr, replacement)
    with pytest.raises(L.PropertyViolation):
        CRITICAL_CHECKS[check]()


def _riccati_corpus_run(check: Callable[[RiccatiInput], None]) -> None:
    _run_all([lambda inp=inp: check(inp) for inp in RICCATI_CORPUS])


@pytest.mark.parametrize(
    ("fault", "attr", "replacement", "check"),
    [(f, a, r, c) for f, a, r, checks in RICCATI_FAULTS for c in checks],
    ids=[f"{f} -> {c}" for f, _a, _r, checks in RICCATI_FAULTS for c in checks])
@pytest.mark.filterwarnings("ignore::RuntimeWarning")  # broken maps may overflow
def test_riccati_fault_is_caught(monkeypatch: pytest.MonkeyPatch, fault: str, attr: str,
                                 replacement: Callable, check: str) -> None:
    monkeypatch.setattr(riccati, attr, replacement)
    with pytest.raises(L.PropertyViolation):
        _riccati_corpus_run(RICCATI_CHECKS[check])


@pytest.mark.parametrize(
    ("fault", "attr", "replacement", "check"),
    [(f, a, r, c) for f, a, r, checks in CRITICAL_FAULTS for c in checks],
    ids=[f"{f} -> {c}" for f, _a, _r, checks in CRITICAL_FAULTS for c in checks])
def test_critical_fault_is_caught(monkeypatch: pytest.MonkeyPatch, fault: str, attr: str,
                                  replacement: Callable, check: str) -> None:
    # the function is patched wherever the critical-value modules call it from
    for module in (critical, critical_values, critical_classify, critical_robust):
        if hasattr(module, attr):
            monkeypatch.setattr(module, attr, replacement)
    with pytest.raises(L.PropertyViolation):
        CRITICAL_CHECKS[check]()


@pytest.mark.parametrize("check", sorted(RICCATI_CHECKS))
def test_riccati_checks_pass_on_the_real_implementation(check: str) -> None:
    _riccati_corpus_run(RICCATI_CHECKS[check])


@pytest.mark.parametrize("check", sorted(CRITICAL_CHECKS))
def test_critical_checks_pass_on_the_real_implementation(check: str) -> None:
    CRITICAL_CHECKS[check]()


# --------------------------------------------------------------------------------------------
# the numeric spot checks of proofs_checks/ see the same faults

PROOF_FAULTS = [
    ("sign error in g_p", "g", _g_sign_error, "check_lemma1a"),
    ("sign error in g_p", "g", _g_sign_error, "check_lemma1b"),
    ("sign error in g_p", "g", _g_sign_error, "check_mo_thm8_scaling"),
    ("Q dropped from g_p", "g", _g_without_q, "check_thm6b_sdp"),
    ("φ with V = Q + K K' (R dropped)", "phi", _phi_printed_v, "check_misprint_thm1_v"),
    ("arrival map equal to the loss map", "f_arrival", _arrival_is_loss, "check_kar_fractal"),
]


@pytest.mark.parametrize(("fault", "attr", "replacement", "module"), PROOF_FAULTS,
                         ids=[f"{f} -> {m}" for f, _a, _r, m in PROOF_FAULTS])
@pytest.mark.filterwarnings("ignore::RuntimeWarning")  # broken maps may overflow
def test_proof_spot_check_catches_fault(monkeypatch: pytest.MonkeyPatch, fault: str, attr: str,
                                        replacement: Callable, module: str) -> None:
    import importlib

    mod = importlib.import_module(f"proofs_checks.{module}")
    monkeypatch.setattr(riccati, attr, replacement)
    with pytest.raises(AssertionError):
        mod.numeric()


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_proofs_checks_command_exits_nonzero_on_a_failure(monkeypatch: pytest.MonkeyPatch,
                                                          capsys: pytest.CaptureFixture) -> None:
    from proofs_checks import __main__ as cli

    monkeypatch.setattr(riccati, "g", _g_sign_error)
    assert cli.main([]) == 1
    out = capsys.readouterr().out
    assert "FAIL" in out and "checks passed" in out
