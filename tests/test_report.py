"""Tests of the design-review report: view model, filters, formulas, figures, HTML, PDF, CLI.

The full record used here is a hand-made FIXTURE (``fixture_record``): it has realistic values for
every key the report reads, so the layout can be checked before every analysis section lands.
Its numbers are those of the rotation example (A = [[1, −√3], [√3, 1]], eigenvalues 1 ± j√3 of
modulus 2, C = [1 0]) from MATH.md §4: q = 3, p_c = 1 − 2^(−2q/(q−1)) = 1 − 2^(−3) = 7/8,
p_low = 1 − 1/4 = 3/4; p_up = 15/16 from shared/cases/expected.json. The lower covariance bound
is hand-derived: A Aᵀ = 4 I, so S̄ = Q / (1 − 4(1 − p)) and tr S̄ = 2 / (4p − 3). Series that are
not closed-form (tr V̄, simulated traces, the CDF) are synthetic shapes, marked as such.
"""
from __future__ import annotations

import copy
import math
import os
import re
import subprocess
import sys
import zipfile
from html.parser import HTMLParser
from pathlib import Path

import pytest

from kfcrit.views import figures
from kfcrit.views import jinja_filters as filters
from kfcrit.views import mathsvg
from kfcrit.views import report
from kfcrit.io.atomic import write_atomic
from kfcrit.errors import InputError

ROOT = Path(__file__).resolve().parents[1]
REPORTS = ROOT / "reports"
SECTION_ORDER = ["verdict", "system", "bounds", "phase-transition", "simulation", "distribution",
                 "statements", "channel", "appendix"]


def fixture_record() -> dict:
    """A complete, hand-made analysis record (FIXTURE; see the module docstring)."""
    p_grid = [0.75 + 0.25 * i / 80 for i in range(1, 80)]
    tr_s = [2 / (4 * p - 3) for p in p_grid]                       # hand-derived (docstring)
    tr_v = [s * (1 + 0.05 / (p - 15 / 16)) if p > 15 / 16 else None  # synthetic shape
            for p, s in zip(p_grid, tr_s)]
    t = list(range(0, 200, 5))
    return {
        "name": "Oscillator sampled at a sixth of its period",
        "classification": "degenerate-second-order",
        "critical_value": {"value": 0.875, "exact": True, "expression": "7/8",
                           "latex": r"1 - 2^{-3} = \frac{7}{8}",
                           "reason": "degenerate equi-block {1, 2} with q = 3 (Mo–Sinopoli Thm 9)"},
        "robust_critical_value": {"value": 0.75, "tolerance": 1e-9, "expression": "3/4",
                                  "nearby_case": "an irrational angle gives 1 − 1/|λ₁|²"},
        "lower_bound": {"value": 0.75, "expression": "3/4"},
        "block_lower_bound": {"value": 0.875, "expression": "7/8"},
        "upper_bound": {"value": 0.9375, "interval": [0.93749999, 0.93750001], "certified": True,
                        "status": "certified", "method": "bisection on LMI feasibility",
                        "certificate": {"kind": "X ≻ g_p(X)", "verified_by": "exact rationals"},
                        "lower_evidence": "MARE iteration diverges at 0.93749999",
                        "solver": "clarabel", "warnings": []},
        "operating_point": {"arrival_probability": 0.9,
                            "channel": {"model": "bernoulli", "arrival_probability": 0.9,
                                        "arrival_probability_expression": "9/10"},
                            "iid": True, "margin": 0.025, "margin_robust": 0.025,
                            "bracket": None, "verdict": "mean-stable"},
        "warnings": ["FIXTURE warning: shown to check the warnings box"],
        "description": "Eigenvalues 2 exp(+-j pi/3) seen through one output; degenerate, q = 3.",
        "system": {"n": 2, "m": 1, "exact_input": True,
                   "matrices": {"A": [["1", "-sqrt(3)"], ["sqrt(3)", "1"]], "C": [["1", "0"]],
                                "Q": [["1", "0"], ["0", "1"]], "R": [["1"]],
                                "Sigma0": [["1", "0"], ["0", "1"]]},
                   "channel": {"model": "bernoulli", "arrival_probability": 0.9,
                               "arrival_probability_expression": "9/10"}},
        "structure": {"path": "exact",
                      "eigenvalues": [{"value": "1 + sqrt(3)*I", "re": 1.0, "im": math.sqrt(3),
                                       "modulus": 2.0, "modulus_expression": "2"},
                                      {"value": "1 - sqrt(3)*I", "re": 1.0, "im": -math.sqrt(3),
                                       "modulus": 2.0, "modulus_expression": "2"}],
                      "equi_blocks": [{"indices": [0, 1], "modulus": 2.0,
                                       "one_step_observable": False, "rank": 1}],
                      "diagonalizable": True, "detectable": True, "controllable_Q": True},
        "theory": {"moment_thresholds": [
            {"q": 1, "value": 0.75, "expression": "3/4", "applies": False},
            {"q": 2, "value": 0.9375, "expression": "15/16", "applies": False}],
            "stochastic_boundedness": "FIXTURE: P_t is stochastically bounded for every p > 0 "
                                      "and converges weakly to a unique invariant distribution.",
            "almost_sure": ["FIXTURE: limsup tr P_t = ∞ almost surely for 0 < p < 1.",
                            "FIXTURE: liminf tr P_t ≤ tr M almost surely."]},
        "covariance_bounds": {"p": 0.9,
                              "lower": {"exists": True, "trace": 2 / (4 * 0.9 - 3),
                                        "max_eig": 1 / (4 * 0.9 - 3), "matrix": None},
                              "upper": {"exists": False, "trace": None, "max_eig": None,
                                        "matrix": None, "residual": None, "method": "MARE"}},
        "phase_transition": {"p": p_grid, "trace_lower": tr_s, "trace_upper": tr_v,
                             "markers": {"p_low": 0.75, "p_c": 0.875, "p_up": 0.9375,
                                         "operating": 0.9}},
        "simulation": {
            "operating_point": {
                "t": t, "mean_trace": [3.3 + 2 * math.exp(-k / 30) for k in t],
                "band_low": [3.0 + 2 * math.exp(-k / 30) for k in t],
                "band_high": [3.6 + 2 * math.exp(-k / 30) for k in t],
                "cdf": {"x": [2 + 0.5 * i for i in range(40)],
                        "F": [1 - math.exp(-0.25 * i) for i in range(40)]},
                "tail_probability": 0.018,
                # synthetic shape: block maxima grow, block minima stay bounded (MATH §6)
                "almost_sure": {"block_start": [2 ** k for k in range(10)],
                                "block_max": [4.0 * 1.6 ** k for k in range(10)],
                                "block_min": [3.3] * 10}},
            "phase_demo": [
                {"p": 0.85, "label": "below p_c", "t": t,
                 "mean_trace": [3 * 1.03 ** k for k in t]},
                {"p": 0.9, "label": "above p_c", "t": t,
                 "mean_trace": [3.3 + 2 * math.exp(-k / 30) for k in t]}],
            "seeds": [0, 1], "paths": 400, "steps": 200},
        "invariant": None,
        "link_budget": None,
        "requirements": {"max_error_trace": 10.0, "max_tail_probability": 0.05},
        "verification": [{"check": "FIXTURE upper-bound certificate", "passed": True,
                          "detail": "exact rationals"}],
        "provenance": {"versions": {"kfcrit": "0.1.0", "numpy": "2.4"}, "seed": 0,
                       "input_path": "reports/rotation-third-turn.yaml",
                       "input_sha256": "ab" * 32,
                       "options": {"tolerance": 1e-9, "quick": False, "seed": 0}},
    }


