"""Packet channels: the arrival process γ_t of the measurements.

A channel model is a frozen dataclass named in system files by ``channel: {model: NAME, ...}``.
Adding a model never touches the others: write a class with ``from_mapping`` and ``to_dict`` and
register its parser where system files are read (:mod:`kfcrit.io.channelfile` for the models of
this module, :mod:`kfcrit.analysis.spec` for those of higher layers such as link budgets).

Every channel exposes ``arrival_probability``: the stationary probability that a packet arrives
(exact sympy number where the input is exact), which is what the mean-stability theory compares
with the critical value p_c for i.i.d. losses.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import sympy as sp

from kfcrit.errors import InputError


def exact_probability(value: Any, field: str, *, low_open: bool = False) -> sp.Rational:
    """Read a probability exactly and check it lies in [0, 1] (or (0, 1] if ``low_open``)."""
    from kfcrit.model.exprparse import compare, number_from_text, parse_expression

    if isinstance(value, bool) or value is None:
        raise InputError("must be a number", field=field)
    if isinstance(value, sp.Basic):
        p = value
    elif isinstance(value, (int, np.integer)):
        p = sp.Integer(int(value))
    elif isinstance(value, (float, np.floating)):
        if not np.isfinite(value):
            raise InputError("must be a finite number", field=field)
        p = number_from_text(repr(float(value)), field)
    elif isinstance(value, str):
        p = parse_expression(value, field)
    else:
        raise InputError(f"must be a number, got {type(value).__name__}", field=field)
    # decided exactly for rationals, else numerically with certain digits (never bool() of a
    # sympy relational); a value provably equal to an end point becomes that end point
    if not p.is_number:
        raise InputError("must be a number", field=field)
    low = compare(p, 0, field, f"{sp.sstr(p)[:40]} - 0")
    high = compare(p, 1, field, f"{sp.sstr(p)[:40]} - 1")
    if not ((low > 0 or (low == 0 and not low_open)) and high <= 0):
        raise InputError(f"must be in {'(0' if low_open else '[0'}, 1], got {sp.sstr(p)[:60]}",
                         field=field)
    if low == 0:
        return sp.Integer(0)
    if high == 0:
        return sp.Integer(1)
    return p


def key_name(key: Any) -> str:
    """A mapping key as it appears in error messages (``<null key>`` for a YAML null key)."""
    if key is None:
        return "<null key>"
    return str(key)[:40]


def check_keys(data: dict, allowed: set[str], required: set[str], prefix: str) -> None:
    """Unknown keys and missing required keys are errors naming the field."""
    for key in data:
        if key not in allowed:
            raise InputError(f"unknown key (allowed: {', '.join(sorted(allowed))})",
                             field=f"{prefix}.{key_name(key)}")
    for key in sorted(required):
        if key not in data:
            raise InputError("is required", field=f"{prefix}.{key}")


@dataclass(frozen=True, eq=False)
class ArrivalProcess:
    """Numeric description of an arrival process γ_t, read by the simulation kernels.

    ``kind`` is one of

    * ``"iid"``: γ_t i.i.d. Bernoulli(``p``);
    * ``"markov"``: the two-state (Gilbert–Elliott) chain with P(γ_{t+1}=0 | γ_t=1) =
      ``failure_rate`` and P(γ_{t+1}=1 | γ_t=0) = ``recovery_rate``, started in its stationary
      law P(γ_0 = 1) = r/(f + r);
    * ``"sequence"``: the given 0/1 ``sequence``, read cyclically.
    """

    kind: str
    p: float = 0.0
    failure_rate: float = 0.0
    recovery_rate: float = 0.0
    sequence: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.kind not in ("iid", "markov", "sequence"):
            raise ValueError(f"unknown arrival process kind {self.kind!r}")


class Channel:
    """Base class of channel models.

    Subclasses must provide ``arrival_probability`` and ``to_dict``. The simulation reads the
    arrival process from :meth:`arrival_process`; the default is i.i.d. Bernoulli with the
    stationary ``arrival_probability``, which is right for every memoryless model (a model with
    memory overrides it).

    Attributes
    ----------
    model : str
        The model's name in a system file (``bernoulli``, ``gilbert-elliott``, ``trace``,
        ``link-budget``).
    arrival_probability : sympy.Expr
        The stationary arrival probability P(γ_t = 1).
    iid : bool
        True when losses are i.i.d. Bernoulli (the setting of the mean-stability theorems).

    Raises
    ------
    NotImplementedError
        ``arrival_probability`` and ``to_dict`` of the base class itself.

    References
    ----------
    docs/theory.md §1 (arrival indicators), §7 and §10 (Markov losses), §14 (measured traces).

    Examples
    --------
    >>> from kfcrit import Bernoulli, Channel, GilbertElliott
    >>> [isinstance(c, Channel) for c in (Bernoulli("1/2"), GilbertElliott("1/10", "1/2"))]
    [True, True]
    >>> import numpy as np
    >>> Bernoulli(1).draw_arrivals(np.random.default_rng(0), 4)
    array([ True,  True,  True,  True])
    """

    model: ClassVar[str]

    @property
    def arrival_probability(self) -> sp.Expr:  # pragma: no cover - abstract
        raise NotImplementedError

    def to_dict(self) -> dict[str, Any]:  # pragma: no cover - abstract
        raise NotImplementedError

    @property
    def iid(self) -> bool:
        """True when losses are i.i.d. Bernoulli (the setting of the mean-stability theorems)."""
        return False

    def arrival_process(self) -> ArrivalProcess:
        """The arrival process for simulation (default: i.i.d. with the stationary probability)."""
        return ArrivalProcess("iid", p=float(self.arrival_probability))

    def draw_arrivals(self, rng: np.random.Generator, steps: int, *,
                      offset: int = 0) -> np.ndarray:
        """Draw γ_0 … γ_{steps−1} (bool array) with a NumPy ``Generator``.

        A plain-NumPy reference implementation of :meth:`arrival_process` (the simulation kernels
        use their own per-path streams; this one serves users and the tests).

        Parameters
        ----------
        rng : numpy.random.Generator
            The random stream (unused for a given sequence).
        steps : int
            Number of arrivals to draw.
        offset : int
            For a given sequence: the index read first (the sequence is read cyclically).
        """
        return process_arrivals(self.arrival_process(), rng, steps, offset=offset)


def process_arrivals(process: ArrivalProcess, rng: np.random.Generator, steps: int, *,
                     offset: int = 0) -> np.ndarray:
    """Draw ``steps`` arrivals of ``process`` with NumPy (see :meth:`Channel.draw_arrivals`).

    The Markov chain is drawn as alternating geometric runs: an arrival run has length
    Geometric(f) (mean 1/f), a loss run Geometric(r) (mean 1/r); the first state is drawn from the
    stationary law r/(f + r), and the first run, by memorylessness, is again geometric.
    """
    if steps < 0:
        raise InputError("must be >= 0", field="steps")
    if process.kind == "iid":
        return rng.random(steps) < process.p
    if process.kind == "sequence":
        seq = np.asarray(process.sequence, dtype=bool)
        return seq[(offset + np.arange(steps)) % seq.size]
    f, r = process.failure_rate, process.recovery_rate
    state = bool(rng.random() < r / (f + r))
    out = np.empty(steps, dtype=bool)
    filled = 0
    while filled < steps:
        run = int(rng.geometric(f if state else r))
        out[filled:filled + run] = state
        filled += run
        state = not state
    return out


@dataclass(frozen=True)
class Bernoulli(Channel):
    """I.i.d. arrivals: P(γ_t = 1) = p.

    The setting of Sinopoli et al. (2004): the estimation error covariance is mean-stable iff
    p > p_c.

    Parameters
    ----------
    p : number or str
        The arrival probability in [0, 1] (a Python float by its shortest decimal, a string as
        an exact expression such as ``"9/10"``).

    Attributes
    ----------
    p, arrival_probability : sympy.Expr
        The exact arrival probability.
    iid : bool
        Always True.

    Raises
    ------
    kfcrit.errors.InputError
        ``p`` outside [0, 1] or not a number; the error names ``arrival_probability``.

    References
    ----------
    Sinopoli et al. (2004), Theorem 2 (the phase transition at p_c); docs/theory.md §1, §3.

    Examples
    --------
    >>> from kfcrit import Bernoulli
    >>> Bernoulli("9/10").arrival_probability
    9/10
    >>> Bernoulli(0.6).to_dict()["arrival_probability_expression"]
    '3/5'
    >>> Bernoulli(90)
    Traceback (most recent call last):
        ...
    kfcrit.errors.InputError: arrival_probability: must be in [0, 1], got 90
    """

    p: sp.Expr
    model: ClassVar[str] = "bernoulli"

    def __post_init__(self) -> None:
        # Bernoulli(90) is a mistake, not a probability: refused here, naming the field
        object.__setattr__(self, "p", exact_probability(self.p, "arrival_probability"))

    @classmethod
    def from_mapping(cls, data: dict, prefix: str, base_dir: Path | None = None) -> Bernoulli:
        check_keys(data, {"model", "arrival_probability"}, {"arrival_probability"}, prefix)
        return cls(exact_probability(data["arrival_probability"],
                                     f"{prefix}.arrival_probability"))

    @property
    def arrival_probability(self) -> sp.Expr:
        return self.p

    @property
    def iid(self) -> bool:
        return True

    def to_dict(self) -> dict[str, Any]:
        return {"model": self.model, "arrival_probability": float(self.p),
                "arrival_probability_expression": sp.sstr(self.p)}


@dataclass(frozen=True)
class GilbertElliott(Channel):
    r"""Two-state Markov losses.

    ``failure_rate`` f = P(lost next | received now), ``recovery_rate`` r = P(received next | lost
    now). Stationary arrival probability r / (f + r); loss bursts are geometric with mean 1/r.

    .. math::

        T = \begin{bmatrix} 1-r & r \\ f & 1-f \end{bmatrix}
        \quad(\text{row = now, state 0 = lost}),\qquad
        P(\text{burst} = j) = (1-r)^{j-1} r .

    Parameters
    ----------
    failure_rate, recovery_rate : number or str
        f and r in (0, 1] (strings such as ``"1/10"`` are exact).

    Attributes
    ----------
    failure_rate, recovery_rate : sympy.Expr
        f and r, exact.
    arrival_probability : sympy.Expr
        r / (f + r).
    iid : bool
        True only when f + r = 1 (the chain is then memoryless).

    Raises
    ------
    kfcrit.errors.InputError
        A rate outside (0, 1] or not a number; the error names the rate.

    References
    ----------
    docs/theory.md §7 (Markov losses, the scalar theorem (1 − r)a² < 1) and §10 (vector systems).

    Examples
    --------
    >>> from kfcrit import GilbertElliott
    >>> ge = GilbertElliott("1/10", "1/2")
    >>> ge.arrival_probability, ge.iid, ge.to_dict()["mean_burst_length"]
    (5/6, False, 2.0)
    >>> GilbertElliott(0, "1/2")
    Traceback (most recent call last):
        ...
    kfcrit.errors.InputError: failure_rate: must be in (0, 1], got 0
    """

    failure_rate: sp.Expr
    recovery_rate: sp.Expr
    model: ClassVar[str] = "gilbert-elliott"

    def __post_init__(self) -> None:
        for name in ("failure_rate", "recovery_rate"):
            object.__setattr__(self, name, exact_probability(getattr(self, name), name,
                                                             low_open=True))

    @classmethod
    def from_mapping(cls, data: dict, prefix: str,
                     base_dir: Path | None = None) -> GilbertElliott:
        check_keys(data, {"model", "failure_rate", "recovery_rate"},
                   {"failure_rate", "recovery_rate"}, prefix)
        return cls(exact_probability(data["failure_rate"], f"{prefix}.failure_rate",
                                     low_open=True),
                   exact_probability(data["recovery_rate"], f"{prefix}.recovery_rate",
                                     low_open=True))

    @property
    def arrival_probability(self) -> sp.Expr:
        return self.recovery_rate / (self.failure_rate + self.recovery_rate)

    @property
    def iid(self) -> bool:
        from kfcrit.errors import ExpressionError
        from kfcrit.model.exprparse import compare

        try:  # f + r = 1 makes the chain memoryless; decided without bool() on a relational
            return compare(self.failure_rate + self.recovery_rate, 1, "channel") == 0
        except ExpressionError:
            return False

    def to_dict(self) -> dict[str, Any]:
        return {"model": self.model, "failure_rate": float(self.failure_rate),
                "recovery_rate": float(self.recovery_rate),
                "arrival_probability": float(self.arrival_probability),
                "arrival_probability_expression": sp.sstr(self.arrival_probability),
                "mean_burst_length": float(1 / self.recovery_rate)}

    def arrival_process(self) -> ArrivalProcess:
        """The two-state Markov chain, started in its stationary law."""
        return ArrivalProcess("markov", failure_rate=float(self.failure_rate),
                              recovery_rate=float(self.recovery_rate))


@dataclass(frozen=True, eq=False)
class Trace(Channel):
    """A measured 0/1 arrival sequence.

    Read from a trace file by :func:`kfcrit.io.tracechannel.measured_trace_from_mapping` (the path
    is relative to the system file) or built in memory by :meth:`from_arrivals`. The stationary
    arrival probability is the empirical frequency of ones.

    The simulations read it cyclically, each path from its own start: the path's 64-bit stream
    key modulo the trace length (path i of ``simulate``: the key of
    ``SeedSequence(seed, spawn_key=(0, i))``; ergodic replica j: ``(2, j)``), so a path's
    arrivals depend on (seed, i) only, never on how many paths are run. All sensors of a
    network read their traces from the same start (time-aligned: their joint law is kept).

    Parameters
    ----------
    path : str
        Where the trace came from (a file name, or a label for an in-memory sequence).
    arrivals : numpy.ndarray of bool
        The sequence γ_0, γ_1, ….
    format : str
        The file format it was read from (``binary``, ``sequence-numbers`` or ``receive-log``).
    confidence : float
        The confidence c of the verdict on the fit's confidence region.
    sensor : str, optional
        The sensor column it was read for (receive logs).
    period_s : str, optional
        The sampling period a receive log was binned with.

    Attributes
    ----------
    arrival_probability : sympy.Rational
        (number of ones) / (length).
    iid : bool
        False: a trace is judged by its fitted Bernoulli or Gilbert–Elliott law.

    Raises
    ------
    kfcrit.errors.InputError
        :meth:`from_arrivals` with an empty or multi-dimensional sequence, or values other than
        0 and 1 (field ``arrivals``).

    References
    ----------
    docs/theory.md §14 (measured links: reading traces, Clopper–Pearson fits, verdict with
    confidence).

    Examples
    --------
    >>> from kfcrit import Trace
    >>> t = Trace.from_arrivals([1, 1, 0, 1])
    >>> t.arrival_probability, t.to_dict()["length"]
    (3/4, 4)
    >>> Trace.from_arrivals([0, 2])
    Traceback (most recent call last):
        ...
    kfcrit.errors.InputError: arrivals: only 0 and 1 are allowed
    """

    path: str
    arrivals: np.ndarray
    format: str = "binary"
    confidence: float = 0.95
    sensor: str | None = None
    period_s: str | None = None
    model: ClassVar[str] = "trace"

    @property
    def arrival_probability(self) -> sp.Expr:
        return sp.Rational(int(self.arrivals.sum()), int(self.arrivals.size))

    def to_dict(self) -> dict[str, Any]:
        out = {"model": self.model, "path": self.path, "length": int(self.arrivals.size),
               "arrival_probability": float(self.arrival_probability),
               "arrival_probability_expression": sp.sstr(self.arrival_probability),
               "format": self.format, "confidence": self.confidence}
        if self.sensor is not None:
            out["sensor"] = self.sensor
        if self.period_s is not None:
            out["period_s"] = self.period_s
        return out

    def arrival_process(self) -> ArrivalProcess:
        """The measured sequence, read cyclically."""
        return ArrivalProcess("sequence", p=float(self.arrival_probability),
                              sequence=self.arrivals)

    @classmethod
    def from_arrivals(cls, arrivals: Any, name: str = "<given sequence>") -> Trace:
        """A trace channel from an in-memory 0/1 sequence (anything else is an error)."""
        arr = np.asarray(arrivals)
        if arr.ndim != 1 or arr.size == 0:
            raise InputError("must be a non-empty 1-D sequence of 0 and 1", field="arrivals")
        if arr.dtype != bool and not np.isin(arr, (0, 1)).all():
            raise InputError("only 0 and 1 are allowed", field="arrivals")
        out = arr.astype(bool)
        out.setflags(write=False)
        return cls(name, out)
