"""The critical arrival probability p_c: which theorem applies, its exact value, its lower bound
p_low, and its robustness (docs/theory.md §3–§4).
"""
