"""Packaging and command-line plumbing: the wheel ships the templates; entry points work."""
from __future__ import annotations

import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
from click.testing import CliRunner

import kfcrit
from kfcrit.cli.main import main
from kfcrit.errors import ExitCode

from ..conftest import ROOT


def test_exit_codes_are_documented_enum() -> None:
    assert [int(c) for c in ExitCode] == [0, 1, 2, 3, 4, 5, 130, 141]
    readme = (ROOT / "README.md").read_text()
    for code in ExitCode:
        assert f"| {int(code)} |" in readme


def test_version_and_help() -> None:
    r = CliRunner().invoke(main, ["--version"])
    assert r.exit_code == 0 and kfcrit.__version__ in r.stdout
    r = CliRunner().invoke(main, ["--help"])
    assert r.exit_code == 0 and "Examples:" in r.stdout and "analyze" in r.stdout


def test_python_dash_m() -> None:
    proc = subprocess.run([sys.executable, "-m", "kfcrit", "--version"], capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 0 and kfcrit.__version__ in proc.stdout


def test_unknown_option_is_usage_error() -> None:
    r = CliRunner().invoke(main, ["analyze", "--no-such-option", "x.yaml"])
    assert r.exit_code == 2


def test_wheel_contains_package_and_templates(tmp_path: Path) -> None:
    pytest.importorskip("hatchling")
    out = tmp_path / "dist"
    src = tmp_path / "src"
    shutil.copytree(ROOT, src, ignore=shutil.ignore_patterns(".git", "__pycache__", "*.egg-info",
                                                             ".hypothesis", "dist", "build"))
    proc = subprocess.run([sys.executable, "-m", "build", "--wheel", "--no-isolation",
                           "--outdir", str(out), str(src)], capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    wheels = list(out.glob("kfcrit-*.whl"))
    assert len(wheels) == 1
    names = zipfile.ZipFile(wheels[0]).namelist()
    assert "kfcrit/__init__.py" in names and "kfcrit/cli/main.py" in names
    assert "kfcrit/analysis/verdict.py" in names and "kfcrit/api/notebook.py" in names
    templates = sorted(n for n in names if n.startswith("kfcrit/templates/"))
    repo_templates = sorted(p.name for p in (ROOT / "templates").iterdir() if p.is_file())
    assert repo_templates, "templates/ is empty"
    assert [Path(n).name for n in templates] == repo_templates
    assert any(n.endswith("entry_points.txt") for n in names)


def test_ruff_clean() -> None:
    ruff = shutil.which("ruff")
    if ruff is None:
        pytest.skip("ruff is not installed (it is in the 'test' extra)")
    proc = subprocess.run([ruff, "check", str(ROOT)], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stdout[-3000:]
