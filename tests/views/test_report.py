"""Tests of the design-review report: filters, formulas, figures, view model, HTML, PDF, command.

Records are real analyses (typed :class:`~kfcrit.analysis.sections.AnalysisRecord` of example
systems in ``reports/``, ``--quick``), made once per test session; a test that needs a variant
replaces a section (:func:`dataclasses.replace`) or edits the record's JSON form and reads it back
with :func:`~kfcrit.analysis.sections.record_from_json` (:func:`edited`). Expected values are the
papers' closed forms, derived by hand in the tests that use them (MATH §3–§5):

* rotation-third-turn: A = [[1, −√3], [√3, 1]], eigenvalues 1 ± j√3 of modulus 2, one output,
  degenerate with q = 3: p_c = 1 − 2^(−2q/(q−1)) = 1 − 2^(−3) = 7/8, p_low = 1 − 1/4 = 3/4;
* kar-scalar-fractal: a = √2, C = Q = R = 1: the arrival map f₁(X) = 2X/(X + 1) + 1 has the fixed
  point P* = 1 + √2 and f₁(∞) = 3; the loss map f₀(X) = 2X + 1 gives f₀(P*) = 3 + 2√2, so
  (3, 3 + 2√2) carries no invariant mass (Kar–Sinopoli–Moura, Theorem 10);
* sinopoli-scalar / link-oqpsk-sensor: p_c = 1 − 1/|λ₁|² = 1 − (4/5)² = 9/25 (|λ₁| = 5/4).
"""
from __future__ import annotations

import dataclasses
import io
import json
import os
import re
from collections.abc import Callable
from html.parser import HTMLParser
from pathlib import Path
from typing import Any

import pytest

from kfcrit.analysis.record import AnalysisOptions, analyze_system
from kfcrit.analysis.sections import AnalysisRecord, record_from_json
from kfcrit.analysis.spec import load_spec
from kfcrit.analysis.verdict import CheckStatus, Decision, Reason, Review
from kfcrit.cli import report as command
from kfcrit.errors import InputError
from kfcrit.io.atomic import write_atomic
from kfcrit.io.typed import RecordError
from kfcrit.views import formatting as filters
from kfcrit.views.figures import mathsvg
from kfcrit.views.figures import record as figures
from kfcrit.views.report import render as report
from kfcrit.views.report import summary
from kfcrit.views.report.sim import appendix_view, seeds_text, simulation_view
from kfcrit.views.report.theory import bounds_view

ROOT = Path(__file__).resolve().parents[2]
REPORTS = ROOT / "reports"
SECTION_ORDER = ["verdict", "channel", "distribution", "system", "bounds", "phase-transition",
                 "simulation", "statements", "appendix"]


class Records:
    """Quick analyses of example systems, each made once per session (typed records are
    frozen: a test makes its variant with :func:`dataclasses.replace` or :func:`edited`)."""

    def __init__(self) -> None:
        self._done: dict[str, AnalysisRecord] = {}

    def __call__(self, stem: str) -> AnalysisRecord:
        if stem not in self._done:
            spec = load_spec(REPORTS / f"{stem}.yaml")
            self._done[stem] = analyze_system(spec, AnalysisOptions(quick=True, seed=0))
        return self._done[stem]


def edited(rec: AnalysisRecord, change: Callable[[dict[str, Any]], Any]) -> AnalysisRecord:
    """``rec`` with its JSON form changed in place by ``change``, read back strictly (a
    corner case the typed record can hold)."""
    data = rec.to_dict()
    change(data)
    return record_from_json(data)


def without(data: dict[str, Any], key: str, missing: Any) -> AnalysisRecord | None:
    """The record ``data`` with top-level ``key`` set to ``missing`` (``...``: the key
    removed), or ``None`` when the record's schema requires that section."""
    changed = {k: v for k, v in data.items() if k != key}
    if missing is not ...:
        changed[key] = missing
    try:
        return record_from_json(changed)
    except RecordError:
        return None


def bare(rec: AnalysisRecord, name: str = "bare") -> AnalysisRecord:
    """``rec`` with every section the schema lets a record lack set to ``None`` or removed."""
    data = {**rec.to_dict(), "name": name}
    for key in list(data):
        for missing in (None, ...):
            smaller = without(data, key, missing)
            if smaller is not None:
                data = smaller.to_dict()
                break
    return record_from_json(data)


