"""The ``loop:`` section of a system file: a closed loop over a sensing and an actuation link.

theory §12. The sensing link is the file's ``channel``; the ``loop:`` mapping adds the input
matrix ``B`` (exact entries, like ``A``), the cost weights ``W`` (n × n, PSD) and ``U``
(m_u × m_u, PD), the actuation link ``channel`` (any channel model, link budgets included),
``acknowledged`` (TCP-like ``true`` / UDP-like ``false``), ``on_loss`` (``zero`` / ``hold``) and
optionally a fixed design: ``estimator_gain`` K (n × m, filter form) and ``controller_gain``
L (m_u × n, u = L x̂_{t|t}); both or neither.

Every error names its field (``loop.B: must have 2 rows …``). This module never imports the
system-file reader (which hooks it in): the caller passes the exact-number converter and the
channel parser of its layer.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import sympy as sp

from kfcrit.errors import InputError
from kfcrit.model.channels import Channel, check_keys
from kfcrit.model.system import is_definite, matrix_and_float

LOOP_KEYS = {"B", "W", "U", "channel", "acknowledged", "on_loss", "estimator_gain",
             "controller_gain"}
LOOP_REQUIRED = {"B", "channel"}
ON_LOSS_POLICIES = ("zero", "hold")


@dataclass(frozen=True, eq=False)
class LoopSpec:
    """A closed loop of a system file (theory §12).

    Attributes
    ----------
    B : sympy.ImmutableMatrix
        Input matrix (n × m_u), exact.
    W, U : sympy.ImmutableMatrix
        State weight (n × n, PSD) and input weight (m_u × m_u, PD) of
        J = lim (1/T) E Σ (x'Wx + a'Ua).
    channel : Channel
        The actuation link (controller → actuator).
    acknowledged : bool
        TCP-like (the controller learns whether its packet arrived) or UDP-like.
    on_loss : str
        ``"zero"`` (a lost packet applies u = 0) or ``"hold"`` (the last applied input).
    estimator_gain, controller_gain : sympy.ImmutableMatrix or None
        A fixed design K (n × m), L (m_u × n); None for the default design.
    """

    B: sp.ImmutableMatrix
    W: sp.ImmutableMatrix
    U: sp.ImmutableMatrix
    channel: Channel
    acknowledged: bool = True
    on_loss: str = "zero"
    estimator_gain: sp.ImmutableMatrix | None = None
    controller_gain: sp.ImmutableMatrix | None = None

    @property
    def inputs(self) -> int:
        """m_u, the number of inputs (columns of B)."""
        return int(self.B.shape[1])

    @property
    def fixed(self) -> bool:
        """Whether the file gives a fixed design (K and L)."""
        return self.estimator_gain is not None

    def to_dict(self) -> dict[str, Any]:
        """The loop as the record's ``system.loop`` shows it (exact entries as text)."""
        def text(M: sp.MatrixBase | None) -> list[list[str]] | None:
            return None if M is None else [[sp.sstr(v) for v in row] for row in M.tolist()]

        return {"B": text(self.B), "W": text(self.W), "U": text(self.U),
                "channel": self.channel.to_dict(), "acknowledged": self.acknowledged,
                "on_loss": self.on_loss, "estimator_gain": text(self.estimator_gain),
                "controller_gain": text(self.controller_gain)}


def _matrix(raw: Any, name: str, shape: tuple[int, int], convert: Callable[[Any, str], Any],
            *, scalar_identity: bool = False) -> tuple[sp.ImmutableMatrix, bool, np.ndarray]:
    """An exact matrix of the given shape, or an error naming ``name``."""
    if raw is None:
        raise InputError("is required", field=name)
    if isinstance(raw, bool) or isinstance(raw, dict):
        raise InputError("expected a number or a matrix (list of rows)", field=name)
    if isinstance(raw, list):
        if not raw or not all(isinstance(r, list) for r in raw):
            raise InputError("must be a non-empty list of rows (e.g. [[0], [1]])", field=name)
        widths = {len(r) for r in raw}
        if len(widths) != 1:
            raise InputError("rows of different lengths", field=name)
        got = (len(raw), widths.pop())
        if got != shape:
            raise InputError(f"must be {shape[0]}x{shape[1]}, got {got[0]}x{got[1]}",
                             field=name)
    elif not scalar_identity and shape != (1, 1):
        raise InputError(f"must be a {shape[0]}x{shape[1]} matrix (list of rows)", field=name)
    value = convert(raw, name)
    M, exact, Mf = matrix_and_float(value, name, allow_scalar_identity=shape[0]
                                    if scalar_identity else None)
    if M.shape != shape:
        raise InputError(f"must be {shape[0]}x{shape[1]}, got {M.shape[0]}x{M.shape[1]}",
                         field=name)
    return M, exact, Mf


