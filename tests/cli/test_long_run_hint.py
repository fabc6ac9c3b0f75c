"""Long ``analyze`` runs are announced on stderr by the state count (no clock)."""
from __future__ import annotations

from kfcrit.cli.main import long_run_hint


def test_hint_above_fifty_states():
    assert long_run_hint(50, quick=False, simulate=True) is None
    assert long_run_hint(100, quick=False, simulate=True) == (
        "kfcrit: n = 100 states: this may take minutes; --quick skips the Monte Carlo")
    assert "--quick draft" in long_run_hint(100, quick=True, simulate=True)
