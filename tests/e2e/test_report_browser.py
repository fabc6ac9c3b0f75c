"""The HTML report as a user sees it: opened in headless Chromium (Debian ``chromium``).

Checks that the page loads with no failed resource and no console error, and that the rendered
DOM shows the verdict and the critical value of a real analysis; a screenshot must be produced.
Skipped only when chromium is not installed (``.ci/run`` installs it).
"""
from __future__ import annotations

import shutil
import subprocess
import tempfile
from pathlib import Path

import pytest

from kfcrit.views.figures import record as figures
from kfcrit.views.report import render as report

CHROMIUM = shutil.which("chromium") or ("/usr/bin/chromium"
                                        if Path("/usr/bin/chromium").exists() else None)
pytestmark = [pytest.mark.browser,
              pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed "
                                 "(apt-get install chromium; .ci/run does this)")]
ROOT = Path(__file__).resolve().parents[2]


def chromium(url: str, *extra: str) -> subprocess.CompletedProcess:
    with tempfile.TemporaryDirectory() as profile:
        return subprocess.run(
            [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
             "--no-first-run", "--disable-background-networking", "--disable-component-update",
             "--disable-sync", f"--user-data-dir={profile}", "--enable-logging=stderr",
             "--v=0", *extra, url], capture_output=True, text=True, timeout=120)


def page_errors(stderr: str) -> list[str]:
    """Console errors and failed loads in Chromium's log (dbus noise is not about the page)."""
    return [line for line in stderr.splitlines()
            if ("CONSOLE" in line and "ERROR" in line.upper()) or "Failed to load" in line
            or "net::ERR_" in line or "Uncaught" in line]


def test_report_in_chromium(tmp_path):
    from kfcrit.analysis.record import AnalysisOptions, analyze_system
    from kfcrit.analysis.spec import load_spec

    spec = load_spec(ROOT / "reports" / "rotation-third-turn.yaml")
    rec = analyze_system(spec, AnalysisOptions(quick=True))
    page = tmp_path / "rotation.html"
    page.write_text(report.render_html(rec, figures.build_figures(rec)), encoding="utf-8")
    run = chromium(page.as_uri(), "--dump-dom")
    assert run.returncode == 0, run.stderr[-2000:]
    dom = run.stdout
    assert 'id="verdict"' in dom and "MEAN STABLE" in dom
    assert "0.875" in dom                                        # p_c = 7/8 (MATH §4)
    assert not page_errors(run.stderr), page_errors(run.stderr)
    shot = tmp_path / "shot.png"
    run = chromium(page.as_uri(), f"--screenshot={shot}", "--window-size=1100,2400")
    assert shot.read_bytes().startswith(b"\x89PNG")


def test_command_output_in_chromium(tmp_path):
    from kfcrit.cli.report import report_command

    out = tmp_path / "scalar.html"
    code = report_command(str(ROOT / "reports" / "sinopoli-scalar.yaml"), [str(out)],
                          quick=True, max_states=50)
    assert code == 0                                             # p = 4/5 > p_c = 9/25
    run = chromium(out.as_uri(), "--dump-dom")
    assert run.returncode == 0
    assert "Review" in run.stdout and "0.36" in run.stdout      # p_c = 9/25 (MATH §3)
    assert not page_errors(run.stderr), page_errors(run.stderr)
