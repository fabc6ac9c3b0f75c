"""Exactness in the report and the reason texts: "exact" only where a value is exact (its flag
and an exact input), one number style, no raw Python (complex reprs, binary-float fractions,
17-digit floats).

Expected values come from closed forms worked by hand, not from the code under test:

* ``rot``: A_c = [[0, 1], [−4, 0.1]] has eigenvalues 0.05 ± jω, ω = √3.9975; sampled with
  T = 1/4 the pair is exp(T(0.05 ± jω)), of modulus e^{0.0125}, a degenerate second-order pair
  with φ/2π = ωT/π irrational, so p_c = 1 − e^{−0.025} (Mo–Sinopoli Thm 5, D_M = 0).
* ``unst``: A_c = [[1, 1], [0, −2]] sampled with T = 1/5: λ = e^{1/5}, e^{−2/5}, one unstable
  eigenvalue, so p_c = p_low = 1 − e^{−2/5}.
"""
from __future__ import annotations

import math
import re

import numpy as np
import pytest
import scipy.linalg as sla

from kfcrit.analysis.record import AnalysisOptions, analyze_system
from kfcrit.analysis.sections import AnalysisRecord
from kfcrit.analysis.spec import load_spec, spec_from_mapping
from kfcrit.theory.critical.numtext import approx_text, complex_text, modulus_from_p_low, value_text
from kfcrit.views.figures import record as figures
from kfcrit.views.formatting import sig
from kfcrit.views.report import render as report
from kfcrit.views.report.theory import bounds_view, structure_view
from kfcrit.views.report.verdict import verdict_view
from tests.views.test_report import REPORTS, visible_text

ROT = {"name": "oscillator",
       "continuous": {"A": [[0, 1], [-4, 0.1]], "Q": [[0, 0], [0, 1]]},
       "sampling_time": "1/4", "C": [[1, 0]], "R": 1,
       "channel": {"model": "bernoulli", "arrival_probability": 0.9}}
UNST = {"name": "unstable continuous plant",
        "continuous": {"A": [[1, 1], [0, -2]], "Q": [[1, 0], [0, 2]]},
        "sampling_time": "1/5", "C": [[1, 0]], "R": 1,
        "channel": {"model": "bernoulli", "arrival_probability": 0.9}}

OMEGA = math.sqrt(3.9975)
ROT_PC = 1 - math.exp(-0.025)
UNST_PC = 1 - math.exp(-0.4)

_CACHE: dict[str, AnalysisRecord] = {}


def record_of(doc: dict, key: str) -> AnalysisRecord:
    if key not in _CACHE:
        _CACHE[key] = analyze_system(spec_from_mapping(doc), AnalysisOptions(quick=True, seed=0))
    return _CACHE[key]


def tracker() -> AnalysisRecord:
    if "tracker" not in _CACHE:
        spec = load_spec(REPORTS / "continuous-cv-tracker.yaml")
        _CACHE["tracker"] = analyze_system(spec, AnalysisOptions(quick=True, seed=0))
    return _CACHE["tracker"]


def page_text(rec: AnalysisRecord) -> str:
    return visible_text(report.render_html(rec, figures.build_figures(rec)))


def between(text: str, start: str, end: str) -> str:
    assert start in text, start
    part = text.split(start, 1)[1]
    assert end in part, end
    return part.split(end, 1)[0]


LONG_DECIMAL = re.compile(r"\d+\.\d+")


def long_decimals(text: str) -> list[str]:
    """Decimals of 13 or more significant digits (a float's full repr, not a stated rounding)."""
    return [m for m in LONG_DECIMAL.findall(text) if len(m.replace(".", "").lstrip("0")) >= 13]


PY_COMPLEX = re.compile(r"\d[+-]\d[\d.e+-]*j|\dj\)|\dj\|")


def reason_texts(rec: AnalysisRecord) -> list[str]:
    th, cv = rec.theory, rec.critical_value
    return [t for t in [cv.reason if cv is not None else None,
                        *([th.stochastic_boundedness, *th.almost_sure] if th is not None else [])]
            if isinstance(t, str)]


# ----------------------------------------------------------------------------- the records

def test_the_records_hold_the_hand_derived_values():
    rot, unst = record_of(ROT, "rot"), record_of(UNST, "unst")
    assert rot.system.exact_input is False
    assert rot.critical_value.value == pytest.approx(ROT_PC, rel=1e-12)
    assert unst.system.exact_input is True
    assert unst.critical_value.value == pytest.approx(UNST_PC, rel=1e-12)


# ----------------------------------------------------------------------------- floating-point input

def test_float_input_verdict_and_bounds_carry_no_exact_label():
    rec = record_of(ROT, "rot")
    text = page_text(rec)
    verdict = between(text, "critical value p c", "margin")
    assert "exact" not in verdict and "algebraic" not in verdict, verdict
    assert f"p c ≈ {ROT_PC:#.6g} · numerical" in verdict
    p_c_row = between(text, "critical value p_c", "robust critical value")
    assert "exact" not in p_c_row, p_c_row
    assert "numerical" in p_c_row and f"{ROT_PC:#.8g}" in p_c_row
    v = verdict_view(rec)
    assert v["critical_exact"] is False and v["critical_expression"] is None
    rows = {r["symbol"]: r for r in bounds_view(rec)["rows"]}
    assert all(r["expression"] is None for r in rows.values()), rows


