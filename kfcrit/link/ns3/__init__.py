"""ns-3 as an optional backend: simulate a file's 802.15.4 link budgets in ns-3's lr-wpan model.

``topology`` (the plan, no ns-3), ``cxx`` (the C++ driver text), ``driver`` (imports ns-3 lazily
and runs the plan), ``results`` (statistics, no ns-3). Importing this package never imports
``ns``.
"""
