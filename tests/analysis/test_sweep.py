"""``kfcrit sweep``: grids and lists, tidy CSV/JSON, plots, progress, resume, local vs Dask.

Expected values are computed here from the formulas written out again (the O-QPSK and BPSK bit
error rates, the log-distance path loss, the thermal noise floor, the scalar critical value
1 − 1/a², the log-normal outage with scipy.stats), never by calling the code under test.
"""
from __future__ import annotations

import csv
import io
import json
import math
import os
import signal
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from click.testing import CliRunner
from scipy import integrate, stats
from scipy.special import erfc

import kfcrit.analysis.sweep.points as sweep_mod
import kfcrit.analysis.sweep.run as run_mod
from kfcrit.cli.main import main

KB = 1.380649e-23
OUTPUTS = ("sweep.csv", "sweep.json", "margin.svg", "margin.png")

LINK_SYSTEM = """\
name: scalar sensor link
A: [[1.25]]
C: [[1]]
Q: [[1]]
R: [[2.5]]
channel:
  model: link-budget
  radio: ieee802154-oqpsk-2450
  tx_power_dbm: 0
  distance_m: 50
  packet_bytes: 40
  path_loss: {model: log-distance, exponent: 3.0, reference_distance_m: 1,
              reference_loss_db: 40.2, shadowing_sigma_db: 4}
  noise: {noise_figure_db: 10, bandwidth_hz: 2.0e6, temperature_k: 290}
  margin_db: 2
  max_outage: 0.1
"""
BPSK_SYSTEM = LINK_SYSTEM.replace("radio: ieee802154-oqpsk-2450",
                                  "radio: {model: bpsk, processing_gain_db: 3}")
BERNOULLI_SYSTEM = """\
name: scalar bernoulli
A: [[1.25]]
C: [[1]]
Q: [[1]]
R: [[2.5]]
channel: {model: bernoulli, arrival_probability: 0.5}
"""


# ---- independent formulas ----------------------------------------------------------------

def oqpsk_ber(sinr_lin: float) -> float:
    """IEEE 802.15.4 O-QPSK: (8/15)(1/16) Σ_{k=2}^{16} (−1)^k C(16,k) e^{20·SINR(1/k − 1)}."""
    return (8 / 15) / 16 * sum((-1) ** k * math.comb(16, k) * math.exp(20 * sinr_lin * (1 / k - 1))
                               for k in range(2, 17))


def bpsk_ber(sinr_lin: float, gain_db: float) -> float:
    """Q(√(2 Eb/N0)) = erfc(√(Eb/N0))/2 with Eb/N0 = SINR·10^{G/10}."""
    return 0.5 * erfc(math.sqrt(sinr_lin * 10 ** (gain_db / 10)))


def arrival(ber: float, packet_bytes: int) -> float:
    return (1.0 - ber) ** (8 * packet_bytes)


def noise_dbm(bandwidth: float = 2e6, nf: float = 10.0, temp: float = 290.0) -> float:
    return 10 * math.log10(KB * temp * bandwidth / 1e-3) + nf


def sinr_db(tx: float, d: float) -> float:
    return tx - (40.2 + 30 * math.log10(d)) - noise_dbm()


def required_sinr(p: float, packet_bytes: int) -> float:
    """Bisection on the written-out O-QPSK formula: (1 − BER(s))^{8L} = p."""
    lo, hi = -40.0, 60.0
    for _ in range(200):
        mid = (lo + hi) / 2
        if arrival(oqpsk_ber(10 ** (mid / 10)), packet_bytes) < p:
            lo = mid
        else:
            hi = mid
    return (lo + hi) / 2


def shadowed_mean(s0: float, sigma: float, packet_bytes: int) -> float:
    """E_z[p(s0 + σ z)], z ~ N(0, 1), by adaptive quadrature."""
    def f(z: float) -> float:
        return arrival(oqpsk_ber(10 ** ((s0 + sigma * z) / 10)), packet_bytes) * stats.norm.pdf(z)
    return integrate.quad(f, -12, 12, points=[(required_sinr(0.5, packet_bytes) - s0) / sigma],
                          epsabs=1e-12, limit=200)[0]


# ---- helpers -------------------------------------------------------------------------------

def run_cli(args: list[str]) -> tuple[int, str, str]:
    r = CliRunner().invoke(main, args)
    return r.exit_code, r.stdout, r.stderr


