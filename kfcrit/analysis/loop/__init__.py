"""Closed loops in the analysis (theory §12): the typed ``loop`` section of the record
(:mod:`kfcrit.analysis.loop.schema`) and its builder (:mod:`kfcrit.analysis.loop.section`)."""
