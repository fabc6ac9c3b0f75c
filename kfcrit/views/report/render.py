"""Design-review reports: one Jinja template set, two outputs (self-contained HTML and PDF).

The typed analysis record (:class:`~kfcrit.analysis.sections.AnalysisRecord`, from an analysis or
read back from ``--json`` with :func:`~kfcrit.analysis.sections.record_from_json`) is the only
input: :func:`kfcrit.views.figures.record.build_figures` draws its figures and
:func:`kfcrit.views.report.viewmodel.view_model` turns record and figures into the plain dict the
templates read. Templates only lay the view model out; numbers are formatted by the registered
filters of :mod:`kfcrit.views.formatting`; formulas are SVG from :mod:`kfcrit.views.figures.mathsvg`.
The PDF is the same HTML printed by WeasyPrint with the print stylesheet (``@media print`` /
``@page`` in ``report.css``), with a URL fetcher that serves ``data:`` URLs only.

:func:`render_documents` makes every requested format from one record and one set of figures
(the PDF variant of a dense figure is a PNG data URI, which WeasyPrint lays out far faster than
thousands of SVG path segments).
"""
from __future__ import annotations

import datetime
import functools
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import jinja2

from kfcrit.errors import InputError
from kfcrit.views import formatting as filters
from kfcrit.views.figures.record import draw_figures, figure_markup
from kfcrit.views.report.viewmodel import view_model

if TYPE_CHECKING:
    from kfcrit.analysis.sections import AnalysisRecord

TEMPLATE = "report.html.j2"
KINDS = ("html", "pdf")


def template_dir() -> Path:
    """Folder of the report templates.

    In an installed wheel they live in ``kfcrit/templates`` (hatchling ``force-include``); after
    ``pip install -e .`` or in a source checkout they are the repository's top-level
    ``templates/``.
    """
    package = Path(__file__).resolve().parents[2]  # kfcrit/ (this file: kfcrit/views/report/)
    for candidate in (package / "templates", package.parent / "templates"):
        if (candidate / TEMPLATE).is_file():
            return candidate
    raise FileNotFoundError(f"report templates not found next to {package} (looked for "
                            f"kfcrit/templates/{TEMPLATE} and templates/{TEMPLATE})")


def environment() -> jinja2.Environment:
    """The Jinja environment: autoescape for ``.html``/``.html.j2``, ``StrictUndefined``.

    Compiled templates are reused across reports for the same template folder (a pure function
    of the folder; Jinja still reloads a template whose file changed).
    """
    return environment_for(str(template_dir()))


@functools.lru_cache(maxsize=4)
def environment_for(folder: str) -> jinja2.Environment:
    """The Jinja environment of one template folder (see :func:`environment`)."""
    env = jinja2.Environment(
        loader=jinja2.FileSystemLoader(folder),
        autoescape=jinja2.select_autoescape(("html", "html.j2")),
        undefined=jinja2.StrictUndefined,
        trim_blocks=True, lstrip_blocks=True, keep_trailing_newline=True)
    return filters.register(env)


def render_html(rec: AnalysisRecord, figures: dict[str, str | None], *,
                today: datetime.date | None = None) -> str:
    """The self-contained HTML report (inline CSS and figures, no scripts, no external URLs)."""
    template = environment().get_template(TEMPLATE)
    return template.render(**view_model(rec, figures, today=today))


def refusing_fetcher() -> Any:
    """A WeasyPrint URL fetcher that serves ``data:`` URLs only and refuses everything else."""
    import weasyprint

    if hasattr(weasyprint, "URLFetcher"):  # WeasyPrint >= 68
        return weasyprint.URLFetcher(allowed_protocols={"data"})

    def fetch(url: str, *args: Any, **kwargs: Any) -> Any:  # pragma: no cover - old WeasyPrint
        if not url.startswith("data:"):
            raise ValueError(f"external URL refused: {url[:80]}")
        return weasyprint.default_url_fetcher(url, *args, **kwargs)

    return fetch


def render_pdf(html: str) -> bytes:
    """Print the HTML report to PDF with WeasyPrint (print stylesheet; no external fetches)."""
    try:
        import weasyprint
    except ImportError:  # pragma: no cover - optional dependency
        raise InputError("PDF output needs WeasyPrint (pip install 'kfcrit[pdf]')",
                         field="format") from None
    doc = weasyprint.HTML(string=html, base_url=None, url_fetcher=refusing_fetcher())
    return doc.write_pdf()


def render_documents(rec: AnalysisRecord, kinds: Iterable[str], *,
                     today: datetime.date | None = None) -> dict[str, bytes]:
    """Every requested format (``html``, ``pdf``) of one record, as bytes, from one drawing.

    The figures are drawn once and saved per medium: inline SVG for the HTML (sharp at any
    zoom), PNG data URIs for the PDF (WeasyPrint's time grows with the number of SVG elements;
    a 170 dpi PNG prints as sharply on paper).
    """
    wanted = list(dict.fromkeys(kinds))
    bad = [k for k in wanted if k not in KINDS]
    if bad:
        raise InputError(f"unknown report format {bad[0]!r} (html or pdf)", field="format")
    drawn = draw_figures(rec)
    out: dict[str, bytes] = {}
    if "html" in wanted:
        out["html"] = render_html(rec, figure_markup(drawn), today=today).encode("utf-8")
    if "pdf" in wanted:
        html = render_html(rec, figure_markup(drawn, "print"), today=today)
        out["pdf"] = render_pdf(html)
    return out
