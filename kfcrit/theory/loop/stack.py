"""A fixed linear design over two lossy links as a jump-linear system z_{t+1} = Φ_m z_t + G_m n_t.

Plant x_{t+1} = A x_t + B a_t + w_t, y_t = C x_t + v_t; the estimator keeps the prediction
x̂_t = x̂_{t|t−1} and uses the gain K (filter form), the controller u_t = L x̂_{t|t}; the applied
input a_t is ν_t u_t ("zero") or ν_t u_t + (1 − ν_t) a_{t−1} ("hold"). The estimator
propagates with the applied input it knows or expects:

.. math::

    \\hat x_{t|t} &= \\hat x_t + \\gamma_t K (y_t - C \\hat x_t), \\qquad u_t = L \\hat x_{t|t},\\\\
    \\hat x_{t+1} &= A \\hat x_{t|t} + B \\hat a_t, \\qquad
    \\hat a_t = \\begin{cases} a_t & \\text{acknowledged (TCP-like)} \\\\
    \\bar\\nu u_t\\ [+ (1-\\bar\\nu) \\hat a_{t-1}\\ \\text{hold}] &
    \\text{not acknowledged (UDP-like)} \\end{cases}

(with acknowledgements and "zero" this is x̂_{t+1} = A x̂_{t|t} + ν_t B u_t; without, + ν̄ B u_t).
The stacked state is z = (x, x̂[, a][, â]) — a for hold, â for hold without acknowledgements —
and the noise n = (w, v) ~ N(0, blkdiag(Q, R)). The applied input is a_t = H_m z_t + J_m v_t;
the stage cost x'Wx + a'Ua charges the applied input (= ν_t u_t'Uu_t for "zero", as in
theory §12).

Every matrix is built either in float64 or exactly (``exact=True``: numpy object arrays of
:class:`fractions.Fraction`, each float input taken as the binary rational it is), so that the
certified stability test of :mod:`kfcrit.theory.loop.msstab` judges the design as given, not a
rounded product.
"""
from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import numpy as np
import scipy.linalg as sla

from kfcrit.theory.loop.links import as_fraction

__all__ = ["FixedDesign", "ModeMatrices", "fixed_design", "mode_matrices"]

ON_LOSS = ("zero", "hold")


@dataclass(frozen=True)
class FixedDesign:
    """A fixed linear estimator–controller design (float64 matrices, taken exactly).

    Attributes
    ----------
    A, B, C : ndarray
        Plant (n × n), input (n × m_u), output (m × n).
    Q, R : ndarray
        Process and measurement noise covariances (R ⪰ 0; R = 0 allows perfect measurements).
    W, U : ndarray
        State and input weights of the cost.
    K : ndarray
        Estimator gain (n × m), filter form x̂_{t|t} = x̂ + γ K (y − C x̂).
    L : ndarray
        Controller gain (m_u × n), u = L x̂_{t|t}.
    acked : bool
        Acknowledged actuation (TCP-like) or not (UDP-like).
    on_loss : str
        ``"zero"`` or ``"hold"``.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    Q: np.ndarray
    R: np.ndarray
    W: np.ndarray
    U: np.ndarray
    K: np.ndarray
    L: np.ndarray
    acked: bool
    on_loss: str

    @property
    def sizes(self) -> dict[str, int]:
        """Block sizes of z: x, x̂, a (hold), â (hold, not acknowledged)."""
        n, mu = self.A.shape[0], self.B.shape[1]
        hold = self.on_loss == "hold"
        return {"x": n, "xhat": n, "a": mu if hold else 0,
                "ahat": mu if hold and not self.acked else 0}


def _arr(M: Any, name: str, shape: tuple[int, int] | None = None) -> np.ndarray:
    X = np.atleast_2d(np.asarray(M, dtype=float))
    if shape is not None and X.shape == (1, 1) and shape != (1, 1) and shape[0] == shape[1]:
        X = X[0, 0] * np.eye(shape[0])
    if shape is not None and X.shape != shape:
        raise ValueError(f"{name} must be {shape[0]}x{shape[1]}, got {X.shape}")
    if not np.all(np.isfinite(X)):
        raise ValueError(f"{name} has non-finite entries")
    X.setflags(write=False)
    return X


def kalman_gain(A: np.ndarray, C: np.ndarray, Q: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Steady-state Kalman gain (filter form) K = P C'(C P C' + R)^{-1}, P from the DARE.

    .. math::

        P = A P A' + Q - A P C'(CPC'+R)^{-1} C P A', \\qquad K = P C'(CPC'+R)^{-1}
    """
    P = sla.solve_discrete_are(A.T, C.T, Q, R)
    return np.linalg.solve(C @ P @ C.T + R, C @ P).T


