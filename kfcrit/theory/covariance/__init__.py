"""The error covariance: the Riccati maps, the bounds S̄ ⪯ lim E[P] ⪯ V̄, the invariant
distribution, tails and design inversion (docs/theory.md §2, §3, §5, §11).
"""
