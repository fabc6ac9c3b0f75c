"""The upper bound p_up of the critical value and the certificates that prove it (docs/theory.md
§3).
"""