@pytest.fixture(scope="session")
def records() -> Records:
    return Records()


@pytest.fixture(scope="session")
def rotation_html(records) -> str:
    rec = records("rotation-third-turn")
    return report.render_html(rec, figures.build_figures(rec))


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

def test_figures_read_the_production_record(records):
    rec = records("kar-scalar-fractal")
    figs = figures.build_figures(rec)
    assert set(figs) == set(figures.FIGURE_KEYS)
    single_link = ("phase_transition", "traces", "operating", "cdf", "almost_sure", "invariant")
    for key in single_link:
        assert figs[key] is not None and figs[key].startswith("<svg"), key
    # one i.i.d. link, no requirement on the mean, no link budget: none of the others
    assert all(figs[key] is None for key in set(figures.FIGURE_KEYS) - set(single_link))
    assert figures.figure_names(rec) == list(single_link)
    # the CDF ends at probability 1 and the tail estimate is the record's own
    x, f = figures.cdf_of(rec)
    assert x == sorted(x) and f[-1] == pytest.approx(1.0)
    exc = rec.simulation.operating_point.exceedance
    assert figures.tail_of(rec) == (exc.estimate if exc is not None else None)


def test_figure_objects_for_notebooks(records):
    from matplotlib.figure import Figure

    rec = records("rotation-third-turn")
    names = figures.figure_names(rec)
    assert "invariant" not in names                     # n = 2: no invariant-support figure
    for name in names:
        fig = figures.figure(rec, name)
        assert isinstance(fig, Figure) and fig.axes
    # the phase-transition axes carry p_c = 7/8 as a vertical line
    ax = figures.figure(rec, "phase_transition").axes[0]
    xs = [line.get_xdata()[0] for line in ax.get_lines() if len(set(line.get_xdata())) == 1]
    assert any(abs(x - 7 / 8) < 1e-12 for x in xs)
    with pytest.raises(ValueError, match="no data"):
        figures.figure(rec, "invariant")
    with pytest.raises(KeyError):
        figures.figure(rec, "no_such_figure")


def test_figures_missing_or_malformed_data_give_none(records):
    assert all(v is None for v in figures.build_figures(bare(records("rotation-third-turn")))
               .values())

    # malformed values (the typed record does not check types at run time)
    full = records("rotation-third-turn")
    pt = dataclasses.replace(full.phase_transition, trace_lower="oops",
                             trace_upper=[1.0])   # wrong length
    demo = full.simulation.phase_demo
    curve = dataclasses.replace(demo.curves[0], arrival_probability=0.5, times=[1, 2],
                                mean_trace=["x", 1])
    sim = dataclasses.replace(full.simulation,
                              phase_demo=dataclasses.replace(demo, curves=[curve]))
    rec = dataclasses.replace(full, phase_transition=pt, simulation=sim)
    figs = figures.build_figures(rec)
    assert figs["phase_transition"] is None and figs["traces"] is None
    assert figs["operating"] is not None


def test_print_figures_are_png_data_uris(records):
    rec = records("rotation-third-turn")
    figs = figures.build_figures(rec, medium="print")
    assert figs["invariant"] is None                   # n = 2: no invariant-support figure
    drawn = [key for key in figures.DENSE if figs[key] is not None]
    assert set(drawn) == {"phase_transition", "traces", "operating", "cdf", "almost_sure"}
    for key in drawn:
        assert figs[key].startswith('<img class="figure-img"'), key
        assert 'src="data:image/png;base64,' in figs[key]
    assert figures.build_figures(rec)["almost_sure"].startswith("<svg")


def test_phase_window_starts_where_the_bounds_exist() -> None:
    """Below p_low both bounds are infinite: the window starts just below the first finite point
    (a tenth of the remaining range), and widens to show an operating point further left."""
    from kfcrit.views.figures.record import phase_window

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
    left, right = phase_window(p, [nan] * 7, None, {})
    assert (left, right) == (0.0, 1.0)


