"""Where a sweep's points are computed: this process, local worker processes, or a Dask cluster.

Each runner takes a :class:`PointJob` (the chunk function and the inputs every point shares) and
yields finished chunks as they complete; the driver (:func:`kfcrit.analysis.sweep.points.run_sweep`)
journals them. Results never depend on the runner (the reproducibility invariant of
:mod:`kfcrit.analysis.sweep.points`).

Invariant (no orphans): local workers leave as soon as the sweep process is gone, even after a
SIGKILL (a watchdog thread in each worker); an interrupted sweep terminates its pool at once.
Invariant (bounded waits): ``--scheduler`` is probed for the Dask handshake within
:data:`DASK_PROBE_SECONDS`, the client is created within :data:`DASK_CONNECT_SECONDS`, and a
scheduler that stops answering, or a cluster left without workers for
:data:`DASK_NO_WORKER_SECONDS`, ends the run with :class:`ClusterLostError` (exit 2, with the
resume hint).
"""
from __future__ import annotations

import math
import os
import re
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

from kfcrit.errors import ExitCode, InputError, KfcritError

_SCHEDULER = re.compile(r"^(tcp|tls)://([A-Za-z0-9.\-]{1,200}|\[[0-9A-Fa-f:.]{2,60}\]):"
                        r"(\d{1,5})$")
DASK_CONNECT_TIMEOUT = "15s"
"""The ``distributed.Client`` connection timeout (after the probe succeeded)."""
DASK_PROBE_SECONDS = 10.0
"""How long the probe of ``--scheduler`` waits for the connection and the Dask handshake."""
DASK_CONNECT_SECONDS = 30.0
"""Upper bound on creating the client (and scattering the base system), whatever the peer."""
DASK_HANDSHAKE_MAX_BYTES = 65536
"""Largest handshake accepted from a scheduler (a real one sends well under 1 KiB)."""
DASK_POLL_SECONDS = 5.0
"""How often a Dask sweep with no finished chunk checks that the scheduler is alive."""
DASK_NO_WORKER_SECONDS = 60.0
"""How long a Dask sweep waits with no worker at all before giving up (exit 2, resume hint)."""

Items = list[tuple[int, str, list[tuple[str, str]]]]
"""Points to compute: (index, key, assignments)."""


@dataclass(frozen=True)
class PointJob:
    """What every chunk of a sweep needs: the chunk function (picklable by reference, e.g.
    :func:`kfcrit.analysis.sweep.points.evaluate_chunk`) and the inputs all points share."""

    evaluate: Callable[..., list[tuple[int, str, dict[str, Any]]]]
    base_doc: dict[str, Any]
    base_dir: str
    tolerance: float
    max_states: int


CHUNK_MAX = 256
"""Most points in one chunk: large enough that sending a chunk, its results and its journal
write (one fsync) cost little per point, small enough that an interrupted sweep loses little."""


def chunks(items: Items, workers: int) -> list[Items]:
    """Items in chunks (the unit of work sent to a worker): about four per worker, at most
    :data:`CHUNK_MAX` points each."""
    size = max(1, min(CHUNK_MAX, math.ceil(len(items) / (4 * max(1, workers)))))
    return [items[i:i + size] for i in range(0, len(items), size)]


def run_serial(job: PointJob, items: Items) -> Iterator[list[tuple[int, str, dict]]]:
    """Evaluate in this process (chunk by chunk, so the journal is written as it goes)."""
    theories: dict[str, Any] = {}
    for chunk in chunks(items, 1):
        yield job.evaluate(job.base_doc, job.base_dir, job.tolerance, job.max_states, chunk,
                           theories)


def start_method() -> str:
    """How local workers start: ``fork`` on Linux when this process runs no other thread,
    else ``spawn``.

    A forked worker inherits this process's imported modules and the memo of the first point
    (:func:`run_processes`), so it starts at once instead of importing kfcrit, NumPy, SciPy
    and SymPy and computing the system's theory again (most of a spawned worker's start-up).
    Forking is safe only without other threads (a lock one of them holds would stay held in
    the child for ever), and macOS system libraries do not support it: there, and whenever
    another thread runs (a progress bar, a Dask client, a notebook's kernel threads),
    workers are spawned as fresh interpreters.
    """
    import multiprocessing
    import sys
    import threading

    if (sys.platform.startswith("linux") and threading.active_count() == 1
            and "fork" in multiprocessing.get_all_start_methods()):
        return "fork"
    return "spawn"