def scalar_fixture() -> dict:
    """FIXTURE of the Kar–Sinopoli–Moura scalar example (MATH §5): P* = 1 + √2, first gap
    (3, 3 + 2√2), S_n = 2 S_{n−1} + 1 so the second gap is (7, 7 + 4√2 + ...)."""
    rec = fixture_record()
    rec["system"]["n"] = 1
    rec["invariant"] = {"fixed_point": 1 + math.sqrt(2),
                        "support_points": [1 + math.sqrt(2), 3, 2 * (1 + math.sqrt(2)) + 1, 7],
                        "gaps": [[3, 3 + 2 * math.sqrt(2)], [7, 4 * (1 + math.sqrt(2)) + 3]]}
    return rec


class _Tags(HTMLParser):
    """Collects tags, ids and attributes (to check structure without a browser)."""

    def __init__(self) -> None:
        super().__init__()
        self.ids: list[str] = []
        self.tags: list[tuple[str, dict]] = []

    def handle_starttag(self, tag: str, attrs: list) -> None:
        d = dict(attrs)
        self.tags.append((tag, d))
        if "id" in d:
            self.ids.append(d["id"])


def parse(html: str) -> _Tags:
    p = _Tags()
    p.feed(html)
    return p


@pytest.fixture(scope="module")
def full_html() -> str:
    rec = fixture_record()
    return report.render_html(rec, figures.build_figures(rec))


# ----------------------------------------------------------------------------- filters

def test_num_formats_and_missing():
    assert filters.num(None) == "—"
    assert filters.num(0.875) == "0.875"
    assert filters.num(1 / 3, 4) == "0.3333"
    assert filters.num(7) == "7"
    assert filters.num(True) == "yes"


def test_signed_interval_yesno_pct():
    assert filters.signed(0.025) == "+0.025"
    assert filters.signed(-0.04) == "−0.04"
    assert filters.signed(None) == "—"
    assert filters.interval([0.75, None]) == "[0.75, —]"
    assert filters.yesno(None) == "not computed"
    assert filters.yesno(False) == "no"
    assert filters.pct(0.0123) == "1.23 %"


def test_pretty_expr_and_indices():
    assert filters.pretty_expr("1 - 2**(-3)") == "1 − 2^−3"
    assert filters.pretty_expr("-sqrt(3)") == "−√3"
    assert filters.pretty_expr("77/64 + sqrt(16169)/64") == "77/64 + √16169/64"
    assert filters.pretty_expr(None) == "—"
    assert filters.indices([0, 1]) == "{1, 2}"
    assert filters.verdict_label("mean-stable") == "MEAN STABLE"
    assert filters.verdict_label(None) == "NOT DETERMINED"


# ----------------------------------------------------------------------------- formulas

def test_latex_svg_is_inline_svg_with_unique_ids():
    a = mathsvg.latex_svg(r"p_c = \frac{7}{8}")
    b = mathsvg.latex_svg(r"p_c = \frac{7}{8}")
    assert a.startswith("<svg") and "<title>" in a
    assert "<?xml" not in a and "<!DOCTYPE" not in a and "<style" not in a
    ids_a = set(re.findall(r'id="([^"]+)"', a))
    ids_b = set(re.findall(r'id="([^"]+)"', b))
    assert ids_a and not ids_a & ids_b
    for ref in re.findall(r'href="#([^"]+)"', a):
        assert ref in ids_a


def test_latex_svg_refuses_bad_latex_and_escapes_label():
    assert mathsvg.latex_svg(r"\frac{") is None
    svg = mathsvg.latex_svg("x", label='<script>"')
    assert "<script>" not in svg and "&lt;script&gt;" in svg


def test_expression_latex_uses_safe_parser():
    assert mathsvg.expression_latex("-sqrt(3)") == r"- \sqrt{3}"
    assert mathsvg.expression_latex("7/8") == r"\frac{7}{8}"
    assert mathsvg.expression_latex("__import__('os')") is None


# ----------------------------------------------------------------------------- figures

def test_every_figure_drawn_from_full_fixture():
    figs = figures.build_figures(scalar_fixture())
    assert set(figs) == set(figures.FIGURE_KEYS)
    for key, svg in figs.items():
        assert svg is not None and svg.startswith("<svg"), key


