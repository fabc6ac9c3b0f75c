"""Bounds on the exact path's work: decided before any algebra starts, and enforced while it runs.

Two guards keep the exact eigen-structure analysis within documented time and memory:

* **Degree estimate from the expression trees** (:func:`field_degree_bound`), before any number
  field is built. Every entry is a rational expression in *radicals* b^{p/q} and in cos, sin, tan
  of rational multiples of π. Adjoining the radicals innermost first, each multiplies the degree
  by at most q (b already lies in the field), and cos(aπ/b), sin(aπ/b), tan(aπ/b) lie in the
  cyclotomic field Q(ζ_L), L = lcm(2b, 4), of degree φ(L):

  .. math:: [K:\\mathbb{Q}] \\le \\varphi(L)\\;\\cdot |H| \\cdot \\prod_{\\text{other radicals}} q .

  For radicals of positive rationals the factor |H| is the order of the group they generate
  modulo Q* — for real radicals this *is* the degree (Besicovitch; Mordell; Siegel, 1972), and
  reading it from a coprime base of the bases (instead of primes) gives an upper bound: H is the
  subgroup of (Q/Z)^m spanned by the exponent vectors e_i/q_i, of order
  ∏_j N / gcd(d_j, N) with N = lcm q_i and d_j the invariant factors of the integer matrix
  (N/q_i)·e_i. ``sqrt(2), sqrt(3), sqrt(6)`` give 4 (not 8); 30 nested square roots of 2 give
  2^30, and the exact path is refused at once (limit ``EXACT_MAX_FIELD_DEGREE``).
* **A hard budget** (:func:`run_bounded`) for what the estimate cannot foresee: the computation
  runs in a forked child process with an address-space limit (``EXACT_MEMORY_BUDGET`` above the
  parent's current size) and a wall-clock deadline; on expiry the child is killed. sympy's inner
  loops (and GMP, which aborts on a failed allocation) cannot be interrupted in-process by a
  signal handler or a cooperative check, a killed child always stops. The result comes back
  pickled through a pipe (measured overhead: a few milliseconds per call), with the names of
  the modules the child imported: the parent imports them too (:func:`adopt_imports`), so that
  sympy's lazy imports are paid once per process, not once per child.

Everything the guards stop becomes a :class:`~kfcrit.theory.structure.records.Fallback` whose
message names the limit; the caller falls back to certified enclosures or to the numeric path and
records the reason (``structure.path_reason``).
"""
from __future__ import annotations

import importlib
import math
import os
import pickle
import resource
import select
import signal
import sys
import time
import traceback
from collections.abc import Callable, Iterable
from typing import Any

import sympy as sp

from kfcrit.theory.structure.records import EXACT_MAX_FIELD_DEGREE, Fallback

EXACT_MEMORY_BUDGET = 512 * 2**20
"""Bytes of address space an exact computation may add to the process (forked child)."""
MIN_CHILD_SECONDS = 1.0
"""Least wall-clock time given to a bounded computation (even when the budget is spent)."""
_TOTIENT_EXACT_BELOW = 10**6
"""φ(L) is computed (by factoring L) only below this; above, L itself bounds φ(L)."""
_MAX_GROUP_RADICALS = 64
"""Most radicals of rationals whose group order is computed (beyond: the product of the q)."""


# --------------------------------------------------------------------------- degree estimate

def _phi_bound(L: int) -> int:
    """φ(L), or the upper bound L when factoring L could be slow."""
    return int(sp.totient(L)) if L < _TOTIENT_EXACT_BELOW else L