def test_cdf_window_reaches_past_the_limit():
    left, right = figures.cdf_window([2.0, 3.0, 4.0, 30.0], 10.0)
    assert left < 2.0 and right > 30.0
    left, right = figures.cdf_window([2.0, 3.0, 4.0], 10.0)   # no path beyond: still past M
    assert right > 10.0


def test_plain_log_tick_labels():
    assert figures.plain_label(0.6) == "0.6" and figures.plain_label(20.0) == "20"
    assert "e" not in figures.plain_label(0.002)


# ----------------------------------------------------------------------------- HTML

def test_report_has_every_section_in_reading_order(rotation_html):
    ids = parse(rotation_html).ids
    positions = [ids.index(s) for s in SECTION_ORDER]
    assert positions == sorted(positions)
    assert len(ids) == len(set(ids)), "duplicate ids in the page"


def test_report_shows_critical_value_and_theorem(rotation_html):
    assert "MEAN STABLE" in rotation_html                   # p = 9/10 > p_c = 7/8
    assert "0.875" in rotation_html and "7/8" in rotation_html
    assert "+0.025" in rotation_html                        # margin 9/10 − 7/8
    assert "Mo–Sinopoli, Theorem 5" in rotation_html        # degenerate second order decides


def test_html_is_self_contained(rotation_html):
    tags = parse(rotation_html).tags
    assert not [t for t, _ in tags if t in ("script", "link", "iframe", "object", "embed")]
    for _, attrs in tags:
        for name in ("src", "href"):
            value = attrs.get(name)
            assert value is None or value.startswith(("#", "data:")), value
    assert "url(http" not in rotation_html and "@import" not in rotation_html


def test_footer_has_system_name_date_and_version(records):
    import datetime

    from kfcrit.version import __version__

    rec = records("rotation-third-turn")
    html = report.render_html(rec, {}, today=datetime.date(2031, 5, 17))
    assert f"2031-05-17 · kfcrit {__version__}" in html
    assert "string-set: sysname" in html and "string(docmeta)" in html
    # a record carries no creation date (the footer's date is the rendering date)
    with pytest.raises(RecordError, match="created"):
        edited(rec, lambda d: d["provenance"].update(created="2030-01-02T10:00:00Z"))


def test_missing_sections_say_not_computed(records):
    rec = bare(records("rotation-third-turn"))
    assert rec.name == "bare" and rec.critical_value is None
    html = report.render_html(rec, figures.build_figures(rec))
    ids = parse(html).ids
    for s in SECTION_ORDER:
        assert s in ids, s
    for phrase in ("operating point: not computed", "structure analysis: not computed",
                   "phase transition: not computed", "simulation: not computed",
                   "covariance bounds: not computed",
                   "almost-sure and distributional statements: not computed"):
        assert phrase in html, phrase


def test_every_single_section_missing_renders(records):
    full = records("rotation-third-turn")
    figs = figures.build_figures(full)
    data = full.to_dict()
    rendered = []
    for key in data:
        rec = without(data, key, None)
        if rec is not None:
            assert 'id="verdict"' in report.render_html(rec, figs), key
            rendered.append(key)
        rec = without(data, key, ...)
        if rec is not None:
            report.render_html(rec, {})
            rendered.append(key)
    # every section but the name, the warnings, the schema version, the review, the system,
    # the verification and the provenance may be missing
    assert {"structure", "simulation", "critical_value", "operating_point"} <= set(rendered)


def test_malformed_sections_are_refused_before_any_view(records, tmp_path):
    rec = records("rotation-third-turn")
    for key, value in (("structure", {"eigenvalues": "not a list", "equi_blocks": [None, 3]}),
                       ("theory", {"moment_thresholds": [None], "almost_sure": "one sentence"}),
                       ("upper_bound", {"interval": "x"}),
                       ("review", {"decision": "maybe", "reasons": "x"})):
        data = rec.to_dict()
        data[key] = value
        with pytest.raises(RecordError, match=key):
            record_from_json(data)
        saved = tmp_path / f"{key}.json"
        saved.write_text(json.dumps(data), encoding="utf-8")
        with pytest.raises(InputError, match="not a record of this kfcrit version") as exc:
            command.report_command(str(saved), str(tmp_path / "r.html"))
        assert exc.value.exit_code == 2 and not (tmp_path / "r.html").exists()


