"""Continuous-time models sampled with a zero-order hold: exact where cheap, certified otherwise.

The plant ``dx = A_c x dt + dw`` with ``w`` a Wiener process of spectral density ``Q_c``
(``E[dw dw'] = Q_c dt``), sampled every ``T`` seconds, is the discrete model
``x_{k+1} = A x_k + w_k`` of kfcrit with

.. math::

    A = e^{A_c T}, \\qquad Q = \\int_0^T e^{A_c s} Q_c e^{A_c' s} \\, ds .

Van Loan's method reads both off one matrix exponential:
``exp([[−A_c, Q_c], [0, A_c']] T) = [[·, F12], [0, F22]]`` gives ``A = F22'`` and ``Q = A F12``.

Exactly (sympy, closed forms) when ``A_c`` is rational with rational eigenvalues and at most
:data:`EXACT_MAX_STATES` states — integrator chains (nilpotent ``A_c``: the series terminates),
rational poles, Jordan blocks. The exponential is then a finite sum
``e^{A_c s} = Σ_λ e^{λ s} Σ_{k<m_λ} s^k/k! · V_λ N_λ^k W_λ`` over the generalized eigenspaces
(``V_λ`` a rational basis, ``W_λ`` the matching rows of ``V^{-1}``, ``N_λ`` nilpotent), and the
integral is a finite sum of ``∫_0^T s^j e^{ν s} ds``, each in closed form. The work is bounded
before it starts (size, rational entries, a characteristic polynomial that splits over ℚ); no
symbolic ``exp``/``integrate``/``simplify`` is ever called.

Otherwise (irrational or complex eigenvalues, irrational entries of ``A_c``, larger systems) the
Van Loan exponential is computed in ball arithmetic (python-flint ``arb_mat.exp``): the result is
float64 matrices together with a proven bound on every entry's error (``error_bound``), and the
reason the exact path was not taken.

The measurement side is not sampled: ``C`` stays, and ``R`` is the covariance of the discrete
measurement noise of the sampled sensor (for an analog sensor of spectral density ``R_c``
averaged over the sample period, ``R = R_c / T``; kfcrit takes ``R`` as given).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import sympy as sp

from kfcrit.errors import InputError
from kfcrit.model.exprparse import sign_of
from kfcrit.model.system import (
    MAX_STATES_DEFAULT,
    System,
    is_definite,
    statespace_entries,
    sym_tolerance,
    to_float,
    to_matrix,
)

EXACT_MAX_STATES = 8
"""Largest ``A_c`` sampled exactly (a rational characteristic polynomial of this degree is
factored; every other step is rational linear algebra of this size)."""

CERTIFIED_MAX_STATES = 64
"""Largest ``A_c`` whose Van Loan exponential (size 2n) is enclosed in ball arithmetic; above,
SciPy's ``expm`` gives float64 values without a proven bound (``error_bound`` is infinite)."""

CERTIFIED_PRECISIONS = (128, 256, 512, 1024)
"""Ball-arithmetic precisions (bits) tried in turn until every entry is known to float accuracy."""

_FLOAT_ACCURACY = 2.0 ** -60
"""Relative ball radius below which an entry's float64 value is as good as its rounding."""

_INPUT_DIGITS = 60
"""Digits to which an irrational exact input entry is evaluated for the ball computation."""


