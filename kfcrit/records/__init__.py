"""The section classes of the typed analysis record (:mod:`kfcrit.analysis.sections` assembles
them into :class:`~kfcrit.analysis.sections.AnalysisRecord`): the contract sections, and one module per
group of detail sections. Every key of the record is typed here — no payload is left as "any JSON".
"""