def test_autoescape_of_record_text(records):
    rec = dataclasses.replace(records("rotation-third-turn"), name="<script>alert(1)</script>",
                              warnings=["<b>bold</b>", "<b>bold</b>"])
    html = report.render_html(rec, {})
    assert "<script>alert" not in html and "&lt;script&gt;alert(1)" in html
    assert "<b>bold</b>" not in html
    assert html.count("&lt;b&gt;bold&lt;/b&gt;") == 1        # identical warnings shown once


def test_scalar_system_shows_invariant_support(records):
    rec = records("kar-scalar-fractal")
    html = report.render_html(rec, figures.build_figures(rec))
    assert "Support of the invariant distribution" in html
    assert "[3, 5.8284271]" in html     # (f₁(∞), f₀(P*)) = (3, 3 + 2√2) (module docstring)
    assert "Support of the invariant" not in report.render_html(records("rotation-third-turn"),
                                                                {})


def test_undetermined_and_unstable_stability_lines(records):
    rec = edited(records("rotation-third-turn"), lambda d: d["operating_point"].update(
        verdict="undetermined", margin=None, margin_robust=None, bracket=[0.875, 0.9375],
        margin_to_bracket=[0.025, -0.0375]))
    html = report.render_html(rec, {})
    assert "stability-undetermined" in html and "[0.875, 0.9375]" in html
    rec = edited(rec, lambda d: d["operating_point"].update(verdict="mean-unstable"))
    assert "stability-unstable" in report.render_html(rec, {})


def test_quick_draft_banner(records):
    rec = records("rotation-third-turn")
    assert 'id="draft"' in report.render_html(rec, {})      # the session records are --quick
    rec = edited(rec, lambda d: d["provenance"]["options"].update(quick=False))
    assert 'id="draft"' not in report.render_html(rec, {})


def test_strict_undefined_catches_template_typos(tmp_path, monkeypatch, records):
    import jinja2

    (tmp_path / report.TEMPLATE).write_text("{{ verdict.no_such_key }}")
    monkeypatch.setattr(report, "template_dir", lambda: tmp_path)
    with pytest.raises(jinja2.UndefinedError):
        report.render_html(records("rotation-third-turn"), {})


def test_template_dir_is_repository_templates_in_a_checkout():
    d = report.template_dir()
    assert (d / "report.html.j2").is_file() and (d / "report.css").is_file()


# ----------------------------------------------------------------------------- review decision

def with_review(rec: AnalysisRecord, decision: str, *statuses: str) -> AnalysisRecord:
    """``rec`` with a ``review`` of the documented shape: one reason per status."""
    checks = ["stability at the operating point", "requirement P(tr P > 20) ≤ 0.01",
              "link margin policy"]
    return dataclasses.replace(rec, review=Review(decision=Decision(decision), reasons=tuple(
        Reason(check=checks[i], status=CheckStatus(s), detail=f"detail {i} of the check ({s})")
        for i, s in enumerate(statuses))))


def verdict_box(html: str) -> str:
    return html.split('id="verdict"')[1].split("</section>")[0]


def test_failed_review_is_a_red_box_beside_a_stable_verdict(records):
    rec = with_review(records("rotation-third-turn"), "fail", "pass", "pass", "fail")
    html = report.render_html(rec, {})
    head = html.split('<section id="verdict"')[1].split(">")[0]
    assert "verdict-fail" in head                   # the box colour is the decision's
    box = verdict_box(html)
    assert "FAIL" in box and "MEAN STABLE" in box   # the stability verdict is one line in it
    for i, s in enumerate(("pass", "pass", "fail")):
        assert f"detail {i} of the check ({s})" in box
    assert box.count("badge-fail") == 1 and box.count("badge-pass") == 2
    assert 'class="verdict verdict-pass' not in html


@pytest.mark.parametrize("decision,css,word", [("pass", "verdict-pass", "PASS"),
                                               ("undetermined", "verdict-undetermined",
                                                "UNDETERMINED")])
def test_pass_and_undetermined_reviews(records, decision, css, word):
    status = "pass" if decision == "pass" else "undetermined"
    rec = with_review(records("rotation-third-turn"), decision, "pass", status,
                      "not applicable")
    html = report.render_html(rec, {})
    assert css in html and word in verdict_box(html)
    assert "badge-none" in verdict_box(html)       # "not applicable" is neither red nor green