@dataclass(frozen=True, eq=False)
class SampledModel:
    """The discrete model of a continuous-time plant sampled with period ``T``.

    Attributes
    ----------
    A, Q : sympy.ImmutableMatrix or numpy.ndarray
        ``e^{A_c T}`` and ``∫_0^T e^{A_c s} Q_c e^{A_c' s} ds``: exact sympy matrices when
        ``exact``, else float64 arrays within ``error_bound`` of the true values.
    exact : bool
        Whether ``A`` and ``Q`` are exact closed forms of the input numbers.
    method : str
        ``"exact-nilpotent"``, ``"exact-rational-eigenvalues"``, ``"certified-van-loan"`` or,
        above :data:`CERTIFIED_MAX_STATES` states, ``"float-van-loan"``.
    reason : str
        Why this method: what made the exponential exact, or why the exact path was not taken.
    A_c, Q_c : sympy.ImmutableMatrix
        The continuous-time state matrix and noise spectral density, as entered.
    sampling_time : sympy.Expr
        ``T`` as entered (exact).
    input_exact : bool
        Whether every input number was exact (text, integers, fractions, sympy); False when any
        came from a binary float (then taken as the rational it is).
    error_bound : float
        Proven bound on ``|computed − true|`` over the entries of ``A`` and ``Q`` (0 if exact,
        ``inf`` for ``"float-van-loan"``, which has no proven bound).
    """

    A: Any
    Q: Any
    exact: bool
    method: str
    reason: str
    A_c: sp.ImmutableMatrix
    Q_c: sp.ImmutableMatrix
    sampling_time: sp.Expr
    input_exact: bool
    error_bound: float = 0.0

    def system(self, C: Any, R: Any, Sigma0: Any = None, name: str | None = None,
               max_states: int = MAX_STATES_DEFAULT) -> System:
        """The discrete :class:`~kfcrit.model.system.System` ``(A, C, Q, R, Σ0)``.

        ``R`` is the discrete measurement-noise covariance of the sampled sensor. The system is
        exact only if the sampling was exact and every input number was exact; otherwise it is
        built from the float64 values (so ``System.exact`` is False, as for float input).
        """
        if self.exact and self.input_exact:
            A, Q = self.A, self.Q
        else:
            A, Q = self.float_a(), self.float_q()
        return System(A, C, Q, R, Sigma0, name=name, max_states=max_states)

    def float_a(self) -> np.ndarray:
        """Float64 view of ``A``."""
        return to_float(self.A) if self.exact else np.array(self.A, dtype=float)

    def float_q(self) -> np.ndarray:
        """Float64 view of ``Q``."""
        return to_float(self.Q) if self.exact else np.array(self.Q, dtype=float)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description of the sampling (for the record's ``system`` section)."""
        def text(M: sp.MatrixBase) -> list[list[str]]:
            return [[sp.sstr(e) for e in M.row(i)] for i in range(M.shape[0])]

        return {"A": text(self.A_c), "Q": text(self.Q_c),
                "sampling_time": sp.sstr(self.sampling_time), "method": self.method,
                "exact": self.exact, "reason": self.reason, "error_bound": self.error_bound}


def sample(A_c: Any, Q_c: Any, T: Any) -> SampledModel:
    r"""Sample ``dx = A_c x dt + dw`` (``w`` of spectral density ``Q_c``) with period ``T``.

    .. math::

        A = e^{A_c T}, \qquad Q = \int_0^T e^{A_c s} Q_c e^{A_c' s}\, ds
          = A \, F_{12}, \quad
        \exp\!\left(\begin{bmatrix} -A_c & Q_c \\ 0 & A_c' \end{bmatrix} T\right)
          = \begin{bmatrix} \cdot & F_{12} \\ 0 & A' \end{bmatrix}.

    Parameters
    ----------
    A_c : array_like
        Continuous-time state matrix (n × n): nested lists, NumPy array or sympy matrix; strings
        are exact expressions (errors name ``continuous.A``).
    Q_c : array_like
        Spectral density of the process noise (n × n, symmetric positive semidefinite); a scalar
        ``q`` means ``q I`` (errors name ``continuous.Q``).
    T : number or str
        Sampling time, > 0 (``"1/10"`` is exact; a Python float is the binary number it is).

    Returns
    -------
    SampledModel
        Exact closed forms when ``A_c`` is rational with rational eigenvalues and
        n ≤ :data:`EXACT_MAX_STATES`; otherwise certified float64 values and the reason.

    Raises
    ------
    kfcrit.errors.InputError
        A non-square ``A_c``, a ``Q_c`` that is not symmetric PSD, or ``T`` ≤ 0 (errors name
        ``continuous.A``, ``continuous.Q`` or the sampling time).

    References
    ----------
    Van Loan (1978), "Computing integrals involving the matrix exponential"; docs/theory.md §1
    (the discrete model that is sampled) and §11 (marginal modes of integrator chains).

    Examples
    --------
    >>> from kfcrit import sample
    >>> model = sample([[0, 1], [0, 0]], [[0, 0], [0, 1]], "1/10")   # double integrator
    >>> model.A, model.Q, model.method
    (Matrix([
    [1, 1/10],
    [0,    1]]), Matrix([
    [1/3000, 1/200],
    [ 1/200,  1/10]]), 'exact-nilpotent')
    """
    A, ea = to_matrix(A_c, "continuous.A")
    n = A.shape[0]
    if A.shape != (n, n):
        raise InputError(f"must be square, got {A.shape[0]}x{A.shape[1]}", field="continuous.A")
    Qc, eq = to_matrix(Q_c, "continuous.Q", allow_scalar_identity=n)
    if Qc.shape != (n, n):
        raise InputError(f"must be {n}x{n} (the size of continuous.A), got "
                         f"{Qc.shape[0]}x{Qc.shape[1]}", field="continuous.Q")
    Qc = _check_density(Qc, eq)
    t, et = _sampling_time(T)
    why = _exact_obstacle(A)
    if why is None:
        blocks = _generalized_eigenspaces(A)
        if blocks is not None:
            Ad, Qd = _exact_sample(blocks, Qc, t)
            nilpotent = len(blocks) == 1 and blocks[0][0] == 0
            method = "exact-nilpotent" if nilpotent else "exact-rational-eigenvalues"
            reason = ("continuous.A is nilpotent: the exponential series terminates"
                      if nilpotent else "continuous.A has rational eigenvalues: exponential "
                      "from its generalized eigenspaces")
            out = SampledModel(Ad, Qd, True, method, reason, A, Qc, t, ea and eq and et)
            _check_finite(out.float_a(), out.float_q())
            return out
        why = ("the eigenvalues of continuous.A are not all rational (its characteristic "
               "polynomial does not split over the rationals)")
    if n > CERTIFIED_MAX_STATES:
        Ad, Qd = _float_sample(A, Qc, t)
        return SampledModel(Ad, Qd, False, "float-van-loan",
                            f"{why}; n > {CERTIFIED_MAX_STATES}: ball arithmetic too costly, "
                            "SciPy expm of the Van Loan block (no proven error bound)",
                            A, Qc, t, ea and eq and et, math.inf)
    Ad, Qd, bound = _certified_sample(A, Qc, t)
    return SampledModel(Ad, Qd, False, "certified-van-loan",
                        f"{why}; matrix exponential of the Van Loan block in ball arithmetic",
                        A, Qc, t, ea and eq and et, bound)


def from_continuous_statespace(sys: Any, sampling_time: Any, Q_c: Any, R: Any,
                               Sigma0: Any = None, name: str | None = None,
                               max_states: int = MAX_STATES_DEFAULT, *, A_c: Any = None,
                               C: Any = None) -> System:
    r"""Build the sampled :class:`System` of a continuous-time python-control ``StateSpace``.

    .. math::

        A = e^{A_c T}, \qquad Q = \int_0^T e^{A_c s} Q_c e^{A_c' s}\, ds
        \quad (\text{see } :func:`sample`).

    Parameters
    ----------
    sys : control.StateSpace
        Continuous time (``sys.dt == 0``). ``sys.A`` and ``sys.C`` are used; ``sys.B`` is not
        (process noise enters through ``Q_c``: for noise ``B_w w`` write ``Q_c = B_w S B_w'``).
    sampling_time : number or str
        ``T > 0``; a string such as ``"1/10"`` is exact (parsed by
        :mod:`kfcrit.model.exprparse`), a Python float is the binary number it is.
    Q_c : array_like
        Spectral density of the process noise (n × n), or a scalar times the identity; strings,
        integers and sympy numbers are exact.
    R : array_like
        Covariance of the *discrete* measurement noise of the sampled sensor.
    A_c, C : array_like, optional
        Exact matrices (lists of strings, integers, sympy numbers) to use instead of
        ``sys.A`` and ``sys.C``; they must agree with the system's floats.

    Returns
    -------
    System
        The discrete-time system (exact when every input is exact).

    Raises
    ------
    kfcrit.errors.InputError
        ``sys`` of the wrong time base or type, a missing ``sampling_time``, ``Q`` or ``R``,
        or exact overrides that disagree with the system's floats (the error names the
        argument).

    Notes
    -----
    python-control stores float arrays. Entries equal to their shortest decimal (integers,
    ``0.5``, ``-1.25``) are read exactly; every other float entry (``0.1``) is taken as its
    binary value, and then the system is built from float64 values (``System.exact`` False).
    With exact entries throughout (``sys`` of integers, ``T = "1/10"``) the sampled ``A`` and
    ``Q`` are exact: the double integrator gives ``A = [[1, T], [0, 1]]`` and
    ``Q = q [[T³/3, T²/2], [T²/2, T]]`` for ``Q_c = diag(0, q)``.

    References
    ----------
    Van Loan (1978) for the sampled noise integral; Sinopoli et al. (2004), eq. (1);
    docs/theory.md §1 and §11 (marginal modes: constant-velocity trackers have p_c = 0).

    Examples
    --------
    >>> import control
    >>> plant = control.ss([[0, 1], [0, 0]], [[0], [1]], [[1, 0]], 0)   # continuous double integrator
    >>> from kfcrit import critical_value, from_continuous_statespace
    >>> system = from_continuous_statespace(plant, "1/10", [[0, 0], [0, 1]], 1)
    >>> system.A, system.exact, critical_value(system).value.value
    (Matrix([
    [1, 1/10],
    [0,    1]]), True, 0.0)
    """
    dt = getattr(sys, "dt", None)
    if dt is None or dt is True or (dt is not False and dt != 0):
        raise InputError("must be a continuous-time StateSpace (dt = 0); for a discrete one "
                         "use kfcrit.from_statespace(sys, Q=Q, R=R)", field="sys")
    return _sampled_system(sys, sampling_time, Q_c, R, Sigma0, name, max_states,
                           (A_c, "A_c"), C)


def _sampled_system(sys: Any, sampling_time: Any, Q_c: Any, R: Any, Sigma0: Any,
                    name: str | None, max_states: int, a_override: tuple[Any, str],
                    c_override: Any) -> System:
    """The sampled system of a continuous ``sys`` (``a_override``: exact A_c and its name)."""
    a = _statespace_matrix(sys.A, a_override[0], a_override[1], "sys.A")
    c = _statespace_matrix(sys.C, c_override, "C", "sys.C")
    model = sample(a, Q_c, sampling_time)
    return model.system(c, R, Sigma0, name=name, max_states=max_states)


def from_statespace(sys: Any, sampling_time: Any = None, Q: Any = None, R: Any = None,
                    Sigma0: Any = None, name: str | None = None, *, A: Any = None,
                    C: Any = None, max_states: int = MAX_STATES_DEFAULT) -> System:
    r"""The kfcrit :class:`System` of a python-control ``StateSpace``, discrete or continuous.

    A discrete ``sys`` (``dt > 0`` or ``True``) gives ``x_{k+1} = A x_k + w_k`` with
    ``E[w w'] = Q`` directly. A continuous ``sys`` (``dt == 0``) needs ``sampling_time`` T and
    takes ``Q`` as the spectral density ``Q_c`` of ``dx = A_c x dt + dw``; it is sampled with a
    zero-order hold by :func:`sample` (Van Loan, exact for integrator chains and rational poles)
    and gives

    .. math::

        A = e^{A_c T}, \qquad Q = \int_0^T e^{A_c s} Q_c e^{A_c' s}\, ds .

    Parameters
    ----------
    sys : control.StateSpace
        ``sys.A`` and ``sys.C`` are used (``sys.B``, ``sys.D`` are not).
    sampling_time : number or str, optional
        Required for (and only for) a continuous ``sys``; ``"1/10"`` is exact.
    Q : array_like
        Discrete process-noise covariance, or for a continuous ``sys`` the spectral density.
    R : array_like
        Discrete measurement-noise covariance (of the sampled sensor).
    Sigma0 : array_like, optional
        Initial error covariance (identity by default).
    A, C : array_like, optional
        Exact matrices (strings, integers, sympy numbers) to use instead of ``sys.A`` (for a
        continuous ``sys``: A_c) and ``sys.C``; they must agree with the system's floats.

    Returns
    -------
    System
        The discrete-time system (exact when every input is exact).

    Raises
    ------
    kfcrit.errors.InputError
        ``sys`` of the wrong time base or type, a missing ``sampling_time``, ``Q`` or ``R``,
        or exact overrides that disagree with the system's floats (the error names the
        argument).

    Notes
    -----
    python-control stores float arrays. Entries equal to their shortest decimal (integers,
    ``0.5``, ``-1.25``) are read exactly; every other float entry (``0.1``) is taken as its
    binary value, and the system is then inexact (``System.exact`` False). Pass ``A``/``C``
    as text (``"1/10"``) for exact values. Errors are :class:`~kfcrit.errors.InputError`
    naming the argument.

    References
    ----------
    Van Loan (1978) for the sampled noise integral; Sinopoli et al. (2004), eq. (1);
    docs/theory.md §1 and §11 (marginal modes: constant-velocity trackers have p_c = 0).

    Examples
    --------
    >>> import control
    >>> plant = control.ss([[0, 1], [0, 0]], [[0], [1]], [[1, 0]], 0)   # continuous double integrator
    >>> from kfcrit import critical_value, from_statespace
    >>> system = from_statespace(plant, sampling_time="1/10", Q=[[0, 0], [0, 1]], R=1)
    >>> system.A, system.exact, critical_value(system).value.value
    (Matrix([
    [1, 1/10],
    [0,    1]]), True, 0.0)
    >>> from_statespace(control.ss([[1.25]], [[1]], [[1]], 0, 1), Q=1, R=1).A   # discrete, dt = 1
    Matrix([[5/4]])
    """
    for value, field in ((Q, "Q"), (R, "R")):
        if value is None:
            raise InputError("is required (from_statespace(sys, sampling_time, Q=..., R=...))",
                             field=field)
    dt = getattr(sys, "dt", _MISSING)
    if dt is _MISSING or not hasattr(sys, "A") or not hasattr(sys, "C"):
        raise InputError(f"must be a python-control StateSpace, got {type(sys).__name__}",
                         field="sys")
    if dt is None:
        raise InputError("has no timebase (dt = None): build it with dt=0 (continuous, then "
                         "give sampling_time) or dt > 0 (discrete)", field="sys")
    continuous = dt is not True and (dt is False or dt == 0)
    if not continuous:
        if sampling_time is not None:
            raise InputError(f"applies to a continuous-time sys only; this one is discrete "
                             f"(dt = {dt})", field="sampling_time")
        a = _statespace_matrix(sys.A, A, "A", "sys.A")
        c = _statespace_matrix(sys.C, C, "C", "sys.C")
        return System(a, c, Q, R, Sigma0, name=name, max_states=max_states)
    if sampling_time is None:
        raise InputError("is required for a continuous-time sys (dt = 0): "
                         "kfcrit.from_statespace(sys, sampling_time=T, Q=Q_c, R=R), Q_c the "
                         "spectral density of the process noise", field="sampling_time")
    return _sampled_system(sys, sampling_time, Q, R, Sigma0, name, max_states, (A, "A"), C)


_MISSING = object()
"""Marker of an absent attribute (``dt`` may legitimately be None)."""

_AGREEMENT = 1e-12
"""Relative difference up to which an exact override of ``sys.A``/``sys.C`` agrees with it."""


def _statespace_matrix(floats: Any, override: Any, field: str, source: str) -> Any:
    """The matrix to use: ``override`` (exact, checked against the system's floats) or the
    system's own floats read by :func:`~kfcrit.model.system.statespace_entries`."""
    if override is None:
        return statespace_entries(floats)
    M, _ = to_matrix(override, field)
    ref = np.atleast_2d(np.asarray(floats, dtype=float))
    mf = to_float(M)
    if mf.shape != ref.shape:
        raise InputError(f"must have the shape of {source}, {ref.shape[0]}x{ref.shape[1]}, "
                         f"got {mf.shape[0]}x{mf.shape[1]}", field=field)
    scale = max(float(np.max(np.abs(ref), initial=0.0)), 1.0)
    if np.max(np.abs(mf - ref), initial=0.0) > _AGREEMENT * scale:
        raise InputError(f"differs from {source} (more than {_AGREEMENT:g} relative): give the "
                         "exact values of the same system", field=field)
    return M


def _sampling_time(T: Any) -> tuple[sp.Expr, bool]:
    """``T`` as an exact positive number (errors name ``sampling_time``)."""
    if isinstance(T, (list, tuple, np.ndarray, sp.MatrixBase)):
        raise InputError("must be a number, not a matrix", field="sampling_time")
    M, exact = to_matrix(T, "sampling_time", allow_scalar_identity=1)
    t = M[0, 0]
    if sign_of(t, "sampling_time") <= 0:
        raise InputError("must be positive", field="sampling_time")
    return t, exact


def _check_density(Qc: sp.ImmutableMatrix, exact: bool) -> sp.ImmutableMatrix:
    """Refuse an asymmetric or indefinite spectral density; return it symmetric."""
    Qf = to_float(Qc)
    if np.max(np.abs(Qf - Qf.T), initial=0.0) > sym_tolerance(Qf):
        raise InputError("must be symmetric", field="continuous.Q")
    n = Qc.shape[0]
    if exact and all(e.is_Rational for e in Qc) and Qc != Qc.T:
        raise InputError("must be symmetric", field="continuous.Q")
    # Numerically equal but not identical exact entries: the upper triangle is used for both.
    Qc = sp.ImmutableMatrix(n, n, lambda i, j: Qc[min(i, j), max(i, j)])
    if not is_definite(Qc, to_float(Qc), exact, strict=False):
        raise InputError("must be symmetric positive semidefinite", field="continuous.Q")
    return Qc


def _exact_obstacle(A: sp.ImmutableMatrix) -> str | None:
    """Why ``A`` cannot go the exact way before any symbolic work, or None."""
    if A.shape[0] > EXACT_MAX_STATES:
        return f"n = {A.shape[0]} > {EXACT_MAX_STATES} states"
    if not all(e.is_Rational for e in A):
        return "continuous.A has irrational entries"
    return None


Block = tuple[sp.Rational, sp.Matrix, sp.Matrix, sp.Matrix]
"""One generalized eigenspace: eigenvalue λ, basis V_λ (n × m), rows W_λ of V^{-1} (m × n),
nilpotent part N_λ (m × m) with A V_λ = V_λ (λ I + N_λ)."""


def _generalized_eigenspaces(A: sp.ImmutableMatrix) -> list[Block] | None:
    """The generalized eigenspaces of a rational ``A`` whose eigenvalues are rational, else None.

    Bounded work: the characteristic polynomial (degree n ≤ :data:`EXACT_MAX_STATES`) is factored
    over ℚ; every other step is rational linear algebra of size n.
    """
    n = A.shape[0]
    _, factors = sp.Matrix(A).charpoly().factor_list()
    eig: list[tuple[sp.Rational, int]] = []
    for poly, mult in factors:
        if poly.degree() != 1:
            return None
        a, b = poly.all_coeffs()
        eig.append((sp.Rational(-b, a), int(mult)))
    M = sp.Matrix(A)
    bases = []
    for lam, mult in eig:
        V = ((M - lam * sp.eye(n)) ** mult).nullspace()
        if len(V) != mult:  # cannot happen for a split characteristic polynomial
            return None
        bases.append((lam, sp.Matrix.hstack(*V)))
    W = sp.Matrix.hstack(*(V for _, V in bases)).inv()
    out: list[Block] = []
    row = 0
    for lam, V in bases:
        m = V.shape[1]
        Wl = W[row:row + m, :]
        row += m
        out.append((lam, V, Wl, Wl * M * V - lam * sp.eye(m)))
    return out


def _exponential_terms(blocks: list[Block]) -> list[tuple[sp.Rational, int, sp.Matrix]]:
    """``e^{A s} = Σ e^{λ s} s^k C_{λ,k}``: the terms (λ, k, C_{λ,k}), zero ones dropped."""
    terms = []
    for lam, V, W, N in blocks:
        P = sp.eye(N.shape[0])
        for k in range(N.shape[0]):
            if P.is_zero_matrix:
                break
            terms.append((lam, k, V * P * W / math.factorial(k)))
            P = P * N
    return terms


def _moment(nu: sp.Rational, j: int, T: sp.Expr) -> sp.Expr:
    r"""Closed form of :math:`\int_0^T s^j e^{\nu s}\, ds`.

    .. math::

        \nu = 0:\ \frac{T^{j+1}}{j+1}; \qquad
        \nu \ne 0:\ e^{\nu T} \sum_{i=0}^{j} (-1)^i \frac{j!}{(j-i)!}
            \frac{T^{j-i}}{\nu^{i+1}} - (-1)^j \frac{j!}{\nu^{j+1}}.
    """
    if nu == 0:
        return T ** (j + 1) / (j + 1)
    poly = sp.Add(*((-1) ** i * sp.Rational(math.factorial(j), math.factorial(j - i))
                    * T ** (j - i) / nu ** (i + 1) for i in range(j + 1)))
    return sp.exp(nu * T) * poly - (-1) ** j * sp.Rational(math.factorial(j)) / nu ** (j + 1)


def _exact_sample(blocks: list[Block], Qc: sp.ImmutableMatrix,
                  T: sp.Expr) -> tuple[sp.ImmutableMatrix, sp.ImmutableMatrix]:
    """Exact ``A = e^{A_c T}`` and ``Q = ∫_0^T e^{A_c s} Q_c e^{A_c' s} ds`` from the terms."""
    terms = _exponential_terms(blocks)
    n = Qc.shape[0]
    A = sp.zeros(n, n)
    for lam, k, C in terms:
        A += C * (T ** k * sp.exp(lam * T))
    # Group the integrand's terms by exponent ν = λ + μ and power j = k + l.
    grouped: dict[tuple[sp.Rational, int], sp.Matrix] = {}
    for lam, k, C in terms:
        CQ = C * Qc
        for mu, l, D in terms:
            key = (lam + mu, k + l)
            grouped[key] = grouped.get(key, sp.zeros(n, n)) + CQ * D.T
    Q = sp.zeros(n, n)
    for (nu, j), M in grouped.items():
        if not M.is_zero_matrix:
            Q += M * _moment(nu, j, T)
    Q = sp.Matrix(n, n, lambda i, j: sp.expand(Q[min(i, j), max(i, j)]))
    return sp.ImmutableMatrix(A.applyfunc(sp.expand)), sp.ImmutableMatrix(Q)


def _check_finite(a: np.ndarray, q: np.ndarray) -> None:
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(q))):
        raise InputError("e^(A_c T) overflows float64: continuous.A times the sampling time is "
                         "too large", field="sampling_time")


