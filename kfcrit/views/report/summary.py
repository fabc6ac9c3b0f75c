"""Short views of a record for notebooks: the verdict box and the bounds table.

:func:`html_summary` renders the report's own verdict box and bounds table (the same templates,
so a notebook shows what the report shows) as one HTML fragment with its stylesheet scoped to
the fragment; :func:`markdown_summary` gives the review decision, its reasons and the bounds as
Markdown.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Any

from kfcrit.views import formatting as filters
from kfcrit.views.report.render import environment
from kfcrit.views.report.theory import bounds_view
from kfcrit.views.report.verdict import verdict_view

if TYPE_CHECKING:
    from kfcrit.analysis.sections import AnalysisRecord

FRAGMENT = "_summary.html.j2"


def html_summary(rec: AnalysisRecord) -> str:
    """The verdict box (review decision, reasons, stability verdict) and the bounds table of
    ``rec`` as an HTML fragment (for ``_repr_html_``)."""
    template = environment().get_template(FRAGMENT)
    return template.render(verdict=verdict_view(rec), bounds=bounds_view(rec),
                           name=rec.name or "unnamed system")


def _cell(text: Any) -> str:
    """Text for a Markdown table cell (pipes escaped, one line)."""
    return " ".join(str(text).split()).replace("|", "\\|")


def markdown_summary(rec: AnalysisRecord) -> str:
    """The review decision with its reasons, the stability verdict and the bounds as Markdown
    (for ``_repr_markdown_``)."""
    verdict = verdict_view(rec)
    review = verdict["review"]
    lines = [f"### {_cell(rec.name or 'unnamed system')}: review {review['word']}", ""]
    if review["available"]:
        lines += ["| check | status | detail |", "|---|---|---|"]
        lines += [f"| {_cell(r['check'])} | {_cell(r['status'])} | {_cell(r['detail'])} |"
                  for r in review["reasons"]]
    else:
        lines.append(review["missing"])
    margin = verdict["margin"]
    lines += ["", f"Stability at the operating point: **{filters.verdict_label(verdict['verdict'])}**"
              + (f" ({_margin_label(verdict)} = "
                 f"{filters.signed(margin, 4)})" if margin is not None else ""), "",
              "| quantity | value | exact form |", "|---|---|---|"]
    for row in bounds_view(rec)["rows"]:
        value = filters.num(row["value"], 8) if row["available"] else row["missing"]
        exact = filters.pretty_expr(row["expression"]) if row["expression"] else ""
        lines.append(f"| {_cell(row['name'])} | {_cell(value)} | {_cell(exact)} |")
    return "\n".join(lines) + "\n"


def _margin_label(verdict: dict[str, Any]) -> str:
    """What the operating point's margin measures (uniform δ, r − r_nec or p − p_c)."""
    if verdict["burst_margin"]:
        return "r − r_nec"
    return "uniform margin δ" if verdict["network"] else "p − p_c"
