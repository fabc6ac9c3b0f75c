"""Multi-hop meshes: shared relays, correlated losses, estimate relaying (theory §13 [beyond]).

The model is :class:`kfcrit.model.mesh.Mesh` (built with :func:`kfcrit.model.mesh.build_mesh`).
Entry points:

* :func:`kfcrit.theory.mesh.law.mesh_law` — the exact joint law π(S) of the received sensor
  set per period (:class:`~kfcrit.theory.mesh.law.JointLaw`); also
  :func:`~kfcrit.theory.mesh.law.product_law`, :func:`~kfcrit.theory.mesh.law.slot_arrival`,
  :func:`~kfcrit.theory.mesh.law.route_arrival`.
* :func:`kfcrit.theory.mesh.stability.law_stability` — necessary and sufficient facts of mean
  stability for any i.i.d. joint law; :func:`kfcrit.theory.mesh.stability.mesh_analysis` —
  the law, facts, marginals, P(all lost), hop headrooms, bottleneck hop and N − 1 cases.
* :func:`kfcrit.theory.mesh.relaying.estimate_relaying` — Gupta et al.'s p_cut·ρ(A)² < 1;
  :func:`kfcrit.theory.mesh.relaying.max_drop_cut`;
  :func:`kfcrit.theory.mesh.relaying.smart_sensor_critical_value` — 1 − 1/ρ(A)².
"""
