"""Support of the invariant distribution (Kar–Sinopoli–Moura; MATH.md §5).

Expected values are the paper's: for A = √2, C = Q = R = 1, P* = 1 + √2, f_0(X) = 2X + 1,
f_1(X) = 3 − 2/(X + 1), no mass in (3, 3 + 2√2) and, generally, in
(2^n·3 + 2^n − 1, 2^{n+1}(1 + √2) + 2^{n+1} − 1); S_n = 2 S_{n−1} + 1. Exact checks use sympy.
"""
from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from kfcrit.errors import InputError
from kfcrit.io.systemfile import read_system_file
from kfcrit.io.typed import to_json
from kfcrit.model.system import System
from kfcrit.sim.montecarlo import ergodic, simulate
from kfcrit.theory.covariance.invariant import ScalarMaps, gap_levels, invariant_section, support_points

from ..conftest import REPORTS, SHARED_CASES

KAR_FILE = REPORTS / "kar-scalar-fractal.yaml"
SQRT2 = sp.sqrt(2)


@pytest.fixture(scope="module")
def kar() -> System:
    return read_system_file(KAR_FILE).system


def test_same_system_as_the_shared_case(kar):
    shared = read_system_file(SHARED_CASES / "kar-scalar-fractal.yaml").system
    assert shared.A == kar.A and shared.C == kar.C and shared.Q == kar.Q and shared.R == kar.R


def test_maps_and_fixed_point_exact(kar):
    maps = ScalarMaps.of(kar)
    X = sp.Symbol("X", positive=True)
    assert sp.simplify(maps.f0(X) - (2 * X + 1)) == 0
    assert sp.simplify(maps.f1(X) - (3 - 2 / (X + 1))) == 0
    pstar = maps.fixed_point()
    assert sp.simplify(pstar - (1 + SQRT2)) == 0
    assert sp.simplify(maps.f1(pstar) - pstar) == 0
    assert maps.f1_limit() == 3


def test_first_gap_is_3_to_3_plus_2_sqrt2(kar):
    sup = support_points(kar, 10)
    lo, hi = sup.first_gap
    assert lo == 3 and sp.simplify(hi - (3 + 2 * SQRT2)) == 0
    inside = (sup.points > 3 + 1e-12) & (sup.points < float(3 + 2 * SQRT2) - 1e-12)
    assert not inside.any()
    assert np.isclose(sup.points, float(3 + 2 * SQRT2)).any()  # f_0(P*) is a support point


def test_gap_levels_match_the_paper_exactly(kar):
    levels = gap_levels(kar, 6)
    assert len(levels) == 6
    for g in levels:
        n = g["n"]
        lo = 2 ** n * 3 + 2 ** n - 1
        hi = 2 ** (n + 1) * (1 + SQRT2) + 2 ** (n + 1) - 1
        assert sp.simplify(g["lower_exact"] - lo) == 0
        assert sp.simplify(g["upper_exact"] - hi) == 0


def test_self_similar_pieces(kar):
    """S_n = f_0(S_{n−1}) = 2 S_{n−1} + 1 as point sets (depth d pieces from depth d−1)."""
    maps = ScalarMaps.of(kar)
    pstar, lim = float(maps.fixed_point()), float(maps.f1_limit())
    d = 12
    deep, shallow = support_points(kar, d).points, support_points(kar, d - 1).points

    def piece(points, n):
        lo, hi = pstar, lim
        for _ in range(n):
            lo, hi = 2 * lo + 1, 2 * hi + 1
        return points[(points >= lo - 1e-9) & (points <= hi + 1e-9)]

    for n in range(1, 5):
        np.testing.assert_allclose(np.sort(piece(deep, n)), np.sort(2 * piece(shallow, n - 1) + 1),
                                   rtol=1e-12)


def test_no_support_point_inside_any_hole(kar):
    sup = support_points(kar, 14)
    assert len(sup.holes) == 7  # G_0, its two images, and their four images
    for lo, hi in sup.holes:
        assert not ((sup.points > lo + 1e-9) & (sup.points < hi - 1e-9)).any()


def test_simulated_paths_from_p_star_never_enter_a_hole(kar):
    """Started at P*, every iterate lies in S ⊂ supp μ_p: no visit to any hole (any p)."""
    sup = support_points(kar, 4)
    pstar = float(sup.fixed_point)
    for p in (0.3, 0.7):
        res = simulate(kar, 20, 2000, 1, arrival_probability=p, initial=[[pstar]],
                       record_traces=True)
        x = res.traces.ravel()
        for lo, hi in sup.holes:
            assert not ((x > lo + 1e-9) & (x < hi - 1e-9)).any()
    # the same through the ergodic tail counters: #(tr P > 3) − #(tr P ≥ 3 + 2√2) = 0
    erg = ergodic(kar, 100_000, 2, arrival_probability=0.7, replicas=2, burn_in=0,
                  initial=[[pstar]], levels=(3 + 1e-9, float(3 + 2 * SQRT2) - 1e-9))
    assert np.all(erg.exceed[:, 0] == erg.exceed[:, 1])
    assert np.all(erg.exceed[:, 0] > 0)  # the path does go above the gap