def test_figures_missing_or_malformed_data_give_none():
    assert all(v is None for v in figures.build_figures({}).values())
    rec = fixture_record()
    rec["phase_transition"]["trace_lower"] = "oops"
    rec["phase_transition"]["trace_upper"] = [1.0]   # wrong length
    rec["simulation"]["phase_demo"] = [{"p": 0.5, "t": [1, 2], "mean_trace": ["x", 1]}]
    figs = figures.build_figures(rec)
    assert figs["phase_transition"] is None and figs["traces"] is None
    assert figs["operating"] is not None


# ----------------------------------------------------------------------------- HTML

def test_full_report_has_every_section_in_reading_order(full_html):
    ids = parse(full_html).ids
    positions = [ids.index(s) for s in SECTION_ORDER]
    assert positions == sorted(positions)
    assert len(ids) == len(set(ids)), "duplicate ids in the page"


def test_full_report_shows_verdict_and_critical_value(full_html):
    assert "MEAN STABLE" in full_html
    assert "0.875" in full_html and "7/8" in full_html
    assert "+0.025" in full_html                     # margin 0.9 − 7/8
    assert "Mo–Sinopoli, Theorem 5" in full_html     # degenerate second order decides p_c


def test_full_report_sections_present_not_missing(full_html):
    body = full_html.split("<main>")[1]
    for text in ("Phase transition", "Simulated error traces", "Distribution of tr P",
                 "0.018", "met", "FIXTURE: limsup", "FIXTURE warning", "ab" * 32):
        assert text in body, text
    # every figure is drawn, none says "not computed"
    for fig_id in ("fig-phase-transition", "fig-traces", "fig-operating", "fig-cdf"):
        chunk = body.split(f'id="{fig_id}"')[1].split("</figure>")[0]
        assert "<svg" in chunk and "not computed" not in chunk


def test_html_is_self_contained(full_html):
    tags = parse(full_html).tags
    assert not [t for t, _ in tags if t in ("script", "link", "iframe", "object", "embed")]
    for _, attrs in tags:
        for name in ("src", "href"):
            value = attrs.get(name)
            assert value is None or value.startswith(("#", "data:")), value
    assert "url(http" not in full_html and "@import" not in full_html


def test_missing_sections_say_not_computed():
    rec = {"name": "bare", "critical_value": None}
    html = report.render_html(rec, figures.build_figures(rec))
    ids = parse(html).ids
    for s in SECTION_ORDER:
        assert s in ids, s
    for phrase in ("operating point: not computed", "structure analysis: not computed",
                   "phase transition: not computed", "simulation: not computed",
                   "covariance bounds: not computed",
                   "almost-sure and distributional statements: not computed"):
        assert phrase in html, phrase


def test_every_single_section_missing_renders():
    full = fixture_record()
    figs = figures.build_figures(full)
    for key in full:
        rec = copy.deepcopy(full)
        rec[key] = None
        html = report.render_html(rec, figs)
        assert 'id="verdict"' in html, key
        rec.pop(key)
        report.render_html(rec, {})


def test_malformed_sections_do_not_crash():
    rec = fixture_record()
    rec["structure"] = {"eigenvalues": "not a list", "equi_blocks": [None, 3]}
    rec["theory"] = {"moment_thresholds": [None], "almost_sure": "one sentence"}
    rec["upper_bound"] = {"interval": "x"}
    html = report.render_html(rec, figures.build_figures(rec))
    assert "one sentence" in html


def test_autoescape_of_record_text():
    rec = fixture_record()
    rec["name"] = "<script>alert(1)</script>"
    rec["warnings"] = ["<b>bold</b>"]
    html = report.render_html(rec, {})
    assert "<script>alert" not in html and "&lt;script&gt;alert(1)" in html
    assert "<b>bold</b>" not in html


def test_scalar_system_shows_invariant_support():
    rec = scalar_fixture()
    html = report.render_html(rec, figures.build_figures(rec))
    assert "Support of the invariant distribution" in html
    assert "[3, 5.8284271]" in html   # 3 + 2√2 = 5.82842712… to 8 digits (MATH §5)
    html2 = report.render_html(fixture_record(), {})
    assert "Support of the invariant" not in html2     # n = 2: not applicable


def test_undetermined_and_unstable_verdicts():
    rec = fixture_record()
    rec["operating_point"].update(verdict="undetermined", margin=None, margin_robust=None,
                                  bracket=[0.875, 0.9375], margin_to_bracket=[0.025, -0.0375])
    html = report.render_html(rec, {})
    assert "verdict-undetermined" in html and "[0.875, 0.9375]" in html
    rec["operating_point"].update(verdict="mean-unstable")
    assert "verdict-unstable" in report.render_html(rec, {})


def test_requirement_not_met_is_flagged():
    rec = fixture_record()
    rec["simulation"]["operating_point"]["tail_probability"] = 0.2   # above 0.05
    rec["requirements"]["assessment"] = {"status": "not met", "basis": "0.2 > 0.05"}
    assert "NOT met" in report.render_html(rec, {})
    rec["requirements"]["assessment"] = {"status": "not demonstrated", "basis": "straddles"}
    html = report.render_html(rec, {})
    assert "not demonstrated" in html and "NOT met" not in html


def test_quick_draft_banner():
    rec = fixture_record()
    rec["provenance"]["options"]["quick"] = True
    assert 'id="draft"' in report.render_html(rec, {})
    assert 'id="draft"' not in report.render_html(fixture_record(), {})


def test_strict_undefined_catches_template_typos(tmp_path, monkeypatch):
    import jinja2

    (tmp_path / report.TEMPLATE).write_text("{{ verdict.no_such_key }}")
    monkeypatch.setattr(report, "template_dir", lambda: tmp_path)
    with pytest.raises(jinja2.UndefinedError):
        report.render_html(fixture_record(), {})


def test_template_dir_is_repository_templates_in_a_checkout():
    d = report.template_dir()
    assert (d / "report.html.j2").is_file() and (d / "report.css").is_file()