def _weight(raw: Any, name: str, size: int, convert: Callable[[Any, str], Any],
            strict: bool) -> sp.ImmutableMatrix:
    r"""A cost weight: symmetric, PSD (``W``) or PD (``U``); a scalar is that multiple of I.

    .. math:: W = W' \succeq 0, \qquad U = U' \succ 0
    """
    if raw is None:
        return sp.ImmutableMatrix(sp.eye(size))
    M, exact, Mf = _matrix(raw, name, (size, size), convert, scalar_identity=True)
    symmetric = (M == M.T) if exact else bool(np.allclose(Mf, Mf.T, rtol=1e-12, atol=0))
    what = "positive definite" if strict else "positive semidefinite"
    if not symmetric or not is_definite(M, Mf, exact, strict):
        raise InputError(f"must be symmetric {what} (a weight of the cost)", field=name)
    return M


def _flag(data: dict, key: str, default: bool) -> bool:
    value = data.get(key, default)
    if not isinstance(value, bool):
        raise InputError("must be true or false", field=f"loop.{key}")
    return value


def loop_from_mapping(data: Any, n: int, m: int, *, convert: Callable[[Any, str], Any],
                      parse_channel: Callable[[Any, str], Channel]) -> LoopSpec:
    """Validate a ``loop:`` mapping for a plant with n states and m outputs.

    Parameters
    ----------
    data : Any
        The parsed ``loop:`` value.
    n, m : int
        States (rows of A) and outputs (rows of C) of the plant.
    convert : callable
        ``convert(raw, field)``: the raw YAML entries as exact numbers or expression strings.
    parse_channel : callable
        ``parse_channel(mapping, prefix)``: a channel of any model (errors name ``prefix``).
    """
    if not isinstance(data, dict):
        raise InputError("must be a mapping with B and channel (and optionally W, U, "
                         "acknowledged, on_loss, estimator_gain, controller_gain)", field="loop")
    check_keys(data, LOOP_KEYS, set(), "loop")
    for key in sorted(LOOP_REQUIRED):
        if data.get(key) is None:
            raise InputError("is required (the "
                             + ("input matrix" if key == "B" else "actuation link") + ")",
                             field=f"loop.{key}")
    raw_b = data["B"]
    rows = len(raw_b) if isinstance(raw_b, list) else 1
    if rows != n:
        raise InputError(f"must have {n} rows (the size of A), got {rows}", field="loop.B")
    cols = len(raw_b[0]) if isinstance(raw_b, list) and raw_b and isinstance(raw_b[0], list) \
        else 1
    B, _, _ = _matrix(raw_b, "loop.B", (n, cols), convert)
    W = _weight(data.get("W"), "loop.W", n, convert, strict=False)
    U = _weight(data.get("U"), "loop.U", cols, convert, strict=True)
    on_loss = data.get("on_loss", "zero")
    if on_loss not in ON_LOSS_POLICIES:
        raise InputError(f"must be one of {', '.join(ON_LOSS_POLICIES)}", field="loop.on_loss")
    gains = [data.get(k) for k in ("estimator_gain", "controller_gain")]
    if (gains[0] is None) != (gains[1] is None):
        missing = "estimator_gain" if gains[0] is None else "controller_gain"
        raise InputError("a fixed design gives both estimator_gain and controller_gain",
                         field=f"loop.{missing}")
    K = L = None
    if gains[0] is not None:
        K, _, _ = _matrix(gains[0], "loop.estimator_gain", (n, m), convert)
        L, _, _ = _matrix(gains[1], "loop.controller_gain", (cols, n), convert)
    channel = parse_channel(data["channel"], "loop.channel")
    return LoopSpec(B=B, W=W, U=U, channel=channel,
                    acknowledged=_flag(data, "acknowledged", True), on_loss=str(on_loss),
                    estimator_gain=K, controller_gain=L)
