"""A saved record of another schema major version is refused (exit 2 naming schema_version)."""
from __future__ import annotations

import json

from click.testing import CliRunner

from kfcrit.cli.main import main

from ..conftest import REPORTS


def test_future_schema_version_refused(tmp_path):
    r = CliRunner().invoke(main, ["analyze", str(REPORTS / "sinopoli-scalar.yaml"), "--json",
                                  "--quick", "--no-simulate"])
    rec = json.loads(r.stdout)
    rec["schema_version"] = "999.0"
    saved = tmp_path / "record.json"
    saved.write_text(json.dumps(rec))
    out = tmp_path / "review.html"
    r = CliRunner().invoke(main, ["report", str(saved), "-o", str(out)])
    assert r.exit_code == 2
    assert "schema_version" in r.output and not out.exists()
