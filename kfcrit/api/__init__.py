"""The Python API as a notebook uses it: records that display themselves, figures, tables.

This is the top of the package beside :mod:`kfcrit.cli`: it joins the analysis (the typed
record) to the views (HTML, Markdown, matplotlib), which the analysis layer itself must not
import. ``kfcrit.analyze`` and ``kfcrit.sweep`` are these functions.
"""
from kfcrit.api.notebook import Analysis, SweepTable, analyze, sweep

__all__ = ["Analysis", "SweepTable", "analyze", "sweep"]
