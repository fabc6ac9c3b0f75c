"""Shared test configuration: Hypothesis profiles and paths to the example systems.

Profiles (choose with ``HYPOTHESIS_PROFILE``; CI uses ``ci``):

* ``ci``: derandomized, no deadline, modest example counts — the whole suite well inside CI's limit;
* ``dev``: the Hypothesis defaults with no deadline (randomized, for local exploration);
* ``thorough``: many more examples; also enables the statistical checks marked ``slow``.
"""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

ROOT = Path(__file__).resolve().parents[1]
REPORTS = ROOT / "reports"
SHARED_CASES = ROOT / "tests" / "data" / "cases"
"""The papers' example systems and their expected values (facts from the papers, kept in the
repository: ``expected.json`` and one system file per case)."""

settings.register_profile("ci", derandomize=True, deadline=None, max_examples=30,
                          print_blob=True, suppress_health_check=[HealthCheck.too_slow])
settings.register_profile("dev", deadline=None, max_examples=100)
settings.register_profile("thorough", deadline=None, max_examples=1000,
                          suppress_health_check=[HealthCheck.too_slow])
PROFILE = os.environ.get("HYPOTHESIS_PROFILE", "dev")
# Exact-path assertions must not depend on machine load: a generous budget for this process and
# for the ``kfcrit`` subprocesses the tests start (read when kfcrit.theory.structure.eigen is imported).
os.environ.setdefault("KFCRIT_EXACT_TIME_BUDGET", "120")
settings.load_profile(PROFILE)


def pytest_configure(config: pytest.Config) -> None:
    """With pytest-xdist workers, compile the numba kernels once, before the workers start.

    Two processes (``tests/warm_jit.py``) fill the kernels' on-disk cache side by side; without
    this, on a fresh clone every worker would compile the same kernels itself at its first
    simulation. A warm cache makes this a few seconds of loading; a failure here is left for
    the tests themselves to report.
    """
    if hasattr(config, "workerinput") or not getattr(config.option, "numprocesses", None):
        return
    procs = [subprocess.Popen([sys.executable, "-m", "tests.warm_jit", part], cwd=ROOT,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
             for part in ("rre", "ergodic")]
    for proc in procs:
        try:
            proc.wait(timeout=600)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Skip ``slow`` tests unless the ``thorough`` profile is active."""
    if PROFILE == "thorough":
        return
    skip = pytest.mark.skip(reason="slow statistical check: run with HYPOTHESIS_PROFILE=thorough")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)


@pytest.fixture(scope="session")
def reports_dir() -> Path:
    return REPORTS


def example_files() -> list[Path]:
    """The example system files shipped in ``reports/`` (sweep files excluded)."""
    return sorted(p for p in REPORTS.glob("*.yaml") if not p.name.startswith("sweep-"))


@pytest.fixture(scope="session")
def example_records() -> dict[str, object]:
    """Every shipped example analysed once per test run (``--quick``), as typed records.

    Shared by the tests that only read records (schema, views, round trips), so the suite pays
    for each analysis once.
    """
    from kfcrit.analysis.record import analyze_system
    from kfcrit.analysis.spec import load_spec

    return {p.name: analyze_system(load_spec(p), quick=True) for p in example_files()}


