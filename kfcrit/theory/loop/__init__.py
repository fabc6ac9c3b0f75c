"""Closed loops over lossy sensing and actuation links (theory §12) — theory core.

Everything here returns *facts* (values, intervals, exactness, certified decisions), never
verdicts; nothing is wired into the record, CLI or views yet. Public entry points:

TCP-like (acknowledged) optimal loop — :mod:`kfcrit.theory.loop.tcp`,
:mod:`kfcrit.theory.loop.thresholds`, :mod:`kfcrit.theory.loop.filter_mean`

* ``actuation_threshold(A, B, W=None, U=None, tol=1e-9) -> Threshold`` — ν_c = p_up(A', B')
  (scalar, B invertible: exact theorems; one input column: exact *claim* checked against the
  certified bracket; otherwise the certified bracket).
* ``sensing_threshold(A, C, Q=None, R=None, tol=1e-9) -> Threshold`` — γ_c = p_c(A, C).
* ``dual_system(A, B, W=None, U=None) -> System`` — System(A', B', W, U).
* ``control_mare(A, B, W, U, nu) -> ndarray | None``; ``control_gain(A, B, U, S) -> ndarray``.
* ``tcp_loop(A, B, C, W, U, Q, R, gamma_bar, nu_bar, tol=1e-9, mc_paths=1000,
  mc_steps=3000, seed=0) -> TCPLoop``.
* ``filter_moments(system, gamma, ...) -> FilterMoments`` — lim E[P_{t|t}] and its bounds.

  ``Threshold(name, value, interval, exact, expression, basis, certified, reason)`` with
  ``basis`` in {"theorem", "claim", "certified-interval", "numerical", "none"} and helpers
  ``contains(p)``, ``below(p)`` (threshold < p proven / threshold ≥ p proven / None).
  ``LoopCost(value, lower, upper, finite, method, error, reason)`` (inf where infinite or no
  finite bound; nan when not computed; ``finite`` True/False/None).
  ``TCPLoop(gamma_bar, nu_bar, nu_c, gamma_c, S, L, cost, filter, notes)``.
  ``FilterMoments(gamma, mean_pred, mean_filt, method, error, lower_filt, upper_filt)``.

Fixed linear designs (zero/hold, acknowledged or not) — :mod:`kfcrit.theory.loop.stack`,
:mod:`kfcrit.theory.loop.fixed`, :mod:`kfcrit.theory.loop.msstab`,
:mod:`kfcrit.theory.loop.curve`, :mod:`kfcrit.theory.loop.links`

* ``fixed_design(A, B, C, Q, R, W, U, K=None, L=None, acked=True, on_loss="zero")
  -> FixedDesign`` (K: steady-state Kalman gain, L: LQR, by default).
* ``LossLink(failure, recovery)``, ``LossLink.bernoulli(p)`` — Gilbert–Elliott / i.i.d. links.
* ``mean_square_stability(design, sensing, actuation, certified=True) -> StabilityFact``.
* ``fixed_loop(design, sensing, actuation, certified=True) -> FixedLoop``.
* ``critical_curve(design, gammas, nu_grid=None, tol=1e-4, certify_ends=False)
  -> CriticalCurve``; ``spectral_radius(design, gamma, nu) -> float``.

  ``StabilityFact(status, holds, rho, method, dimension)`` with ``status`` one of
  "holds (certified)", "fails (certified)", "not decided".
  ``FixedLoop(stability, cost: LoopCost, second_moment, sizes, markov)``.
  ``CriticalCurve(gammas, nu_grid, rho, nu_star, bracket, monotone_at_grid, stable_intervals,
  certified)``.

Simulation: :mod:`kfcrit.sim.loop` — ``simulate_tcp(...)`` and ``simulate_fixed(...)`` return
``LoopSimulation(cost, ci, std_error, confidence, growth_rate, second_moment, finite, paths,
steps, burn_in, seed, loop)``.

The symbolic checks live in ``proofs_checks/check_loop_duality.py`` (not yet listed in
``proofs_checks.MODULES``).
"""