def lqr_gain(A: np.ndarray, B: np.ndarray, W: np.ndarray, U: np.ndarray) -> np.ndarray:
    """Infinite-horizon LQR gain L = −(B'SB + U)^{-1}B'SA, S from the DARE.

    .. math::

        S = A'SA + W - A'SB(B'SB+U)^{-1}B'SA, \\qquad L = -(B'SB+U)^{-1}B'SA
    """
    S = sla.solve_discrete_are(A, B, W, U)
    return -np.linalg.solve(B.T @ S @ B + U, B.T @ S @ A)


def fixed_design(A: Any, B: Any, C: Any, Q: Any, R: Any, W: Any, U: Any, K: Any = None,
                 L: Any = None, acked: bool = True, on_loss: str = "zero") -> FixedDesign:
    r"""Build a :class:`FixedDesign`; K defaults to the steady-state Kalman gain, L to LQR.

    Scalars for Q, R, W, U mean that multiple of the identity. The estimator and controller

    .. math::

        \hat x_{t+1} = A \hat x_t + \nu B u_t + \gamma_t K (y_t - C \hat x_t),\qquad u_t = L \hat x_t

    (with the held or zero input on an actuation loss) are fixed, whatever the losses.

    Parameters
    ----------
    A, B, C : array_like
        Plant, input and output matrices.
    Q, R : array_like
        Process and measurement noise covariances.
    W, U : array_like
        State and input weights of the cost.
    K, L : array_like, optional
        Estimator and controller gains (default: steady-state Kalman gain and LQR gain).
    acked : bool
        Whether actuation losses are acknowledged (TCP-like) or not (UDP-like).
    on_loss : {"zero", "hold"}
        The input applied when a control packet is lost.

    Returns
    -------
    FixedDesign
        The matrices and gains as float64 arrays.

    Raises
    ------
    ValueError
        ``on_loss`` not "zero" or "hold", or matrices of inconsistent shapes.

    References
    ----------
    Schenato, Sinopoli, Franceschetti, Poolla & Sastry (2007), "Foundations of control and
    estimation over lossy networks", Proc. IEEE 95(1); docs/theory.md §12
    Costa, Fragoso & Marques (2005) for jump-linear systems.

    Examples
    --------
    >>> from kfcrit.theory.loop.stack import fixed_design
    >>> design = fixed_design([[1.25]], [[1]], [[1]], 1, 1, 1, 1)   # steady Kalman gain and LQR
    >>> design.K.round(6), design.L.round(6)
    (array([[0.672158]]), array([[-0.840197]]))
    >>> fixed_design([[1.25]], [[1]], [[1]], 1, 1, 1, 1, on_loss="drop")
    Traceback (most recent call last):
        ...
    ValueError: on_loss must be one of ('zero', 'hold'), got 'drop'
    """
    if on_loss not in ON_LOSS:
        raise ValueError(f"on_loss must be one of {ON_LOSS}, got {on_loss!r}")
    A_ = _arr(A, "A")
    n = A_.shape[0]
    B_ = _arr(B, "B")
    if B_.shape[0] != n:
        B_ = _arr(np.asarray(B, dtype=float).reshape(n, -1), "B")
    C_ = _arr(C, "C")
    if C_.shape[1] != n:
        raise ValueError(f"C must have {n} columns, got {C_.shape}")
    m, mu = C_.shape[0], B_.shape[1]
    Q_, R_ = _arr(Q, "Q", (n, n)), _arr(R, "R", (m, m))
    W_, U_ = _arr(W, "W", (n, n)), _arr(U, "U", (mu, mu))
    K_ = _arr(kalman_gain(A_, C_, Q_, R_) if K is None else K, "K", (n, m))
    L_ = _arr(lqr_gain(A_, B_, W_, U_) if L is None else L, "L", (mu, n))
    return FixedDesign(A_, B_, C_, Q_, R_, W_, U_, K_, L_, bool(acked), on_loss)