def run_processes(job: PointJob, items: Items, workers: int,
                  ) -> Iterator[list[tuple[int, str, dict]]]:
    """Evaluate on a local process pool, started before this returns (:func:`start_method`).

    Forked workers: the first point is evaluated here first (its batch is yielded first), so
    the modules it imports and the memo it fills (parsed system, theory sections) are
    inherited by every worker. The pool is started before this function returns (so that it
    forks before the caller starts a progress bar's thread); closing the returned iterator,
    started or not, terminates the pool.
    """
    method = start_method()
    memo: dict[str, Any] = {}
    first: list[tuple[int, str, dict]] = []
    if method == "fork" and items:
        first = job.evaluate(job.base_doc, job.base_dir, job.tolerance, job.max_states,
                             items[:1], memo)
        items = items[1:]
    batches = _pool_batches(job, items, workers, method, memo, first)
    next(batches)  # runs up to the started pool
    return batches


def _pool_batches(job: PointJob, items: Items, workers: int, method: str,
                  memo: dict[str, Any], first: list[tuple[int, str, dict]],
                  ) -> Iterator[list[tuple[int, str, dict]]]:
    """Start the pool, yield once (nothing), then ``first`` and the workers' finished chunks."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor, as_completed

    ctx = multiprocessing.get_context(method)
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_worker_init,
                               initargs=(os.getpid(), memo if method == "fork" else None))
    try:
        futures = [pool.submit(evaluate_in_worker, job.evaluate, job.base_doc, job.base_dir,
                               job.tolerance, job.max_states, chunk)
                   for chunk in chunks(items, workers)]
        yield []  # the pool runs: the caller gets the iterator now
        if first:
            yield first
        for fut in as_completed(futures):
            yield fut.result()
    except BaseException:  # interrupted (or closed early): stop the workers before leaving
        terminate_pool(pool)
        raise
    pool.shutdown(wait=True)


WORKER_MEMO_MAX = 256
"""Most memoised entries (theory sections, parsed systems) a worker process keeps; beyond, the
memo starts afresh (memory stays bounded when every point changes the system)."""
_worker_memo: dict[str, Any] = {}
"""The memo of this worker process (a local worker or a Dask worker): chunks evaluated by one
process share the theory computed once per system. Results never depend on it (the
reproducibility invariant); Dask worker threads may share it (each entry is a pure function
of its key, so two threads that compute one entry store the same value)."""


def evaluate_in_worker(evaluate: Callable[..., list], base_doc: dict[str, Any], base_dir: str,
                       tolerance: float, max_states: int, chunk: Items) -> list:
    """Run ``evaluate`` on a chunk with this process's memo (sent by reference to workers)."""
    if len(_worker_memo) > WORKER_MEMO_MAX:
        _worker_memo.clear()
    return evaluate(base_doc, base_dir, tolerance, max_states, chunk, _worker_memo)


PARENT_POLL_SECONDS = 0.5
"""How often a worker process checks that the sweep that started it is still alive."""


def _worker_init(parent_pid: int | None = None, memo: dict[str, Any] | None = None) -> None:
    """Set up a local worker process.

    * SIGINT is ignored: a Ctrl-C reaches the whole process group, and the parent alone
      decides (it terminates the workers); a worker must not die mid-chunk with a traceback.
      SIGTERM takes its default action: a forked worker would otherwise keep the sweep's own
      handler (SIGTERM → ``KeyboardInterrupt``), and the parent's ``terminate`` must end it at
      once, without a traceback.
    * The worker leaves (``os._exit``) as soon as its parent is gone: a sweep killed with
      SIGKILL runs no cleanup, and its workers (and, once they are gone, multiprocessing's
      resource tracker, which ends when the last holder of its pipe exits) must not keep
      computing as orphans. A daemon thread compares ``os.getppid()`` with the sweep's pid
      every :data:`PARENT_POLL_SECONDS`; it works on every POSIX system and, unlike
      ``PR_SET_PDEATHSIG``, does not depend on which thread of the parent spawned the worker.
    * Warnings from NumPy/SciPy are not printed: each point's record carries kfcrit's own
      warnings, and dozens of repeated library lines from every worker would drown the
      sweep's one summary line.
    * ``memo``: the memo of the first point (forked workers; :func:`run_processes`) becomes
      this worker's memo.
    """
    import signal
    import threading
    import warnings

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    warnings.simplefilter("ignore")
    if memo:
        _worker_memo.update(memo)
    if parent_pid is None:
        return
    if os.getppid() != parent_pid:  # the parent died before this worker got here
        os._exit(int(ExitCode.INTERRUPTED))

    def _watch() -> None:
        import time

        while True:
            time.sleep(PARENT_POLL_SECONDS)
            if os.getppid() != parent_pid:
                os._exit(int(ExitCode.INTERRUPTED))

    threading.Thread(target=_watch, name="kfcrit-parent-watchdog", daemon=True).start()


