"""Run an :class:`~kfcrit.link.ns3.topology.Ns3Plan` in ns-3 (the optional ``kfcrit[ns3]`` extra).

``import kfcrit`` never imports ``ns``: the wheel is imported here, inside :func:`load_ns3`, the
first time a simulation runs (it takes 20–40 s: cppyy loads every ns-3 library and parses its
headers), and the C++ driver of :mod:`kfcrit.link.ns3.cxx` is compiled once per process. A
missing wheel is one :class:`Ns3NotInstalledError` line (exit code 2).

Seeding: ``RngSeedManager::SetSeed(seed + 1)`` and ``SetRun(1)`` before any object is
created, so a run is a function of (file, options, seed) and the ns-3 version.
"""
from __future__ import annotations

import contextlib
import importlib
import os
import sys
import tempfile
from collections.abc import Iterator
from typing import Any

import numpy as np

from kfcrit.errors import ExitCode, KfcritError
from kfcrit.link.ns3.cxx import DRIVER_SOURCE
from kfcrit.link.ns3.results import Ns3Run
from kfcrit.link.ns3.topology import Ns3Plan

INSTALL_HINT = "ns-3 is not installed: pip install 'kfcrit[ns3]'"
"""The one-line error when the ``ns`` module (the ns-3 wheel) cannot be imported."""


class Ns3NotInstalledError(KfcritError):
    """The optional ns-3 backend is not installed (exit code 2, like bad usage)."""

    exit_code = ExitCode.BAD_INPUT


_STATE: dict[str, Any] = {}


@contextlib.contextmanager
def _quiet_stderr() -> Iterator[None]:
    """Hide what the C++ side prints on file descriptor 2 while ns-3 loads (cling's notes about
    static initialisers); restored afterwards, and shown if loading fails."""
    try:
        fd = sys.stderr.fileno()
    except (AttributeError, OSError, ValueError):  # a captured stderr (tests): nothing to do
        yield
        return
    sys.stderr.flush()
    saved = os.dup(fd)
    with tempfile.TemporaryFile() as sink:
        os.dup2(sink.fileno(), fd)
        failed = True
        try:
            yield
            failed = False
        finally:
            os.dup2(saved, fd)
            os.close(saved)
            if failed:
                sink.seek(0)
                sys.stderr.write(sink.read().decode(errors="replace")[-2000:])


def ns3_version() -> str:
    """The installed ns-3 wheel's version, or ``unknown``."""
    try:
        from importlib.metadata import version

        return version("ns3")
    except Exception:  # noqa: BLE001 - metadata missing: informational only
        return "unknown"


def require_ns3() -> None:
    """Raise :class:`Ns3NotInstalledError` unless the ns-3 wheel can be found (cheap check,
    nothing is loaded)."""
    import importlib.util

    try:
        found = importlib.util.find_spec("ns") is not None
    except (ImportError, ValueError):
        found = False
    if not found or sys.modules.get("ns", True) is None:
        raise Ns3NotInstalledError(INSTALL_HINT)


def load_ns3() -> Any:
    """Import ns-3 and compile the driver (once per process); return ``cppyy.gbl.kfcrit_ns3``.

    Raises
    ------
    Ns3NotInstalledError
        The ``ns`` module or cppyy is missing.
    """
    if "driver" in _STATE:
        return _STATE["driver"]
    require_ns3()
    try:
        with _quiet_stderr():
            importlib.import_module("ns").ns  # noqa: B018 - loads every ns-3 library
            cppyy = importlib.import_module("cppyy")
            cppyy.cppdef(DRIVER_SOURCE)
    except ImportError as exc:
        raise Ns3NotInstalledError(f"{INSTALL_HINT} ({str(exc)[:80]})") from None
    _STATE["cppyy"] = cppyy
    _STATE["driver"] = cppyy.gbl.kfcrit_ns3
    return _STATE["driver"]


def _vector(kind: str, values: Any) -> Any:
    std = _STATE["cppyy"].gbl.std
    out = std.vector[kind]()
    arr = np.asarray(values).ravel().tolist()
    out.reserve(len(arr))
    for v in arr:
        out.push_back(v)
    return out


def _array(vec: Any, dtype: Any) -> np.ndarray:
    n = int(vec.size())
    if n == 0:
        return np.zeros(0, dtype=dtype)
    return np.fromiter(vec, dtype=dtype, count=n)


def _config(driver: Any, plan: Ns3Plan) -> Any:
    cfg = driver.Config()
    s = plan.sensors
    cfg.sensors = len(s)
    cfg.periods = plan.periods
    cfg.period = plan.period_s
    cfg.jitter = plan.jitter_s
    cfg.xs = _vector("double", [x.position_m[0] for x in s])
    cfg.ys = _vector("double", [x.position_m[1] for x in s])
    cfg.zs = _vector("double", [x.position_m[2] for x in s])
    cfg.sinkX, cfg.sinkY, cfg.sinkZ = plan.sink_position_m
    cfg.txPowerDbm = _vector("double", [x.tx_power_dbm for x in s])
    cfg.sinkTxPowerDbm = plan.sink_tx_power_dbm
    cfg.payload = _vector("unsigned int", [x.link.packet_bytes for x in s])
    cfg.retries = _vector("unsigned int", [x.link.max_retries for x in s])
    cfg.offsetDb = _vector("double", [x.offset_db for x in s])
    lengths = [int(x.shadowing_db.size) for x in s]
    starts = np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(int)
    cfg.shadowDb = _vector("double", np.concatenate([x.shadowing_db for x in s]))
    cfg.shadowStart = _vector("unsigned int", starts)
    cfg.shadowLen = _vector("unsigned int", lengths)
    cfg.attemptSigmaDb = _vector("double", [x.attempt_sigma_db for x in s])
    cfg.exponent = plan.exponent
    cfg.refDistance = plan.reference_distance_m
    cfg.refLoss = plan.reference_loss_db
    cfg.nakagamiM = plan.nakagami_m or 0.0
    cfg.noiseDbm = plan.noise_dbm
    return cfg


def run_plan(plan: Ns3Plan) -> Ns3Run:
    """Simulate ``plan`` in ns-3 (in this process) and return the raw outcome.

    Parameters
    ----------
    plan : Ns3Plan
        From :func:`kfcrit.link.ns3.topology.build_plan`.

    Returns
    -------
    Ns3Run
        Per-period outcomes and the transmission log (see :mod:`kfcrit.link.ns3.results`).
    """
    driver = load_ns3()
    res = driver.Run(_config(driver, plan), (plan.seed % 4_294_967_294) + 1, 1)
    shape = (len(plan.sensors), plan.periods)
    return Ns3Run(
        delivered=_array(res.delivered, np.int8).reshape(shape),
        status=_array(res.status, np.int16).reshape(shape),
        tx_node=_array(res.txNode, np.int64), tx_period=_array(res.txPeriod, np.int64),
        tx_start=_array(res.txStart, float), tx_end=_array(res.txEnd, float),
        base_noise_dbm=float(res.baseNoiseDbm), noise_dbm=float(res.noiseDbm),
        duplicates=int(res.duplicates), ns3_version=ns3_version())