def test_record_without_review_is_refused(records, tmp_path):
    data = records("rotation-third-turn").to_dict()
    data.pop("review")
    with pytest.raises(RecordError, match="review"):
        record_from_json(data)
    saved = tmp_path / "no-review.json"
    saved.write_text(json.dumps(data), encoding="utf-8")
    with pytest.raises(InputError, match="missing key 'review'") as exc:
        command.report_command(str(saved), str(tmp_path / "r.html"))
    assert exc.value.exit_code == 2 and not (tmp_path / "r.html").exists()


def test_notebook_summaries(records):
    rec = with_review(records("rotation-third-turn"), "fail", "pass", "fail")
    html = summary.html_summary(rec)
    assert "verdict-fail" in html and "FAIL" in html and "0.875" in html
    assert "<html" not in html and "<script" not in html
    md = summary.markdown_summary(rec)
    assert md.startswith("### Oscillator") and "review FAIL" in md
    assert "| requirement P(tr P > 20) ≤ 0.01 | fail |" in md
    assert "| critical value p_c | 0.875 | 7/8 |" in md
    assert "**MEAN STABLE**" in md


# ----------------------------------------------------------------------------- content audit

def test_no_internal_names_in_the_page(records):
    rec = records("link-oqpsk-sensor")
    text = visible_text(report.render_html(rec, figures.build_figures(rec)))
    for leak in ("SeedSequence", "spawn_key", "^", "output compression output"):
        assert leak not in text, leak
    # full float precision never shows (a p_up bracket closed to 1e-9 needs 10 decimals)
    assert not re.search(r"\d\.\d{11,}", text), re.search(r"\d\.\d{11,}", text)
    assert not raw_dumps(text), raw_dumps(text)


def test_seed_rules_in_words():
    from kfcrit.records.simulation import OperatingPointSeeds, SimulationSeeds

    text = seeds_text(SimulationSeeds(operating_point=OperatingPointSeeds(
        seed=0, paths="SeedSequence(seed, spawn_key=(0, i))",
        ergodic="SeedSequence(seed, spawn_key=(1, j))")))
    assert text == ("operating point (seed: 0, paths: stream (0, i) of the base seed for path i, "
                    "ergodic: stream (1, j) of the base seed for replica j)")
    assert seeds_text(7) == "7"


def test_passed_checks_are_never_red(records):
    rec = records("requirements-tail")
    checks = appendix_view(rec)["checks"]
    recorded = rec.verification
    assert len(checks) == len(recorded) + 1
    for c, r in zip(checks, recorded):
        assert (c["css"] == "pass") == (r.passed is True), (c, r)
        assert (c["css"] == "fail") == (r.passed is False), (c, r)
    # numerical p_c is information, not failure
    rec = dataclasses.replace(rec, critical_value=dataclasses.replace(rec.critical_value,
                                                                      exact=False))
    assert appendix_view(rec)["checks"][-1]["css"] == "none"


def test_exact_forms_only_where_exact(records):
    rec = records("rotation-third-turn")
    rows = {r["symbol"]: r for r in bounds_view(rec)["rows"]}
    assert rows["p_c"]["expression"] == "7/8" and rows["p_low"]["expression"] == "3/4"
    rec = dataclasses.replace(rec, critical_value=dataclasses.replace(
        rec.critical_value, exact=False, expression="0.87500000000000011"))
    rows = {r["symbol"]: r for r in bounds_view(rec)["rows"]}
    assert rows["p_c"]["expression"] is None


def test_block_maxima_caption_states_the_data_not_a_limit(records):
    rec = records("rotation-third-turn")
    html = report.render_html(rec, figures.build_figures(rec))
    cap = html.split('id="fig-almost-sure"')[1].split("</figcaption>")[0]
    assert "= ∞" not in cap and "limsup tr P" not in cap
    top = rec.simulation.operating_point.almost_sure.block_max
    assert filters.num(top[-1], 4) in cap


