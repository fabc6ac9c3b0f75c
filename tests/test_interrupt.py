"""Interrupted runs: ``report`` and ``sweep`` killed at arbitrary moments leave the previous
output or nothing — never a truncated file — and never touch the input."""
from __future__ import annotations

import hashlib
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from .conftest import REPORTS

PREVIOUS = b"PREVIOUS OUTPUT\n"
# derandomized "random moments": spread over start-up, analysis, figures and writing
DELAYS = (0.5, 1.8, 3.2)
SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGKILL)


def _complete_html(data: bytes) -> bool:
    return data.rstrip().endswith(b"</html>")


def _complete_pdf(data: bytes) -> bool:
    return data.startswith(b"%PDF") and data.rstrip().endswith(b"%%EOF")


@pytest.mark.parametrize("sig", SIGNALS, ids=lambda s: s.name)
@pytest.mark.parametrize("suffix", [".html", ".pdf"])
def test_report_killed_mid_run(sig: signal.Signals, suffix: str, tmp_path: Path) -> None:
    src = tmp_path / "system.yaml"
    shutil.copy(REPORTS / "sinopoli-general.yaml", src)
    digest = hashlib.sha256(src.read_bytes()).hexdigest()
    out = tmp_path / f"review{suffix}"
    complete = _complete_html if suffix == ".html" else _complete_pdf
    for delay in DELAYS:
        out.write_bytes(PREVIOUS)
        proc = subprocess.Popen([sys.executable, "-m", "kfcrit", "report", str(src), "-o",
                                 str(out), "--quick"], stdout=subprocess.DEVNULL,
                                stderr=subprocess.PIPE)
        time.sleep(delay)
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=120)
        data = out.read_bytes()
        assert data == PREVIOUS or complete(data), (delay, data[:80])
        if proc.returncode not in (0, -sig):
            assert b"Traceback" not in err, err.decode()
            assert len(err.decode().strip().splitlines()[-1:]) == 1
        if sig != signal.SIGKILL:  # only SIGKILL can leave a temporary file behind
            leftovers = [p.name for p in tmp_path.iterdir() if p.name.endswith(".tmp")]
            assert not leftovers, leftovers
    assert hashlib.sha256(src.read_bytes()).hexdigest() == digest


def test_report_refuses_to_overwrite_its_input(tmp_path: Path) -> None:
    src = tmp_path / "system.html"
    shutil.copy(REPORTS / "sinopoli-scalar.yaml", src)
    before = src.read_bytes()
    proc = subprocess.run([sys.executable, "-m", "kfcrit", "report", str(src), "-o", str(src)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert src.read_bytes() == before


@pytest.mark.skipif(os.name != "posix", reason="signals")
def test_sweep_killed_then_resumed_matches_uninterrupted(tmp_path: Path) -> None:
    sweep_file = REPORTS / "sweep-link-distance.yaml"
    if not sweep_file.exists():
        pytest.skip("no example sweep file")
    work = tmp_path / "w"
    work.mkdir()
    for p in REPORTS.glob("*.yaml"):
        shutil.copy(p, work / p.name)
    digest = hashlib.sha256((work / sweep_file.name).read_bytes()).hexdigest()
    ref_dir, cut_dir = tmp_path / "ref", tmp_path / "cut"
    cmd = [sys.executable, "-m", "kfcrit", "sweep", str(work / sweep_file.name), "--workers", "1"]
    ref = subprocess.run(cmd + ["-o", str(ref_dir)], capture_output=True, text=True, timeout=600)
    assert ref.returncode == 0, ref.stderr
    for delay, sig in ((1.5, signal.SIGKILL), (2.5, signal.SIGINT), (3.0, signal.SIGTERM)):
        proc = subprocess.Popen(cmd + ["-o", str(cut_dir)], stdout=subprocess.DEVNULL,
                                stderr=subprocess.DEVNULL)
        time.sleep(delay)
        proc.send_signal(sig)
        proc.wait(timeout=120)
        for f in cut_dir.glob("*") if cut_dir.exists() else []:
            if f.suffix == ".json" and not f.name.startswith("."):
                import json

                json.loads(f.read_text())  # never truncated
    done = subprocess.run(cmd + ["-o", str(cut_dir)], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    for f in ref_dir.iterdir():
        if f.name in ("sweep.csv", "sweep.json"):  # run.json counts reused points
            assert (cut_dir / f.name).read_bytes() == f.read_bytes(), f.name
    assert hashlib.sha256((work / sweep_file.name).read_bytes()).hexdigest() == digest
