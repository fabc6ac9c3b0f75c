"""Every public object and theory entry point has a numpydoc docstring with the sections
Parameters, Returns (Attributes for classes), Raises, References and Examples; the references
cite docs/theory.md by section."""
from __future__ import annotations

import inspect
import re

import pytest

from tests.docs.public_docs import DOCUMENTED, NO_PARAMETERS, resolve


def _sections(doc: str) -> set[str]:
    return set(re.findall(r"^([A-Z][A-Za-z ]+)\n-{3,}\s*$", doc, re.M))


@pytest.mark.parametrize("spec", DOCUMENTED)
def test_numpydoc_sections(spec):
    obj = resolve(spec)
    doc = inspect.getdoc(obj)
    assert doc, f"{spec} has no docstring"
    found = _sections(doc)
    wanted = {"Raises", "References", "Examples"}
    wanted.add("Attributes" if inspect.isclass(obj) else "Returns")
    if spec not in NO_PARAMETERS:
        wanted.add("Parameters")
    missing = wanted - found
    assert not missing, f"{spec}: docstring lacks the section(s) {sorted(missing)}"


@pytest.mark.parametrize("spec", DOCUMENTED)
def test_references_cite_the_theory_document(spec):
    doc = inspect.getdoc(resolve(spec))
    refs = doc.split("References\n----------", 1)[1].split("\nExamples\n--------", 1)[0]
    assert re.search(r"docs/theory\.md §\d+", refs), f"{spec}: References cite no docs/theory.md §"
    assert ">>>" in doc.split("Examples\n--------", 1)[1], f"{spec}: Examples has no example"
