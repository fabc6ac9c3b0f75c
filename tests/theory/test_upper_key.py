"""The key that identifies one p_up computation: equal for equal (A, C, tol, method) however
the systems were built, different when any of them differs (docs/theory.md §3)."""
from __future__ import annotations

import numpy as np

from kfcrit.model.system import System
from kfcrit.theory.upper.bracket import problem_key


def _exact(a01: str) -> System:
    return System([["5/4", a01], ["0", "11/10"]], [["1", "1"]], 1, 1)


def test_equal_exact_systems_share_the_key():
    # 1/2 written two ways is one rational: the same exact matrix
    assert problem_key(_exact("1/2"), 1e-9, "auto") == problem_key(_exact("2/4"), 1e-9, "auto")


def test_different_exact_systems_do_not_share_the_key():
    first = problem_key(_exact("1/2"), 1e-9, "auto")
    assert problem_key(_exact("1/3"), 1e-9, "auto") != first
    assert problem_key(_exact("1/2"), 1e-6, "auto") != first
    assert problem_key(_exact("1/2"), 1e-9, "lmi") != first


def test_float_systems_are_keyed_by_their_binary_floats():
    rng = np.random.default_rng(0)
    A, C = rng.normal(size=(5, 5)), rng.normal(size=(2, 5))
    one = System(A, C, np.eye(5), np.eye(2))
    two = System(A.copy(), C.copy(), 2 * np.eye(5), np.eye(2))     # Q does not enter p_up
    assert problem_key(one, 1e-9, "auto") == problem_key(two, 1e-9, "auto")
    B = A.copy()
    B[3, 1] = np.nextafter(B[3, 1], np.inf)                         # one ulp apart
    assert problem_key(System(B, C, np.eye(5), np.eye(2)), 1e-9, "auto") \
        != problem_key(one, 1e-9, "auto")
