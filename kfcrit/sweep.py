"""Parameter sweeps (placeholder until the sweep work lands)."""
from __future__ import annotations

from .errors import InputError


def sweep_command(sweep_file: str, *, output: str | None, scheduler: str | None,
                  workers: int | None, max_states: int) -> int:
    """Run the sweep subcommand; return the exit code."""
    raise InputError("sweep is not implemented yet", field="sweep")
