"""The linear system (A, C, Q, R, Σ0): exact matrices, float views, validation.

Invariant: ``System.A`` … ``System.Sigma0`` are immutable sympy matrices holding exactly what the
user entered (rationals and exact expressions; binary floats from NumPy input are kept exactly as
the rationals they are), and ``System.a`` … ``System.sigma0`` are the float64 views of the same
numbers. ``System.exact`` is True when every entry came from exact input (YAML text, integers,
fractions, sympy), False when any entry came from a binary float array.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Any

import numpy as np
import sympy as sp
from sympy.core.evalf import PrecisionExhausted

from kfcrit.defaults import MAX_STATES_DEFAULT
from kfcrit.errors import InputError
from kfcrit.model.exprparse import MAX_WORKING_DIGITS

PARSE_TIME_BUDGET = 15.0
"""Seconds one System construction may spend parsing and checking expression strings; beyond
it the input is refused (exit code 2) naming the entry reached. A backstop for files of slow
expressions within :data:`MAX_EXPRESSION_TEXT` (measured: up to ~350 µs per character for
expressions that need the exact zero test, 1–10 µs for typical ones)."""


class ParseBudget:
    """One System construction's parsing: each distinct expression string is parsed once (a
    table local to the construction, dropped with it) and the work stops at a deadline."""

    def __init__(self, seconds: float = PARSE_TIME_BUDGET) -> None:
        self.seconds = seconds
        self.deadline = time.monotonic() + seconds
        self.values: dict[str, tuple[sp.Expr, float]] = {}

    def check(self, where: str) -> None:
        """Refuse the input (naming ``where``) once the deadline has passed."""
        if time.monotonic() > self.deadline:
            raise InputError(f"parsing and checking the expression strings took longer than "
                             f"{self.seconds:g} s (stopped here); write plain numbers or fewer "
                             "distinct expressions", field=where)

    def parse(self, text: str, where: str) -> tuple[sp.Expr, float]:
        """The exact value and float view of an expression string (parsed once)."""
        from kfcrit.model.exprparse import parse_with_float

        hit = self.values.get(text)
        if hit is None:
            self.check(where)
            hit = self.values[text] = parse_with_float(text, where)
        return hit


def _entry_to_sympy(value: Any, where: str) -> tuple[sp.Expr, bool]:
    """Convert one matrix entry to an exact sympy number; return it and whether input was exact."""
    if isinstance(value, str):
        from kfcrit.model.exprparse import parse_expression

        return parse_expression(value, where), True
    return _entry_value(value, where)


def _entry_value(value: Any, where: str) -> tuple[sp.Expr, bool]:
    """:func:`_entry_to_sympy` for a non-string entry."""
    from kfcrit.model.exprparse import finish_value, number_from_text

    if isinstance(value, bool):
        raise InputError("booleans are not numbers", field=where)
    if isinstance(value, sp.Rational):  # already exact; range-checked where it was read
        return value, True
    if isinstance(value, sp.Basic):
        if not value.is_number:
            raise InputError("symbolic entries are not allowed", field=where)
        return finish_value(sp.nsimplify(value) if isinstance(value, sp.Float) else value, where,
                       str(value)), not isinstance(value, sp.Float)
    if isinstance(value, (int, np.integer)):
        return number_from_text(str(int(value)), where), True
    if isinstance(value, Fraction):
        return finish_value(sp.Rational(value.numerator, value.denominator), where, str(value)), True
    if isinstance(value, (float, np.floating)):
        f = float(value)
        if not np.isfinite(f):
            raise InputError(f"{f} is not a finite number", field=where)
        return finish_value(sp.Rational(f), where, repr(f)), False
    if isinstance(value, (complex, np.complexfloating)):
        raise InputError("complex entries are not allowed", field=where)
    raise InputError(f"expected a number, got {type(value).__name__}", field=where)


def to_matrix(value: Any, name: str, *, allow_scalar_identity: int | None = None,
              max_size: int = MAX_STATES_DEFAULT) -> tuple[sp.ImmutableMatrix, bool]:
    """Convert nested lists / arrays / sympy matrices to an exact immutable sympy matrix.

    See :func:`matrix_and_float` (which also returns the float64 view) for the parameters.
    """
    M, exact, _ = matrix_and_float(value, name, allow_scalar_identity=allow_scalar_identity,
                                   max_size=max_size, budget=ParseBudget())
    return M, exact


def matrix_and_float(value: Any, name: str, *, allow_scalar_identity: int | None = None,
                     max_size: int = MAX_STATES_DEFAULT,
                     budget: ParseBudget | None = None,
                     ) -> tuple[sp.ImmutableMatrix, bool, np.ndarray]:
    """Convert nested lists / arrays / sympy matrices to an exact immutable sympy matrix and
    its float64 view (each entry rounded once; see :func:`to_float`).

    Parameters
    ----------
    value
        Nested list, NumPy array, sympy matrix or scalar.
    name : str
        The user's name for the matrix (``"Q"``), used in every error message.
    allow_scalar_identity : int, optional
        If given, a scalar means that scalar times the identity of this size.
    max_size : int
        Guard on either dimension.
    budget : ParseBudget, optional
        The construction's parsing state (distinct strings parsed once, deadline); a fresh one
        with the default deadline when omitted.
    """
    if budget is None:
        budget = ParseBudget()
    if isinstance(value, sp.MatrixBase):
        rows = value.tolist()
    elif isinstance(value, np.ndarray):
        if value.ndim == 0:
            rows = value.item()
        elif value.ndim == 2:
            if max(value.shape) > max_size:
                raise InputError(f"has more than {max_size} rows or columns (raise the limit "
                                 "with --max-states)", field=name)
            if value.dtype.kind == "f" and value.size > 0:
                return float_array_matrix(value, name)
            rows = value.tolist()
        else:
            raise InputError(f"must be a matrix (2-D), got {value.ndim}-D array", field=name)
    else:
        rows = value
    if not isinstance(rows, (list, tuple)):
        if isinstance(rows, str):
            (entry, value), exact = budget.parse(rows, name), True
        else:
            entry, exact = _entry_value(rows, name)
            value = _float_of(entry)
        size = allow_scalar_identity if allow_scalar_identity is not None else 1
        return sp.ImmutableMatrix(sp.eye(size) * entry), exact, np.eye(size) * value
    if len(rows) == 0:
        raise InputError("must be a non-empty matrix", field=name)
    if not all(isinstance(r, (list, tuple)) for r in rows):
        raise InputError("must be a list of rows (e.g. [[1, 0], [0, 1]])", field=name)
    ncols = len(rows[0])
    if len(rows) > max_size or ncols > max_size:
        raise InputError(f"has more than {max_size} rows or columns (raise the limit with "
                         "--max-states)", field=name)
    if ncols == 0:
        raise InputError("has an empty row", field=name)
    if all(len(row) == ncols and all(isinstance(v, sp.Rational) for v in row) for row in rows):
        flat = [v for row in rows for v in row]
        return (rational_matrix(len(rows), ncols, flat), True,
                rational_floats(flat).reshape(len(rows), ncols))
    too_much = expression_budget(rows)
    if too_much is not None:
        raise InputError(too_much, field=name)
    exact_all = True
    out = []
    floats = np.empty((len(rows), ncols))
    for i, row in enumerate(rows):
        if len(row) != ncols:
            raise InputError(f"row {i} has {len(row)} entries, row 0 has {ncols}", field=name)
        new_row = []
        for j, v in enumerate(row):
            if isinstance(v, str):
                entry, floats[i, j] = budget.parse(v, f"{name}[{i}][{j}]")
                exact = True
            else:
                entry, exact = _entry_value(v, f"{name}[{i}][{j}]")
                floats[i, j] = _float_of(entry)
            exact_all &= exact
            new_row.append(entry)
        out.append(new_row)
    return sp.ImmutableMatrix(out), exact_all, floats


def rational_matrix(rows: int, cols: int, flat: list[sp.Rational]) -> sp.ImmutableMatrix:
    """``sympy.ImmutableMatrix(rows, cols, flat)`` for sympy rationals, the same matrix built
    directly: its domain matrix (over ZZ when every entry is an integer, else QQ, sparse as
    sympy's own) from each distinct entry converted once, and ``flat`` kept as its entries.

    sympy's general constructor converts every entry to its domain through the expression
    domain and back to a new rational, which costs several times as much per entry (measured:
    0.49 s against 0.05 s for 40,000 entries). tests/model check that both build equal
    matrices with equal representations.
    """
    from sympy.polys.domains import QQ, ZZ
    from sympy.polys.matrices import DomainMatrix

    if not hasattr(sp.ImmutableMatrix, "_fromrep"):  # a sympy without domain matrices
        return sp.ImmutableMatrix(rows, cols, flat)
    domain = ZZ if all(isinstance(v, sp.Integer) for v in flat) else QQ
    converted: dict[tuple[int, int], Any] = {}
    dod: dict[int, dict[int, Any]] = {}
    for k, v in enumerate(flat):
        p, q = v.p, v.q
        if p:
            d = converted.get((p, q))
            if d is None:
                d = converted[(p, q)] = domain(p) if domain is ZZ else domain(p, q)
            i, j = divmod(k, cols)
            dod.setdefault(i, {})[j] = d
    rep = DomainMatrix(dod, (rows, cols), domain)
    obj = sp.Basic.__new__(sp.ImmutableMatrix, sp.Integer(rows), sp.Integer(cols),
                           sp.Tuple(*flat, sympify=False))
    obj._rows, obj._cols, obj._rep = rows, cols, rep
    return obj


def rational_floats(flat: list[sp.Rational]) -> np.ndarray:
    """The float64 values of sympy rationals within the range rule, each correctly rounded.

    ``p / q`` of Python integers is correctly rounded (round half to even), as is
    ``float(sympy.Rational)`` (mpmath, round to nearest) for every value whose double is
    normal, which the range rule [1e-300, 1e300] guarantees; this one is a plain division.
    """
    try:
        out = np.array([v.p / v.q for v in flat], dtype=float)
    except OverflowError:  # beyond the double range (only from a sympy rational given as such)
        return np.array([float(v) for v in flat], dtype=float)
    for k in np.flatnonzero(np.abs(out) < np.finfo(float).tiny):  # what underflows (not 0)
        if flat[k].p:
            out[k] = float(flat[k])
    return out


def matrix_rows(M: sp.MatrixBase) -> list[list[sp.Expr]]:
    """``M.tolist()``, read from the entries an immutable matrix keeps (its ``args``) rather
    than converted back from its domain matrix one new sympy number at a time."""
    rows, cols = M.shape
    args = M.args if isinstance(M, sp.ImmutableDenseMatrix) else ()
    if len(args) == 3 and isinstance(args[2], sp.Tuple) and len(args[2]) == rows * cols:
        flat = args[2].args
        return [list(flat[i * cols:(i + 1) * cols]) for i in range(rows)]
    return M.tolist()


RANGE_EDGE = (2e-300, 5e299)
"""Float entries with 0 < |x| < 2e-300 or |x| > 5e299 are range-checked exactly, one by one
(the rule |x| ∈ [1e-300, 1e300] is on the exact value); every other float is within it."""


def float_array_matrix(value: np.ndarray, name: str
                       ) -> tuple[sp.ImmutableMatrix, bool, np.ndarray]:
    """:func:`matrix_and_float` for a 2-D float array, without a per-entry parse.

    Each entry x is the exact binary rational it is (``sympy.Rational(x)``, as for a float
    entry of a list); the checks are vectorised: non-finite entries are refused naming the first
    one, and only entries near the ends of the range rule are checked exactly. The float view
    is the array itself, and the matrix is not exact (float input). Distinct values are
    converted once (an identity costs two conversions).
    """
    a = np.array(value, dtype=float)
    bad = np.argwhere(~np.isfinite(a))
    if bad.size:
        i, j = (int(v) for v in bad[0])
        raise InputError(f"{a[i, j]} is not a finite number", field=f"{name}[{i}][{j}]")
    mag = np.abs(a)
    for i, j in np.argwhere((mag > RANGE_EDGE[1]) | ((mag < RANGE_EDGE[0]) & (mag > 0))):
        _entry_value(float(a[i, j]), f"{name}[{int(i)}][{int(j)}]")
    exact: dict[float, sp.Rational] = {}
    flat = []
    for x in a.ravel().tolist():
        r = exact.get(x)
        if r is None:
            r = exact[x] = sp.Rational(x)
        flat.append(r)
    return sp.ImmutableMatrix(a.shape[0], a.shape[1], flat), False, a


MAX_EXPRESSION_TEXT = 500_000
"""Most characters of distinct expression strings (entries that are not plain numbers) in one
matrix, checked before any parsing: a documented bound on the parsing work (typical expressions
cost 1–10 µs per character, measured: a 200×200 matrix of distinct ``sqrt(2)/k`` in a few
seconds). Plain numbers (YAML numbers, NumPy arrays) and repeats of a string are not counted;
:data:`PARSE_TIME_BUDGET` bounds the rest."""


def expression_budget(rows: Any) -> str | None:
    """Why the expression strings of a matrix exceed the parsing budget, or None.

    Counts the characters of the *distinct* strings (each is parsed once), before any parsing.
    """
    seen: set[str] = set()
    total = 0
    for row in rows:
        if not isinstance(row, (list, tuple)):
            continue
        for v in row:
            if isinstance(v, str) and v not in seen:
                seen.add(v)
                total += len(v)
    if total <= MAX_EXPRESSION_TEXT:
        return None
    return (f"holds {len(seen)} distinct expression strings with {total} characters in all, "
            f"above the parsing budget of {MAX_EXPRESSION_TEXT} characters per matrix; write "
            "plain numbers, or repeat a few expressions (each distinct string is parsed once)")


def _float_of(e: sp.Expr) -> float:
    return float(e) if e.is_Rational else float(sp.N(e, 20))


def to_float(M: sp.MatrixBase) -> np.ndarray:
    """Float64 view of an exact matrix (each entry rounded once, to nearest)."""
    rows, cols = M.shape
    flat = [_float_of(e) for row in matrix_rows(M) for e in row]
    return np.array(flat, dtype=float).reshape(rows, cols)


def sym_tolerance(M: np.ndarray) -> float:
    """Scale-aware tolerance for symmetry/definiteness of a float matrix: ``64·n·eps·‖M‖``."""
    n = M.shape[0]
    return 64 * n * np.finfo(float).eps * max(np.linalg.norm(M, ord=2), np.finfo(float).tiny)


SYMMETRY_DIGITS = MAX_WORKING_DIGITS - 100
"""Exact entries M[i][j], M[j][i] that agree to this many digits but are not provably equal
by the bounded exact test are taken as equal (the upper-triangle entry is used for both)."""


def _check_symmetric(M: sp.ImmutableMatrix, Mf: np.ndarray, name: str,
                     exact: bool, budget: ParseBudget | None = None,
                     tol: float | None = None) -> sp.ImmutableMatrix:
    """Refuse an asymmetric matrix; return it (exact input: symmetrised where numerically equal).

    The float views are compared first (a clear asymmetry is refused at once). Exact entries are
    then compared pairwise with bounded effort, never ``simplify``: a rational difference
    exactly; otherwise :func:`kfcrit.model.exprparse.sign_of`-style evaluation with certain digits (a
    digit found means asymmetric), and a difference with no digit up to ``SYMMETRY_DIGITS``
    digits counts as zero (proven or not), in which case the upper entry is used for both.
    ``tol`` is ``sym_tolerance(Mf)`` when the caller has it.
    """
    if np.max(np.abs(Mf - Mf.T), initial=0.0) > (sym_tolerance(Mf) if tol is None else tol):
        raise InputError("must be symmetric", field=name)
    if not exact:
        return M
    n = M.shape[0]
    entries = matrix_rows(M)
    rows = None
    for i in range(n):
        if budget is not None:
            budget.check(f"{name}[{i}]")
        for j in range(i + 1, n):
            a, b = entries[i][j], entries[j][i]
            if a == b:
                continue
            d = a - b
            if d.is_Rational:
                if d != 0:
                    raise InputError(f"must be symmetric ({name}[{i}][{j}] != {name}[{j}][{i}])",
                                     field=name)
                continue
            try:
                approx = d.evalf(30, maxn=MAX_WORKING_DIGITS, strict=True)
                nonzero = approx.as_real_imag()[0] != 0 or approx.as_real_imag()[1] != 0
            except PrecisionExhausted:
                nonzero = False
            if nonzero:
                raise InputError(f"must be symmetric ({name}[{i}][{j}] != {name}[{j}][{i}])",
                                 field=name)
            if rows is None:
                rows = [list(r) for r in entries]
            rows[j][i] = a
    return M if rows is None else sp.ImmutableMatrix(rows)


EXACT_DEFINITE_MAX = 12
"""Largest rational matrix whose definiteness is decided exactly (sympy); above, in floats."""


def is_definite(M: sp.MatrixBase, Mf: np.ndarray, exact: bool, strict: bool = True,
                tol: float | None = None) -> bool:
    """Whether a symmetric matrix is positive definite (``strict``) or semidefinite.

    Exact for exact rational input up to :data:`EXACT_DEFINITE_MAX` states (``1e-250`` is
    positive, whatever its size); otherwise from the float eigenvalues against the
    scale-aware tolerance :func:`sym_tolerance` (λ_min > tol, resp. ≥ −tol), so scaling the
    matrix by any power of ten never changes the answer. Never an absolute threshold.
    ``tol`` is ``sym_tolerance(Mf)`` when the caller has it (a singular value decomposition).
    """
    if exact and M.shape[0] <= EXACT_DEFINITE_MAX and all(e.is_Rational for e in M):
        return bool(M.is_positive_definite) if strict else bool(M.is_positive_semidefinite)
    with np.errstate(all="ignore"):
        w = np.linalg.eigvalsh(0.5 * (Mf + Mf.T))
    tol = sym_tolerance(Mf) if tol is None else tol
    return bool(w.min() > tol) if strict else bool(w.min() >= -tol)


def _check_definite(M: sp.ImmutableMatrix, Mf: np.ndarray, name: str, exact: bool,
                    strict: bool, tol: float | None = None) -> None:
    """Positive (semi)definiteness (:func:`is_definite`), or an error naming the matrix."""
    what = "positive definite" if strict else "positive semidefinite"
    if not is_definite(M, Mf, exact, strict, tol):
        raise InputError(f"must be symmetric {what}", field=name)


@dataclass(frozen=True, eq=False)
class System:
    r"""A linear system x_{t+1} = A x_t + w_t, y_t = C x_t + v_t, w ~ N(0,Q), v ~ N(0,R).

    The plant and sensor of Sinopoli et al. (2004), eq. (1); the arrival indicator γ_t is given
    separately by a channel. Exact input (integers, fractions, strings such as ``"5/4"``, sympy
    numbers) stays exact; a binary float is taken as the rational number it is.

    .. math::

        x_{t+1} = A x_t + w_t,\qquad y_t = C x_t + v_t,\qquad
        w_t \sim N(0, Q),\ v_t \sim N(0, R),\ x_0 \sim N(\bar x_0, \Sigma_0).

    Parameters
    ----------
    A, C, Q, R : array_like
        Nested lists, NumPy arrays or sympy matrices. ``Q`` and ``R`` may be scalars (times I).
    Sigma0 : array_like, optional
        Initial covariance, default identity. A scalar means that scalar times I.
    name : str, optional
        A label for reports.
    max_states : int
        Guard on the state dimension.

    Attributes
    ----------
    A, C, Q, R, Sigma0 : sympy.ImmutableMatrix
        The matrices as entered (exact rationals where the input was exact).
    a, c, q, r, sigma0 : numpy.ndarray
        Their float64 values.
    exact : bool
        True when every entry was exact (then the theory decides structure exactly).
    n, m : int
        State and output dimensions.

    Raises
    ------
    kfcrit.errors.InputError
        A matrix of the wrong shape, a non-symmetric ``Q``, ``R`` or ``Sigma0``, ``R`` not positive
        definite, ``Q`` or ``Sigma0`` not positive semidefinite, or a size above ``max_states``;
        the error's ``field`` names the matrix.

    References
    ----------
    Sinopoli, Schenato, Franceschetti, Poolla, Jordan & Sastry (2004), "Kalman filtering with
    intermittent observations", eq. (1); docs/theory.md §1.

    Examples
    --------
    >>> from kfcrit import System
    >>> s = System(A=[[1.25, 0], [1, 1.1]], C=[[1, 1]], Q=20, R=2.5)
    >>> s.n, s.m, s.exact
    (2, 1, False)
    >>> s.Q
    Matrix([
    [20,  0],
    [ 0, 20]])
    >>> System(A=[["5/4"]], C=[[1]], Q=1, R=1).exact
    True
    >>> System(A=[[1]], C=[[1]], Q=1, R=0)
    Traceback (most recent call last):
        ...
    kfcrit.errors.InputError: R: must be symmetric positive definite
    """

    A: sp.ImmutableMatrix
    C: sp.ImmutableMatrix
    Q: sp.ImmutableMatrix
    R: sp.ImmutableMatrix
    Sigma0: sp.ImmutableMatrix
    name: str
    exact: bool
    a: np.ndarray = field(repr=False)
    c: np.ndarray = field(repr=False)
    q: np.ndarray = field(repr=False)
    r: np.ndarray = field(repr=False)
    sigma0: np.ndarray = field(repr=False)

    def __init__(self, A: Any, C: Any, Q: Any, R: Any, Sigma0: Any = None, name: str | None = None,
                 max_states: int = MAX_STATES_DEFAULT) -> None:
        budget = ParseBudget()
        A_, ea, fa = matrix_and_float(A, "A", max_size=max_states, budget=budget)
        n = A_.shape[0]
        if A_.shape != (n, n):
            raise InputError(f"must be square, got {A_.shape[0]}x{A_.shape[1]}", field="A")
        C_, ec, fc = matrix_and_float(C, "C", max_size=max_states, budget=budget)
        if C_.shape[1] != n:
            raise InputError(f"must have {n} columns (the size of A), got {C_.shape[1]}",
                             field="C")
        m = C_.shape[0]
        Q_, eq, fq = matrix_and_float(Q, "Q", allow_scalar_identity=n, max_size=max_states,
                                      budget=budget)
        R_, er, fr = matrix_and_float(R, "R", allow_scalar_identity=m, max_size=max_states,
                                      budget=budget)
        if Sigma0 is None:
            S_, es = sp.ImmutableMatrix(sp.eye(n)), True
            fs = np.eye(n)
        else:
            S_, es, fs = matrix_and_float(Sigma0, "Sigma0", allow_scalar_identity=n,
                                          max_size=max_states, budget=budget)
        for M, nm, size in ((Q_, "Q", n), (R_, "R", m), (S_, "Sigma0", n)):
            if M.shape != (size, size):
                raise InputError(f"must be {size}x{size}, got {M.shape[0]}x{M.shape[1]}",
                                 field=nm)
        exact = ea and ec and eq and er and es
        floats = {"A": fa, "C": fc, "Q": fq, "R": fr, "Sigma0": fs}
        checked = {}
        for M, nm, ex, strict in ((Q_, "Q", eq, False), (R_, "R", er, True),
                                  (S_, "Sigma0", es, False)):
            tol = sym_tolerance(floats[nm])   # one singular value decomposition per matrix
            # the parsing deadline bounds the evaluation of expressions; rational entries are
            # compared exactly in bounded time (a slow or busy machine never refuses them)
            rational = all(isinstance(e, sp.Rational) for row in matrix_rows(M) for e in row)
            checked[nm] = _check_symmetric(M, floats[nm], nm, ex, None if rational else budget,
                                           tol)
            _check_definite(checked[nm], floats[nm], nm, ex, strict, tol)
        Q_, R_, S_ = checked["Q"], checked["R"], checked["Sigma0"]
        set_ = object.__setattr__
        for key, val in (("A", A_), ("C", C_), ("Q", Q_), ("R", R_), ("Sigma0", S_)):
            set_(self, key, val)
        set_(self, "name", str(name) if name is not None else "unnamed system")
        set_(self, "exact", bool(exact))
        for key, nm in (("a", "A"), ("c", "C"), ("q", "Q"), ("r", "R"), ("sigma0", "Sigma0")):
            arr = floats[nm]
            arr.setflags(write=False)
            set_(self, key, arr)

    @property
    def n(self) -> int:
        """State dimension."""
        return self.A.shape[0]

    @property
    def m(self) -> int:
        """Output dimension."""
        return self.C.shape[0]

    @classmethod
    def from_statespace(cls, sys: Any, Q: Any, R: Any, Sigma0: Any = None,
                        name: str | None = None) -> System:
        """Build from a discrete-time python-control ``StateSpace`` (needs ``control``).

        ``sys.A`` and ``sys.C`` are float arrays: entries that are their own shortest decimal
        (integers, 0.5, 1.25) are read exactly, every other entry as the binary number it is
        (:func:`statespace_entries`). A continuous-time ``sys`` (dt = 0) is sampled by
        ``kfcrit.from_statespace(sys, sampling_time=T, Q=Q_c, R=R)``.
        """
        dt = getattr(sys, "dt", None)
        if dt is None or dt is False or dt == 0:
            raise InputError(
                "must be a discrete-time StateSpace (dt > 0 or True); for a continuous-time one "
                "(dt = 0) give the sampling_time: kfcrit.from_statespace(sys, "
                "sampling_time=T, Q=Q_c, R=R) with Q_c the noise spectral density", field="sys")
        return cls(statespace_entries(sys.A), statespace_entries(sys.C), Q, R, Sigma0,
                   name=name)

    def is_positive_definite(self, name: str) -> bool:
        """Whether ``Q``, ``R`` or ``Sigma0`` is positive definite (:func:`is_definite`: exact
        for exact rational input, scale-aware for float input; ``Q = 1e-250`` is)."""
        views = {"Q": (self.Q, self.q), "R": (self.R, self.r),
                 "Sigma0": (self.Sigma0, self.sigma0)}
        if name not in views:
            raise InputError("must be Q, R or Sigma0", field="name")
        M, Mf = views[name]
        return is_definite(M, Mf, self.exact, strict=True)

    def matrices_text(self) -> dict[str, list[list[str]]]:
        """Exact entries as strings readable by :func:`kfcrit.model.exprparse.parse_expression`.

        Computed once per system (the matrices never change) and returned as a fresh copy.
        """
        cached = self.__dict__.get("_matrices_text")
        if cached is None:
            cached = {nm: [[entry_text(e) for e in row] for row in matrix_rows(M)]
                      for nm, M in (("A", self.A), ("C", self.C), ("Q", self.Q), ("R", self.R),
                                    ("Sigma0", self.Sigma0))}
            object.__setattr__(self, "_matrices_text", cached)
        return {nm: [list(row) for row in rows] for nm, rows in cached.items()}


def entry_text(e: Any) -> str:
    """``sympy.sstr(e)``, formatted directly for a rational (p/q, or p when q = 1: the same
    text, without sympy's printer, which costs tens of microseconds per entry)."""
    if isinstance(e, sp.Rational):
        return str(e.p) if e.q == 1 else f"{e.p}/{e.q}"
    return sp.sstr(e)


def statespace_entries(M: Any) -> list[list[Any]]:
    """The entries of a python-control float matrix, exact where the float is.

    A python-control ``StateSpace`` stores float64 arrays, so the numbers the user meant are
    lost; an entry equal to its own shortest decimal (``1.0``, ``0.0``, ``0.5``, ``-1.25``:
    ``Fraction(repr(x)) == Fraction(x)``) is returned as that exact rational, so integer and
    short dyadic matrices stay exact. Every other entry (``0.1`` is
    3602879701896397/36028797018963968 in binary) stays a float: :func:`matrix_and_float`
    takes it as the binary number it is and marks the matrix inexact.
    """
    rows = np.atleast_2d(np.asarray(M, dtype=float))
    out: list[list[Any]] = []
    for row in rows:
        new_row: list[Any] = []
        for x in row.tolist():
            if np.isfinite(x) and Fraction(repr(x)) == Fraction(x):
                new_row.append(sp.Rational(Fraction(x).numerator, Fraction(x).denominator))
            else:
                new_row.append(x)
        out.append(new_row)
    return out


ILL_CONDITIONED = 1e8
"""Ratio above which a spread of scales is reported as ill-conditioned."""


def conditioning_warnings(system: System) -> list[str]:
    """Warnings about data that float64 numerics handle badly (the exact decisions are unaffected).

    Checked: the spread of eigenvalue moduli of A (max/min over non-zero moduli), the condition
    number of R, and of the observability Gramian-like matrix [C; CA; …] restricted to the
    modes with |λ| ≥ 1 (a nearly unobservable unstable mode).
    """
    out: list[str] = []
    mod = np.abs(np.linalg.eigvals(system.a))
    nz = mod[mod > 0]
    if nz.size and nz.max() / nz.min() > ILL_CONDITIONED:
        out.append(f"ill-conditioned A: eigenvalue moduli span {nz.min():.3g} to {nz.max():.3g}; "
                   "the numerical bounds and simulations may lose accuracy")
    cond_r = np.linalg.cond(system.r)
    if not np.isfinite(cond_r) or cond_r > ILL_CONDITIONED:
        out.append(f"nearly singular R: condition number {cond_r:.3g}; the Kalman update divides "
                   "by C P C' + R")
    w, v = np.linalg.eig(system.a)
    for lam, vec in zip(w, v.T):
        if abs(lam) >= 1:
            seen = np.linalg.norm(system.c @ vec) / max(np.linalg.norm(system.c), 1e-300)
            if 0 < seen < 1e-6:
                out.append(f"nearly unobservable mode: eigenvalue {complex(lam):.6g} is seen "
                           f"through C with relative gain {seen:.3g}")
    return out
