"""Monte Carlo of the random Riccati equation (RRE): the public entry points in one place.

The simulation is split by concern:

* :mod:`kfcrit.sim.arrivals` — per-path random streams (SeedSequence → SplitMix64) and the
  arrival sequences γ_t of i.i.d., Gilbert–Elliott and trace channels;
* :mod:`kfcrit.sim.kernels` — the compiled lane-parallel kernels (Joseph-form Riccati step,
  λ_max, the batch and ergodic loops, the scaled form for diverging paths);
* :mod:`kfcrit.sim.stats` — streaming statistics (Welford, log-sum-exp), proportions;
* :mod:`kfcrit.sim.results` — :class:`SimulationResult`, :class:`ErgodicResult`;
* :mod:`kfcrit.sim.engine` — :func:`simulate` (one link, or several sensors each over its own
  link: ``sensors=[(rows of C, channel), …]``) and :func:`ergodic`;
* :mod:`kfcrit.sim.checks` — whether the mean exists and the variance is finite at an operating
  point, and the self-checks of a simulation;
* :mod:`kfcrit.sim.section` — :func:`simulation_section`, the record section of an analysis.

Plots live in :mod:`kfcrit.views.figures.sim`, the ``simulate`` command in
:mod:`kfcrit.cli.simulate`.
"""
from __future__ import annotations

from kfcrit.sim.arrivals import KIND_CODE, arrival_sequence, path_keys
from kfcrit.sim.checks import mean_regime, simulation_checks, tail_regime
from kfcrit.sim.engine import ergodic, simulate
from kfcrit.sim.kernels import LANES
from kfcrit.sim.results import ErgodicResult, FullStateResult, SimulationResult
from kfcrit.sim.section import Budget, phase_probabilities, simulation_section
from kfcrit.sim.stats import proportion, quiet_numerics

__all__ = ["LANES", "KIND_CODE", "Budget", "ErgodicResult", "FullStateResult", "SimulationResult",
           "arrival_sequence", "ergodic", "mean_regime", "path_keys", "phase_probabilities",
           "proportion", "quiet_numerics", "simulate", "simulation_checks", "simulation_section",
           "tail_regime"]
