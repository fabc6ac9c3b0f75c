"""Every module path the documentation names (``kfcrit/…/x.py`` in README.md and docs/) exists:
the docs follow the package when it moves."""
from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PATH = re.compile(r"kfcrit/[A-Za-z0-9_/]+\.py")


def test_every_named_module_exists() -> None:
    docs = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    missing = sorted({(d.name, p) for d in docs for p in PATH.findall(d.read_text())
                      if not (ROOT / p).is_file()})
    assert missing == []
