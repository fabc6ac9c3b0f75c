"""The Examples of the documented objects (tests/docs/public_docs.py) run as doctests.

Only these objects' own docstrings are collected (``recurse=False``), each in empty globals so
that every example imports what it uses; ``--doctest-modules`` stays off for the suite.
"""
from __future__ import annotations

import doctest
import importlib.util
import inspect
import io
import time

import pytest

from tests.docs.public_docs import DOCUMENTED, NEEDS, resolve

FLAGS = doctest.ELLIPSIS


@pytest.mark.parametrize("spec", DOCUMENTED)
def test_examples_run(spec):
    needed = NEEDS.get(spec)
    if needed and importlib.util.find_spec(needed) is None:
        pytest.skip(f"the examples of {spec} need {needed}")
    obj = resolve(spec)
    finder = doctest.DocTestFinder(recurse=False, exclude_empty=True)
    tests = finder.find(obj, spec, module=inspect.getmodule(obj), globs={})
    assert tests and any(t.examples for t in tests), f"{spec}: no examples found"
    out = io.StringIO()
    runner = doctest.DocTestRunner(optionflags=FLAGS)
    t0 = time.perf_counter()
    for test in tests:
        runner.run(test, out=out.write)
    seconds = time.perf_counter() - t0
    result = runner.summarize(verbose=False)
    assert result.failed == 0, f"{spec}: {result.failed} example(s) failed\n{out.getvalue()}"
    print(f"{spec}: {result.attempted} examples in {seconds:.2f} s")
