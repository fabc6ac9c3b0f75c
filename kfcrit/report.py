"""Design-review reports (placeholder until the report work lands)."""
from __future__ import annotations

from .errors import InputError


def report_command(system_file: str, output: str, *, fmt: str | None, quick: bool, seed: int,
                   max_states: int) -> int:
    """Write the report; return the exit code."""
    raise InputError("report is not implemented yet", field="report")
