"""System construction from float arrays (kfcrit.model.system.float_array_matrix)."""
from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from kfcrit.errors import InputError
from kfcrit.model.system import System


def test_a_float_array_is_read_like_the_same_floats_in_lists():
    # the vectorised path for 2-D float arrays must give the list path's exact entries,
    # float views, exactness flag and errors (field named, range rule on the exact value)
    rng = np.random.default_rng(3)
    A, C = rng.normal(size=(5, 5)), rng.normal(size=(2, 5))
    Q = np.eye(5) * 0.1
    a, b = System(A, C, Q, 1.0), System(A.tolist(), C.tolist(), Q.tolist(), 1.0)
    assert (a.A, a.C, a.Q, a.exact) == (b.A, b.C, b.Q, b.exact)
    assert a.A[0, 0] == sp.Rational(float(A[0, 0]))
    assert np.array_equal(a.a, A) and not a.a.flags.writeable
    for bad, field in ((np.nan, "A[1][2]"), (1e-310, "A[1][2]"), (3e300, "A[1][2]")):
        M = A.copy()
        M[1, 2] = bad
        with pytest.raises(InputError) as err:
            System(M, C, Q, 1.0)
        assert err.value.field == field