def test_diverged_paths_are_described_as_they_were_handled(records):
    def divergence(**changes: Any) -> Callable[[dict], None]:
        return lambda d: d["simulation"]["operating_point"]["divergence"].update(changes)

    rec = edited(records("rotation-third-turn"), divergence(
        diverged_paths=3, continued=False, mean_is_lower_bound=True, threshold=1e10))
    rows = {r["label"]: r for r in simulation_view(rec)["rows"]}
    assert "censored at the threshold; means are lower bounds" in rows["diverged paths"]["note"]
    rec = edited(rec, divergence(continued=True, mean_is_lower_bound=False))
    rows = {r["label"]: r for r in simulation_view(rec)["rows"]}
    assert "true values" in rows["diverged paths"]["note"]
    assert "lower bounds" not in rows["diverged paths"]["note"]


def test_time_average_interval_clamped_and_flagged(records):
    def ergodic(data: dict) -> None:
        erg = data["simulation"]["operating_point"]["ergodic"]
        erg.update(replicas=4, steps=10_000, burn_in=1_000)
        erg["time_averages"]["pooled_mean_trace"].update(mean=17643.0, lower=-4760.7,
                                                         upper=40048.0)
        erg["time_averages"]["replica_mean_trace"] = [210.0, 1248.0, 196.0, 68000.0]

    rec = edited(records("rotation-third-turn"), ergodic)
    rows = {r["label"]: r for r in simulation_view(rec)["rows"]}
    note = rows["time average of tr P_t (one long path per replica)"]["note"]
    assert "95 % interval 0 – 40048" in note and "−4760" not in note and "-4760" not in note
    assert "unreliable" in note


def test_versions_list_report_dependencies(records):
    names = [r["label"] for r in appendix_view(records("rotation-third-turn"))["versions"]]
    for name in ("weasyprint", "PyYAML", "numba", "mpmath"):
        assert name in names


# ----------------------------------------------------------------------------- PDF

def pdf_pages(data: bytes) -> list[str]:
    pypdf = pytest.importorskip("pypdf")
    return [page.extract_text() for page in pypdf.PdfReader(io.BytesIO(data)).pages]


@pytest.fixture(scope="session")
def link_documents(records) -> dict[str, bytes]:
    pytest.importorskip("weasyprint")
    rec = with_review(records("link-oqpsk-sensor"), "fail", "pass", "not applicable", "fail")
    return report.render_documents(rec, ["html", "pdf"])


HEADING = re.compile(r"^(\d\. [A-Z]|Appendix|[A-Z][a-z]+( [a-z-]+){0,6}$)")


def test_link_review_pdf_layout(link_documents, records):
    from kfcrit.version import __version__

    pages = pdf_pages(link_documents["pdf"])
    flat = [" ".join(p.split()) for p in pages]
    assert "Review: FAIL" in flat[0] and "MEAN STABLE" in flat[0]
    name = records("link-oqpsk-sensor").name
    for i, page in enumerate(flat, 1):
        assert name in page and f"kfcrit {__version__}" in page and f"page {i} of" in page
    before_appendix = next(i for i, p in enumerate(flat) if "Appendix: details" in p)
    # verdict, link design, requirement and theory sections in four pages; details after
    assert before_appendix <= 4, f"{before_appendix} pages before the appendix"
    # the link design comes before the theory sections
    text = " ".join(flat)
    assert text.index("Design outputs") < text.index("3. The system")
    # no heading (section, subsection, table caption) is the last text line of a page
    # (footer lines excluded)
    html = link_documents["html"].decode()
    headings = {" ".join(re.sub(r"<[^>]+>", "", h).split()) for h in re.findall(
        r'<h[23][^>]*>(.*?)</h[23]>|<p class="kv-caption">(.*?)</p>', html, re.S) for h in h if h}
    assert "1. The link: radio link budget" in headings and "Design outputs" in headings
    for page in pages:
        lines = [ln.strip() for ln in page.splitlines() if ln.strip()]
        body = [ln for ln in lines if name not in ln and "page " not in ln and
                "DRAFT" not in ln and "kfcrit " not in ln]
        assert body and not re.match(r"^\d\. [A-Z]", body[-1]), body[-3:]
        assert " ".join(body[-1].split()) not in headings, body[-3:]


