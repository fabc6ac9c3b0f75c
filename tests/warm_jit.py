"""Compile kfcrit's numba kernels into their on-disk cache (``kfcrit/sim/__pycache__``).

``python -m tests.warm_jit rre`` compiles the Monte Carlo kernels, ``... ergodic`` the
long-path kernels. The test session's controller runs both at once before its workers start
(see ``conftest.py``): on a fresh clone the workers then load compiled kernels instead of
each compiling the same ones (about 25 s of CPU per process).
"""
from __future__ import annotations

import sys


def main(part: str) -> None:
    import sympy as sp

    from kfcrit.model.channels import GilbertElliott
    from kfcrit.model.system import System
    from kfcrit.sim.engine import ergodic, simulate

    system = System([[1.25, 0], [1, 1.1]], [[1, 1]], [[20, 0], [0, 20]], [[2.5]])
    if part == "rre":
        simulate(system, paths=8, steps=4, seed=0, arrival_probability=0.9)
        bursty = GilbertElliott(sp.Rational(1, 10), sp.Rational(1, 2))
        simulate(system, paths=8, steps=4, seed=0, channel=bursty, record_traces=True,
                 track_lambda_max=False)
    else:
        ergodic(system, steps=64, seed=0, arrival_probability=0.9, levels=(10.0,))


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "rre")
