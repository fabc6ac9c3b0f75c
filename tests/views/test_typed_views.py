"""The views read the typed record: the same record built by the analysis and read back from its
JSON form (``--json``, :func:`record_from_json`) renders the same terminal summary and figures,
and an absent optional key is never printed (no ``ABSENT`` in the text)."""
from __future__ import annotations

from pathlib import Path

import pytest

from kfcrit.analysis.record import AnalysisOptions, analyze_system
from kfcrit.analysis.sections import record_from_json
from kfcrit.analysis.spec import load_spec
from kfcrit.views.figures import record as figures
from kfcrit.views.text import terminal

REPORTS = Path(__file__).resolve().parents[2] / "reports"

STEMS = ("sinopoli-scalar", "network-redundant-gauges", "mesh-pipeline-relaying",
         "loop-tcp-vs-udp", "trace-bursty-link", "link-oqpsk-sensor")


@pytest.fixture(scope="module", params=STEMS)
def analysed(request):
    spec = load_spec(REPORTS / f"{request.param}.yaml")
    return analyze_system(spec, AnalysisOptions(simulate=False))


def test_summary_of_the_record_and_of_its_json_form_agree(analysed) -> None:
    text = terminal.summary(analysed)
    assert text == terminal.summary(record_from_json(analysed.to_dict()))
    assert text.startswith(f"kfcrit analysis: {analysed.name}")
    assert "ABSENT" not in text


def test_figure_names_of_the_record_and_of_its_json_form_agree(analysed) -> None:
    names = figures.figure_names(analysed)
    assert names == figures.figure_names(record_from_json(analysed.to_dict()))
    assert set(names) <= set(figures.FIGURE_KEYS)
