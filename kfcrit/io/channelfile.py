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

import numpy as np

from kfcrit.errors import InputError
from kfcrit.io.safeio import read_text
from kfcrit.model.channels import Bernoulli, Channel, GilbertElliott, Trace, check_keys

MAX_TRACE_BYTES = 50_000_000
"""Largest trace file read (bytes)."""

ChannelParser = Callable[[dict, str, "Path | None"], Channel]


def read_trace(path: Path, field: str) -> np.ndarray:
    """Read a 0/1 packet trace; anything but 0 and 1 separated by spaces/commas is an error."""
    text, _ = read_text(path, field=field, max_bytes=MAX_TRACE_BYTES, what="trace file")
    tokens = text.replace(",", " ").split()
    bad = next((i for i, t in enumerate(tokens) if t not in ("0", "1")), None)
    if bad is not None:  # the offending text is not echoed: the file may not be a trace at all
        raise InputError(f"trace file value number {bad + 1} is not 0 or 1; only 0 and 1 are "
                         "allowed", field=field)
    if not tokens:
        raise InputError("trace file is empty", field=field)
    arr = np.fromiter((t == "1" for t in tokens), dtype=bool, count=len(tokens))
    arr.setflags(write=False)
    return arr


def trace_from_mapping(data: dict, prefix: str, base_dir: Path | None = None) -> Trace:
    """``{model: trace, path: FILE}``: the file is read relative to the system file's folder."""
    check_keys(data, {"model", "path"}, {"path"}, prefix)
    raw = data["path"]
    if not isinstance(raw, str) or not raw.strip():
        raise InputError("must be a file path", field=f"{prefix}.path")
    path = Path(raw)
    if not path.is_absolute() and base_dir is not None:
        path = base_dir / path
    return Trace(raw, read_trace(path, f"{prefix}.path"))


BASIC_CHANNELS: Mapping[str, ChannelParser] = {
    "bernoulli": Bernoulli.from_mapping,
    "gilbert-elliott": GilbertElliott.from_mapping,
    "trace": trace_from_mapping,
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
