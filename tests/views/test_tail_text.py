"""The tail exponent β as the report writes it never contradicts the exact comparisons that
decide whether E[tr P] (β > 1) and its variance (β > 2) are finite (theory §5)."""
from __future__ import annotations

from kfcrit.views.report.design import beta_text


def test_a_beta_that_rounds_onto_one_is_written_on_its_exact_side() -> None:
    assert beta_text(1.0, True, False).startswith("1⁺")      # p = 9/25 + 10⁻⁴⁰
    assert beta_text(1.0000000000000002, False, False).startswith("≤ 1")
    assert beta_text(2.0, True, True).startswith("2⁺")


def test_an_ordinary_beta_is_its_number() -> None:
    assert beta_text(1.5, True, False) == "1.5"
    assert beta_text(0.5, False, False) == "0.5"
    assert beta_text(3.25, True, True) == "3.25"