def terminate_pool(pool: Any, timeout: float = 5.0) -> None:
    """Shut a ``ProcessPoolExecutor`` down *now*: cancel queued chunks, terminate the worker
    processes (SIGTERM, then SIGKILL after ``timeout``), join them and the executor's manager
    thread, and release the pool's queues.

    The interrupted CLI leaves with ``os._exit`` (no interpreter shutdown, no atexit hooks), so
    without this the workers would finish their chunk as orphans. Releasing the queues (their
    semaphores unregister from multiprocessing's resource tracker) lets the tracker end quietly
    as soon as this process exits, with nothing "leaked" to report.
    """
    import gc

    procs = list((getattr(pool, "_processes", None) or {}).values())
    for proc in procs:
        try:
            proc.terminate()
        except (OSError, ValueError, AttributeError):
            pass
    for proc in procs:
        try:
            proc.join(timeout)
            if proc.is_alive():
                proc.kill()
                proc.join(timeout)
        except (OSError, ValueError, AssertionError, AttributeError):
            pass
    # The manager thread sees the dead workers, fails the futures and closes the queues. The
    # shutdown runs in a daemon thread joined with a timeout: the interrupt may have landed
    # while this thread held one of the executor's (non-reentrant) locks, and a blocking
    # shutdown here would then wait for ever; the process leaves with os._exit regardless.
    import threading

    def _shutdown(executor: Any) -> None:
        try:
            executor.shutdown(wait=True, cancel_futures=True)
        except Exception:  # noqa: BLE001 - a broken pool must not mask the interrupt
            pass

    closer = threading.Thread(target=_shutdown, args=(pool,), name="kfcrit-pool-shutdown",
                              daemon=True)
    closer.start()
    closer.join(timeout)
    del pool
    gc.collect()


def check_scheduler(scheduler: str) -> None:
    """The ``--scheduler`` address must be ``tcp://HOST:PORT`` (or ``tls://``), port ≤ 65535."""
    m = _SCHEDULER.match(scheduler)
    if not m or not 0 < int(m.group(3)) < 65536:
        raise InputError(f"must look like tcp://HOST:PORT (or tls://), got "
                         f"{scheduler[:60]!r}", field="--scheduler")


def _scheduler_error(scheduler: str, reason: str) -> InputError:
    return InputError(f"cannot connect to the Dask scheduler at {scheduler[:60]}: {reason}",
                      field="--scheduler")


def _read_exactly(sock: Any, count: int, deadline: float) -> bytes:
    """``count`` bytes from ``sock`` before the monotonic ``deadline`` (socket.timeout else)."""
    import time

    chunks: list[bytes] = []
    got = 0
    while got < count:
        left = deadline - time.monotonic()
        if left <= 0:
            raise TimeoutError
        sock.settimeout(left)
        block = sock.recv(min(65536, count - got))
        if not block:
            raise ConnectionResetError
        chunks.append(block)
        got += len(block)
    return b"".join(chunks)