def _float_sample(A: sp.ImmutableMatrix, Qc: sp.ImmutableMatrix,
                  T: sp.Expr) -> tuple[np.ndarray, np.ndarray]:
    """Van Loan in float64 (SciPy's scaling-and-squaring Padé ``expm``), Q symmetrized."""
    from scipy.linalg import expm

    n = A.shape[0]
    a, q, t = to_float(A), to_float(Qc), float(T)
    with np.errstate(over="ignore", invalid="ignore"):
        F = expm(np.block([[-a, q], [np.zeros((n, n)), a.T]]) * t)
        Ad = F[n:, n:].T.copy()
        Qd = Ad @ F[:n, n:]
    Qd = np.triu(Qd) + np.triu(Qd, 1).T
    _check_finite(Ad, Qd)
    return Ad, Qd


def _ball(x: sp.Expr) -> Any:
    """An arb ball containing the exact real number ``x``."""
    import flint

    if x.is_Rational:
        return flint.arb(flint.fmpq(int(x.p), int(x.q)))
    mid = sp.Float(x.evalf(_INPUT_DIGITS + 10, strict=True), _INPUT_DIGITS + 10)
    rad = sp.Float(10, 20) ** -_INPUT_DIGITS * max(1, abs(mid))
    return flint.arb(sp.sstr(mid, full_prec=True), sp.sstr(rad))


