"""The ``structure`` (eigen-structure of (A, C)) and ``theory`` (moment thresholds, boundedness,
almost-sure statements) sections.
"""
from __future__ import annotations

from dataclasses import dataclass

from kfcrit.io.typed import opt_key


@dataclass(frozen=True, kw_only=True)
class StructureTolerances:
    """`structure.tolerances`"""

    exact: bool = opt_key()
    time_budget_seconds: float | None = opt_key()
    max_states: int = opt_key()
    modulus_relative: float | None = opt_key()
    rank_relative: float | None = opt_key()
    turn_absolute: float | None = opt_key()
    eigenvalue_cluster_relative: float | None = opt_key()
    geometric_multiplicity_relative: float | None = opt_key()
    max_denominator: int = opt_key()
    certified_enclosures: bool = opt_key()
    precision_bits: int = opt_key()


@dataclass(frozen=True, kw_only=True)
class Eigenvalue:
    """`structure.eigenvalues[]`"""

    value: str
    re: float | None
    im: float | None
    modulus: float | None
    modulus_expression: str


@dataclass(frozen=True, kw_only=True)
class EquiBlockRecord:
    """`structure.equi_blocks[]`"""

    indices: list[int]
    modulus: float | None
    modulus_expression: str
    one_step_observable: bool
    rank: int
    size: int
    unstable_or_critical: bool


@dataclass(frozen=True, kw_only=True)
class EqualModulusPair:
    """`structure.equal_modulus_pairs[]`"""

    indices: list[int]
    rank: int
    size: int
    degenerate: bool
    q: int | None
    turn: float | None
    turn_expression: str


@dataclass(frozen=True, kw_only=True)
class StandardFormBlock:
    """`structure.standard_form.equi_blocks[]`"""

    indices: list[int]
    eigenvalues: list[str] | list[list[float | None]]
    C_columns: list[list[str]] | list[list[list[float | None]]]


@dataclass(frozen=True, kw_only=True)
class StandardForm:
    """`structure.standard_form`"""

    eigenvalues: list[str] | list[list[float | None]]
    basis: str
    equi_blocks: list[StandardFormBlock]


@dataclass(frozen=True, kw_only=True)
class StructureRecord:
    """`structure`"""

    path: str
    path_reason: str
    tolerances: StructureTolerances
    eigenvalues: list[Eigenvalue]
    equi_blocks: list[EquiBlockRecord]
    equal_modulus_pairs: list[EqualModulusPair]
    diagonalizable: bool
    detectable: bool
    controllable_Q: bool
    observability_index: int | None
    observable: bool
    standard_form: StandardForm
    unresolved: list[str]


@dataclass(frozen=True, kw_only=True)
class MomentThreshold:
    """`theory.moment_thresholds[]`"""

    q: int
    value: float | None
    expression: str | None
    applies: bool


@dataclass(frozen=True, kw_only=True)
class Theory:
    """`theory`"""

    moment_thresholds: list[MomentThreshold]
    moment_thresholds_note: str
    stochastic_boundedness: str
    almost_sure: list[str]
    observability_index: int | None