def probe_scheduler(scheduler: str, timeout: float | None = None) -> None:
    """Check, within ``timeout`` seconds in all (default :data:`DASK_PROBE_SECONDS`), that
    ``scheduler`` speaks Dask's protocol.

    A Dask scheduler opens every connection with its handshake: an 8-byte length
    :math:`L \\le` :data:`DASK_HANDSHAKE_MAX_BYTES`, then :math:`L` bytes holding a frame count
    :math:`k`, :math:`k` frame lengths and a msgpack mapping with a ``python`` entry. A port
    that accepts and stays silent, closes, or answers anything else is refused here with one
    line naming the scheduler, before ``distributed`` would wait without bound or allocate
    whatever length a stranger announces. ``tls://`` addresses are only connected to (the
    handshake is encrypted); the client's own timeout bounds the rest.
    """
    import socket
    import struct
    import time

    timeout = DASK_PROBE_SECONDS if timeout is None else timeout
    m = _SCHEDULER.match(scheduler)
    assert m is not None  # check_scheduler ran first
    host, port = m.group(2).strip("[]"), int(m.group(3))
    deadline = time.monotonic() + timeout
    try:
        sock = socket.create_connection((host, port), timeout=timeout)
    except TimeoutError:
        raise _scheduler_error(scheduler, f"no connection within {timeout:g} s") from None
    except OSError as exc:
        raise _scheduler_error(scheduler, exc.strerror or type(exc).__name__) from None
    try:
        if m.group(1) == "tls":
            return
        try:
            (length,) = struct.unpack("=Q", _read_exactly(sock, 8, deadline))
            if not 16 <= length <= DASK_HANDSHAKE_MAX_BYTES:
                raise ValueError
            body = _read_exactly(sock, length, deadline)
            (frames,) = struct.unpack_from("=Q", body)
            if not 1 <= frames <= 16 or 8 + 8 * frames > length:
                raise ValueError
            sizes = struct.unpack_from(f"={frames}Q", body, 8)
            if 8 + 8 * frames + sum(sizes) != length:
                raise ValueError
            _check_handshake(body[8 + 8 * frames:8 + 8 * frames + sizes[0]])
        except TimeoutError:
            raise _scheduler_error(scheduler, f"the port accepted the connection but sent no "
                                   f"Dask handshake within {timeout:g} s") from None
        except (ValueError, struct.error):
            raise _scheduler_error(scheduler, "the port does not speak the Dask protocol "
                                   "(unexpected handshake)") from None
        except OSError as exc:
            raise _scheduler_error(scheduler, f"the connection was closed during the handshake "
                                   f"({exc.strerror or type(exc).__name__})") from None
    finally:
        sock.close()


def _check_handshake(frame: bytes) -> None:
    """The first handshake frame must be a msgpack mapping with a ``python`` entry."""
    try:
        import msgpack
    except ImportError:  # distributed depends on msgpack; without it the length checks stand
        return
    try:
        info = msgpack.unpackb(frame, raw=False, strict_map_key=False)
    except Exception:  # noqa: BLE001 - msgpack raises several unrelated types on garbage
        raise ValueError from None
    if not (isinstance(info, dict) and "python" in info):
        raise ValueError


def connect_dask(scheduler: str) -> Any:
    """A ``distributed.Client`` on an existing scheduler (every failure is one InputError).

    The address is probed first (:func:`probe_scheduler`); the client is then created in a
    daemon thread that is given :data:`DASK_CONNECT_SECONDS` in all, so no scheduler can make
    the sweep wait longer than that before its one-line error.
    """
    import threading

    check_scheduler(scheduler)
    try:
        from distributed import Client
    except ImportError:
        raise InputError("needs dask[distributed] (pip install 'kfcrit[dask]')",
                         field="--scheduler") from None
    probe_scheduler(scheduler)
    box: dict[str, Any] = {}

    def _connect() -> None:
        try:
            box["client"] = Client(scheduler, timeout=DASK_CONNECT_TIMEOUT,
                                   set_as_default=False)
        except BaseException as exc:  # noqa: BLE001 - reported in the caller's thread
            box["error"] = exc

    thread = threading.Thread(target=_connect, name="kfcrit-dask-connect", daemon=True)
    thread.start()
    thread.join(DASK_CONNECT_SECONDS)
    if thread.is_alive():
        raise _scheduler_error(scheduler, f"no answer within {DASK_CONNECT_SECONDS:g} s")
    if "error" in box:
        exc = box["error"]
        if isinstance(exc, MemoryError):
            raise _scheduler_error(scheduler, "the port does not speak the Dask protocol") \
                from None
        if isinstance(exc, (OSError, TimeoutError, ValueError, EOFError, TypeError)):
            raise _scheduler_error(scheduler, f"{type(exc).__name__} after at most "
                                   f"{DASK_CONNECT_TIMEOUT}") from None
        raise exc
    return box["client"]


class ClusterLostError(KfcritError):
    """The Dask scheduler or all of its workers went away during a sweep (exit code 2).

    The message names the scheduler and says how to resume: the finished points are in the
    journal, and running the same command again computes only the missing ones.
    """

    exit_code = ExitCode.BAD_INPUT


