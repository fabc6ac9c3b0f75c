"""Mechanical checks of the proof steps kfcrit relies on (docs/theory.md §8).

One module per checked step, ``check_<step>.py``. Each module states its source (paper, equation)
and exposes ``CHECKS``, a list of :class:`Check` records, each a function that returns a one-line
detail and raises ``AssertionError`` when the step does not hold. The methods are

* ``sympy symbolic``: the identity with symbolic entries (general, or for a stated dimension);
* ``sympy exact``: exact rational/algebraic instances where the general statement is too slow;
* ``numeric``: a float spot check, usually of kfcrit's own implementation of the same formula.

Misprint checks show the printed form is wrong (a counterexample, or an ill-formed expression)
and the corrected form right. ``python -m proofs_checks`` prints a table and exits 1 on any
failure; pytest collects the same checks through the ``test_*`` functions of each module.
"""
from __future__ import annotations

import importlib
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass

MODULES = (
    "check_lemma1a",
    "check_lemma1b",
    "check_misprint_thm1_v",
    "check_thm5_schur",
    "check_thm6b_sdp",
    "check_misprint_thm6b",
    "check_lyapunov_lower",
    "check_mo_eq51_det",
    "check_mo_sqi_count",
    "check_mo_root_test",
    "check_misprint_mo_cor2",
    "check_mo_thm8_scaling",
    "check_kar_fractal",
    "check_marginal_modes",
)
"""The check modules, in the order of the table."""


@dataclass(frozen=True)
class Check:
    """One mechanical check of one proof step.

    Attributes
    ----------
    step : str
        The proof step, e.g. ``"Lemma 1(a): g_p(X) = φ(K_X, X)"``.
    source : str
        Paper and equation, e.g. ``"Sinopoli et al. 2004, App. A, Lemma 1(a), eq. (23)"``.
    method : str
        ``"sympy symbolic"``, ``"sympy exact"`` or ``"numeric"`` (with a short qualifier).
    run : callable
        Returns a one-line detail; raises ``AssertionError`` if the step fails.
    """

    step: str
    source: str
    method: str
    run: Callable[[], str]


@dataclass(frozen=True)
class Outcome:
    """The result of running one :class:`Check`."""

    step: str
    source: str
    method: str
    passed: bool
    detail: str
    seconds: float

    def to_dict(self) -> dict[str, object]:
        return {"step": self.step, "source": self.source, "method": self.method,
                "result": "pass" if self.passed else "FAIL", "detail": self.detail,
                "seconds": round(self.seconds, 3)}


def run_check(check: Check) -> Outcome:
    """Run one check, catching any exception as a failure."""
    start = time.perf_counter()
    try:
        detail, passed = check.run(), True
    except Exception as exc:  # a failing step, or a bug in the check: both are failures
        last = traceback.extract_tb(exc.__traceback__)[-1]
        detail = f"{type(exc).__name__}: {exc} (line {last.lineno})"
        passed = False
    return Outcome(check.step, check.source, check.method, passed, " ".join(detail.split()),
                   time.perf_counter() - start)


def all_checks() -> list[Check]:
    """Every check of every module in :data:`MODULES`."""
    out: list[Check] = []
    for name in MODULES:
        out.extend(importlib.import_module(f"{__name__}.{name}").CHECKS)
    return out


def run_all() -> list[Outcome]:
    """Run every check."""
    return [run_check(c) for c in all_checks()]


