"""Figures of the record (matplotlib, SVG): each plot drawn once."""