def _lost(scheduler: str, what: str) -> ClusterLostError:
    return ClusterLostError(f"{what} during the sweep; the finished points are kept in the "
                            "journal (run the same command again to resume)",
                            field=f"--scheduler {scheduler[:60]}")


def _live_workers(client: Any) -> int:
    """Workers the scheduler knows now (an ``OSError`` or ``TimeoutError`` if it is gone)."""
    return len(client.sync(client.scheduler.identity, n_workers=-1,
                           callback_timeout=DASK_POLL_SECONDS * 4).get("workers", {}))


def _lost_types() -> tuple[type[BaseException], ...]:
    """Exceptions that mean the cluster, not the computation, failed."""
    import asyncio
    import concurrent.futures

    types: tuple[type[BaseException], ...] = (OSError, TimeoutError, asyncio.CancelledError,
                                              concurrent.futures.CancelledError)
    try:
        from distributed import KilledWorker
        types += (KilledWorker,)
    except ImportError:
        pass
    return types


class ClusterHealth:
    """Asks the scheduler for its workers every :data:`DASK_POLL_SECONDS` while nothing
    finishes; raises :class:`ClusterLostError` when it does not answer or has had no worker for
    :data:`DASK_NO_WORKER_SECONDS`."""

    def __init__(self, client: Any, scheduler: str) -> None:
        import time

        self.client, self.scheduler = client, scheduler
        self.checked = time.monotonic()
        self.idle_since: float | None = None

    def progress(self) -> None:
        import time

        self.checked = time.monotonic()
        self.idle_since = None

    def check(self, *, force: bool = False) -> int:
        import time

        now = time.monotonic()
        if not force and now - self.checked < DASK_POLL_SECONDS:
            return -1
        self.checked = now
        try:
            alive = _live_workers(self.client)
        except _lost_types():
            raise _lost(self.scheduler, "the scheduler stopped answering") from None
        if alive:
            self.idle_since = None
        elif self.idle_since is None:
            self.idle_since = now
        elif now - self.idle_since >= DASK_NO_WORKER_SECONDS:
            raise _lost(self.scheduler, f"no worker was left for {DASK_NO_WORKER_SECONDS:g} s")
        return alive


def run_dask(job: PointJob, items: Items, client: Any, scheduler: str = "the scheduler",
             ) -> Iterator[list[tuple[int, str, dict]]]:
    """Evaluate on an existing Dask distributed cluster through ``client`` (closed at the end).

    Finished chunks are yielded as they complete. While no chunk finishes, the scheduler is
    asked every :data:`DASK_POLL_SECONDS` how many workers it has: a scheduler that does not
    answer, or no worker for :data:`DASK_NO_WORKER_SECONDS` (also before the first chunk is
    sent), ends the run with :class:`ClusterLostError` (exit 2, resume hint), as do chunks
    lost with their workers.
    """
    import time

    from distributed import as_completed

    lost_types = _lost_types()
    health = ClusterHealth(client, scheduler)
    futures: list[Any] = []
    try:
        try:
            workers = health.check(force=True)
            while workers == 0:
                time.sleep(min(1.0, DASK_POLL_SECONDS))
                workers = health.check(force=True)
            base = client.scatter([job.base_doc], broadcast=True,
                                  timeout=DASK_CONNECT_SECONDS)[0]
        except lost_types:
            raise _lost(scheduler, "the scheduler stopped answering") from None
        # through evaluate_in_worker: the chunks one worker evaluates share its memo, so the
        # theory of the system is computed once per worker, not once per chunk
        futures = [client.submit(evaluate_in_worker, job.evaluate, base, job.base_dir,
                                 job.tolerance, job.max_states, chunk, pure=False)
                   for chunk in chunks(items, workers)]
        # the client is not the default one (set_as_default=False): name its loop
        pending = as_completed(futures, loop=client.loop)
        while not pending.is_empty():
            batch = pending.next_batch(block=False)
            if not batch:
                health.check()
                time.sleep(0.05)
                continue
            health.progress()
            for fut in batch:
                try:
                    yield fut.result()
                except lost_types as exc:
                    raise _lost(scheduler, f"workers or the scheduler were lost "
                                f"({type(exc).__name__})") from None
    except BaseException:
        try:
            client.cancel(futures)
        except Exception:  # noqa: BLE001 - the scheduler may be gone already
            pass
        raise
    finally:
        try:
            client.close(timeout=DASK_POLL_SECONDS)
        except Exception:  # noqa: BLE001 - closing a client whose scheduler is gone
            pass