# ----------------------------------------------------------------------------- PDF

@pytest.fixture(scope="module")
def full_pdf(full_html) -> bytes:
    pytest.importorskip("weasyprint")
    return report.render_pdf(full_html)


def pdf_text(data: bytes) -> tuple[int, str]:
    import io

    pypdf = pytest.importorskip("pypdf")
    reader = pypdf.PdfReader(io.BytesIO(data))
    return len(reader.pages), "\n".join(page.extract_text() for page in reader.pages)


def test_pdf_text_has_verdict_and_critical_value(full_pdf):
    pages, text = pdf_text(full_pdf)
    assert full_pdf.startswith(b"%PDF")
    assert pages >= 2
    flat = " ".join(text.split())
    assert "MEAN STABLE" in flat
    assert "0.875" in flat
    assert f"page 1 of {pages}" in flat            # page numbers from the print stylesheet


def test_pdf_fetcher_refuses_external_urls(monkeypatch):
    pytest.importorskip("weasyprint")
    import urllib.request

    def no_network(*args, **kwargs):
        raise AssertionError("network access attempted")

    monkeypatch.setattr(urllib.request.OpenerDirector, "open", no_network)
    html = ('<html><body><p>x</p><img src="http://example.invalid/a.png">'
            '<link rel="stylesheet" href="https://example.invalid/s.css"></body></html>')
    assert report.render_pdf(html).startswith(b"%PDF")
    fetcher = report._refusing_fetcher()
    fetch = getattr(fetcher, "fetch", fetcher)
    with pytest.raises(Exception):  # noqa: B017 - any refusal is fine
        fetch("http://example.invalid/a.png")


# ----------------------------------------------------------------------------- command

def test_output_format_rules():
    assert report.output_format("a.html", None) == "html"
    assert report.output_format("a.PDF", None) == "pdf"
    assert report.output_format("a.txt", "pdf") == "pdf"
    with pytest.raises(InputError) as exc:
        report.output_format("a.txt", None)
    assert exc.value.exit_code == 2


def test_refuses_to_overwrite_input(tmp_path):
    src = tmp_path / "sys.html"
    src.write_text((REPORTS / "sinopoli-scalar.yaml").read_text())
    before = src.read_bytes()
    with pytest.raises(InputError, match="input file"):
        report.report_command(str(src), str(src), fmt=None, quick=True, seed=0, max_states=50)
    link = tmp_path / "link.html"
    link.symlink_to(src)
    with pytest.raises(InputError, match="input file"):
        report.report_command(str(src), str(link), fmt=None, quick=True, seed=0, max_states=50)
    assert src.read_bytes() == before


def test_refuses_missing_folder_and_directory(tmp_path):
    src = REPORTS / "sinopoli-scalar.yaml"
    with pytest.raises(InputError, match="does not exist"):
        report.check_output_path(src, tmp_path / "nope" / "r.html")
    (tmp_path / "d.html").mkdir()
    with pytest.raises(InputError, match="directory"):
        report.check_output_path(src, tmp_path / "d.html")


def test_write_atomic_replaces_and_leaves_no_temporary(tmp_path):
    target = tmp_path / "r.html"
    target.write_text("old")
    write_atomic(target, b"new")
    assert target.read_bytes() == b"new"
    assert [p.name for p in tmp_path.iterdir()] == ["r.html"]


def test_write_atomic_gives_usual_permissions(tmp_path):
    """``mkstemp`` creates 0600 files; outputs must get 0666 & ~umask like any new file."""
    old = os.umask(0o022)
    try:
        write_atomic(tmp_path / "out.csv", b"x")
    finally:
        os.umask(old)
    assert (tmp_path / "out.csv").stat().st_mode & 0o777 == 0o644


