"""What a new user meets first: ``kfcrit check`` on sweep and system files, a saved record given
where a system file belongs, the imports of ``check``, ``kfcrit radios`` and the reference."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import jsonschema
import pytest
import yaml
from click.testing import CliRunner

from kfcrit.cli.main import main
from kfcrit.errors import InputError
from kfcrit.io.fileschema import RADIO_MAPPING_KEYS, system_schema
from kfcrit.link.radios import radio_catalogue, radio_from_mapping

from ..conftest import REPORTS, ROOT


def run(*args: str):
    return CliRunner().invoke(main, list(args))


def one_error_line(result) -> str:
    """The single stderr line of a refused input (exit code 2)."""
    assert result.exit_code == 2, (result.exit_code, result.stdout, result.stderr)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, lines
    return lines[0]


@pytest.fixture()
def link_dir(tmp_path: Path) -> Path:
    shutil.copy(REPORTS / "link-oqpsk-sensor.yaml", tmp_path / "base.yaml")
    return tmp_path


def sweep_file(folder: Path, text: str) -> str:
    path = folder / "sweep.yaml"
    path.write_text("system: base.yaml\n" + text)
    return str(path)


# --- sweep files ------------------------------------------------------------------------------

def test_a_misspelled_sweep_key_names_the_sweep_field_and_the_sweep_keys(link_dir: Path) -> None:
    line = one_error_line(run("check", sweep_file(link_dir, "grids:\n  channel.distance_m: [20]\n")))
    assert "sweep.grids: unknown key" in line
    for key in ("system", "grid", "points", "tolerance", "plot"):
        assert key in line
    assert "Sigma0" not in line and "R_cross" not in line   # not the system file's keys


def test_a_negative_distance_in_the_grid_is_refused_by_check(link_dir: Path) -> None:
    line = one_error_line(run("check", sweep_file(link_dir,
                                                  "grid:\n  channel.distance_m: [20, -40]\n")))
    assert "sweep.grid.channel.distance_m[1]" in line and "-40" in line


def test_a_packet_longer_than_the_frame_is_refused_by_check(link_dir: Path) -> None:
    # 802.15.4: PSDU ≤ 127 bytes; 200 + 11 bytes of MAC overhead do not fit, 40 + 11 do
    line = one_error_line(run("check", sweep_file(link_dir,
                                                  "grid:\n  channel.packet_bytes: [40, 200]\n")))
    assert "sweep.grid.channel.packet_bytes[1]" in line and "200" in line


def test_explicit_points_name_the_point(link_dir: Path) -> None:
    text = "points:\n  - {channel.distance_m: 20}\n  - {channel.distance_m: -3}\n"
    line = one_error_line(run("check", sweep_file(link_dir, text)))
    assert "sweep.points[1].channel.distance_m" in line and "-3" in line


def test_values_valid_alone_but_not_together_name_the_point(link_dir: Path) -> None:
    # 116 + 11 = 127 bytes fits the PSDU, and 40 + 20 = 60 does; 116 + 20 = 136 > 127 does not
    text = "grid:\n  channel.packet_bytes: [40, 116]\n  channel.mac_overhead_bytes: [11, 20]\n"
    line = one_error_line(run("check", sweep_file(link_dir, text)))
    assert "point 3" in line and "channel.packet_bytes = 116" in line \
        and "channel.mac_overhead_bytes = 20" in line


def test_a_matrix_entry_is_validated_as_in_a_system_file(tmp_path: Path) -> None:
    shutil.copy(REPORTS / "sinopoli-general.yaml", tmp_path / "base.yaml")
    line = one_error_line(run("check", sweep_file(tmp_path, "grid:\n  Q[0][0]: [1, -5]\n")))
    assert "sweep.grid.Q[0][0][1]" in line and "-5" in line and "semidefinite" in line


def test_valid_sweeps_pass_check(link_dir: Path) -> None:
    r = run("check", str(REPORTS / "sweep-link-distance.yaml"))
    assert r.exit_code == 0 and "valid sweep file: 51 points" in r.stdout   # 3 sizes × 17
    r = run("check", sweep_file(link_dir, "grid:\n  channel.distance_m: {start: 20, stop: 60, "
                                          "num: 3}\n  channel.packet_bytes: [20, 116]\n"))
    assert r.exit_code == 0 and "6 points" in r.stdout


def test_a_mapping_where_a_matrix_belongs(tmp_path: Path) -> None:
    path = tmp_path / "m.yaml"
    path.write_text("name: m\nA: {x: 1}\nC: [[1]]\nQ: 1\nR: 1\n")
    line = one_error_line(run("check", str(path)))
    assert "A: expected a number or a matrix (list of rows), got a mapping" in line
    path.write_text("name: m\nA: [[1]]\nC: [[1]]\nQ: [[{x: 1}]]\nR: 1\n")
    assert "Q[0][0]: expected a number, got a mapping" in one_error_line(run("check", str(path)))


# --- a saved record where a system file belongs -----------------------------------------------

def saved_record(folder: Path) -> Path:
    """The top of a record as ``kfcrit analyze --json`` writes it (the keys that mark one)."""
    path = folder / "rec.json"
    path.write_text(json.dumps({"name": "r", "classification": "non-degenerate",
                                "schema_version": "2.0",
                                "review": {"decision": "pass", "reasons": []}}))
    return path


@pytest.mark.parametrize("command", ["analyze", "check", "simulate"])
def test_a_saved_record_is_named_and_the_report_command_given(tmp_path: Path,
                                                              command: str) -> None:
    rec = saved_record(tmp_path)
    line = one_error_line(run(command, str(rec)))
    assert "saved analysis record" in line and f"kfcrit report {rec} -o" in line
    assert "unknown key" not in line


def test_a_sweep_file_given_to_analyze_is_named(link_dir: Path) -> None:
    path = sweep_file(link_dir, "grid:\n  channel.distance_m: [20]\n")
    line = one_error_line(run("analyze", path))
    assert "sweep file" in line and "kfcrit sweep" in line


# --- check imports only what it needs ---------------------------------------------------------

HEAVY = ("scipy", "numba", "matplotlib", "cvxpy", "jinja2")


def modules_after_check(path: Path) -> set[str]:
    code = ("import sys\nfrom kfcrit.cli.main import main\ntry:\n    main(['check', sys.argv[1]])"
            "\nexcept SystemExit as e:\n    assert e.code == 0, e.code\n"
            "print(' '.join(sorted({m.split('.')[0] for m in sys.modules})))\n")
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True, text=True,
                         env=env, cwd=ROOT, timeout=120, check=True)
    return set(out.stdout.split())


def test_check_of_a_system_file_imports_no_heavy_library() -> None:
    loaded = modules_after_check(REPORTS / "sinopoli-general.yaml")
    assert "sympy" in loaded                      # exact parsing needs it
    assert not loaded & set(HEAVY), loaded & set(HEAVY)


# --- radios and the reference -----------------------------------------------------------------

VALID = {"sensitivity_dbm": -95, "reference_per": "1/100", "reference_psdu_bytes": 20,
         "processing_gain_db": 3}
"""A valid value of every settable radio key (ranges: IEEE 802.15.4 sensitivity test)."""


@pytest.mark.parametrize("entry", radio_catalogue(), ids=lambda e: e.name)
def test_settable_radio_keys_are_exactly_what_the_parser_accepts(entry) -> None:
    settable = RADIO_MAPPING_KEYS.get(entry.name, {})
    radio_from_mapping({"model": entry.name, **{k: VALID[k] for k in settable}}, "radio")
    others = (set(VALID) - set(settable)) | {"formula", "source", "frame"}
    for key in sorted(others):
        with pytest.raises(InputError, match="unknown key"):
            radio_from_mapping({"model": entry.name, **{k: VALID[k] for k in settable},
                                key: VALID.get(key, 1)}, "radio")


def test_radios_marks_the_settable_keys() -> None:
    r = run("radios")
    assert r.exit_code == 0
    lines = r.stdout.splitlines()
    names = [e.name for e in radio_catalogue()]
    heads = [i for i, line in enumerate(lines) if line.split("  (")[0] in names]
    assert len(heads) == len(names)
    for start, end in zip(heads, heads[1:] + [len(lines)]):
        block = lines[start:end]
        assert sum("settable keys" in line for line in block) == 1, block
    calibrated = next(line for line in lines if "settable keys (radio: {model: "
                      "ieee802154-oqpsk-calibrated" in line)
    assert "sensitivity_dbm (required)" in calibrated and "reference_psdu_bytes" in calibrated
    data = json.loads(run("radios", "--json").stdout)
    assert {e["name"]: e["settable_keys"] for e in data}["bpsk"] == ["processing_gain_db"]


def test_the_reference_lists_radio_links_and_grid_keys() -> None:
    text = (REPORTS / "REFERENCE.md").read_text()
    for key in ("channel.radio.sensitivity_dbm", "channel.radio.reference_per",
                "channel.radio.reference_psdu_bytes", "channel.radio.processing_gain_db",
                "links.radio", "links.packet_bytes", "links.path_loss", "grid.PARAMETER"):
        assert f"| `{key}` |" in text, key
    for key in ("channel.packet_bytes", "channel.max_retries", "links.max_retries"):
        assert f"| `{key}` | integer |" in text, key
    assert "| `links.distance_m` |" not in text       # per sensor, refused in links:


def test_the_schema_and_the_reader_agree_on_radio_mappings(tmp_path: Path) -> None:
    base = yaml.safe_load((REPORTS / "link-oqpsk-sensor.yaml").read_text())
    validator = jsonschema.Draft202012Validator(system_schema())
    cases = [({"model": "bpsk", "processing_gain_db": 3}, True),
             ({"model": "ieee802154-oqpsk-calibrated", "sensitivity_dbm": -95}, True),
             ({"model": "bpsk", "sensitivity_dbm": -95}, False),
             ({"model": "ieee802154-oqpsk-calibrated"}, False),
             ({"model": "cc2420", "sensitivity_dbm": -95}, False)]
    for radio, ok in cases:
        doc = {**base, "channel": {**base["channel"], "radio": radio}}
        assert validator.is_valid(doc) is ok, radio
        path = tmp_path / "r.yaml"
        path.write_text(yaml.safe_dump(doc))
        assert (run("check", str(path)).exit_code == 0) is ok, radio


def test_check_describes_a_network_by_its_sensors() -> None:
    r = run("check", str(REPORTS / "network-redundant-gauges.yaml"))
    assert r.exit_code == 0, r.stderr
    sensors = yaml.safe_load((REPORTS / "network-redundant-gauges.yaml").read_text())["sensors"]
    assert f"network of {len(sensors)} sensors" in r.stdout and "no channel" not in r.stdout