def _coprime_base(numbers: Iterable[int]) -> list[int]:
    """Pairwise coprime integers > 1 such that every given number is a product of their powers
    (repeated gcd splitting; no factorisation)."""
    base: list[int] = []
    for x in numbers:
        pending = [abs(int(x))]
        while pending:
            y = pending.pop()
            if y <= 1:
                continue
            for i, c in enumerate(base):
                g = math.gcd(y, c)
                if g > 1:
                    base.pop(i)
                    pending.extend((c // g, g, y // g))
                    break
            else:
                base.append(y)
    return base


def _valuation(x: int, c: int) -> int:
    k = 0
    while x % c == 0:
        x //= c
        k += 1
    return k


def rational_radical_degree(radicals: dict[sp.Rational, int]) -> int:
    """Upper bound on [Q(b^{1/q} : b ∈ radicals):Q] for positive rationals b (``radicals`` maps b
    to q): the order of the group the radicals generate modulo Q* (see the module docstring)."""
    if not radicals:
        return 1
    plain = math.prod(radicals.values())
    if len(radicals) > _MAX_GROUP_RADICALS:
        return plain
    from sympy.polys.matrices import DomainMatrix
    from sympy.polys.matrices.normalforms import invariant_factors

    items = list(radicals.items())
    base = _coprime_base([int(b.p) for b, _ in items] + [int(b.q) for b, _ in items])
    if not base:
        return 1
    N = math.lcm(*(q for _, q in items))
    rows = [[(_valuation(int(b.p), c) - _valuation(int(b.q), c)) * (N // q) for b, q in items]
            for c in base]
    factors = list(invariant_factors(DomainMatrix(
        [[sp.ZZ(v) for v in row] for row in rows], (len(base), len(items)), sp.ZZ)))
    factors += [0] * (len(base) - len(factors))
    order = 1
    for d in factors:
        order *= N // math.gcd(int(d), N)
    return min(order, plain)


def field_degree_bound(entries: Iterable[sp.Expr]) -> int | None:
    """An upper bound on the degree over Q of the field generated by ``entries``, read from
    their expression trees without building any number field (see the module docstring).

    Returns None when an entry is not visibly algebraic (π, e, exp, log, cos of a non-rational
    multiple of π, ...): the exact algebra does not apply to it.
    """
    rational_radicals: dict[sp.Rational, int] = {}
    other_radicals: dict[sp.Expr, int] = {}
    L = 1
    seen: set[sp.Expr] = set()
    stack = [sp.sympify(e) for e in entries]
    while stack:
        e = stack.pop()
        if e.is_Rational or e in seen:
            continue
        seen.add(e)
        if e.is_Add or e.is_Mul:
            stack.extend(e.args)
        elif e.is_Pow:
            ex = e.exp
            if not ex.is_Rational:
                return None
            if not ex.is_Integer:
                b = e.base
                table = rational_radicals if (b.is_Rational and b > 0) else other_radicals
                table[b] = math.lcm(table.get(b, 1), int(ex.q))
            stack.append(e.base)
        elif isinstance(e, (sp.cos, sp.sin, sp.tan)):
            r = e.args[0] / sp.pi
            if not r.is_Rational:
                return None
            L = math.lcm(L, 2 * int(r.q) if isinstance(e, sp.cos) else math.lcm(2 * int(r.q), 4))
        elif e is sp.I:
            L = math.lcm(L, 4)
        else:
            return None
    return (_phi_bound(L) * rational_radical_degree(rational_radicals)
            * math.prod(other_radicals.values()))


def degree_text(d: int) -> str:
    """A degree for a message: exact up to 12 digits, else ``≈ 1.07e+09``-style."""
    return str(d) if d < 10**12 else f"≈ {float(d):.3g}" if d < 10**300 else "> 1e300"


def exact_refusal(entries: Iterable[sp.Expr], what: str) -> str | None:
    """Why the exact algebra must not start on ``entries`` (the entries of ``what``), or None.

    Refused: entries that are not visibly algebraic, and entries whose field degree estimate
    (:func:`field_degree_bound`) exceeds ``EXACT_MAX_FIELD_DEGREE``.
    """
    entries = list(entries)
    if all(sp.sympify(e).is_Rational for e in entries):
        return None
    d = field_degree_bound(entries)
    if d is None:
        return (f"the entries of {what} are not all algebraic numbers (π, e, exp, log or a "
                "trigonometric function of a non-rational multiple of π)")
    if d > EXACT_MAX_FIELD_DEGREE:
        return (f"the entries of {what} may generate a number field of degree up to "
                f"{degree_text(d)} over Q (estimated from the expressions before any algebra; "
                f"the exact path's limit is {EXACT_MAX_FIELD_DEGREE})")
    return None


# --------------------------------------------------------------------------- hard budget

def _address_space() -> int:
    """Current virtual size of this process in bytes (0 when unknown)."""
    try:
        with open("/proc/self/statm") as fh:
            return int(fh.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        return 0


def _limit_child(memory: int, seconds: float) -> None:
    """Limits of the forked child: address space (current + ``memory``, never above the
    inherited limit) and CPU time (so that an orphaned child stops by itself)."""
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    current = _address_space()
    if current:
        want = current + memory
        if soft != resource.RLIM_INFINITY:
            want = min(want, soft)
        if hard != resource.RLIM_INFINITY:
            want = min(want, hard)
        resource.setrlimit(resource.RLIMIT_AS, (want, hard))
    cpu_soft, cpu_hard = resource.getrlimit(resource.RLIMIT_CPU)
    used = resource.getrusage(resource.RUSAGE_SELF)
    limit = int(used.ru_utime + used.ru_stime + seconds) + 2
    if cpu_hard == resource.RLIM_INFINITY or limit < cpu_hard:
        resource.setrlimit(resource.RLIMIT_CPU, (limit, cpu_hard))


def _child(write_fd: int, fn: Callable[..., Any], args: tuple[Any, ...], memory: int,
           seconds: float, what: str) -> None:
    """Body of the forked child: run ``fn(*args)``, send the pickled outcome, never return."""
    try:
        signal.signal(signal.SIGINT, signal.SIG_DFL)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        _limit_child(memory, seconds)
        before = set(sys.modules)
        try:
            outcome: tuple[str, Any] = ("ok", fn(*args))
        except MemoryError:
            outcome = ("exc", Fallback(f"{what} exceeded its memory budget of "
                                       f"{memory // 2**20} MB"))
        except BaseException as exc:  # noqa: BLE001 - every outcome goes back to the parent
            outcome = ("exc", exc, traceback.format_exc())
        imported = sorted(set(sys.modules) - before)
        try:
            data = pickle.dumps((imported, outcome), protocol=pickle.HIGHEST_PROTOCOL)
        except Exception as exc:  # noqa: BLE001 - an unpicklable outcome is reported as such
            data = pickle.dumps((imported, ("exc", Fallback(f"{what}: result could not be "
                                                            f"returned ({type(exc).__name__})"))))
        view = memoryview(data)
        while view:
            view = view[os.write(write_fd, view):]
    finally:
        os._exit(0)


def _collect(read_fd: int, deadline: float) -> bytes | None:
    """Read the child's message until EOF; None when the deadline passes first."""
    chunks = []
    while True:
        left = deadline - time.monotonic()
        if left <= 0:
            return None
        ready, _, _ = select.select([read_fd], [], [], left)
        if not ready:
            return None
        chunk = os.read(read_fd, 1 << 16)
        if not chunk:
            return b"".join(chunks)
        chunks.append(chunk)


def _reap(pid: int, kill: bool) -> int:
    """Wait for the child (killing it first if asked); its wait status."""
    if kill:
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    while True:
        try:
            return os.waitpid(pid, 0)[1]
        except ChildProcessError:
            return 0
        except InterruptedError:  # pragma: no cover - PEP 475 retries already
            continue


def adopt_imports(names: Iterable[str]) -> list[str]:
    """Import here the modules a bounded child imported, of packages this process has already
    imported (sympy imports many of its modules lazily, on first use: in a child that import is
    lost with it, and every later child would pay it again, ~0.1 s each). Returns the names
    imported; a module that fails to import is left alone (the child managed without it here).
    """
    done = []
    for name in names:
        if name in sys.modules or name.partition(".")[0] not in sys.modules:
            continue
        try:
            importlib.import_module(name)
        except Exception:  # noqa: BLE001,S112 - a warm-up only: the child imports it again
            continue
        done.append(name)
    return done


def run_bounded(fn: Callable[..., Any], *args: Any, seconds: float, what: str,
                memory: int = EXACT_MEMORY_BUDGET) -> Any:
    """``fn(*args)`` in a forked child limited to ``seconds`` of wall-clock time and ``memory``
    bytes of additional address space; its result, or its exception re-raised here.

    Budget overrun, a failed allocation or a crashed child raise
    :class:`~kfcrit.theory.structure.records.Fallback` naming ``what`` and the limit. Without
    ``os.fork`` (non-POSIX systems) ``fn`` runs in this process under its own cooperative
    checks only.
    """
    if not hasattr(os, "fork"):  # pragma: no cover - POSIX in CI
        return fn(*args)
    seconds = max(float(seconds), MIN_CHILD_SECONDS)
    read_fd, write_fd = os.pipe()
    try:
        pid = os.fork()
    except OSError as exc:
        os.close(read_fd)
        os.close(write_fd)
        raise Fallback(f"{what} could not start in a bounded process ({exc.strerror})") from None
    if pid == 0:  # pragma: no cover - the child's coverage is not collected
        os.close(read_fd)
        _child(write_fd, fn, args, memory, seconds, what)
    os.close(write_fd)
    finished = False
    try:
        data = _collect(read_fd, time.monotonic() + seconds)
        finished = data is not None
    finally:
        os.close(read_fd)
        status = _reap(pid, kill=not finished)
    if data is None:
        raise Fallback(f"{what} exceeded its {seconds:.3g} s budget (stopped)")
    if not data:
        why = (f"signal {signal.Signals(os.WTERMSIG(status)).name}" if os.WIFSIGNALED(status)
               else f"exit status {os.waitstatus_to_exitcode(status)}")
        raise Fallback(f"{what} stopped ({why}; memory budget {memory // 2**20} MB)")
    try:
        imported, outcome = pickle.loads(data)  # noqa: S301 - bytes from our own forked child
    except Exception as exc:  # noqa: BLE001 - e.g. an exception class that does not unpickle
        raise Fallback(f"{what}: result could not be read ({type(exc).__name__})") from None
    adopt_imports(imported)
    if outcome[0] == "ok":
        return outcome[1]
    exc = outcome[1]
    if len(outcome) > 2 and hasattr(exc, "add_note"):
        exc.add_note(f"in the bounded child process:\n{outcome[2]}")
    raise exc
