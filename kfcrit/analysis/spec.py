"""System files with every channel model: the io reader plus the models of higher layers.

:mod:`kfcrit.io.systemfile` reads and validates system files but knows only the channels of the
model layer; link budgets live in :mod:`kfcrit.link`. This module joins them: :data:`CHANNELS`
is the full table of channel parsers, and :func:`load_spec` / :func:`spec_from_mapping` are the
readers every command and the public API use.
"""
from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from kfcrit.io import systemfile
from kfcrit.io.channelfile import BASIC_CHANNELS, ChannelParser, channel_from_mapping
from kfcrit.io.systemfile import SystemSpec
from kfcrit.model.channels import Channel
from kfcrit.model.system import MAX_STATES_DEFAULT, System


def link_budget_from_mapping(data: dict, prefix: str, base_dir: Path | None) -> Channel:
    """A link-budget channel from its system-file mapping.

    :mod:`kfcrit.link.linkbudget` (and SciPy behind it) is imported here, when a file names
    a link budget, so that checking any other system file never pays for it.
    """
    from kfcrit.link.linkbudget import LinkBudget

    return LinkBudget.from_mapping(data, prefix, base_dir)


CHANNELS: Mapping[str, ChannelParser] = {**BASIC_CHANNELS, "link-budget": link_budget_from_mapping}
"""Parser of every channel model a system file may name."""


def channel_models() -> list[str]:
    """Names of the channel models a system file may use."""
    return sorted(CHANNELS)


def parse_channel(data: Any, prefix: str = "channel", base_dir: Path | None = None) -> Channel:
    """A channel of any model from its system-file mapping (errors name the field)."""
    return channel_from_mapping(data, prefix, base_dir, parsers=CHANNELS)


def spec_from_mapping(doc: Any, *, base_dir: Path | None = None,
                      max_states: int = MAX_STATES_DEFAULT) -> SystemSpec:
    """Validate a parsed system document (any channel model) and build the spec."""
    return systemfile.read_system_mapping(doc, base_dir=base_dir, max_states=max_states,
                                        channels=CHANNELS)


def load_spec(path: str | Path, *, max_states: int = MAX_STATES_DEFAULT) -> SystemSpec:
    r"""Load a system file: system, channel (any model), requirements and provenance.

    Parameters
    ----------
    path : str or pathlib.Path
        The YAML system file.
    max_states : int
        Largest state dimension accepted (the ``--max-states`` option).

    Returns
    -------
    SystemSpec
        The system, its channel, requirements, and the file's path and SHA-256.

    Raises
    ------
    kfcrit.errors.InputError
        An unreadable file, invalid YAML, or an invalid field (the message names it).

    References
    ----------
    docs/theory.md §1 (the model a file describes), §14 (trace channels).

    Examples
    --------
    >>> import pathlib, tempfile
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "scalar.yaml"
    >>> _ = path.write_text("name: scalar\nA: [[1.25]]\nC: [[1]]\nQ: 1\nR: 1\n"
    ...                     "channel: {model: bernoulli, arrival_probability: 0.5}\n")
    >>> from kfcrit import load_spec
    >>> spec = load_spec(path)
    >>> spec.system.A, spec.channel
    (Matrix([[5/4]]), Bernoulli(p=1/2))
    >>> load_spec(path.with_name("missing.yaml"))  # doctest: +ELLIPSIS
    Traceback (most recent call last):
        ...
    kfcrit.errors.InputError: file: cannot read '...missing.yaml' (no such file or not readable)
    """
    return systemfile.read_system_file(path, max_states=max_states, channels=CHANNELS)


def load_system(path: str | Path, *, max_states: int = MAX_STATES_DEFAULT) -> System:
    r"""Load only the :class:`~kfcrit.model.system.System` of a system file.

    Parameters
    ----------
    path : str or pathlib.Path
        The YAML system file.
    max_states : int
        Largest state dimension accepted.

    Returns
    -------
    System
        ``load_spec(path).system``.

    Raises
    ------
    kfcrit.errors.InputError
        As :func:`load_spec`.

    References
    ----------
    docs/theory.md §1.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "scalar.yaml"
    >>> _ = path.write_text("name: scalar\nA: [[1.25]]\nC: [[1]]\nQ: 1\nR: 1\n"
    ...                     "channel: {model: bernoulli, arrival_probability: 0.5}\n")
    >>> from kfcrit import critical_value, load_system
    >>> system = load_system(path)
    >>> system.n, critical_value(system).value.expr
    (1, 9/25)
    """
    return load_spec(path, max_states=max_states).system
