"""Random Riccati simulation (placeholder until the simulation work lands)."""
from __future__ import annotations

from .errors import InputError


def simulate_command(system_file: str, *, paths: int, steps: int, seed: int, as_json: bool,
                     plot: str | None, max_states: int) -> int:
    """Run the simulate subcommand; return the exit code."""
    raise InputError("simulate is not implemented yet", field="simulate")
