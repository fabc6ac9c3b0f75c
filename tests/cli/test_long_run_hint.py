"""Long ``analyze`` runs are announced on stderr by the state count (no clock)."""
from __future__ import annotations

from kfcrit.cli.main import long_run_hint


def test_hint_above_fifty_states():
    assert long_run_hint(50, quick=False, simulate=True) is None
    assert long_run_hint(100, quick=False, simulate=True) == (
        "kfcrit: n = 100 states: this may take minutes; --quick skips the Monte Carlo")
    assert "--quick draft" in long_run_hint(100, quick=True, simulate=True)


def test_large_analyses_run_openblas_on_one_thread_unless_the_user_chose() -> None:
    from contextlib import nullcontext

    from kfcrit.cli.main import LONG_RUN_STATES, blas_threads_for
    from kfcrit.theory.covariance.riccati import openblas_thread_controls

    assert isinstance(blas_threads_for(LONG_RUN_STATES, {}), nullcontext)
    assert isinstance(blas_threads_for(LONG_RUN_STATES + 1, {"OPENBLAS_NUM_THREADS": "2"}),
                      nullcontext)
    controls = openblas_thread_controls()
    with blas_threads_for(LONG_RUN_STATES + 1, {}):
        assert all(int(get()) == 1 for get, _ in controls)
