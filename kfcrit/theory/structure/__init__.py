"""Eigen-structure of (A, C) in the diagonal standard form the Mo–Sinopoli theorems read: exact,
certified and numeric paths (docs/theory.md §4).
"""
