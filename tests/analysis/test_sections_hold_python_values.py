"""The closed-loop, measured-link and mesh sections are built with Python values: every leaf of
the typed section is text, a bool, an int, a finite float, None or an enum (never a NumPy or
sympy number, never an infinity that only the JSON writer would turn into null), so the typed
record equals what its JSON form reads back."""
from __future__ import annotations

import dataclasses
import enum
import math
from pathlib import Path
from typing import Any

import pytest

import kfcrit
from kfcrit.analysis.spec import load_spec, spec_from_mapping
from kfcrit.io.typed import ABSENT, from_json, to_json

REPORTS = Path(__file__).resolve().parents[2] / "reports"


def foreign_leaves(value: Any, path: str) -> list[str]:
    """The places under ``value`` that hold anything but Python values (with their type)."""
    kind = type(value)
    if value is None or value is ABSENT or kind in (bool, int, str) or isinstance(value,
                                                                                enum.Enum):
        return []
    if kind is float:
        return [] if math.isfinite(value) else [f"{path}: {value!r}"]
    if kind is list:
        return [p for i, v in enumerate(value) for p in foreign_leaves(v, f"{path}[{i}]")]
    if kind is dict:
        return [p for k, v in value.items()
                for p in ([f"{path}: key {k!r}"] if type(k) is not str else [])
                + foreign_leaves(v, f"{path}.{k}")]
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return [p for f in dataclasses.fields(value)
                for p in foreign_leaves(getattr(value, f.name), f"{path}.{f.name}")]
    return [f"{path}: {kind.__name__}"]


def loop_doc(**loop: Any) -> dict:
    """A scalar plant a = 5/4 over two Bernoulli links of 4/5 (γ_c = ν_c = 9/25 < 4/5)."""
    body = {"B": [[1]], "W": 1, "U": 1,
            "channel": {"model": "bernoulli", "arrival_probability": "4/5"}, **loop}
    return {"name": "scalar loop", "A": [[1.25]], "C": [[1]], "Q": 1, "R": 1,
            "channel": {"model": "bernoulli", "arrival_probability": "4/5"}, "loop": body}


def check(section: Any, name: str) -> None:
    assert section, f"no {name} section"
    assert foreign_leaves(section, name) == []
    assert from_json(type(section), to_json(section)) == section


@pytest.mark.parametrize("loop", [{}, {"acknowledged": False, "on_loss": "hold"}],
                         ids=["tcp-optimal", "udp-hold"])
def test_loop_section_holds_python_values(loop: dict) -> None:
    spec = spec_from_mapping(loop_doc(**loop), base_dir=Path("."))
    rec = kfcrit.analyze(spec, quick=True, simulate=True)
    check(rec.loop, "loop")
    assert rec.loop.comparison and rec.loop.cost_curves and rec.loop.simulation is not None


@pytest.mark.parametrize("name, key", [("trace-bursty-link", "channel_fit"),
                                       ("trace-contention-hidden4", "channel_fit"),
                                       ("mesh-pipeline-relaying", "mesh")])
def test_measured_and_mesh_sections_hold_python_values(name: str, key: str) -> None:
    rec = kfcrit.analyze(load_spec(REPORTS / f"{name}.yaml"), quick=True)
    check(getattr(rec, key), key)