def test_invariant_section_kar(kar):
    d = to_json(invariant_section(kar))
    assert d["fixed_point"]["expression"] in ("1 + sqrt(2)", "sqrt(2) + 1")
    assert d["first_gap"]["lower"] == 3.0
    assert d["first_gap"]["upper"] == pytest.approx(3 + 2 * 2 ** 0.5, rel=1e-15)
    assert d["self_similarity"]["statement"] == "S_n = 2*S_(n-1) + 1"
    assert d["maps"]["loss"] == "f0(X) = 2*X + 1"
    assert d["gap_levels"][1]["lower_expression"] == "7"
    import json

    json.dumps(d, allow_nan=False)


def test_invariant_section_scalar_only_and_overlapping_images():
    assert to_json(invariant_section(System([[1, 1], [0, 1]], [[1, 0]], 1, 1))) is None
    # r/c² = 100 ≥ P*: the images of f_0 and f_1 overlap, so there is no first-level hole
    d = to_json(invariant_section(System([["1/2"]], [[1]], 1, 100)))
    assert d["first_gap"] is None and d["gap_levels"] == [] and d["holes"] == []
    with pytest.raises(InputError):
        support_points(System([[2]], [[1]], 1, 1), 99)
    with pytest.raises(InputError):
        support_points(System([[2]], [[0]], 1, 1), 3)


# ---- hostile scales: certified comparison, no NumPy warnings, overflow stated --------------

def test_tiny_scalar_a_is_decided_by_a_certified_comparison() -> None:
    # bool(lo < hi) on a sympy Relational it cannot decide must not raise (TypeError → exit 4)
    from kfcrit.theory.covariance.invariant import gap_is_open

    s = System([["1e-200"]], 1, 1, 1)
    sec = to_json(invariant_section(s))
    assert sec is not None and sec["first_gap"] is not None  # hi - lo ≈ 5e-801 > 0, certified
    assert len(gap_levels(s)) == 5
    maps = ScalarMaps.of(s)
    assert gap_is_open(maps.f1_limit(), maps.f0(maps.fixed_point())) is True
    assert gap_is_open(sp.Integer(1), (sp.cos(1) ** 2 + sp.sin(1) ** 2) ** 64) is None
    assert gap_is_open(sp.Integer(2), sp.Integer(1)) is False


def test_tiny_scalar_a_through_the_cli(tmp_path) -> None:  # noqa: ANN001
    import json

    from click.testing import CliRunner

    from kfcrit.cli.main import main

    p = tmp_path / "tiny.yaml"
    p.write_text("name: tiny\nA: [[1e-200]]\nC: 1\nQ: 1\nR: 1\n")
    r = CliRunner().invoke(main, ["analyze", str(p), "--no-simulate", "--json"])
    assert r.exit_code in (0, 3), r.stderr
    assert "internal error" not in r.stderr and "Traceback" not in r.stderr
    assert json.loads(r.stdout)["invariant"]["first_gap"] is not None


def test_undecidable_first_hole_skips_the_holes_with_a_note(monkeypatch) -> None:  # noqa: ANN001
    import kfcrit.theory.covariance.invariant as inv
    from kfcrit.errors import ExpressionError

    def undecidable(*args, **kwargs):  # noqa: ANN002, ANN003, ANN202
        raise ExpressionError("cannot decide the sign", field="x")

    monkeypatch.setattr(inv, "compare", undecidable)
    s = System([[SQRT2]], 1, 1, 1)
    assert gap_levels(s) == []
    sup = support_points(s, 4)
    assert sup.first_gap is None and sup.holes == () and not sup.gap_decided
    sec = to_json(invariant_section(s))
    assert sec["first_gap"] is None and sec["gap_levels"] == [] and sec["holes"] == []
    assert sec["note"] == inv.UNDECIDED_GAP
    assert any("cannot decide" in w for w in sec["warnings"])


def test_huge_values_warn_in_the_record_and_print_nothing(tmp_path) -> None:  # noqa: ANN001
    import json
    import subprocess
    import sys
    import warnings

    from kfcrit.theory.covariance.invariant import OVERFLOW

    s = System([["2**64"]], 1, 1, "1e250")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a NumPy RuntimeWarning fails the test
        sec = to_json(invariant_section(s))
    assert any(OVERFLOW in w for w in sec["warnings"])
    assert np.isfinite(support_points(s, 6).points).all()
    assert sec["first_gap"]["upper"] is None and sec["first_gap"]["upper_expression"]
    p = tmp_path / "huge.yaml"
    p.write_text('name: huge\nA: "2**64"\nC: 1\nQ: 1\nR: 1e250\n')
    # a real process: under pytest, warnings are collected by pytest instead of printed
    proc = subprocess.run([sys.executable, "-m", "kfcrit", "analyze", str(p), "--no-simulate",
                           "--json"], capture_output=True, text=True, timeout=300)
    assert proc.returncode in (0, 3), proc.stderr
    assert proc.stderr == "", proc.stderr  # no RuntimeWarning lines
    rec = json.loads(proc.stdout)
    assert any(OVERFLOW in w for w in rec["warnings"])