def test_float_input_matrices_are_decimals_not_binary_fractions():
    rec = record_of(ROT, "rot")
    text = page_text(rec)
    assert not re.search(r"\d{10,}/\d{10,}", text)
    # A = exp(A_c T) by scipy's Padé expm (a second method), shown to 10 significant digits
    a = sla.expm(np.array([[0.0, 1.0], [-4.0, 0.1]]) * 0.25)
    for x in a.ravel():
        assert f"{x:#.10g}".replace("-", "−") in text
    assert "decimals to 10 significant digits" in text


def test_complex_numbers_read_a_plus_bj_and_moduli_as_decimals():
    rec = record_of(ROT, "rot")
    text = page_text(rec)
    assert not PY_COMPLEX.search(text), PY_COMPLEX.search(text)
    for reason in reason_texts(rec):
        assert not PY_COMPLEX.search(reason), reason
    r = math.exp(0.0125)
    re_, im = r * math.cos(OMEGA / 4), r * math.sin(OMEGA / 4)
    assert f"{re_:#.6g} + {im:#.6g}j (numerical)" in text
    assert f"{re_:#.6g} − {im:#.6g}j (numerical)" in text
    reason = rec.critical_value.reason
    assert f"|λ| ≈ {r:.12g}" in reason
    assert "|0." not in reason


def test_float_input_statement_gives_p_c_as_a_decimal():
    sb = record_of(ROT, "rot").theory.stochastic_boundedness
    assert f"finite mean iff p > p_c ≈ {ROT_PC:.12g}." in sb
    assert not re.search(r"\d{10,}/\d", sb) and not long_decimals(sb)


# ----------------------------------------------------------------------------- exact input, numeric path

def test_transcendental_plant_prose_numbers_are_short():
    rec = record_of(UNST, "unst")
    for reason in reason_texts(rec):
        assert not long_decimals(reason), (long_decimals(reason), reason)
    assert f"|λ₁| = {math.exp(0.2):.12g}" in rec.critical_value.reason
    assert f"p > p_c ≈ {UNST_PC:.12g}." in rec.theory.stochastic_boundedness
    text = page_text(rec)
    assert not long_decimals(text), long_decimals(text)
    assert "an algebraic number (no short closed form)" not in text   # entries involve exp


def test_transcendental_plant_shows_its_exact_modulus_and_p_low():
    rec = record_of(UNST, "unst")
    eigs = structure_view(rec)["eigenvalues"]
    assert eigs[0]["modulus"] == pytest.approx(math.exp(0.2), rel=1e-14)
    assert eigs[0]["modulus_expression"] == "exp(1/5)"
    assert eigs[0]["value"] == "exp(1/5)"
    assert eigs[1]["modulus_expression"] == "— (numerical)"
    assert eigs[1]["value"] == f"{math.exp(-0.4):#.6g} (numerical)"
    rows = {r["symbol"]: r for r in bounds_view(rec)["rows"]}
    assert rows["p_low"]["expression"] == "1 - exp(-2/5)"
    assert rows["p_c"]["expression"] is None and "exact" not in rows["p_c"]["detail"]
    verdict = between(page_text(rec), "critical value p c", "margin")
    assert "p low = 1 − exp(−2/5)" in verdict and "numerical" in verdict
    assert f"{UNST_PC:#.6g}" in verdict


# ----------------------------------------------------------------------------- exact input, exact path

def test_an_exact_unit_modulus_reads_1():
    rec = tracker()
    assert rec.system.exact_input is True
    for e in structure_view(rec)["eigenvalues"]:
        assert e["modulus_expression"] == "1" and e["value"] == "1"
    text = page_text(rec)
    table = between(text, "exact form of |λ i |", "equi-block")
    assert "numerical" not in table and table.split() == ["1", "1", "1", "1", "2", "1", "1",
                                                          "1"]


def test_marginal_mode_reason_has_no_caret_and_no_file_path():
    reason = tracker().critical_value.reason
    assert "^" not in reason and "proofs_checks/" not in reason and ".py" not in reason
    assert "θᵏ with θ = 1 − pᴵᵒ and k = ⌊w/Iₒ⌋" in reason
    assert "proof checks (check_marginal_modes)" in reason


# ----------------------------------------------------------------------------- number styles

@pytest.mark.parametrize("x, text", [
    (1 / 3, "0.333333333333"),
    (1.9999999999999998, "1.9999999999999998"),   # no rounding to a value it does not have
    (1.2214027581601699, "1.22140275816"),
    (0.5, "0.5"),
])
def test_approx_text(x, text):
    assert approx_text(x) == text


def test_complex_and_value_text():
    assert complex_text(complex(0.8886970451177834, -0.48531709481878904)) == \
        "0.888697045118 − 0.485317094819j"
    assert value_text(0.75, "3/4") == "3/4"
    assert value_text(0.75, "3/4", exact_input=False) == "≈ 0.75"
    assert value_text(0.1, "3602879701896397/36028797018963968") == "≈ 0.1"
    assert value_text(UNST_PC, None) == f"{UNST_PC:.12g}"


def test_modulus_from_p_low_inverts_sinopoli_thm3():
    text, value = modulus_from_p_low("1 - exp(-2/5)")
    assert text == "exp(1/5)" and value == pytest.approx(math.exp(0.2), rel=1e-15)
    assert modulus_from_p_low("3/4") == ("2", 2.0)            # 1 − 1/2² = 3/4
    assert modulus_from_p_low("0") is None                    # ρ(A) ≤ 1: no information


def test_sig_keeps_trailing_zeros_of_a_rounding_only():
    assert sig(1.2214027581601699) == "1.22140"
    assert sig(1.0) == "1" and sig(0.5) == "0.5"
    assert sig(0.3296799539643607, 8) == "0.32967995"
