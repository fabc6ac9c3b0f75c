"""Channels from system files: the models of :mod:`kfcrit.model.channels` and measured traces.

:func:`channel_from_mapping` dispatches on ``model`` through a table of parsers; the table of this
layer (:data:`BASIC_CHANNELS`) knows the channels that need no radio model. Higher layers pass a
larger table (:func:`kfcrit.analysis.spec.parse_channel` adds ``link-budget``), so reading a file
never imports upward.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from kfcrit.errors import InputError
from kfcrit.io.tracechannel import measured_trace_from_mapping
from kfcrit.io.traceformats import MAX_TRACE_BYTES
from kfcrit.model.channels import Bernoulli, Channel, GilbertElliott

__all__ = ["BASIC_CHANNELS", "MAX_TRACE_BYTES", "ChannelParser", "channel_from_mapping"]

ChannelParser = Callable[[dict, str, "Path | None"], Channel]


BASIC_CHANNELS: Mapping[str, ChannelParser] = {
    "bernoulli": Bernoulli.from_mapping,
    "gilbert-elliott": GilbertElliott.from_mapping,
    "trace": measured_trace_from_mapping,
}
"""Parsers of the channel models that need no radio model."""


def channel_from_mapping(data: Any, prefix: str = "channel", base_dir: Path | None = None, *,
                         parsers: Mapping[str, ChannelParser] = BASIC_CHANNELS) -> Channel:
    """Build a channel from its system-file mapping, dispatching on ``model``."""
    known = ", ".join(sorted(parsers))
    if not isinstance(data, dict):
        raise InputError("must be a mapping with a 'model' key", field=prefix)
    model = data.get("model")
    if not isinstance(model, str):
        raise InputError(f"is required (one of: {known})", field=f"{prefix}.model")
    if model not in parsers:
        raise InputError(f"unknown channel model {model[:40]!r} (known: {known})",
                         field=f"{prefix}.model")
    return parsers[model](data, prefix, base_dir)
