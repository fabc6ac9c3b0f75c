"""Numeric path of the eigen-structure: the Mo–Sinopoli decisions in float64 with tolerances.

Used for n > ``EXACT_MAX_STATES``, non-algebraic entries, binary-float input beyond small n, and
whatever the exact path and its certified stage cannot decide. Moduli are equal within the
relative modulus tolerance, ranks within ``rank_relative``·‖C‖, φ/2π is matched to r/q within
``turn_absolute`` (see :func:`kfcrit.theory.structure.records.numeric_tolerances`).
"""
from __future__ import annotations

import math
import time
from fractions import Fraction

import numpy as np

from kfcrit.model.system import System
from kfcrit.records.structure import StandardForm, StandardFormBlock
from kfcrit.theory.structure.records import (
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

_RESOLVED_SPREAD = 1e-4
"""Largest relative spread of a cluster read as one multiple eigenvalue (a Jordan block of size
k splits by about ε^{1/k}: 1.5e-8, 6e-6, 1.2e-4 for k = 2, 3, 4 at unit scale)."""


def _clusters(a: np.ndarray, w: np.ndarray, norm_a: float, rel: float) -> list[list[int]]:
    """Groups of computed eigenvalues that float64 cannot tell apart: w_i, w_j join when
    |w_i − w_j| ≤ r_i + r_j, r_i = 64·ε·‖A‖₂·κ_i (first-order error bound of a backward-stable
    eigensolver, κ_i = ‖x_i‖‖y_i‖/|y_i^H x_i|), or when |w_i − w_j| ≤ ``rel``·max(1, |w_i|, |w_j|).

    .. math:: |\\hat\\lambda_i - \\lambda_i| \\lesssim \\varepsilon \\|A\\|_2 \\kappa_i
    """
    import scipy.linalg as sla

    n = len(w)
    try:
        _, yl, xr = sla.eig(a, left=True, right=True)
        dots = np.abs(np.sum(yl.conj() * xr, axis=0))
        norms = np.linalg.norm(yl, axis=0) * np.linalg.norm(xr, axis=0)
        with np.errstate(divide="ignore", invalid="ignore"):
            kappa = np.where(dots > 0, norms / dots, np.inf)
    except (np.linalg.LinAlgError, ValueError):
        kappa = np.full(n, np.inf)
    radius = 64 * np.finfo(float).eps * norm_a * np.minimum(kappa, 1 / np.finfo(float).eps)
    parent = list(range(n))

    def find(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i
    gap = np.abs(w[:, None] - w[None, :])
    size = np.maximum(1.0, np.maximum(np.abs(w)[:, None], np.abs(w)[None, :]))
    close = (gap <= radius[:, None] + radius[None, :]) | (gap <= rel * size)
    for i, j in zip(*np.nonzero(np.triu(close, 1))):
        parent[find(i)] = find(j)
    groups: dict[int, list[int]] = {}
    for i in range(n):
        groups.setdefault(find(i), []).append(i)
    return list(groups.values())


def _cluster_values(a: np.ndarray, w: np.ndarray, norm_a: float, rel: float,
                    unresolved: list[str]) -> list[tuple[list[int], complex]]:
    """(members, value) per distinct eigenvalue. A cluster of :func:`_clusters` whose relative
    spread is at most ``_RESOLVED_SPREAD`` is one multiple eigenvalue, valued at its mean (the
    mean of a split Jordan block is accurate). A wider cluster is not resolved by float64: its
    members stay separate at their computed values (never averaged, so an unstable eigenvalue
    is not hidden in a mean), and a sentence saying so is appended to ``unresolved``."""
    out: list[tuple[list[int], complex]] = []
    for members in _clusters(a, w, norm_a, rel):
        ws = w[members]
        mean = complex(np.mean(ws))
        spread = float(np.max(np.abs(ws[:, None] - ws[None, :]))) if len(ws) > 1 else 0.0
        if spread <= max(rel, _RESOLVED_SPREAD) * max(1.0, abs(mean)):
            out.append((members, mean))
            continue
        unresolved.append(
            f"eigenvalues {', '.join(f'{complex(z):.6g}' for z in ws)} are not resolved in "
            f"float64 (spread {spread:.3g}, each within the error bound 64·ε·‖A‖·κ of another): "
            "kept apart at their computed values, which float64 does not guarantee")
        out.extend(([i], complex(w[i])) for i in members)
    return out


def numeric_structure(system: System, start: float, reason: str,
                       tolerance: float | None = None) -> Structure:
    a, c = system.a, system.c
    n = a.shape[0]
    tol = numeric_tolerances(tolerance)
    norm_a = float(np.linalg.norm(a, 2))
    norm_c = float(np.linalg.norm(c, 2))
    scale = max(1.0, norm_a)
    w, V = np.linalg.eig(a)
    eigen, unresolved = [], []
    for members, mu in _cluster_values(a, w, norm_a, tol["eigenvalue_cluster_relative"],
                                       unresolved):
        if abs(mu.imag) <= tol["eigenvalue_cluster_relative"] * max(1.0, abs(mu)):
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
                           mod2=abs(mu) ** 2 if abs(mu) < 1e154 else math.inf, basis=basis))
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
    form = StandardForm(
        eigenvalues=[[float(e.value.real), float(e.value.imag)] for e in eigen],
        basis="V: orthonormal float bases of ker(A − λI); entries of C·V as [re, im]",
        equi_blocks=[StandardFormBlock(
            indices=[int(i) for i in eigen_indices(eigen, grp)],
            eigenvalues=[[float(eigen[i].value.real), float(eigen[i].value.imag)]
                         for i in grp],
            C_columns=[[[float(z.real), float(z.imag)] for z in col]
                       for col in (c @ np.hstack([eigen[i].basis for i in grp])).T])
            for grp in groups])
    return Structure(
        standard_form=form, path="numeric", path_reason=reason, tolerances=dict(tol),
        eigen=tuple(eigen),
        blocks=tuple(blocks), pairs=tuple(pairs), diagonalizable=diagonalizable,
        detectable=not undetectable, undetectable=tuple(undetectable),
        controllable_Q=numeric_controllable(a, system.q),
        observability_index=observability_index(a, c),
        observable=all(rank_of([i]) == e.geometric for i, e in enumerate(eigen)),
        norm_A=norm_a, norm_C=norm_c,
        seconds=time.monotonic() - start, unresolved=tuple(unresolved))


