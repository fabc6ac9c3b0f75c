"""An independent MARE oracle for the p_up tests: random unstable systems and the plain MARE
iteration from P = 0 (written here, not taken from the code under test)."""
from __future__ import annotations

import numpy as np

from kfcrit.model.system import System


def random_unstable_system(n: int, m: int, seed: int) -> System:
    """A Gaussian A scaled to ρ(A) = 1.3, Gaussian C, Q = I, R = I."""
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, n))
    A *= 1.3 / max(abs(np.linalg.eigvals(A)))
    return System(A, rng.normal(size=(m, n)), np.eye(n), np.eye(m))


def mare_bounded(A: np.ndarray, C: np.ndarray, p: float, steps: int = 4000) -> bool:
    """P ← A P A' + I − p A P C'(C P C' + I)⁻¹ C P A' from P = 0: converged (bounded) or not."""
    n, m = A.shape[0], C.shape[0]
    P = np.zeros((n, n))
    for _ in range(steps):
        APC = A @ P @ C.T
        Pn = A @ P @ A.T + np.eye(n) - p * APC @ np.linalg.solve(C @ P @ C.T + np.eye(m), APC.T)
        Pn = 0.5 * (Pn + Pn.T)
        if np.trace(Pn) > 1e9:
            return False
        if np.abs(Pn - P).max() <= 1e-10 * np.abs(Pn).max():
            return True
        P = Pn
    return False
