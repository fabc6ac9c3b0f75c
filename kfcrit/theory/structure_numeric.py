"""Numeric path of the eigen-structure: the Mo–Sinopoli decisions in float64 with tolerances.

Used for n > ``EXACT_MAX_STATES``, non-algebraic entries, binary-float input beyond small n, and
whatever the exact path and its certified stage cannot decide. Moduli are equal within the
relative modulus tolerance, ranks within ``rank_relative``·‖C‖, φ/2π is matched to r/q within
``turn_absolute`` (see :func:`kfcrit.theory.structure_records.numeric_tolerances`).
"""
from __future__ import annotations

import time
from fractions import Fraction

import numpy as np

from kfcrit.model.system import System
from kfcrit.theory.structure_records import (
    MAX_DENOMINATOR,
    Eigen,
    EquiBlock,
    Pair,
    Structure,
    eigen_indices,
    is_relevant,
    numeric_controllable,
    numeric_tolerances,
    observability_index,
    simplest_rational,
    turn_of,
)

# --------------------------------------------------------------------------- numeric path

def numeric_structure(system: System, start: float, reason: str,
                       tolerance: float | None = None) -> Structure:
    a, c = system.a, system.c
    n = a.shape[0]
    tol = numeric_tolerances(tolerance)
    norm_a = float(np.linalg.norm(a, 2))
    norm_c = float(np.linalg.norm(c, 2))
    scale = max(1.0, norm_a)
    w, V = np.linalg.eig(a)
    # Cluster numerically equal eigenvalues (a Jordan block of size 2 splits them by ~√eps).
    parent = list(range(n))

    def find(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i
    close = np.abs(w[:, None] - w[None, :]) <= tol["eigenvalue_cluster_relative"] * scale
    for i, j in zip(*np.nonzero(np.triu(close, 1))):
        parent[find(i)] = find(j)
    clusters: dict[int, list[int]] = {}
    for i in range(n):
        clusters.setdefault(find(i), []).append(i)
    eigen = []
    for members in clusters.values():
        mu = complex(np.mean(w[members]))
        if abs(mu.imag) <= tol["eigenvalue_cluster_relative"] * scale:
            mu = complex(mu.real, 0.0)
        if len(members) == 1:
            v = V[:, members[0]]
            basis = (v / np.linalg.norm(v))[:, None]
            g = 1
        else:
            _, s, vh = np.linalg.svd(a.astype(complex) - mu * np.eye(n))
            g = int(np.sum(s <= tol["geometric_multiplicity_relative"] * scale))
            g = max(1, min(g, len(members)))
            basis = vh[n - g:].conj().T
        eigen.append(Eigen(value=mu, multiplicity=len(members), geometric=g,
                           mod2=abs(mu) ** 2, basis=basis))
    eigen.sort(key=lambda e: (-e.modulus, turn_of(e.value)))
    diagonalizable = all(e.geometric == e.multiplicity for e in eigen)
    rank_tol = tol["rank_relative"] * max(norm_c, np.finfo(float).tiny)

    def rank_of(ids: list[int]) -> int:
        M = c @ np.hstack([eigen[i].basis for i in ids])
        if M.size == 0:
            return 0
        return int(np.sum(np.linalg.svd(M, compute_uv=False) > rank_tol))
    groups: list[list[int]] = []
    for i, e in enumerate(eigen):
        if groups and abs(eigen[groups[-1][0]].modulus - e.modulus) \
                <= tol["modulus_relative"] * max(eigen[groups[-1][0]].modulus, 1e-300):
            groups[-1].append(i)
        else:
            groups.append([i])
    undetectable = [i for i, e in enumerate(eigen)
                    if is_relevant(e, tol) and rank_of([i]) < e.geometric]
    blocks, pairs = [], []
    for grp in groups:
        relevant = is_relevant(eigen[grp[0]], tol)
        size = sum(eigen[i].geometric for i in grp)
        blocks.append(EquiBlock(members=tuple(grp), indices=eigen_indices(eigen, grp),
                                mod2=eigen[grp[0]].mod2, mod2_expr=None,
                                rank=rank_of(grp), size=size, relevant=relevant))
        if not relevant:
            continue
        for ia in range(len(grp)):
            for ib in range(ia + 1, len(grp)):
                ea, eb = eigen[grp[ia]], eigen[grp[ib]]
                turn = turn_of(eb.value / ea.value)
                frac = simplest_rational(turn - tol["turn_absolute"], turn + tol["turn_absolute"])
                q = frac.denominator if frac.denominator <= MAX_DENOMINATOR else None
                if q is not None:
                    frac = Fraction(frac.numerator % q, q)
                psize = ea.geometric + eb.geometric
                prank = rank_of([grp[ia], grp[ib]])
                pairs.append(Pair(a=grp[ia], b=grp[ib], rank=prank, size=psize,
                                  degenerate=prank < psize, q=q,
                                  turn=float(frac) if q else turn,
                                  turn_text=(str(frac) if q else
                                             f"no r/q with q <= {MAX_DENOMINATOR} within "
                                             f"{tol['turn_absolute']:g}")))
    form = {"eigenvalues": [[float(e.value.real), float(e.value.imag)] for e in eigen],
            "basis": "V: orthonormal float bases of ker(A − λI); entries of C·V as [re, im]",
            "equi_blocks": [{
                "indices": list(eigen_indices(eigen, grp)),
                "eigenvalues": [[float(eigen[i].value.real), float(eigen[i].value.imag)]
                                for i in grp],
                "C_columns": [[[float(z.real), float(z.imag)] for z in col]
                              for col in (c @ np.hstack([eigen[i].basis for i in grp])).T]}
                for grp in groups]}
    return Structure(
        standard_form=form, path="numeric", path_reason=reason, tolerances=dict(tol),
        eigen=tuple(eigen),
        blocks=tuple(blocks), pairs=tuple(pairs), diagonalizable=diagonalizable,
        detectable=not undetectable, undetectable=tuple(undetectable),
        controllable_Q=numeric_controllable(a, system.q),
        observability_index=observability_index(a, c),
        observable=all(rank_of([i]) == e.geometric for i, e in enumerate(eigen)),
        norm_A=norm_a, norm_C=norm_c,
        seconds=time.monotonic() - start)


