"""Links beyond one i.i.d. channel: bursty (Gilbert–Elliott) links and sensor networks
(docs/theory.md §9–§10).
"""
