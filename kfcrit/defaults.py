"""Defaults shared by every layer, importable without the numerical stack (so that the command
line answers ``--help`` and input errors at once)."""
from __future__ import annotations

MAX_STATES_DEFAULT = 400
"""Largest state dimension accepted unless ``--max-states`` / ``max_states`` raises it."""

DEFAULT_TOLERANCE = 1e-9
"""Relative perturbation size of the robust critical value (``--tolerance``)."""