def _certified_sample(A: sp.ImmutableMatrix, Qc: sp.ImmutableMatrix,
                      T: sp.Expr) -> tuple[np.ndarray, np.ndarray, float]:
    """Van Loan in ball arithmetic: float64 ``A``, ``Q`` and a proven entrywise error bound."""
    import flint

    n = A.shape[0]
    old = flint.ctx.prec
    try:
        for prec in CERTIFIED_PRECISIONS:
            flint.ctx.prec = prec
            t = _ball(T)
            a = [[_ball(A[i, j]) for j in range(n)] for i in range(n)]
            q = [[_ball(Qc[i, j]) for j in range(n)] for i in range(n)]
            zero = flint.arb(0)
            block = [[-a[i][j] * t for j in range(n)] + [q[i][j] * t for j in range(n)]
                     for i in range(n)]
            block += [[zero] * n + [a[j][i] * t for j in range(n)] for i in range(n)]
            F = flint.arb_mat(block).exp()
            Ad = flint.arb_mat([[F[n + j, n + i] for j in range(n)] for i in range(n)])
            F12 = flint.arb_mat([[F[i, n + j] for j in range(n)] for i in range(n)])
            Qd = Ad * F12
            Qd = flint.arb_mat([[Qd[min(i, j), max(i, j)] for j in range(n)]
                                for i in range(n)])
            values, bound, accurate = _to_floats([Ad, Qd], n)
            if accurate:
                break
    finally:
        flint.ctx.prec = old
    return values[0], values[1], bound


