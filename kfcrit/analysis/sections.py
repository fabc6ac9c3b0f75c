"""The typed analysis record: one frozen dataclass per section, typed all the way down.

The record's JSON form (``--json``), its JSON Schema (``kfcrit schema record``) and the typed
objects are generated from these classes by :mod:`kfcrit.io.typed`; views and tests build records
through the same classes. The section classes live in :mod:`kfcrit.records` (one module per group
of sections), below the theory, so the layer that computes a section builds it as its class;
every payload — matrices, curves, per-eigenvalue tables, certificates — is a dataclass or a
list/dict of typed values, so the schema and the strict reader check every key.

``schema_version`` changes when a key is renamed or removed (never for an added key).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from kfcrit.analysis.loop.schema import LoopSection
from kfcrit.analysis.measured.section import ChannelFitSection
from kfcrit.analysis.mesh.section import MeshSection
from kfcrit.analysis.verdict import Reason, Review, exit_code_of
from kfcrit.io.typed import from_json, internal, json_schema, opt_key, to_json
from kfcrit.records.bursty import GilbertElliottSection
from kfcrit.records.contract import (
    BlockLowerBound,
    Classification,
    CriticalValueRecord,
    LowerBound,
    OperatingPoint,
    Provenance,
    RequirementAssessment,
    RequirementsRecord,
    RobustCriticalValue,
    SystemSection,
    UpperBoundRecord,
    VerificationCheck,
)
from kfcrit.records.covariance import (
    AccuracyDesign,
    CovarianceBounds,
    Invariant,
    PhaseTransition,
    StaticGain,
    TailSection,
)
from kfcrit.records.link import LinkBudgetRecord
from kfcrit.records.network import NetworkSection
from kfcrit.records.simulation import Simulation
from kfcrit.records.structure import StructureRecord, Theory

SCHEMA_VERSION = "2.0"
"""Version of the record's JSON contract (2.0: typed record with ``review``)."""


# ----------------------------------------------------------------------------- the record

CONTRACT_KEYS = ("name", "classification", "critical_value", "robust_critical_value",
                 "lower_bound", "block_lower_bound", "upper_bound", "operating_point",
                 "warnings")
"""The keys every record has had since schema 1 (kept, never renamed)."""


@dataclass(frozen=True)
class AnalysisRecord:
    """The analysis record of one system file (JSON contract, schema :data:`SCHEMA_VERSION`).

    Build with :func:`kfcrit.analyze`; read with :meth:`to_dict` (the ``--json`` form), by
    attribute (typed sections) or by key (``record["critical_value"]``, the JSON form of one
    section).
    """

    name: str
    classification: Classification | None
    critical_value: CriticalValueRecord | None
    robust_critical_value: RobustCriticalValue | None
    lower_bound: LowerBound | None
    block_lower_bound: BlockLowerBound | None
    upper_bound: UpperBoundRecord | None
    operating_point: OperatingPoint | None
    warnings: list[str]
    schema_version: str
    review: Review
    description: str | None
    system: SystemSection
    structure: StructureRecord | None
    theory: Theory | None
    covariance_bounds: CovarianceBounds | None
    static_gain: StaticGain | None
    phase_transition: PhaseTransition | None
    simulation: Simulation | None
    invariant: Invariant | None
    link_budget: LinkBudgetRecord | GilbertElliottSection | None
    """A link budget's design, or (Gilbert–Elliott channel) the bursty-link conditions."""
    requirements: RequirementsRecord | None
    verification: list[VerificationCheck]
    provenance: Provenance
    design: AccuracyDesign = opt_key()
    tail: TailSection = opt_key()
    network: NetworkSection = opt_key()
    mesh: MeshSection = opt_key()
    """A mesh file's routes, joint losses, facts, forwarding modes and N − 1 (theory §13)."""
    loop: LoopSection = opt_key()
    """A closed loop over the sensing and actuation links (theory §12)."""
    channel_fit: ChannelFitSection = opt_key()
    """A measured trace's fits and the confidence region of its verdict (theory §14)."""
    timings: dict[str, float] = internal(dict)
    """Wall-clock seconds of the sections (kept out of the JSON form: same input and seed give
    byte-identical JSON)."""

    def to_dict(self) -> dict[str, Any]:
        """The record as plain JSON types (what ``--json`` prints and every view renders)."""
        return to_json(self)

    def __getitem__(self, key: str) -> Any:
        return self.to_dict()[key]

    @property
    def decision(self) -> str:
        """The review decision: ``pass``, ``fail`` or ``undetermined``."""
        return self.review.decision.value

    @property
    def exit_code(self) -> int:
        """The documented exit code (:func:`kfcrit.analysis.verdict.exit_code_of`)."""
        return exit_code_of(any(c.passed is False for c in self.verification),
                            self.review.decision.value)

    @property
    def verdict(self) -> str | None:
        """Mean stability at the operating point (None without a channel)."""
        return self.operating_point.verdict.value if self.operating_point else None

    def __repr__(self) -> str:
        pc = self.critical_value.value if self.critical_value else None
        pc_text = (self.critical_value.expression or f"{pc:.6g}") if pc is not None else "bracket"
        cls = self.classification.value if self.classification else "?"
        return (f"<kfcrit Analysis {self.name!r}: {cls}, "
                f"p_c = {pc_text}, verdict {self.verdict or 'n/a'}, review {self.decision}>")


def record_from_json(data: dict[str, Any]) -> AnalysisRecord:
    """The typed record from its JSON form (strict: unknown, missing or mistyped keys fail)."""
    return from_json(AnalysisRecord, data)


def record_schema() -> dict[str, Any]:
    """JSON Schema (draft 2020-12) of the record's JSON form."""
    schema = json_schema(AnalysisRecord, title="kfcrit analysis record")
    schema["$id"] = f"https://kfcrit.invalid/schema/record-{SCHEMA_VERSION}.json"
    return schema


__all__ = ["SCHEMA_VERSION", "AccuracyDesign", "AnalysisRecord", "BlockLowerBound", "Classification",
           "CovarianceBounds", "CriticalValueRecord", "GilbertElliottSection", "Invariant",
           "LinkBudgetRecord", "LowerBound", "NetworkSection", "OperatingPoint", "PhaseTransition",
           "Provenance", "Reason", "RequirementAssessment", "RequirementsRecord", "Review",
           "RobustCriticalValue", "Simulation", "StaticGain", "StructureRecord", "SystemSection",
           "TailSection", "Theory", "UpperBoundRecord", "VerificationCheck", "record_from_json",
           "record_schema"]