def write_case(folder: Path, sweep_text: str, system: str = LINK_SYSTEM) -> Path:
    (folder / "system.yaml").write_text(system)
    p = folder / "sweep.yaml"
    p.write_text(sweep_text)
    return p


def read_csv(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def outputs(folder: Path) -> dict[str, bytes]:
    return {name: (folder / name).read_bytes() for name in OUTPUTS}


def count_evaluations(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """Count the points evaluated in this process (serial runs)."""
    calls = [0]
    original = sweep_mod.evaluate_point

    def counting(*args, **kwargs):  # noqa: ANN002, ANN003, ANN202
        calls[0] += 1
        return original(*args, **kwargs)

    monkeypatch.setattr(sweep_mod, "evaluate_point", counting)
    return calls


def assert_valid_plots(folder: Path) -> None:
    root = ET.fromstring((folder / "margin.svg").read_bytes())
    assert root.tag.endswith("svg")
    assert root.findall(".//{http://www.w3.org/2000/svg}path")  # something was drawn
    png = (folder / "margin.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and png[12:16] == b"IHDR"
    width, height = int.from_bytes(png[16:20], "big"), int.from_bytes(png[20:24], "big")
    assert width > 100 and height > 100


# ---- grid over distance and packet size (link budget) --------------------------------------

def test_link_grid_distance_by_packet_size(tmp_path: Path) -> None:
    sweep = write_case(tmp_path, "name: link grid\nsystem: system.yaml\ngrid:\n"
                       "  channel.packet_bytes: [20, 116]\n"
                       "  channel.distance_m: {start: 40, stop: 160, num: 3}\n")
    code, out, err = run_cli(["sweep", str(sweep), "-o", str(tmp_path / "out"), "--workers", "1"])
    assert code == 0, err
    assert out == ""  # stdout carries data only; the summary goes to stderr
    assert err.count("\n") == 1 and "6 points (6 computed, 0 from the journal), 0 errors" in err
    rows = read_csv(tmp_path / "out" / "sweep.csv")
    # first parameter varies slowest; distances 40, 100, 160 (inclusive, exact steps)
    assert [(float(r["channel.packet_bytes"]), float(r["channel.distance_m"])) for r in rows] == \
        [(20, 40), (20, 100), (20, 160), (116, 40), (116, 100), (116, 160)]
    assert [int(r["index"]) for r in rows] == list(range(6))
    margin = max(2.0, 4.0 * stats.norm.ppf(1 - 0.1))  # margin policy: 5.126 dB
    for r in rows:
        # packet_bytes is the payload: the PER covers it plus 11 bytes of 802.15.4 MAC header
        # and FCS (the 127-byte PSDU limit allows payloads up to 116 bytes) and the 6-byte PHY
        # header (preamble 4, SFD 1, PHR 1; per_over: ppdu, the default)
        L, d = 6 + int(float(r["channel.packet_bytes"])) + 11, float(r["channel.distance_m"])
        s = sinr_db(0.0, d)
        p = arrival(oqpsk_ber(10 ** (s / 10)), L)
        s_req = required_sinr(0.36, L)
        assert r["status"] == "ok" and r["classification"] == "non-degenerate"
        assert float(r["critical_value"]) == pytest.approx(1 - 1 / 1.25 ** 2, abs=1e-15)
        assert r["critical_expression"] == "9/25"
        assert float(r["sinr_db"]) == pytest.approx(s, abs=1e-9)
        assert float(r["arrival_probability"]) == pytest.approx(p, rel=1e-9, abs=1e-15)
        assert float(r["margin"]) == pytest.approx(p - 0.36, abs=1e-9)
        assert r["verdict"] == ("mean-stable" if p > 0.36 else "mean-unstable")
        assert float(r["required_sinr_db"]) == pytest.approx(s_req, abs=1e-7)
        assert float(r["link_margin_db"]) == pytest.approx(s - s_req, abs=1e-7)
        # log-distance solved by hand: 0 − (40.2 + 30 log10 d) − N − s_req − margin = 0
        d_max = 10 ** ((0.0 - noise_dbm() - s_req - margin - 40.2) / 30)
        assert float(r["max_distance_m"]) == pytest.approx(d_max, rel=1e-7)
        assert float(r["outage_probability"]) == pytest.approx(
            stats.norm.cdf((s_req - s) / 4.0), abs=1e-9)
        assert float(r["mean_arrival_probability"]) == pytest.approx(shadowed_mean(s, 4.0, L),
                                                                     abs=1e-7)
    # the 160 m link with 127-byte packets is below p_c, the 40 m one far above
    assert rows[5]["verdict"] == "mean-unstable" and rows[3]["verdict"] == "mean-stable"
    assert_valid_plots(tmp_path / "out")


def test_json_rows_equal_csv_rows(tmp_path: Path) -> None:
    sweep = write_case(tmp_path, "system: system.yaml\ngrid:\n"
                       "  channel.distance_m: [30, 90]\n  channel.packet_bytes: [40]\n")
    code, _, err = run_cli(["sweep", str(sweep), "-o", str(tmp_path / "o"), "--workers", "1"])
    assert code == 0, err
    record = json.loads((tmp_path / "o" / "sweep.json").read_text())
    rows = read_csv(tmp_path / "o" / "sweep.csv")
    meta = record["sweep"]
    assert meta["parameters"] == ["channel.distance_m", "channel.packet_bytes"]
    assert list(rows[0]) == meta["columns"] and meta["points"] == 2
    for jrow, crow in zip(record["rows"], rows):
        assert list(jrow) == meta["columns"]
        for col, value in jrow.items():
            if value is None:
                assert crow[col] == ""
            elif isinstance(value, bool):
                assert crow[col] == str(value)
            elif isinstance(value, float):
                assert float(crow[col]) == value  # repr round-trips exactly
            else:
                assert crow[col] == str(value)


# ---- list over transmit power (a second radio) -----------------------------------------------

def test_list_over_tx_power_with_bpsk(tmp_path: Path) -> None:
    sweep = write_case(tmp_path, "system: system.yaml\npoints:\n"
                       + "".join(f"  - {{channel.tx_power_dbm: {tx}, channel.distance_m: 150}}\n"
                                 for tx in (-12, -6, 0, 6)), system=BPSK_SYSTEM)
    code, _, err = run_cli(["sweep", str(sweep), "-o", str(tmp_path / "o"), "--workers", "1"])
    assert code == 0, err
    rows = read_csv(tmp_path / "o" / "sweep.csv")
    assert [float(r["channel.tx_power_dbm"]) for r in rows] == [-12, -6, 0, 6]
    for r in rows:
        s = sinr_db(float(r["channel.tx_power_dbm"]), 150.0)
        assert float(r["sinr_db"]) == pytest.approx(s, abs=1e-9)
        p = arrival(bpsk_ber(10 ** (s / 10), 3.0), 40)
        assert float(r["arrival_probability"]) == pytest.approx(p, rel=1e-9, abs=1e-15)
    # 6 dB more power = 6 dB more SINR at the same distance
    assert float(rows[3]["sinr_db"]) - float(rows[2]["sinr_db"]) == pytest.approx(6.0, abs=1e-12)


# ---- grid over an entry of A and the arrival probability ----------------------------------

def test_grid_over_matrix_entry_and_bernoulli_probability(tmp_path: Path) -> None:
    sweep = write_case(tmp_path, "system: system.yaml\ngrid:\n"
                       "  A[0][0]: [0.5, 1.25, 2, sqrt(2)]\n"
                       "  channel.arrival_probability: [0.2, 0.5, 0.9]\n",
                       system=BERNOULLI_SYSTEM)
    code, _, err = run_cli(["sweep", str(sweep), "-o", str(tmp_path / "o"), "--workers", "1"])
    assert code == 0, err
    rows = read_csv(tmp_path / "o" / "sweep.csv")
    assert len(rows) == 12
    for r in rows:
        a, p = float(r["A[0][0]"]), float(r["channel.arrival_probability"])
        pc = max(0.0, 1 - 1 / a ** 2)  # scalar: p_c = 1 − 1/a² (0 when |a| < 1)
        assert float(r["critical_value"]) == pytest.approx(pc, abs=1e-15)
        assert float(r["arrival_probability"]) == p
        assert float(r["margin"]) == pytest.approx(p - pc, abs=1e-15)
        assert r["iid"] == "True"
        # at a = √2 and p = 1/2 the arrival probability equals p_c exactly: not mean-stable
        assert r["verdict"] == ("mean-stable" if p > pc else "mean-unstable")
        assert r["sinr_db"] == "" and r["link_margin_db"] == ""  # no link budget
    by_a = {float(r["A[0][0]"]): r for r in rows}
    assert by_a[math.sqrt(2)]["critical_expression"] == "1/2"
    assert by_a[2.0]["critical_expression"] == "3/4"
    assert by_a[0.5]["classification"] == "stable"
    assert_valid_plots(tmp_path / "o")


# ---- progress ------------------------------------------------------------------------------

def test_progress_bar_on_a_terminal_only(tmp_path: Path) -> None:
    import pty
    import select

    sweep = write_case(tmp_path, "system: system.yaml\ngrid:\n"
                       "  channel.distance_m: {start: 20, stop: 200, num: 7}\n")
    master, slave = pty.openpty()
    proc = subprocess.Popen([sys.executable, "-m", "kfcrit", "sweep", str(sweep), "-o",
                             str(tmp_path / "o"), "--workers", "1"], stdout=subprocess.PIPE,
                            stderr=slave, stdin=subprocess.DEVNULL)
    os.close(slave)
    buf = b""
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        ready, _, _ = select.select([master], [], [], 0.2)
        if ready:
            try:
                data = os.read(master, 65536)
            except OSError:
                break
            if not data:
                break
            buf += data
        elif proc.poll() is not None:
            break
    os.close(master)
    assert proc.wait(timeout=60) == 0
    assert proc.stdout.read() == b""
    text = buf.decode(errors="replace")
    assert "sweep" in text and "7/7" in text and "points" in text  # the rich bar, on stderr
    assert "7 points (7 computed" in text
    # not a terminal (CliRunner): no bar, only the one summary line
    code, _, err = run_cli(["sweep", str(sweep), "-o", str(tmp_path / "o2"), "--workers", "1"])
    assert code == 0 and err.count("\n") == 1 and "7/7" not in err


# ---- resume --------------------------------------------------------------------------------

RESUME_SWEEP = ("system: system.yaml\ngrid:\n  channel.packet_bytes: [20, 116]\n"
                "  channel.distance_m: {start: 40, stop: 160, num: 5}\n")


def test_resume_from_a_partial_journal(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    sweep = write_case(tmp_path, RESUME_SWEEP)
    ref, part = tmp_path / "ref", tmp_path / "part"
    calls = count_evaluations(monkeypatch)
    assert run_cli(["sweep", str(sweep), "-o", str(ref), "--workers", "1"])[0] == 0
    assert calls[0] == 10
    # a run that stopped after 4 points, the 5th torn mid-line, and no tables written yet
    lines = (ref / "sweep.journal.jsonl").read_text().splitlines(keepends=True)
    assert len(lines) == 10
    part.mkdir()
    (part / "sweep.journal.jsonl").write_text("".join(lines[:4]) + lines[4][:40])
    calls[0] = 0
    code, _, err = run_cli(["sweep", str(sweep), "-o", str(part), "--workers", "1"])
    assert code == 0, err
    assert calls[0] == 6  # only the missing points were computed
    assert "10 points (6 computed, 4 from the journal)" in err
    assert json.loads((part / "run.json").read_text())["reused"] == 4
    assert outputs(part) == outputs(ref)  # byte for byte
    # the journal stays parseable line by line after the torn line
    for line in (part / "sweep.journal.jsonl").read_text().splitlines()[5:]:
        json.loads(line)
    # a second run reuses everything
    calls[0] = 0
    code, _, err = run_cli(["sweep", str(sweep), "-o", str(part), "--workers", "1"])
    assert code == 0 and calls[0] == 0 and "(0 computed, 10 from the journal)" in err
    assert outputs(part) == outputs(ref)
    # a changed base system invalidates the journal: everything is recomputed
    (tmp_path / "system.yaml").write_text(LINK_SYSTEM.replace("tx_power_dbm: 0",
                                                              "tx_power_dbm: 1"))
    calls[0] = 0
    assert run_cli(["sweep", str(sweep), "-o", str(part), "--workers", "1"])[0] == 0
    assert calls[0] == 10


def test_interrupted_run_resumes_to_the_same_outputs(tmp_path: Path,
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    sweep = write_case(tmp_path, "system: system.yaml\ngrid:\n  channel.packet_bytes: [20, 40]\n"
                       "  channel.distance_m: {start: 30, stop: 179, num: 60}\n")
    out = tmp_path / "out"
    journal = out / "sweep.journal.jsonl"
    proc = subprocess.Popen([sys.executable, "-m", "kfcrit", "sweep", str(sweep), "-o", str(out),
                             "--workers", "1"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and proc.poll() is None:
        if journal.exists() and journal.stat().st_size > 0:
            break
        time.sleep(0.02)
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 130, stderr
    assert stdout == "" and "Traceback" not in stderr
    assert len(stderr.strip().splitlines()) == 1
    assert stderr.startswith("kfcrit: error: interrupted;") and "resume" in stderr
    assert not (out / "sweep.csv").exists()  # no table from an unfinished run
    done = sum(1 for line in journal.read_text().splitlines() if line.endswith("}"))
    assert 0 < done < 120
    calls = count_evaluations(monkeypatch)
    code, _, err = run_cli(["sweep", str(sweep), "-o", str(out), "--workers", "1"])
    assert code == 0, err
    assert calls[0] == 120 - done and f"({120 - done} computed, {done} from the journal)" in err
    calls[0] = 0
    assert run_cli(["sweep", str(sweep), "-o", str(tmp_path / "ref"), "--workers", "1"])[0] == 0
    assert calls[0] == 120
    assert outputs(out) == outputs(tmp_path / "ref")


# ---- local processes, one process and Dask give identical outputs --------------------------

def test_serial_processes_and_dask_localcluster_agree(tmp_path: Path) -> None:
    from distributed import LocalCluster

    sweep = write_case(tmp_path, "system: system.yaml\ngrid:\n  channel.packet_bytes: [20, 116]\n"
                       "  channel.distance_m: {start: 50, stop: 120, num: 8}\n")
    serial, procs, dask = tmp_path / "serial", tmp_path / "procs", tmp_path / "dask"
    assert run_cli(["sweep", str(sweep), "-o", str(serial), "--workers", "1"])[0] == 0
    code, _, err = run_cli(["sweep", str(sweep), "-o", str(procs), "--workers", "2"])
    assert code == 0, err
    assert json.loads((procs / "run.json").read_text()) == {
        "runner": "local", "workers": 2, "computed": 16, "reused": 0}
    with LocalCluster(n_workers=1, threads_per_worker=2, processes=False, protocol="tcp",
                      host="127.0.0.1", dashboard_address=None) as cluster:
        address = cluster.scheduler_address
        assert address.startswith("tcp://127.0.0.1:")
        code, _, err = run_cli(["sweep", str(sweep), "-o", str(dask), "--scheduler", address])
    assert code == 0, err
    assert json.loads((dask / "run.json").read_text())["runner"] == "dask"
    assert outputs(serial) == outputs(procs) == outputs(dask)


# ---- bad sweep files and options -----------------------------------------------------------

BAD_SWEEPS = {
    "missing-grid": ("system: system.yaml\n", "sweep.grid"),
    "grid-and-points": ("system: system.yaml\ngrid: {channel.distance_m: [1]}\n"
                        "points: [{channel.distance_m: 2}]\n", "sweep.grid"),
    "missing-system": ("grid: {channel.distance_m: [1]}\n", "sweep.system"),
    "system-file-missing": ("system: nowhere.yaml\ngrid: {channel.distance_m: [1]}\n",
                            "system"),
    "unknown-top-key": ("system: system.yaml\ngird: {channel.distance_m: [1]}\n", "sweep.gird"),
    "unknown-matrix": ("system: system.yaml\ngrid:\n  B[0][0]: [1, 2]\n", "sweep.grid.B[0][0]"),
    "matrix-index-out-of-range": ("system: system.yaml\ngrid:\n  A[1][0]: [1, 2]\n",
                                  "sweep.grid.A[1][0]"),
    "unknown-channel-key": ("system: system.yaml\ngrid: {channel.distanse_m: [1, 2]}\n",
                            "sweep.grid.channel.distanse_m"),
    "unknown-nested-key": ("system: system.yaml\ngrid: {channel.noise.gain: [1, 2]}\n",
                           "sweep.grid.channel.noise.gain"),
    "not-a-path": ("system: system.yaml\ngrid: {'os.system': [1]}\n", "sweep.grid.os.system"),
    "non-numeric-value": ("system: system.yaml\ngrid: {channel.distance_m: [10, far, 30]}\n",
                          "sweep.grid.channel.distance_m[1]"),
    "non-numeric-matrix": ("system: system.yaml\ngrid:\n  A[0][0]: ['__import__(\"os\")']\n",
                           "sweep.grid.A[0][0]"),
    "non-numeric-point": ("system: system.yaml\npoints: [{channel.tx_power_dbm: 0}, "
                          "{channel.tx_power_dbm: loud}]\n",
                          "sweep.points[1].channel.tx_power_dbm"),
    "boolean-value": ("system: system.yaml\ngrid: {channel.distance_m: [true]}\n",
                      "sweep.grid.channel.distance_m[0]"),
    "empty-grid": ("system: system.yaml\ngrid: {}\n", "sweep.grid"),
    "empty-values": ("system: system.yaml\ngrid: {channel.distance_m: []}\n",
                     "sweep.grid.channel.distance_m"),
    "empty-points": ("system: system.yaml\npoints: []\n", "sweep.points"),
    "enormous-grid": ("system: system.yaml\ngrid:\n"
                      "  channel.distance_m: {start: 1, stop: 100, num: 100000}\n"
                      "  channel.tx_power_dbm: {start: -10, stop: 10, num: 100000}\n",
                      "sweep.grid"),
    "too-many-values": ("system: system.yaml\ngrid:\n"
                        "  channel.distance_m: {start: 1, stop: 100, num: 1000000000}\n",
                        "sweep.grid.channel.distance_m.num"),
    "zero-step": ("system: system.yaml\ngrid:\n"
                  "  channel.distance_m: {start: 1, stop: 100, step: 0}\n",
                  "sweep.grid.channel.distance_m.step"),
    "plot-not-swept": ("system: system.yaml\ngrid: {channel.distance_m: [1, 2]}\n"
                       "plot: {x: channel.tx_power_dbm}\n", "sweep.plot.x"),
    "not-a-mapping": ("- system.yaml\n", "file"),
}


def assert_refused(code: int, out: str, err: str, field: str) -> None:
    assert code == 2, (code, err)
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("kfcrit: error: "), err
    assert field in lines[0], (field, err)
    assert "Traceback" not in err and out == ""


@pytest.mark.parametrize("name", sorted(BAD_SWEEPS))
def test_bad_sweep_file_is_one_line_naming_the_field(name: str, tmp_path: Path) -> None:
    text, field = BAD_SWEEPS[name]
    sweep = write_case(tmp_path, text)
    before = sorted(tmp_path.iterdir())
    code, out, err = run_cli(["sweep", str(sweep), "-o", str(tmp_path / "out")])
    assert_refused(code, out, err, field)
    assert sorted(tmp_path.iterdir()) == before  # nothing written, not even the folder


GOOD_SWEEP = "system: system.yaml\ngrid: {channel.distance_m: [30, 60]}\n"


@pytest.mark.parametrize("address", ["127.0.0.1:8786", "tcp://127.0.0.1", "http://x:1",
                                     "tcp://host:99999", "tcp://a b:1", "tcp://;rm -rf /:1"])
def test_bad_scheduler_address(address: str, tmp_path: Path) -> None:
    sweep = write_case(tmp_path, GOOD_SWEEP)
    code, out, err = run_cli(["sweep", str(sweep), "-o", str(tmp_path / "out"),
                              "--scheduler", address])
    assert_refused(code, out, err, "--scheduler")
    assert not (tmp_path / "out").exists()


def test_unreachable_scheduler(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(run_mod, "DASK_PROBE_SECONDS", 1.0)
    sweep = write_case(tmp_path, GOOD_SWEEP)
    code, out, err = run_cli(["sweep", str(sweep), "-o", str(tmp_path / "out"),
                              "--scheduler", "tcp://127.0.0.1:1"])
    assert_refused(code, out, err, "--scheduler")
    assert "cannot connect" in err
    assert not (tmp_path / "out").exists()


def test_bad_output_folder(tmp_path: Path) -> None:
    sweep = write_case(tmp_path, GOOD_SWEEP)
    code, out, err = run_cli(["sweep", str(sweep), "-o", str(tmp_path / "missing" / "out")])
    assert_refused(code, out, err, "--output")
    assert not (tmp_path / "missing").exists()
    (tmp_path / "afile").write_text("x")
    code, out, err = run_cli(["sweep", str(sweep), "-o", str(tmp_path / "afile")])
    assert_refused(code, out, err, "--output")
    assert (tmp_path / "afile").read_text() == "x"


def test_missing_sweep_file(tmp_path: Path) -> None:
    code, out, err = run_cli(["sweep", str(tmp_path / "nope.yaml"), "-o", str(tmp_path / "o")])
    assert code == 2 and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert not (tmp_path / "o").exists()


def test_a_failing_point_is_a_row_not_a_crash(tmp_path: Path) -> None:
    # a value the channel refuses (a negative distance) fails that point only, exit code 2
    sweep = write_case(tmp_path, "system: system.yaml\ngrid: {channel.distance_m: [30, -5]}\n")
    code, out, err = run_cli(["sweep", str(sweep), "-o", str(tmp_path / "o"), "--workers", "1"])
    assert code == 2 and out == "" and "Traceback" not in err
    rows = read_csv(tmp_path / "o" / "sweep.csv")
    assert rows[0]["status"] == "ok"
    assert rows[1]["status"] == "error" and "channel.distance_m" in rows[1]["error"]
    assert "first failing point 1: channel.distance_m" in err


def test_shipped_sweep_file_loads() -> None:
    spec = sweep_mod.load_sweep(Path(__file__).resolve().parents[2] / "reports"
                                / "sweep-link-distance.yaml")
    assert spec.parameters == ("channel.packet_bytes", "channel.distance_m")
    assert len(spec.points) == 3 * 17 and spec.points[1] == ("20", "65")


# ---- benchmark smoke test ------------------------------------------------------------------

def test_benchmark_module_runs_with_a_few_points() -> None:
    from kfcrit.bench import bench_sweep

    buf = io.StringIO()
    result = bench_sweep.sweep_throughput(points=24, workers=1, dask_workers=1, dask_processes=False,
                             out=buf)
    text = buf.getvalue()
    assert result["points"] == 24 and result["identical"] is True
    assert "points/s" in text and "ratio" in text
    assert result["local"]["points_per_second"] > 0 and result["dask"]["points_per_second"] > 0


def test_a_named_field_can_be_swept_and_bad_names_fail_their_points(tmp_path: Path) -> None:
    # `radio` holds a name in the base system, so names are values there (not numbers)
    sweep = write_case(tmp_path, "system: system.yaml\ngrid:\n"
                       "  channel.radio: [bpsk, ieee802154-oqpsk-2450, nonsense]\n"
                       "  channel.distance_m: [60, 120]\n")
    code, out, err = run_cli(["sweep", str(sweep), "-o", str(tmp_path / "o"), "--workers", "1"])
    assert code == 2 and out == "" and "Warning" not in err and len(err.splitlines()) == 2
    record = json.loads((tmp_path / "o" / "sweep.json").read_text())
    assert record["sweep"]["plot_x"] == "channel.distance_m"  # the first numeric parameter
    rows = record["rows"]
    assert [r["status"] for r in rows] == ["ok"] * 4 + ["error"] * 2
    s = sinr_db(0.0, 60.0)
    assert rows[0]["arrival_probability"] == pytest.approx(
        arrival(bpsk_ber(10 ** (s / 10), 0.0), 40), rel=1e-9)
    assert rows[2]["arrival_probability"] == pytest.approx(
        arrival(oqpsk_ber(10 ** (s / 10)), 40), rel=1e-9)
    assert "unknown radio" in rows[4]["error"]


def test_upper_bound_column_is_filled_once_per_system(tmp_path: Path,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    import kfcrit.theory.upper.bracket as upper_mod

    calls: list[float] = []
    real = upper_mod.upper_bound

    def counting(system, *args, **kwargs):  # noqa: ANN001, ANN002, ANN003
        calls.append(float(system.a[0, 0]))
        return real(system, *args, **kwargs)

    monkeypatch.setattr(upper_mod, "upper_bound", counting)
    sweep = write_case(tmp_path, "system: system.yaml\ngrid:\n"
                       "  A[0][0]: [1.25, 2, sqrt(2)]\n"
                       "  channel.arrival_probability: [0.2, 0.5, 0.9]\n"
                       "  R[0][0]: [1, 3]\n",
                       system=BERNOULLI_SYSTEM)
    code, _, err = run_cli(["sweep", str(sweep), "-o", str(tmp_path / "o"), "--workers", "1"])
    assert code == 0, err
    rows = read_csv(tmp_path / "o" / "sweep.csv")
    assert len(rows) == 18
    for r in rows:
        a = float(r["A[0][0]"])
        # scalar: p_up = p_c = 1 − 1/a² (Sinopoli Thm 3: p_low = p_up when C is invertible)
        assert float(r["upper_bound"]) == pytest.approx(1 - 1 / a ** 2, abs=2e-6)
    # p_up depends on (A, C) only: three distinct A, so three computations for 18 points
    assert sorted(calls) == pytest.approx([1.25, math.sqrt(2), 2.0])
    assert len(calls) == 3


def test_shipped_sweep_fills_upper_bound() -> None:
    # the Sinopoli general plant: p_up = 1 − 1/(1.25 · 1.1)² = 57/121 (expected.json, MATH §3)
    doc = {"name": "g", "A": [[1.25, 0], [1, 1.1]], "C": [[1, 1]], "Q": 20, "R": 2.5}
    row = sweep_mod.evaluate_point(doc, ".", 1e-9, 400, [])
    assert row["status"] == "ok"
    assert row["upper_bound"] == pytest.approx(57 / 121, abs=2e-6)


# ---- special files: never read without bound, never block ---------------------------------

def _sweep_subprocess(args: list[str], timeout: float = 90) -> subprocess.CompletedProcess:
    import resource

    def limit() -> None:  # an unbounded read fails fast instead of eating the machine
        resource.setrlimit(resource.RLIMIT_AS, (2_000_000_000, 2_000_000_000))

    return subprocess.run([sys.executable, "-m", "kfcrit", "sweep", *args], capture_output=True,
                          text=True, timeout=timeout, preexec_fn=limit)


@pytest.mark.skipif(not os.path.exists("/dev/zero"), reason="needs /dev/zero")
def test_sweep_file_dev_zero_and_base_system_dev_zero(tmp_path: Path) -> None:
    proc = _sweep_subprocess(["/dev/zero", "-o", str(tmp_path / "o")])
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert "file: " in proc.stderr and "character device" in proc.stderr
    sweep = write_case(tmp_path, "system: /dev/zero\ngrid: {channel.distance_m: [30, 60]}\n")
    code, out, err = run_cli(["sweep", str(sweep), "-o", str(tmp_path / "o")])
    assert_refused(code, out, err, "system: base system file: file: ")
    assert "character device" in err
    assert not (tmp_path / "o").exists()


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
def test_sweep_file_fifo_and_base_system_fifo_do_not_hang(tmp_path: Path) -> None:
    os.mkfifo(tmp_path / "sweep-fifo.yaml")
    proc = _sweep_subprocess([str(tmp_path / "sweep-fifo.yaml"), "-o", str(tmp_path / "o")])
    assert proc.returncode == 2 and "FIFO" in proc.stderr
    os.mkfifo(tmp_path / "base.yaml")
    (tmp_path / "sweep.yaml").write_text("system: base.yaml\ngrid: "
                                         "{channel.arrival_probability: [0.5, 0.9]}\n")
    proc = _sweep_subprocess([str(tmp_path / "sweep.yaml"), "-o", str(tmp_path / "o")])
    assert proc.returncode == 2 and "system: base system file" in proc.stderr
    assert "FIFO" in proc.stderr and len(proc.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "o").exists()


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
def test_journal_replaced_by_a_fifo_is_refused_without_hanging(tmp_path: Path) -> None:
    sweep = write_case(tmp_path, "system: system.yaml\ngrid: "
                                 "{channel.arrival_probability: [0.5, 0.9]}\n",
                       system=BERNOULLI_SYSTEM)
    out_dir = tmp_path / "o"
    out_dir.mkdir()
    os.mkfifo(out_dir / "sweep.journal.jsonl")
    proc = _sweep_subprocess([str(sweep), "-o", str(out_dir), "--workers", "1"])
    assert proc.returncode == 2, proc.stderr
    assert "output: the journal" in proc.stderr and "FIFO" in proc.stderr
    assert sorted(p.name for p in out_dir.iterdir()) == ["sweep.journal.jsonl"]


def test_a_million_point_sweep_is_refused_in_bounded_time_and_memory(tmp_path: Path) -> None:
    """A 130-byte sweep file asking for 10^6 points is refused before any point is keyed
    (exit 2, one line), within a second of CPU and far below 1 GB."""
    import resource

    sweep = write_case(tmp_path, "system: system.yaml\ngrid:\n"
                       "  channel.distance_m: {start: 1, stop: 100, num: 1000}\n"
                       "  channel.tx_power_dbm: {start: -10, stop: 10, num: 1000}\n")

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (1_000_000_000, 1_000_000_000))

    proc = subprocess.run([sys.executable, "-m", "kfcrit", "sweep", str(sweep), "-o",
                           str(tmp_path / "o")], capture_output=True, text=True, timeout=120,
                          preexec_fn=limit)
    assert proc.returncode == 2, proc.stderr
    assert "sweep.grid" in proc.stderr and "100000" in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "o").exists()