def _to_floats(mats: list[Any], n: int) -> tuple[list[np.ndarray], float, bool]:
    """Float64 midpoints of ball matrices, the largest |float − true| bound, and whether every
    ball is narrow to float accuracy (an error if a value overflows float64)."""
    out, bound, accurate = [], 0.0, True
    for M in mats:
        arr, rads = np.empty((n, n)), []
        for i in range(n):
            for j in range(n):
                x = M[i, j]
                f = float(x.mid()) if x.is_finite() else math.inf
                if not math.isfinite(f):
                    _check_finite(np.array([f]), np.array([f]))
                rad = float(x.rad()) + abs(float(x.mid() - _exact_arb(f)))
                arr[i, j] = f
                bound = max(bound, rad)
                rads.append(rad)
        scale = float(np.max(np.abs(arr)))
        # Accurate when every entry is known to float64 resolution relative to the matrix.
        accurate &= max(rads) <= _FLOAT_ACCURACY * scale
        out.append(arr)
    # Round the bound up: it is the sum of two floats rounded to nearest.
    return out, float(np.nextafter(bound * (1 + 2 ** -50), math.inf)), accurate


def _exact_arb(f: float) -> Any:
    """The exact arb of a float64 (binary floats are exact dyadic rationals)."""
    import flint

    return flint.arb(flint.fmpq(*float(f).as_integer_ratio()))