def test_pdf_fetcher_refuses_external_urls(monkeypatch):
    pytest.importorskip("weasyprint")
    import urllib.request

    def no_network(*args, **kwargs):
        raise AssertionError("network access attempted")

    monkeypatch.setattr(urllib.request.OpenerDirector, "open", no_network)
    html = ('<html><body><p>x</p><img src="http://example.invalid/a.png">'
            '<link rel="stylesheet" href="https://example.invalid/s.css"></body></html>')
    assert report.render_pdf(html).startswith(b"%PDF")
    fetcher = report.refusing_fetcher()
    fetch = getattr(fetcher, "fetch", fetcher)
    with pytest.raises(Exception):  # noqa: B017 - any refusal is fine
        fetch("http://example.invalid/a.png")


# ----------------------------------------------------------------------------- command

def test_output_format_rules():
    assert command.output_format("a.html", None) == "html"
    assert command.output_format("a.PDF", None) == "pdf"
    assert command.output_format("a.txt", "pdf") == "pdf"
    with pytest.raises(InputError) as exc:
        command.output_format("a.txt", None)
    assert exc.value.exit_code == 2


def test_plan_outputs_refuses_duplicates_and_ambiguous_format(tmp_path):
    src = REPORTS / "sinopoli-scalar.yaml"
    plan = command.plan_outputs(src, [tmp_path / "a.html", tmp_path / "a.pdf"], None)
    assert [k for _, k in plan] == ["html", "pdf"]
    with pytest.raises(InputError, match="given twice"):
        command.plan_outputs(src, [tmp_path / "a.html", tmp_path / "a.html"], None)
    with pytest.raises(InputError, match="single output"):
        command.plan_outputs(src, [tmp_path / "a.html", tmp_path / "b.pdf"], "pdf")
    with pytest.raises(InputError, match="at least one"):
        command.plan_outputs(src, [], None)


def test_refuses_to_overwrite_input(tmp_path):
    src = tmp_path / "sys.html"
    src.write_text((REPORTS / "sinopoli-scalar.yaml").read_text())
    before = src.read_bytes()
    with pytest.raises(InputError, match="input file"):
        command.report_command(str(src), str(src), quick=True)
    link = tmp_path / "link.html"
    link.symlink_to(src)
    with pytest.raises(InputError, match="input file"):
        command.report_command(str(src), [str(tmp_path / "ok.html"), str(link)], quick=True)
    assert src.read_bytes() == before and not (tmp_path / "ok.html").exists()


def test_refuses_missing_folder_and_directory(tmp_path):
    src = REPORTS / "sinopoli-scalar.yaml"
    with pytest.raises(InputError, match="does not exist"):
        command.check_output_path(src, tmp_path / "nope" / "r.html")
    (tmp_path / "d.html").mkdir()
    with pytest.raises(InputError, match="directory"):
        command.check_output_path(src, tmp_path / "d.html")


def test_saved_record_renders_without_analysing(tmp_path, records, monkeypatch, capsys):
    pytest.importorskip("weasyprint")
    from kfcrit.analysis import record as analysis
    from kfcrit.io.jsonio import dumps

    rec = records("sinopoli-scalar")
    saved = tmp_path / "record.txt"            # no .json extension: detected by content
    saved.write_text(dumps(rec.to_dict()), encoding="utf-8")

    def refuse(*args, **kwargs):
        raise AssertionError("the saved record was analysed again")

    monkeypatch.setattr(analysis, "analyze_system", refuse)
    code = command.report_command(str(saved), [str(tmp_path / "r.html"),
                                                str(tmp_path / "r.pdf")])
    assert code == analysis.exit_code(rec.to_dict())
    html = (tmp_path / "r.html").read_text(encoding="utf-8")
    assert "9/25" in html and "<svg" in html.split('id="fig-phase-transition"')[1]
    assert (tmp_path / "r.pdf").read_bytes().startswith(b"%PDF")
    assert capsys.readouterr().out == ""
    with pytest.raises(InputError, match="saved record"):
        command.report_command(str(saved), str(tmp_path / "s.html"), options_given=["quick"])


