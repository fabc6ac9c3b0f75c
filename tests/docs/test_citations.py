"""Every section of the theory documentation that the code cites exists, and the code cites the
repository's own documentation (docs/theory.md), not an outside digest."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
THEORY = ROOT / "docs" / "theory.md"
SCANNED = ("kfcrit", "templates", "proofs_checks")
SUFFIXES = {".py", ".j2", ".html", ".css", ".md", ".txt", ".yaml", ".json"}

CITATION = re.compile(r"§\s?(\d+(?:\.\d+)?)")
HEADING = re.compile(r"^#{2,3} §(\d+(?:\.\d+)?) \S", re.M)
OUTSIDE_DIGEST = re.compile(r"MATH\s?§|MATH\.md")


def _files(top: str) -> list[Path]:
    return sorted(p for p in (ROOT / top).rglob("*")
                  if p.is_file() and p.suffix in SUFFIXES and "__pycache__" not in p.parts)


def _headings() -> set[str]:
    return set(HEADING.findall(THEORY.read_text(encoding="utf-8")))


def _citations() -> dict[str, list[str]]:
    found: dict[str, list[str]] = {}
    for top in SCANNED:
        for path in _files(top):
            text = path.read_text(encoding="utf-8")
            for m in CITATION.finditer(text):
                line = text.count("\n", 0, m.start()) + 1
                found.setdefault(m.group(1), []).append(f"{path.relative_to(ROOT)}:{line}")
    return found


def test_theory_has_the_numbered_sections():
    heads = _headings()
    top = sorted(int(h) for h in heads if "." not in h)
    assert top == list(range(1, 17)), f"docs/theory.md top-level sections: {top}"
    text = THEORY.read_text(encoding="utf-8")
    assert re.search(r"^## §1 Model$", text, re.M)
    assert re.search(r"^## §15 Networks without enumerating received sets$", text, re.M)
    assert re.search(r"^## §16 Verdicts and the review decision$", text, re.M)


def test_code_cites_something():
    assert _citations(), "no § citation found: the scan is broken"


@pytest.mark.parametrize("top", SCANNED)
def test_every_cited_section_exists(top):
    heads = _headings()
    missing = {sec: [w for w in where if w.startswith(top + "/")]
               for sec, where in _citations().items() if sec not in heads}
    missing = {sec: where for sec, where in missing.items() if where}
    assert not missing, f"sections cited but not in docs/theory.md: {missing}"


def test_code_does_not_cite_the_outside_digest():
    bad = []
    for path in _files("kfcrit"):
        for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            if OUTSIDE_DIGEST.search(line):
                bad.append(f"{path.relative_to(ROOT)}:{n}: {line.strip()}")
    assert not bad, "cite docs/theory.md (theory §n), not MATH:\n" + "\n".join(bad)


def test_templates_and_proof_checks_do_not_cite_the_outside_digest():
    bad = [f"{p.relative_to(ROOT)}" for top in ("templates", "proofs_checks")
           for p in _files(top) if OUTSIDE_DIGEST.search(p.read_text(encoding="utf-8"))]
    assert not bad, f"cite docs/theory.md, not MATH: {bad}"
