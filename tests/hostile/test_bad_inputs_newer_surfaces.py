"""Issue 18, items 8-12: outputs, the sweep journal, Dask schedulers, exit codes, terminal text.

Each test is built from the case the audit reported; files are written here, nothing outside the
repository is read (devices are created in the test folder, /dev/null and /dev/full are only
written to, never read, and /dev/null is only *checked*, never a write target).
"""
from __future__ import annotations

import errno
import json
import os
import signal
import socket
import stat
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

import kfcrit.analysis.sweep.points as sweep_mod
import kfcrit.analysis.sweep.run as run_mod
from kfcrit.analysis.sweep.journal import Journal, journal_check, valid_result
from kfcrit.cli.main import main
from kfcrit.errors import ExitCode, OutputError
from kfcrit.io.atomic import check_writable, write_atomic

from ..conftest import REPORTS

BERNOULLI = """\
name: scalar bernoulli
A: [[1.25]]
C: [[1]]
Q: [[1]]
R: [[2.5]]
channel: {model: bernoulli, arrival_probability: 0.5}
"""
SWEEP = "system: system.yaml\ngrid: {channel.arrival_probability: [0.5, 0.9, 0.95]}\n"


def run_cli(args: list[str]) -> tuple[int, str, str]:
    r = CliRunner().invoke(main, args)
    return r.exit_code, r.stdout, r.stderr


def one_error_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("kfcrit: error: "), err
    assert "Traceback" not in err
    return lines[0]


def make_char_device(path: Path) -> None:
    """A character device with the numbers of /dev/null (harmless if anything wrote to it)."""
    try:
        os.mknod(path, stat.S_IFCHR | 0o666, os.makedev(1, 3))
    except (PermissionError, AttributeError) as exc:
        pytest.skip(f"cannot create a device node here: {exc}")


def assert_same_device(path: Path, before: os.stat_result) -> None:
    now = os.lstat(path)
    assert stat.S_ISCHR(now.st_mode)
    assert (now.st_rdev, now.st_ino) == (before.st_rdev, before.st_ino)


# ---- 8: outputs that are not regular files -------------------------------------------------

def test_dev_null_is_refused_by_the_check_alone() -> None:
    with pytest.raises(OutputError, match="character device"):
        check_writable(os.devnull)


def test_link_to_dev_null_is_refused_by_the_check(tmp_path: Path) -> None:
    link = tmp_path / "out.html"
    link.symlink_to(os.devnull)
    with pytest.raises(OutputError, match="character device"):
        check_writable(link)
    assert link.is_symlink()


@pytest.mark.parametrize("command", ["report", "simulate"])
def test_report_and_plot_refuse_a_character_device(command: str, tmp_path: Path) -> None:
    node = tmp_path / ("node.html" if command == "report" else "node.svg")
    make_char_device(node)
    before = os.lstat(node)
    system = str(REPORTS / "sinopoli-scalar.yaml")
    args = (["report", system, "-o", str(node), "--quick"] if command == "report" else
            ["simulate", system, "--paths", "10", "--steps", "10", "--plot", str(node)])
    code, out, err = run_cli(args)
    assert code == ExitCode.BAD_INPUT, err
    line = one_error_line(err)
    assert str(node) in line and "character device" in line
    assert_same_device(node, before)
    assert sorted(p.name for p in tmp_path.iterdir()) == [node.name]  # no temporary file left


def test_write_atomic_refuses_a_device_and_leaves_it(tmp_path: Path) -> None:
    node = tmp_path / "dev"
    make_char_device(node)
    before = os.lstat(node)
    with pytest.raises(OutputError, match="character device"):
        write_atomic(node, b"data")
    assert_same_device(node, before)
    assert [p.name for p in tmp_path.iterdir()] == ["dev"]


def test_write_atomic_refuses_a_fifo(tmp_path: Path) -> None:
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    with pytest.raises(OutputError, match="FIFO"):
        write_atomic(fifo, b"data")
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)