def test_bad_saved_records_are_refused(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text("{not json", encoding="utf-8")
    with pytest.raises(InputError, match="not valid JSON") as exc:
        command.report_command(str(bad), str(tmp_path / "r.html"))
    assert exc.value.exit_code == 2
    bad.write_text(json.dumps({"hello": 1}), encoding="utf-8")
    with pytest.raises(InputError, match="not a kfcrit analysis record"):
        command.report_command(str(bad), str(tmp_path / "r.html"))
    assert not (tmp_path / "r.html").exists()


def test_one_analysis_for_html_and_pdf(tmp_path, monkeypatch, capsys):
    pytest.importorskip("weasyprint")
    from kfcrit.analysis import record as analysis

    calls = []
    real = analysis.analyze_system
    monkeypatch.setattr(analysis, "analyze_system", lambda *a, **k: calls.append(1) or real(*a, **k))
    src = REPORTS / "sinopoli-scalar.yaml"
    code = command.report_command(str(src), [str(tmp_path / "a.html"), str(tmp_path / "a.pdf")],
                                  quick=True)
    assert calls == [1] and code == 0     # p = 4/5 > p_c = 9/25, decided exactly
    assert (tmp_path / "a.pdf").read_bytes().startswith(b"%PDF")
    assert "MEAN STABLE" in (tmp_path / "a.html").read_text(encoding="utf-8")
    err = capsys.readouterr().err
    assert err.count("analysing") == 1 and err.count("wrote") == 2


def example_files() -> list[Path]:
    """The example *system* files in ``reports/`` (sweep files, with a ``grid``, are not)."""
    import yaml

    return [p for p in sorted(REPORTS.glob("*.yaml"))
            if "A" in (yaml.safe_load(p.read_text(encoding="utf-8")) or {})]


@pytest.mark.parametrize("path", example_files(), ids=lambda p: p.stem)
def test_render_every_example_html(path, records, capsys):
    rec = records(path.stem)
    html = report.render_html(rec, figures.build_figures(rec))
    ids = parse(html).ids
    assert [s for s in SECTION_ORDER if s in ids] == SECTION_ORDER
    assert len(ids) == len(set(ids))
    assert "Review" in html and "critical value" in html
    text = visible_text(html)
    assert not raw_dumps(text), raw_dumps(text)
    assert "SeedSequence" not in text and "^" not in text
    network = "\nsensors:" in path.read_text(encoding="utf-8")  # a sensors: file
    mesh = path.stem.startswith("mesh-")
    # every example has a channel; a network's record has its own Lyapunov bound (no i.i.d.
    # phase-transition curve of one link) and always its stability-region figure; a mesh its map
    for fig_id in (("fig-network-region",) if network else ("fig-mesh-topology",) if mesh else
                   ("fig-phase-transition", "fig-traces", "fig-operating", "fig-cdf",
                    "fig-almost-sure")):
        chunk = html.split(f'id="{fig_id}"')[1].split("</figure>")[0]
        assert "<svg" in chunk, fig_id
    if path.stem == "link-oqpsk-sensor":
        check_link_budget_report(html)


def test_gilbert_elliott_report_has_bursty_section(records):
    rec = records("ge-bursty-scalar")
    html = report.render_html(rec, figures.build_figures(rec))
    assert 'id="bursty-link"' in html and "verdict basis" in html
    rows = qty_rows(html, "channel")
    r = rec.link_budget.recovery_rate
    a2 = rec.link_budget.spectral_radius ** 2
    assert rows["recovery rate r"] == filters.num(r)
    assert rows["required recovery rate 1 − 1/a²"] == filters.num(1 - 1 / a2, 6)   # MATH §7
    assert 'id="fig-invariant"' in html                                 # scalar: support drawn
    assert not raw_dumps(visible_text(html)), raw_dumps(visible_text(html))


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
    rows = {**qty_rows(html, "channel"), **qty_rows(html, "link-details")}
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
    margin_row = verdict.split("link policy: margin")[1].split("</tr>")[0]
    assert "badge-fail" in margin_row and "policy" in margin_row



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


def test_prose_sets_theory_symbols_with_subscripts_and_keeps_file_keys():
    out = str(filters.supmath("p > p_c = 9/25; p_up, p_low; P(p_link < p_S); max_outage"))
    assert "p<sub>c</sub>" in out and "p<sub>up</sub>" in out and "p<sub>low</sub>" in out
    assert "p<sub>link</sub>" in out and "p<sub>S</sub>" in out
    assert "max_outage" in out            # a file key stays as the user writes it