@dataclass(frozen=True)
class ModeMatrices:
    """The jump-linear form of a design: per mode m = (γ, ν), z' = Φ_m z + G_m n, a = H_m z + J_m v.

    Attributes
    ----------
    modes : list of (int, int)
    Phi, G, H, J : list of ndarray
        Float64 or exact (object arrays of Fraction) per ``exact``.
    sizes : dict
    exact : bool
    """

    modes: list[tuple[int, int]]
    Phi: list[np.ndarray]
    G: list[np.ndarray]
    H: list[np.ndarray]
    J: list[np.ndarray]
    sizes: dict[str, int]
    exact: bool


def _exact(M: np.ndarray) -> np.ndarray:
    out = np.empty(M.shape, dtype=object)
    for idx, v in np.ndenumerate(M):
        out[idx] = Fraction(float(v))
    return out


def _zeros(r: int, c: int, exact: bool) -> np.ndarray:
    return np.full((r, c), Fraction(0), dtype=object) if exact else np.zeros((r, c))


def _eye(k: int, exact: bool) -> np.ndarray:
    if not exact:
        return np.eye(k)
    E = _zeros(k, k, True)
    for i in range(k):
        E[i, i] = Fraction(1)
    return E


def _one_mode(d: FixedDesign, g: int, v: int, nu_est: Any, exact: bool, mats: dict
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Φ, G, H, J of one mode (γ, ν) = (g, v)."""
    A, B, C, K, L = (mats[k] for k in "ABCKL")
    sz = d.sizes
    n, mu, m = sz["x"], d.B.shape[1], d.C.shape[0]
    N = sum(sz.values())
    sx, sh = slice(0, n), slice(n, 2 * n)
    sa = slice(2 * n, 2 * n + sz["a"])
    sah = slice(2 * n + sz["a"], N)
    one = Fraction(1) if exact else 1.0
    sel = {k: _zeros(sz[k] if k != "ahat" else sz["ahat"], N, exact) for k in sz}
    for k, s in (("x", sx), ("xhat", sh), ("a", sa), ("ahat", sah)):
        sel[k][:, s] = _eye(sz[k], exact)
    # x̂_{t|t} = Fx z + γ K v
    Fx = sel["xhat"] + g * (K @ C) @ (sel["x"] - sel["xhat"])
    Kv = g * K
    U_ = L @ Fx                      # u = U_ z + L Kv v
    Uv = L @ Kv
    H = v * U_ + ((one - v) * sel["a"] if sz["a"] else 0 * U_)
    Jv = v * Uv
    if d.acked:
        Hh, Jh = H, Jv
    else:
        Hh = nu_est * U_ + ((one - nu_est) * sel["ahat"] if sz["ahat"] else 0 * U_)
        Jh = nu_est * Uv
    rows, noise = [A @ sel["x"] + B @ H], [np.hstack([_eye(n, exact), B @ Jv])]
    rows.append(A @ Fx + B @ Hh)
    noise.append(np.hstack([_zeros(n, n, exact), A @ Kv + B @ Jh]))
    if sz["a"]:
        rows.append(H)
        noise.append(np.hstack([_zeros(mu, n, exact), Jv]))
    if sz["ahat"]:
        rows.append(Hh)
        noise.append(np.hstack([_zeros(mu, n, exact), Jh]))
    del m
    return np.vstack(rows), np.vstack(noise), H, Jv


def mode_matrices(design: FixedDesign, nu_est: Any, exact: bool = False) -> ModeMatrices:
    """Φ_m, G_m, H_m, J_m for the four modes m = (γ, ν) ∈ {0,1}².

    .. math::

        z_{t+1} = \\Phi_m z_t + G_m \\begin{pmatrix} w_t \\\\ v_t \\end{pmatrix}, \\qquad
        a_t = H_m z_t + J_m v_t

    Parameters
    ----------
    design : FixedDesign
    nu_est : number
        The ν̄ a UDP-like estimator uses for the expected applied input (the actuation link's
        stationary arrival probability); ignored when acknowledged.
    exact : bool
        Build exact Fraction matrices (float inputs taken exactly).
    """
    conv = _exact if exact else (lambda M: np.asarray(M, dtype=float))
    mats = {k: conv(getattr(design, k)) for k in "ABCKL"}
    nu = as_fraction(nu_est) if exact else float(nu_est)
    modes = [(g, v) for g in (0, 1) for v in (0, 1)]
    Phi, G, H, J = [], [], [], []
    for g, v in modes:
        p, gm, h, j = _one_mode(design, g, v, nu, exact, mats)
        Phi.append(p)
        G.append(gm)
        H.append(h)
        J.append(j)
    return ModeMatrices(modes, Phi, G, H, J, dict(design.sizes), exact)
