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

from ..conftest import REPORTS

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


def _children(pid: int) -> dict[int, str]:
    """Live child processes of ``pid`` (from /proc): pid → command line."""
    out = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
            cmd = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except OSError:
            continue
        fields = stat.rsplit(")", 1)[1].split()
        if int(fields[1]) == pid and fields[0] != "Z":
            out[int(entry.name)] = cmd
    return out


def _is_worker(cmd: str, sweep_cmd: str) -> bool:
    """A worker process of the sweep: spawned (``spawn_main``) or forked (the sweep's own
    command line)."""
    return "spawn_main" in cmd or cmd == sweep_cmd


def _alive(pid: int, cmd: str) -> bool:
    """The process exists, is not a zombie, and is still the one recorded (no pid reuse)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
        now = Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode(
            errors="replace")
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z" and now == cmd


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc")
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=lambda s: s.name)
def test_interrupted_sweep_leaves_no_worker_processes(sig: signal.Signals,
                                                      tmp_path: Path) -> None:
    # 3000 distinct systems: long enough to be interrupted mid-run with 2 worker processes
    sweep = tmp_path / "long.yaml"
    sweep.write_text("name: long\nsystem:\n  name: s\n  A: [[1.2, 1], [0.3, 1.1]]\n"
                     "  C: [[1, 0]]\n  Q: 1\n  R: 1\n"
                     "  channel: {model: bernoulli, arrival_probability: 0.9}\n"
                     "grid:\n  A[0][0]: {start: 1.01, stop: 9.5, num: 3000}\n")
    out = tmp_path / "out"
    args = [sys.executable, "-m", "kfcrit", "sweep", str(sweep), "--workers", "2", "-o",
            str(out)]
    proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    sweep_cmd = " ".join(args) + " "
    seen: dict[int, str] = {}
    journal = out / "sweep.journal.jsonl"
    deadline = time.monotonic() + 90
    try:
        while time.monotonic() < deadline and proc.poll() is None:
            seen.update(_children(proc.pid))
            workers = [p for p, c in seen.items() if _is_worker(c, sweep_cmd)]
            if len(workers) >= 2 and journal.exists() and journal.stat().st_size > 0:
                break
            time.sleep(0.05)
        assert proc.poll() is None, "the sweep ended before it could be interrupted"
        seen.update(_children(proc.pid))
        assert sum(_is_worker(c, sweep_cmd) for c in seen.values()) >= 2, seen
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 130, err.decode()
    assert b"Traceback" not in err, err.decode()
    # every process the sweep started (workers, resource tracker) is gone soon after it exits
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and any(_alive(p, c) for p, c in seen.items()):
        time.sleep(0.1)
    survivors = {p: c for p, c in seen.items() if _alive(p, c)}
    for p in survivors:  # do not leave them running after a failure
        os.kill(p, signal.SIGKILL)
    assert not survivors, survivors


# ---- exit codes of interruptions and internal errors ---------------------------------------

def test_exit_code_enum_has_internal_and_interrupted() -> None:
    from kfcrit.errors import ExitCode

    assert ExitCode.INTERNAL == 4 and ExitCode.INTERRUPTED == 130
    readme = (Path(__file__).resolve().parents[2] / "README.md").read_text()
    assert "| 4 |" in readme and "| 130 |" in readme


def test_cli_uses_the_enum_not_bare_exit_literals() -> None:
    import importlib
    import re

    # import_module: ``kfcrit.cli.main`` as an attribute is the click group, not the module
    for name in ("kfcrit.cli.main", "kfcrit.cli.common", "kfcrit.cli.sweep",
                 "kfcrit.analysis.sweep.run"):
        source = Path(importlib.import_module(name).__file__).read_text()
        assert not re.search(r"_exit\(\s*\d+\s*\)", source), name
        assert not re.search(r"fail\([^)]*,\s*\d+\s*\)", source, flags=re.S), name


def test_internal_error_is_one_short_line_exit_4(tmp_path: Path,
                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    from click.testing import CliRunner

    import kfcrit.io.systemfile as sf
    from kfcrit.cli.main import main

    def broken(*args: object, **kwargs: object) -> None:
        raise TypeError("x" * 5000)  # e.g. a sympy relational printed in full

    monkeypatch.setattr(sf, "read_system_file", broken)
    r = CliRunner().invoke(main, ["analyze", str(REPORTS / "sinopoli-scalar.yaml")])
    assert r.exit_code == 4
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "internal error (TypeError:" in lines[0]
    assert len(lines[0]) < 400 and "--debug" in lines[0]


_SIGTERM_AT = """
import os, signal, sys
import click
import kfcrit.io.systemfile as sf
from kfcrit.cli.main import KfcritGroup, main

def term_now():
    os.kill(os.getpid(), signal.SIGTERM)  # the handler runs before kill() returns to Python

where = sys.argv[1]
if where == "parse":   # start-up: before click has parsed the command line
    real = click.Group.parse_args
    def parse_args(self, ctx, args):
        term_now()
        return real(self, ctx, args)
    KfcritGroup.parse_args = parse_args
else:                  # inside the command, while the system file is read
    real_load = sf.read_system_file
    def read_system_file(*a, **k):
        term_now()
        return real_load(*a, **k)
    sf.read_system_file = read_system_file
sys.argv = ["kfcrit", "analyze", sys.argv[2], "--no-simulate"]
main()
"""


@pytest.mark.skipif(os.name != "posix", reason="signals")
@pytest.mark.parametrize("where", ["parse", "command"])
def test_sigterm_during_start_up_exits_130_with_one_line(where: str) -> None:
    # before the fix the handler was installed by the group callback, after parsing: a SIGTERM
    # before it ended the process with 143 and no message
    proc = subprocess.run([sys.executable, "-c", _SIGTERM_AT, where,
                           str(REPORTS / "sinopoli-scalar.yaml")],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 130, (proc.returncode, proc.stderr)
    lines = proc.stderr.strip().splitlines()
    assert lines == ["kfcrit: error: interrupted; nothing was written"], proc.stderr
    assert proc.stdout == ""


@pytest.mark.skipif(os.name != "posix", reason="signals")
def test_sigterm_once_running_exits_130_and_keeps_the_previous_output(tmp_path: Path) -> None:
    out = tmp_path / "review.html"
    out.write_bytes(PREVIOUS)
    proc = subprocess.Popen([sys.executable, "-m", "kfcrit", "report",
                             str(REPORTS / "sinopoli-general.yaml"), "-o", str(out), "--quick"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        first = proc.stderr.readline()  # "kfcrit: reading …": start-up is over
        assert first.startswith(b"kfcrit: reading"), first
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode in (130, 0), err.decode()  # 0 only if it finished first
    if proc.returncode == 130:
        assert err.decode().strip().splitlines()[-1] == \
            "kfcrit: error: interrupted; nothing was written"
        assert out.read_bytes() == PREVIOUS
    assert b"Traceback" not in err


def test_closed_stdout_pipe_exits_141_quietly() -> None:
    # `kfcrit analyze … --json | head -c 0`: the reader is gone before kfcrit writes; the
    # documented outcome is exit 141 (128 + SIGPIPE) with nothing on stderr, not an
    # "internal error".
    r, w = os.pipe()
    os.close(r)
    try:
        proc = subprocess.run([sys.executable, "-m", "kfcrit", "analyze",
                               str(REPORTS / "sinopoli-scalar.yaml"), "--json", "--no-simulate"],
                              stdout=w, stderr=subprocess.PIPE, timeout=300)
    finally:
        os.close(w)
    assert proc.returncode == 141, proc.stderr
    assert proc.stderr.decode() == ""
