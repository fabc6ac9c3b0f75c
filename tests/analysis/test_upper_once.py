"""p_up is computed once per record: the covariance bounds, static gains and phase-transition
curve take the bracket the theory sections computed (no memo behind the scenes)."""
from __future__ import annotations

from pathlib import Path

import pytest

from kfcrit.analysis.record import AnalysisOptions, analyze_system
from kfcrit.analysis.spec import load_spec
from kfcrit.theory.upper import bracket

REPORTS = Path(__file__).resolve().parents[2] / "reports"


@pytest.mark.parametrize("name", ["sinopoli-general", "mo-nondegenerate-four", "loop-dc-motor"])
def test_one_bracket_per_record(name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    calls: list[tuple] = []
    real = bracket._solve

    def counting(problem):  # noqa: ANN001, ANN202
        calls.append(problem.key)
        return real(problem)

    monkeypatch.setattr(bracket, "_solve", counting)
    rec = analyze_system(load_spec(REPORTS / f"{name}.yaml"),
                         AnalysisOptions(simulate=False, quick=True))
    assert rec["covariance_bounds"] is not None and rec["phase_transition"] is not None
    # the estimator's p_up(A, C) once; a closed loop adds its actuation threshold p_up(A', B')
    systems = {key[0] for key in calls}
    assert len(calls) == len(systems) <= 2