def test_write_atomic_failure_keeps_old_file(tmp_path, monkeypatch):
    target = tmp_path / "r.html"
    target.write_text("old")

    def boom(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", boom)
    with pytest.raises(OSError):
        write_atomic(target, b"new")
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["r.html"]


def example_files() -> list[Path]:
    """The example *system* files in ``reports/`` (sweep files, with a ``grid``, are not)."""
    import yaml

    return [p for p in sorted(REPORTS.glob("*.yaml"))
            if "A" in (yaml.safe_load(p.read_text(encoding="utf-8")) or {})]


@pytest.mark.parametrize("path", example_files(), ids=lambda p: p.stem)
def test_render_every_example_html(path, tmp_path, capsys):
    out = tmp_path / f"{path.stem}.html"
    code = report.report_command(str(path), str(out), fmt=None, quick=True, seed=0,
                                 max_states=50)
    assert code in (0, 3)
    html = out.read_text(encoding="utf-8")
    ids = parse(html).ids
    assert [s for s in SECTION_ORDER if s in ids] == SECTION_ORDER
    assert len(ids) == len(set(ids))
    assert "Verdict" in html and "critical value" in html
    err = capsys.readouterr().err
    assert "wrote" in err and str(out) in err
    assert capsys.readouterr().out == ""            # stdout carries no progress
    assert not raw_dumps(visible_text(html)), raw_dumps(visible_text(html))
    for fig_id in ("fig-phase-transition", "fig-traces", "fig-operating", "fig-cdf",
                   "fig-almost-sure"):              # every example has a channel
        chunk = html.split(f'id="{fig_id}"')[1].split("</figure>")[0]
        assert "<svg" in chunk, fig_id
    if path.stem == "link-oqpsk-sensor":
        check_link_budget_report(html)


class _Text(HTMLParser):
    """The text a reader sees (no SVG, style or title content)."""

    def __init__(self) -> None:
        super().__init__()
        self.parts: list[str] = []
        self.hidden = 0

    def handle_starttag(self, tag: str, attrs: list) -> None:
        self.hidden += tag in ("svg", "style", "title")

    def handle_endtag(self, tag: str) -> None:
        self.hidden -= tag in ("svg", "style", "title")

    def handle_data(self, data: str) -> None:
        if not self.hidden:
            self.parts.append(data)


def visible_text(html: str) -> str:
    t = _Text()
    t.feed(html)
    return " ".join(" ".join(t.parts).split())


# Raw record leaking into the page: a dict repr, a "snake_key: value" dump, Python literals.
RAW_DUMP = re.compile(r"\{'|'[a-z_]+': |\b[a-z]+_[a-z_]+: |\bNone\b|\bTrue\b|\bFalse\b|\bnan\b")


def raw_dumps(text: str) -> list[str]:
    return [m.group(0) for m in RAW_DUMP.finditer(text)]


def qty_rows(html: str, section_id: str) -> dict[str, str]:
    """``{label: value}`` of the labelled quantity tables inside one section."""
    body = html.split(f'id="{section_id}"')[1].split("</section>")[0]
    rows = {}
    for tr in re.findall(r"<tr[^>]*>(.*?)</tr>", body, re.DOTALL):
        th = re.search(r'<th scope="row">(.*?)</th>', tr, re.DOTALL)
        td = re.search(r'<td class="(?:num|val)">(.*?)</td>', tr, re.DOTALL)
        if th and td:
            rows[visible_text(th.group(1))] = visible_text(td.group(1))
    return rows


def check_link_budget_report(html: str) -> None:
    """The link-budget example: design outputs as labelled rows with units, and the verdict
    box says the 2 dB / 10 % margin policy is not met at 105 m (max distance ≈ 81 m)."""
    rows = qty_rows(html, "channel")
    expect_units = {"required SINR": " dB", "required received power": " dBm",
                    "link margin at the configured distance": " dB",
                    "maximum distance at the margin policy": " m",
                    "transmit power": " dBm", "path loss (median)": " dB",
                    "noise bandwidth": " MHz", "noise temperature": " K",
                    "shadowing outage P(p_link ≤ design requirement)": " %"}
    for label, unit in expect_units.items():
        assert label in rows, (label, sorted(rows))
        assert rows[label].endswith(unit), (label, rows[label])
    assert rows["required arrival probability"] == "0.36"           # p_c = 9/25
    assert re.fullmatch(r"\d+\.\d m", rows["maximum distance at the margin policy"])
    assert 'id="link-design"' in html
    verdict = html.split('id="verdict"')[1].split("</section>")[0]
    assert "margin policy NOT met" in verdict and "policy needs" in verdict


def test_cli_report_pdf_and_unknown_extension(tmp_path):
    src = REPORTS / "sinopoli-scalar.yaml"
    out = tmp_path / "r.pdf"
    run = subprocess.run([sys.executable, "-m", "kfcrit", "report", str(src), "-o", str(out),
                          "--quick"], capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert run.returncode in (0, 3), run.stderr
    assert out.read_bytes().startswith(b"%PDF") and run.stdout == ""
    pages, text = pdf_text(out.read_bytes())
    assert "Verdict" in text and "critical value" in text
    # What a reviewer reads in the printed example: the verdict and p_c = 9/25 = 0.36.
    flat = " ".join(text.split())
    assert "MEAN STABLE" in flat and "0.36" in flat and "9/25" in flat
    # --quick: the draft mark is on every page (an @page margin box), not only on page 1.
    import io

    import pypdf

    reader = pypdf.PdfReader(io.BytesIO(out.read_bytes()))
    assert pages >= 2
    assert all("DRAFT" in page.extract_text() for page in reader.pages)
    bad = subprocess.run([sys.executable, "-m", "kfcrit", "report", str(src), "-o",
                          str(tmp_path / "r.txt")], capture_output=True, text=True, cwd=ROOT,
                         timeout=120)
    assert bad.returncode == 2 and "--format" in bad.stderr
    assert not (tmp_path / "r.txt").exists()


@pytest.mark.slow
def test_wheel_ships_templates(tmp_path):
    """The built wheel holds kfcrit/templates/report.html.j2 and report.css (force-include)."""
    run = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps",
                          "--no-build-isolation", "-w", str(tmp_path), str(ROOT)],
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    wheel = next(tmp_path.glob("kfcrit-*.whl"))
    names = set(zipfile.ZipFile(wheel).namelist())
    for name in ("kfcrit/templates/report.html.j2", "kfcrit/templates/report.css",
                 "kfcrit/templates/_verdict.html.j2", "kfcrit/report.py"):
        assert name in names, name


# ----------------------------------------------------------------------------- labelled tables

def test_unit_and_number_filters():
    assert filters.unit(-100.9648, "dBm") == "−100.96 dBm"
    assert filters.unit(81.187, "m") == "81.2 m"
    assert filters.unit(2.0e6, "Hz") == "2 MHz"
    assert filters.unit(None, "dB") == "—"
    assert filters.sci(4.261669270870999e-16) == "4.26 × 10⁻¹⁶"
    assert filters.sci(0.5) == "0.5"
    assert filters.prob(0.32859750788) == "0.3286"
    assert filters.prob(1.2e-4) == "1.2 × 10⁻⁴"
    assert filters.count(50000) == "50\u202f000"
    assert filters.vector([[-0.80098], [-0.99706]]) == "[−0.801, −0.9971]"
    assert filters.quantity(1.7752, "dB") == "1.78 dB"
    assert filters.quantity(0.3286, "pct") == "32.9 %"
    assert filters.quantity(None, "yesno") == "not computed"


def test_eigenvalues_with_imaginary_unit_are_typeset():
    assert mathsvg.expression_latex("1 + sqrt(3)*I") == r"1 + \sqrt{3} i"
    assert mathsvg.expression_svg("1 - sqrt(3)*I") is not None
    assert mathsvg.expression_latex("exp(I*pi/3)") is None      # not misread as E**(E*pi/3)


def test_invariant_gaps_keep_exact_hole_over_numerical_estimate():
    inv = {"holes": [[2.5, 2.7071067811865475], [3.0, 5.82842712474619]],
           "support_points": {"largest_gaps": [[2.4999284826384978, 2.7071067811865475],
                                               [2.9997139714660026, 5.82842712474619]]}}
    assert figures.invariant_gaps(inv) == [[2.5, 2.7071067811865475],
                                           [3.0, 5.82842712474619]]


def test_fixture_report_has_no_raw_dumps(full_html):
    assert not raw_dumps(visible_text(full_html)), raw_dumps(visible_text(full_html))


def link_record() -> dict:
    """FIXTURE: the link-budget section shape of ``linkbudget.design_section`` (numbers of the
    link-oqpsk-sensor example, rounded), with the analysis' ``design_check``."""
    from kfcrit.analysis.record import design_check

    rec = fixture_record()
    channel = {"model": "link-budget", "radio": {"model": "ieee802154-oqpsk-2450"},
               "tx_power_dbm": 0.0, "distance_m": 105.0, "packet_bytes": 40,
               "path_loss": {"model": "log-distance", "shadowing_sigma_db": 4.0,
                             "shadowing": "per-link"},
               "margin_db": 2.0, "max_outage": 0.1, "sinr_db": 0.1292,
               "arrival_probability": 0.96214, "arrival_probability_expression": "0.96214"}
    rec["operating_point"]["channel"] = channel
    lb = {"applicable": True, "radio": {"model": "ieee802154-oqpsk-2450", "formula": "BER"},
          "link": {"tx_power_dbm": 0.0, "distance_m": 105.0, "path_loss_db": 100.836,
                   "rx_power_dbm": -100.836, "bandwidth_hz": 2e6, "interference_dbm": None,
                   "sinr_db": 0.1292, "packet_error_rate": 0.0379, "arrival_probability": 0.962},
          "margin_policy": {"margin_db": 2.0, "max_outage": 0.1, "effective_margin_db": 5.126,
                            "rule": "keep max(margin_db, sigma * Phi^-1(1 - max_outage)) dB"},
          "required_arrival_probability": {"design_value": 0.875, "basis": "critical value p_c"},
          "required_sinr_db": -1.646, "required_rx_power_dbm": -102.611,
          "link_margin_db": 1.7752, "max_distance_m": 81.187, "max_distance_unbounded": False,
          "mean_stable_at_distance": True,
          "shadowing": {"sigma_db": 4.0, "mode": "per-link", "mean_arrival_probability": 0.64,
                        "outage_below_critical": 0.3286, "outage_below_upper": 0.3473},
          "thresholds": [{"label": "critical_value", "arrival_probability": 0.875,
                          "required_sinr_db": -1.646, "required_rx_power_dbm": -102.611,
                          "link_margin_db": 1.7752, "max_distance_m": 81.187,
                          "max_distance_unbounded": False, "outage_probability": 0.3286,
                          "reachable": True}],
          "notes": ["per-link shadowing: FIXTURE note"]}
    lb["design_check"] = design_check(lb)
    rec["link_budget"] = lb
    return rec


def test_design_check_compares_the_link_with_its_policy():
    dc = link_record()["link_budget"]["design_check"]
    assert dc["margin_policy_met"] is False            # 1.7752 dB < 5.126 dB
    assert dc["outage_within_policy"] is False         # 32.9 % > 10 %
    assert dc["max_distance_m"] == 81.187 and dc["distance_m"] == 105.0


def test_link_budget_section_is_a_labelled_table_with_units():
    rec = link_record()
    html = report.render_html(rec, {})
    rows = qty_rows(html, "channel")
    assert rows["required SINR"] == "−1.65 dB"
    assert rows["required received power"] == "−102.61 dBm"
    assert rows["link margin at the configured distance"] == "1.78 dB"
    assert rows["maximum distance at the margin policy"] == "81.2 m"
    assert rows["noise bandwidth"] == "2 MHz"
    assert rows["shadowing outage P(p_link ≤ design requirement)"] == "32.9 %"
    assert rows["interference"] == "none"
    assert "margin policy NOT met" in html
    assert not raw_dumps(visible_text(html)), raw_dumps(visible_text(html))


def test_gilbert_elliott_report_has_bursty_section(tmp_path):
    src = tmp_path / "ge.yaml"
    src.write_text("name: bursty\nA: [[-1.25]]\nC: [[1]]\nQ: [[1]]\nR: [[2.5]]\n"
                   "channel: {model: gilbert-elliott, failure_rate: 0.2, recovery_rate: 0.4}\n"
                   "requirements: {max_error_trace: 20, max_tail_probability: 0.05}\n",
                   encoding="utf-8")
    out = tmp_path / "ge.html"
    assert report.report_command(str(src), str(out), fmt=None, quick=True, seed=0,
                                 max_states=50) in (0, 3)
    html = out.read_text(encoding="utf-8")
    assert 'id="bursty-link"' in html and "verdict basis" in html
    rows = qty_rows(html, "channel")
    assert rows["recovery rate r"] == "0.4" and rows["mean loss-burst length 1/r"] == "2.5"
    assert rows["required recovery rate 1 − 1/a²"] == "0.36"           # 1 − (4/5)² (MATH §7)
    assert "P(tr P &gt; 20)" in html and "95 % interval" in html        # requirement + CI
    assert 'id="fig-invariant"' in html                                 # scalar: support drawn
    assert "not the verdict's basis for a bursty channel" in html      # the i.i.d. margin
    assert not raw_dumps(visible_text(html)), raw_dumps(visible_text(html))


def test_missing_figures_say_why():
    rec = fixture_record()
    rec["operating_point"] = None
    rec["system"]["channel"] = None
    rec["simulation"]["operating_point"] = None
    html = report.render_html(rec, figures.build_figures(rec))
    chunk = html.split('id="fig-cdf"')[1].split("</figure>")[0]
    assert "not computed (the system file has no channel section" in chunk
    assert "channel: not computed (the system file has no channel section" in html
    rec["simulation"] = {"skipped": True, "reason": "simulation disabled (--no-simulate)"}
    html = report.render_html(rec, figures.build_figures(rec))
    assert "simulation: not computed (simulation disabled (--no-simulate))" in html


def test_simulation_summary_is_labelled():
    rec = fixture_record()
    rows = qty_rows(report.render_html(rec, {}), "simulation")
    assert rows["mean tr P_t at the horizon"] == filters.num(3.3 + 2 * math.exp(-195 / 30), 6)
    html = report.render_html(rec, {})
    assert "400 paths × 200 steps" in html


def test_phase_window_starts_where_the_bounds_exist() -> None:
    """Below p_low both bounds are infinite: the window starts just below the first finite point
    (a tenth of the remaining range), and widens to show an operating point further left."""
    from kfcrit.views.figures import phase_window

    p = [0.0, 0.25, 0.5, 0.75, 0.8, 0.9, 1.0]
    nan = float("nan")
    lower = [nan, nan, nan, nan, 40.0, 8.0, 2.0]
    upper = [nan, nan, nan, nan, nan, 30.0, 3.0]
    marks = {"p_low": 0.75, "p_c": 0.9375, "p_up": 0.9375, "operating": 0.95}
    left, right = phase_window(p, lower, upper, marks)
    assert right == 1.0
    assert left == pytest.approx(0.75 - 0.1 * 0.25)
    left, _ = phase_window(p, lower, upper, {**marks, "operating": 0.5})
    assert left == pytest.approx(0.5 - 0.1 * 0.5)
    # nothing finite at all: fall back to the whole grid
    left, right = phase_window(p, [nan] * 7, None, {})
    assert (left, right) == (0.0, 1.0)


# ----------------------------------------------------------------------------- audit regressions

def test_num_and_sci_share_the_scientific_style():
    assert filters.num(160480.0, 5) == "1.6048 × 10⁵"
    assert filters.num(2.5e-5, 3) == "2.5 × 10⁻⁵"
    assert filters.num(12345.6) == "12345.6" and filters.num(0.000123, 3) == "0.000123"
    assert filters.num(0.0) == "0" and filters.sci(0.0) == "0" and filters.sci(0) == "0"
    assert filters.sci(4.26e-16) == "4.26 × 10⁻¹⁶" and filters.sci(5e5) == "5 × 10⁵"
    assert filters.span(87308.2, 112890.0, 5) == "8.7308 × 10⁴ – 1.1289 × 10⁵"
    assert "e+" not in filters.num(1e12) and "e-" not in filters.num(1e-12)


def test_pretty_text_unicode_notation():
    t = filters.pretty_text
    assert t("|1 + sqrt(3)*I| = |1 - sqrt(3)*I| = 2") == "|1 + i√3| = |1 − i√3| = 2"
    assert t("entries in QQ(sqrt(3))") == "entries in ℚ(√3)"
    assert t("f0(X) = 2*X + 1; f1(X) = 2*X/(X + 1) + 1") == "f₀(X) = 2X + 1; f₁(X) = 2X/(X + 1) + 1"
    assert t("S_n = 2*S_(n-1) + 1") == "Sₙ = 2Sₙ₋₁ + 1"
    assert t("supp(mu) within [f0^n(P*), f0^n(f1(inf))]") == "supp(μ) within [f₀ⁿ(P*), f₀ⁿ(f₁(∞))]"
    assert t("none: p <= p_up (Thm 3)") == "none: p ≤ p_up (Thm 3)"
    assert t("(>= −5 required)") == "(≥ −5 required)"
    assert t("(1 - r) a^2 < 1") == "(1 − r) a² < 1"
    assert t("max(margin_db, sigma * Phi^-1(1 - max_outage))") == \
        "max(margin_db, σ·Φ⁻¹(1 − max_outage))"
    # prose survives: hyphenated names, identifiers, the *-mixing property
    assert t("Kar-Sinopoli-Moura; *-mixing; p_low") == "Kar-Sinopoli-Moura; *-mixing; p_low"
    assert t("threshold tr P > 3.19e+10 (diverged)") == "threshold tr P > 3.19 × 10¹⁰ (diverged)"
    assert t(None) == ""


def _with_operating_sim(rec: dict, **op) -> dict:
    rec["simulation"]["operating_point"].update(op)
    return rec


def test_diverged_paths_are_described_as_censored_lower_bounds():
    rec = _with_operating_sim(fixture_record(), paths=400, steps=200,
                              divergence={"threshold": 1e10, "diverged_paths": 3,
                                          "mean_is_lower_bound": True})
    rows = {r["label"]: r for r in report.simulation_view(rec)["rows"]}
    note = rows["diverged paths"]["note"]
    assert "censored at the threshold; means are lower bounds" in note
    assert "not averaged" not in note and "flagged" not in note
    # the newer rule: paths continued in scaled form keep true values (no lower-bound claim)
    rec["simulation"]["operating_point"]["divergence"].update(continued=True,
                                                               mean_is_lower_bound=False)
    rows = {r["label"]: r for r in report.simulation_view(rec)["rows"]}
    assert "true values" in rows["diverged paths"]["note"]
    assert "lower bounds" not in rows["diverged paths"]["note"]
    rec["verification"] = [{"check": "simulation: all statistics finite (divergence flagged, "
                                     "not propagated)", "passed": True, "detail": "0 of 1"}]
    names = [c["name"] for c in report.appendix_view(rec)["checks"]]
    assert not any("flagged" in n for n in names)
    assert any("censored" in n for n in names)


def test_cdf_points_keep_the_tail_and_the_maximum():
    import numpy as np

    from kfcrit.sim.montecarlo import SimulationResult

    def result(traces, threshold=1e10):
        res = object.__new__(SimulationResult)      # cdf_points reads these two fields only
        object.__setattr__(res, "horizon_traces", np.asarray(traces, dtype=float))
        object.__setattr__(res, "divergence_threshold", threshold)
        return res

    rng = np.random.default_rng(0)
    x = np.concatenate([rng.uniform(3, 15, 997), [25.0, 40.0, 90.0]])   # 3 paths above M = 20
    cdf = result(x).cdf_points()
    assert len(cdf["trace"]) == x.size                       # N ≤ 2000: the exact ECDF
    assert max(cdf["trace"]) == 90.0 and cdf["probability"][-1] == 1.0
    above = [f for v, f in zip(cdf["trace"], cdf["probability"]) if v > 20]
    assert len(above) == 3
    big = np.concatenate([rng.uniform(3, 15, 49_990), np.linspace(21, 500, 10)])
    cdf = result(big).cdf_points()
    assert len(cdf["trace"]) < 2000 and max(cdf["trace"]) == 500.0
    assert sum(v > 20 for v in cdf["trace"]) == 10            # every exceeding path is drawn
    assert cdf["trace"] == sorted(cdf["trace"])
    censored = result([1.0, 2.0, 1e10, 1e10], threshold=1e10).cdf_points()
    assert censored["trace"] == [1.0, 2.0] and censored["probability"] == [0.25, 0.5]


def test_cdf_figure_reaches_past_the_limit():
    rec = fixture_record()
    rec["simulation"]["operating_point"]["cdf"] = {"x": [2.0, 3.0, 4.0, 30.0],
                                                   "F": [0.25, 0.5, 0.75, 1.0]}
    assert figures.cdf_svg(rec) is not None
    left, right = figures.cdf_window(rec["simulation"]["operating_point"]["cdf"]["x"], 10.0)
    assert left < 2.0 and right > 30.0
    left, right = figures.cdf_window([2.0, 3.0, 4.0], 10.0)   # no path beyond: still past M
    assert right > 10.0


def test_time_average_interval_clamped_and_flagged():
    erg = {"replicas": 4, "steps": 10_000, "burn_in": 1_000,
           "time_averages": {"pooled_mean_trace": {"mean": 17643.0, "lower": -4760.7,
                                                   "upper": 40048.0},
                             "replica_mean_trace": [210.0, 1248.0, 196.0, 68000.0]}}
    rec = _with_operating_sim(fixture_record(), ergodic=erg)
    rows = {r["label"]: r for r in report.simulation_view(rec)["rows"]}
    note = rows["time average of tr P_t (one long path per replica)"]["note"]
    assert "95 % interval 0 – 40048" in note and "−4760" not in note and "-4760" not in note
    assert "unreliable" in note
    erg["time_averages"] = {"pooled_mean_trace": {"mean": 5.1, "lower": 4.9, "upper": 5.3},
                            "replica_mean_trace": [5.04, 4.98, 5.3, 5.09]}
    rows = {r["label"]: r for r in report.simulation_view(rec)["rows"]}
    assert "unreliable" not in rows["time average of tr P_t (one long path per replica)"]["note"]


def test_verdict_legend_without_channel_gives_the_reason():
    rec = fixture_record()
    rec["operating_point"] = None
    html = report.render_html(rec, {})
    legend = html.split('class="legend"')[1].split("</p>")[0]
    assert "no operating point" in legend and "bracket" not in legend
    rec = fixture_record()
    rec["operating_point"].update(verdict="undetermined", bracket=[0.875, 0.9375])
    assert "bracket" in report.verdict_view(rec)["legend"]
    assert report.verdict_view(fixture_record())["legend"] == ""


def test_exact_upper_bound_shows_its_expression():
    rec = fixture_record()
    rec["upper_bound"] = {"value": 0.36000000000000004, "interval": [0.36, 0.36000000000000004],
                          "certified": True, "status": "determined", "method": "exact",
                          "lower_evidence": {"kind": "theorem", "value": 0.36,
                                             "expression": "9/25",
                                             "statement": "p_up = p_low exactly (C invertible)"}}
    row = {r["symbol"]: r for r in report.bounds_view(rec)["rows"]}["p_up"]
    assert row["expression"] == "9/25" and "decided exactly" in row["detail"]


def test_versions_list_report_dependencies():
    names = [r["label"] for r in report.appendix_view(fixture_record())["versions"]]
    for name in ("weasyprint", "PyYAML", "numba", "mpmath"):
        assert name in names


def test_notes_end_with_full_stops():
    rec = fixture_record()
    rec["theory"]["moment_thresholds_note"] = "applies when all eigenvalues are all unstable"
    assert report.bounds_view(rec)["moments_note"].endswith("unstable.")
    rec["operating_point"]["note"] = "the verdict follows the basis stated"
    assert report.verdict_view(rec)["note"].endswith("stated.")


def test_plain_log_tick_labels():
    assert figures._plain_label(0.6) == "0.6" and figures._plain_label(20.0) == "20"
    assert "e" not in figures._plain_label(0.002)


def test_report_tolerance_option_reaches_the_robust_value(tmp_path: Path) -> None:
    # the third-turn rotation entered with a float √3 is exactly irrational as entered
    # (p_c = 3/4, Thm 10) but within 1e-9 of q = 3 (p_c = 1 − 2^{−3} = 7/8, Thm 9): the
    # report shows the robust value 0.875 at the default tolerance and none at 1e-18
    from click.testing import CliRunner

    from kfcrit.cli.main import main

    src = tmp_path / "float-third-turn.yaml"
    src.write_text("name: float third turn\nA: [[1, -1.7320508075688772], "
                   "[1.7320508075688772, 1]]\nC: [[1, 0]]\nQ: 1\nR: 1\n")
    texts = {}
    for tol in ("1e-9", "1e-18"):
        out = tmp_path / f"r{tol}.html"
        r = CliRunner().invoke(main, ["report", str(src), "-o", str(out), "--quick",
                                      "--tolerance", tol])
        assert r.exit_code in (0, 3), r.stderr
        texts[tol] = out.read_text()
    calm = "no perturbation within the tolerance changes it"
    assert calm not in texts["1e-9"] and "0.875" in texts["1e-9"]
    assert calm in texts["1e-18"]