def test_device_swapped_in_after_the_check_is_not_replaced(tmp_path: Path,
                                                           monkeypatch: pytest.MonkeyPatch) -> None:
    """A node that appears between the early check and the rename is still refused."""
    target = tmp_path / "report.html"
    real_fsync = os.fsync

    def fsync_then_swap(fd: int) -> None:
        real_fsync(fd)
        if not target.exists():
            make_char_device(target)

    monkeypatch.setattr(os, "fsync", fsync_then_swap)
    with pytest.raises(OutputError, match="character device"):
        write_atomic(target, b"<html></html>")
    assert stat.S_ISCHR(os.lstat(target).st_mode)
    assert [p.name for p in tmp_path.iterdir()] == ["report.html"]


def test_symlink_is_written_through_in_the_target_folder(tmp_path: Path,
                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    """The temporary file is created beside the link's *target*: the rename never crosses file
    systems, so a link into another file system cannot fail with EXDEV after the run."""
    here, there = tmp_path / "here", tmp_path / "there"
    here.mkdir()
    there.mkdir()
    (there / "report.html").write_text("old")
    link = here / "report.html"
    link.symlink_to(there / "report.html")
    renames: list[tuple[str, str]] = []
    real_replace = os.replace

    def cross_device_unless_same_folder(src: str, dst: str) -> None:
        renames.append((str(src), str(dst)))
        if Path(src).parent != Path(dst).parent:
            raise OSError(errno.EXDEV, "Invalid cross-device link")
        real_replace(src, dst)

    monkeypatch.setattr(os, "replace", cross_device_unless_same_folder)
    write_atomic(link, b"new")
    assert link.is_symlink() and (there / "report.html").read_text() == "new"
    assert renames and all(Path(s).parent == there.resolve() for s, _ in renames)
    assert sorted(p.name for p in there.iterdir()) == ["report.html"]


def test_own_files_replace_a_planted_link_instead_of_following_it(tmp_path: Path) -> None:
    victim = tmp_path / "victim.txt"
    victim.write_text("keep")
    link = tmp_path / "sweep.csv"
    link.symlink_to(victim)
    write_atomic(link, b"table", follow_symlinks=False)
    assert not link.is_symlink() and link.read_text() == "table"
    assert victim.read_text() == "keep"


# ---- 9: the sweep journal --------------------------------------------------------------------

def sweep_case(folder: Path, text: str = SWEEP) -> Path:
    (folder / "system.yaml").write_text(BERNOULLI)
    (folder / "sweep.yaml").write_text(text)
    return folder / "sweep.yaml"


def tables(folder: Path) -> dict[str, bytes]:
    return {n: (folder / n).read_bytes() for n in ("sweep.csv", "sweep.json")}


def test_journal_symlink_is_refused_and_its_target_untouched(tmp_path: Path) -> None:
    sweep = sweep_case(tmp_path)
    victim = tmp_path / "victim.txt"
    victim.write_text("precious\n")
    out = tmp_path / "out"
    out.mkdir()
    (out / "sweep.journal.jsonl").symlink_to(victim)
    code, _, err = run_cli(["sweep", str(sweep), "-o", str(out), "--workers", "1"])
    assert code == ExitCode.BAD_INPUT
    assert "symbolic link" in one_error_line(err)
    assert victim.read_text() == "precious\n"
    assert sorted(p.name for p in out.iterdir()) == ["sweep.journal.jsonl"]


def test_journal_append_never_follows_a_link(tmp_path: Path) -> None:
    victim = tmp_path / "victim.txt"
    victim.write_text("precious\n")
    path = tmp_path / "sweep.journal.jsonl"
    path.symlink_to(victim)
    with pytest.raises(OutputError, match="symbolic link"):
        Journal(path, "x" * 64, sweep_mod.RESULT_COLUMNS).append([("a" * 64, {"status": "ok"})])
    assert victim.read_text() == "precious\n"


def _rewrite(journal: Path, edit, *, recheck: bool, binding: str) -> None:  # noqa: ANN001
    lines = []
    for i, line in enumerate(journal.read_text().splitlines()):
        entry = json.loads(line)
        edit(i, entry["result"])
        if recheck:  # an adversary who recomputes the check from kfcrit's source
            entry["check"] = journal_check(binding, entry["key"], entry["result"])
        lines.append(json.dumps(entry))
    journal.write_text("\n".join(lines) + "\n")


@pytest.mark.parametrize("recheck", [False, True], ids=["stale-check", "recomputed-check"])
def test_forged_journal_entries_are_recomputed_not_reused(tmp_path: Path, recheck: bool) -> None:
    sweep = sweep_case(tmp_path)
    ref, out = tmp_path / "ref", tmp_path / "out"
    assert run_cli(["sweep", str(sweep), "-o", str(ref), "--workers", "1"])[0] == 0
    assert run_cli(["sweep", str(sweep), "-o", str(out), "--workers", "1"])[0] == 0
    binding = sweep_mod.load_sweep(sweep).sha256

    def forge(i: int, result: dict) -> None:
        if i == 0:
            result["classification"] = "<script>alert(1)</script>"
        elif i == 1:
            result.update(status="error", error="interrupted", error_code=130)
        else:
            result["verdict"] = ("mean-unstable" if result["verdict"] == "mean-stable"
                                 else "mean-stable")

    _rewrite(out / "sweep.journal.jsonl", forge, recheck=recheck, binding=binding)
    code, _, err = run_cli(["sweep", str(sweep), "-o", str(out), "--workers", "1"])
    # the edited verdict passes the shape check; only a recomputed check can make it pass
    recomputed = 2 if recheck else 3
    assert code == 0, err  # never 130 from a journal line
    assert f"({recomputed} computed, {3 - recomputed} from the journal)" in err
    data = tables(out)
    assert b"<script>" not in data["sweep.csv"] and b"<script>" not in data["sweep.json"]
    if not recheck:
        assert data == tables(ref)


def test_journal_lines_of_another_sweep_file_are_not_reused(tmp_path: Path) -> None:
    sweep = sweep_case(tmp_path)
    out = tmp_path / "out"
    assert run_cli(["sweep", str(sweep), "-o", str(out), "--workers", "1"])[0] == 0
    sweep.write_text("# edited\n" + SWEEP)
    code, _, err = run_cli(["sweep", str(sweep), "-o", str(out), "--workers", "1"])
    assert code == 0 and "(3 computed, 0 from the journal)" in err


def test_journal_lines_without_a_check_are_not_reused(tmp_path: Path) -> None:
    sweep = sweep_case(tmp_path)
    out = tmp_path / "out"
    assert run_cli(["sweep", str(sweep), "-o", str(out), "--workers", "1"])[0] == 0
    journal = out / "sweep.journal.jsonl"
    old = [json.loads(line) for line in journal.read_text().splitlines()]
    journal.write_text("".join(json.dumps({"key": e["key"], "result": e["result"]}) + "\n"
                               for e in old))
    code, _, err = run_cli(["sweep", str(sweep), "-o", str(out), "--workers", "1"])
    assert code == 0 and "(3 computed, 0 from the journal)" in err


def test_valid_result_accepts_computed_rows_and_refuses_mutations() -> None:
    doc = {"name": "p", "A": [["1.25"]], "C": [["1"]], "Q": [["1"]], "R": [["2.5"]],
           "channel": {"model": "bernoulli", "arrival_probability": "0.9"}}
    columns = sweep_mod.RESULT_COLUMNS
    ok = sweep_mod.evaluate_point(doc, ".", 1e-9, 400, [])
    bad_doc = dict(doc, channel={"model": "bernoulli", "arrival_probability": "1.5"})
    error = sweep_mod.evaluate_point(bad_doc, ".", 1e-9, 400, [])
    assert ok["status"] == "ok" and error["status"] == "error"
    assert valid_result(ok, columns) and valid_result(error, columns)
    mutations = [
        {"verdict": "MEAN-STABLE"}, {"decision": "maybe"}, {"margin": "0.5"},
        {"classification": "\x1b[2Kstable"}, {"critical_expression": "<b>9/25</b>"},
        {"iid": "yes"}, {"status": "done"}, {"extra": 1}, {"error_code": 2},
    ]
    for change in mutations:
        assert not valid_result({**ok, **change}, columns), change
    for code in (0, 4, 5, 130, 141, True, "2"):
        assert not valid_result({**error, "error_code": code}, columns), code
    assert not valid_result({k: v for k, v in ok.items() if k != "margin"}, columns)


def test_full_disk_during_a_sweep_is_one_line_and_leaves_no_journal(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    sweep = sweep_case(tmp_path)
    out = tmp_path / "out"
    real_write = os.write

    def full(fd: int, data: bytes) -> int:
        if os.path.basename(os.readlink(f"/proc/self/fd/{fd}")) == "sweep.journal.jsonl":
            raise OSError(errno.ENOSPC, "No space left on device")
        return real_write(fd, data)

    if not Path("/proc/self/fd").is_dir():
        pytest.skip("needs /proc/self/fd")
    monkeypatch.setattr(os, "write", full)
    code, _, err = run_cli(["sweep", str(sweep), "-o", str(out), "--workers", "1"])
    assert code == ExitCode.BAD_INPUT
    line = one_error_line(err)
    assert "sweep.journal.jsonl" in line and "No space left on device" in line
    assert list(out.iterdir()) == []  # no empty journal, no tables


# ---- 10: schedulers that do not speak Dask ---------------------------------------------------

class Server:
    """A local TCP server that accepts and then stays silent, sends ``payload``, or closes."""

    def __init__(self, payload: bytes | None, close: bool = False) -> None:
        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(8)
        self.port = self.sock.getsockname()[1]
        self.conns: list[socket.socket] = []
        self.payload, self.close_at_once = payload, close
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        while True:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                return
            self.conns.append(conn)
            try:
                if self.payload:
                    conn.sendall(self.payload)
                if self.close_at_once:
                    conn.close()
            except OSError:
                pass

    def stop(self) -> None:
        self.sock.close()
        for conn in self.conns:
            conn.close()


@pytest.mark.parametrize("payload, close, expected", [
    (None, False, "no Dask handshake within"),
    (b"HTTP/1.1 400 Bad Request\r\n\r\n" * 50, False, "does not speak the Dask protocol"),
    (b"\xff" * 64, False, "does not speak the Dask protocol"),  # announces 2**64 - 1 bytes
    (b"", True, "closed during the handshake"),
], ids=["silent", "http", "huge-length", "closes"])
def test_bad_scheduler_fails_fast_in_one_line(payload: bytes | None, close: bool, expected: str,
                                              tmp_path: Path,
                                              monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(run_mod, "DASK_PROBE_SECONDS", 2.0)
    server = Server(payload, close)
    try:
        sweep = sweep_case(tmp_path)
        address = f"tcp://127.0.0.1:{server.port}"
        code, out, err = run_cli(["sweep", str(sweep), "-o", str(tmp_path / "out"),
                                  "--scheduler", address])
    finally:
        server.stop()
    assert code == ExitCode.BAD_INPUT and out == ""
    line = one_error_line(err)
    assert address in line and expected in line and "out of memory" not in line
    assert not (tmp_path / "out").exists()


class FakeClient:
    """Just enough of ``distributed.Client`` for the health check."""

    def __init__(self, answer: object) -> None:
        self.answer = answer
        self.scheduler = type("S", (), {"identity": None})()

    def sync(self, func, *args, **kwargs):  # noqa: ANN001, ANN002, ANN003, ANN201
        if isinstance(self.answer, BaseException):
            raise self.answer
        return self.answer


def test_scheduler_that_stops_answering_is_exit_2_with_the_resume_hint() -> None:
    health = run_mod.ClusterHealth(FakeClient(OSError("connection reset")), "tcp://10.0.0.5:8786")
    with pytest.raises(run_mod.ClusterLostError) as info:
        health.check(force=True)
    assert info.value.exit_code == ExitCode.BAD_INPUT
    assert "tcp://10.0.0.5:8786" in str(info.value) and "resume" in str(info.value)


def test_cluster_without_workers_gives_up_after_the_grace_period(
        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(run_mod, "DASK_NO_WORKER_SECONDS", 0.0)
    health = run_mod.ClusterHealth(FakeClient({"workers": {}}), "tcp://10.0.0.5:8786")
    assert health.check(force=True) == 0  # the first look only starts the clock
    with pytest.raises(run_mod.ClusterLostError, match="no worker was left"):
        health.check(force=True)
    alive = run_mod.ClusterHealth(FakeClient({"workers": {"w": {}}}), "tcp://10.0.0.5:8786")
    assert alive.check(force=True) == 1 and alive.check(force=True) == 1


def test_all_workers_lost_mid_run_is_exit_2_not_4(tmp_path: Path) -> None:
    """A real cluster whose only worker goes away after the run started."""
    distributed = pytest.importorskip("distributed")
    sweep = sweep_case(tmp_path, "system: system.yaml\ngrid: {channel.arrival_probability: "
                                 "{start: 0.5, stop: 0.99, num: 40}}\n")
    cluster = distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                       protocol="tcp", dashboard_address=None)
    try:
        address = cluster.scheduler_address
        journal = tmp_path / "out" / "sweep.journal.jsonl"

        def kill_worker_after_first_chunk() -> None:
            deadline = time.monotonic() + 120
            while time.monotonic() < deadline:
                if journal.exists() and journal.stat().st_size > 0:
                    break
                time.sleep(0.02)
            for worker in list(cluster.workers.values()):
                cluster.sync(worker.close)

        killer = threading.Thread(target=kill_worker_after_first_chunk, daemon=True)
        killer.start()
        code, out, err = run_cli(["sweep", str(sweep), "-o", str(tmp_path / "out"),
                                  "--scheduler", address])
        killer.join(30)
    finally:
        cluster.close()
    if code == 0:
        pytest.skip("the sweep finished before the worker was closed")
    assert code == ExitCode.BAD_INPUT, err
    line = one_error_line(err)
    assert address in line and "resume" in line


# ---- 11: valid input and environment never exit 4 --------------------------------------------

def _system(tmp_path: Path, a: str, extra: str = "") -> Path:
    path = tmp_path / "system.yaml"
    path.write_text(f"name: big\nA: {a}\nC: [[1]]\nQ: [[1]]\nR: [[1]]\n{extra}"
                    "channel: {model: bernoulli, arrival_probability: 0.5}\n")
    return path


def _big_7x7(tmp_path: Path) -> Path:
    n = 7
    rows = [[("1e200" if j in (i, i + 1) else "0") for j in range(n)] for i in range(n)]
    eye = [[1 if i == j else 0 for j in range(n)] for i in range(n)]
    path = tmp_path / "big.yaml"
    path.write_text(json.dumps({"name": "big", "A": rows, "C": eye, "Q": eye, "R": eye,
                                "channel": {"model": "bernoulli", "arrival_probability": 0.5}}))
    return path


@pytest.mark.parametrize("case", ["exp(690)", "pi*1e200", "7x7 of 1e200"])
def test_huge_but_finite_entries_never_exit_4(case: str, tmp_path: Path) -> None:
    path = _big_7x7(tmp_path) if case.startswith("7x7") else _system(tmp_path, f"[[{case}]]")
    code, _, err = run_cli(["analyze", str(path), "--no-simulate"])
    assert code != ExitCode.INTERNAL and "internal error" not in err, err
    # |a| > 1e199 makes p_c = 1 - 1/|a|^2 indistinguishable from 1: p = 0.5 fails the review,
    # or the analysis says it is undetermined; never a crash
    assert code in (ExitCode.INCONCLUSIVE, ExitCode.REVIEW_FAILED), err


@pytest.mark.parametrize("case", ["exp(690)", "7x7 of 1e200"])
def test_huge_entries_are_analysed_not_undetermined(case: str, tmp_path: Path) -> None:
    path = _big_7x7(tmp_path) if case.startswith("7x7") else _system(tmp_path, f"[[{case}]]")
    code, _, err = run_cli(["analyze", str(path), "--no-simulate"])
    assert code == ExitCode.REVIEW_FAILED, err  # 0.5 < p_c = 1 - 1/|a|^2 (> 0.99)


@pytest.mark.parametrize("case", ["Sigma0", "Q-R"])
def test_huge_scales_do_not_blame_a_field_the_user_never_wrote(case: str,
                                                              tmp_path: Path) -> None:
    path = tmp_path / "s.yaml"
    q, r, extra = ("1", "1", "Sigma0: [[1e300]]\n") if case == "Sigma0" else ("1e300", "1e-300",
                                                                              "")
    path.write_text(f"name: s\nA: [[1.2]]\nC: [[1]]\nQ: [[{q}]]\nR: [[{r}]]\n{extra}"
                    "channel: {model: bernoulli, arrival_probability: 0.5}\n")
    code, _, err = run_cli(["analyze", str(path), "--quick"])
    assert "divergence_threshold" not in err and code != ExitCode.INTERNAL, err
    assert code in (ExitCode.OK, ExitCode.VERIFICATION_FAILED, ExitCode.INCONCLUSIVE), err


def test_huge_scales_never_exit_4(tmp_path: Path) -> None:
    path = tmp_path / "s.yaml"
    path.write_text("name: s\nA: [[1.2]]\nC: [[1]]\nQ: [[1e300]]\nR: [[1e-300]]\n"
                    "channel: {model: bernoulli, arrival_probability: 0.5}\n")
    code, _, err = run_cli(["analyze", str(path), "--quick"])
    assert code != ExitCode.INTERNAL and "internal error" not in err and "Traceback" not in err


def test_max_error_trace_in_yaml_exponent_form_is_accepted_like_a_matrix_entry(
        tmp_path: Path) -> None:
    """YAML 1.1 reads ``1e3`` (no dot) as a string; both places must read it as 1000."""
    from kfcrit.analysis.spec import load_spec

    path = tmp_path / "req.yaml"
    path.write_text("name: r\nA: [[1e3]]\nC: [[1]]\nQ: [[1]]\nR: [[1]]\n"
                    "channel: {model: bernoulli, arrival_probability: 0.5}\n"
                    "requirements: {max_error_trace: 1e3, max_tail_probability: 0.01}\n")
    spec = load_spec(str(path))
    assert float(spec.system.a[0, 0]) == 1000.0
    assert float(spec.requirements.max_error_trace) == 1000.0
    code, _, err = run_cli(["check", str(path)])
    assert code == 0, err


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="needs /dev/full")
@pytest.mark.parametrize("as_json", [True, False], ids=["json", "text"])
def test_stdout_on_a_full_device_is_one_line_exit_2(as_json: bool) -> None:
    args = [sys.executable, "-m", "kfcrit", "analyze", str(REPORTS / "sinopoli-scalar.yaml"),
            "--no-simulate"] + (["--json"] if as_json else [])
    with open("/dev/full", "w") as full:  # written to only
        proc = subprocess.run(args, stdout=full, stderr=subprocess.PIPE, text=True, timeout=300,
                              env={**os.environ, "PYTHONPATH": str(REPORTS.parent)})
    assert proc.returncode == ExitCode.BAD_INPUT, proc.stderr
    line = one_error_line(proc.stderr)
    assert "standard output" in line and "No space left on device" in line


def test_environment_errors_without_a_path_are_exit_2(monkeypatch: pytest.MonkeyPatch) -> None:
    import kfcrit.analysis.spec as spec_mod

    def full_disk(*args, **kwargs):  # noqa: ANN002, ANN003, ANN202
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(spec_mod, "load_spec", full_disk)
    code, _, err = run_cli(["analyze", str(REPORTS / "sinopoli-scalar.yaml")])
    assert code == ExitCode.BAD_INPUT
    assert "No space left on device" in one_error_line(err)


# ---- 12: terminal text, library warnings, orphans --------------------------------------------

ESCAPES = ("\x1b", "\r", "\x9b", "\u202e")


def test_control_characters_in_the_name_do_not_reach_the_terminal(tmp_path: Path) -> None:
    path = tmp_path / "esc.yaml"
    path.write_text('name: "ok\\e[2K\\rMEAN-UNSTABLE\\u202e"\nA: [[1.2]]\nC: [[1]]\nQ: [[1]]\n'
                    "R: [[1]]\nchannel: {model: bernoulli, arrival_probability: 0.5}\n")
    code, out, err = run_cli(["analyze", str(path), "--no-simulate"])
    assert code == 0, err
    assert not any(c in out + err for c in ESCAPES)


def test_error_lines_escape_control_characters_from_the_file(tmp_path: Path) -> None:
    path = tmp_path / "esc.yaml"
    path.write_text('name: e\nA: [[1.2]]\nC: [[1]]\nQ: [[1]]\nR: [[1]]\n'
                    'channel: {model: bernoulli, arrival_probability: 0.5, '
                    '"\\e[2K\\rfake\\u202e": 1}\n')
    code, out, err = run_cli(["analyze", str(path), "--no-simulate"])
    assert code == ExitCode.BAD_INPUT
    line = one_error_line(err)
    assert not any(c in line for c in ESCAPES)
    assert "\\x1b" in line or "fake" not in line


def test_fail_escapes_what_it_echoes(capsys: pytest.CaptureFixture[str]) -> None:
    from kfcrit.cli.common import fail

    with pytest.raises(SystemExit):
        fail("bad value '\x1b[31mred\r\u202eevil'\nsecond line", 2)
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and not any(c in err for c in ESCAPES)
    assert "\\x1b[31mred" in err and "\\u202eevil" in err


def test_library_warnings_are_summarised_in_one_line(tmp_path: Path) -> None:
    """A = [[1, 1e15], [0, 1]] makes SciPy's Lyapunov/Riccati solvers warn dozens of times."""
    path = tmp_path / "ill.yaml"
    path.write_text("name: ill\nA: [[1, 1e15], [0, 1]]\nC: [[1, 0]]\nQ: [[1, 0], [0, 1]]\n"
                    "R: [[1]]\nchannel: {model: bernoulli, arrival_probability: 0.9}\n")
    proc = subprocess.run([sys.executable, "-m", "kfcrit", "analyze", str(path), "--quick"],
                          capture_output=True, text=True, timeout=600,
                          env={**os.environ, "PYTHONPATH": str(REPORTS.parent)})
    assert proc.returncode != ExitCode.INTERNAL, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert "RuntimeWarning" not in "\n".join(l for l in lines if not l.startswith("kfcrit:"))
    assert len(lines) <= 1, proc.stderr
    if lines:
        assert lines[0].startswith("kfcrit: warning: the numerical libraries reported")


def _children(pid: int) -> dict[int, str]:
    out = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            cmd = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except OSError:
            continue
        if int(fields[1]) == pid and fields[0] != "Z":
            out[int(entry.name)] = cmd
    return out


def _alive(pid: int, cmd: str) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
        now = Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode(
            errors="replace")
    except OSError:
        return False
    return state != "Z" and now == cmd


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc")
def test_sigkill_of_a_sweep_leaves_no_workers_and_no_resource_tracker(tmp_path: Path) -> None:
    (tmp_path / "system.yaml").write_text(BERNOULLI)
    sweep = tmp_path / "sweep.yaml"
    sweep.write_text("system: system.yaml\ngrid:\n  channel.arrival_probability: "
                     "{start: 0.5, stop: 0.999, num: 400}\n  Q[0][0]: [1, 2]\n")
    args = [sys.executable, "-m", "kfcrit", "sweep", str(sweep), "-o", str(tmp_path / "out"),
            "--workers", "2"]
    proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            env={**os.environ, "PYTHONPATH": str(REPORTS.parent)})
    sweep_cmd = " ".join(args) + " "
    children: dict[int, str] = {}
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and proc.poll() is None:
        children = _children(proc.pid)
        # spawned workers run spawn_main (with a resource tracker beside them); forked ones
        # keep the sweep's command line (and need no tracker)
        spawned = [c for c in children.values() if "spawn_main" in c]
        forked = [c for c in children.values() if c == sweep_cmd]
        if (len(spawned) >= 2 and any("resource_tracker" in c for c in children.values())) \
                or len(forked) >= 2:
            break
        time.sleep(0.05)
    assert proc.poll() is None, "the sweep ended before its workers were seen"
    time.sleep(0.5)  # the workers are past their start-up
    children.update(_children(proc.pid))
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=30)
    deadline = time.monotonic() + 20
    while time.monotonic() < deadline and any(_alive(p, c) for p, c in children.items()):
        time.sleep(0.1)
    left = {p: c[:80] for p, c in children.items() if _alive(p, c)}
    for pid in left:  # do not leave them behind for the next test
        os.kill(pid, signal.SIGKILL)
    assert not left, left
