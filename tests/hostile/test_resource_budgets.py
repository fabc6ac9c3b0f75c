"""Documented limits bound time and memory (issue 18 items 6 and 7, loading part).

Each hostile case of the issue runs the real command in a subprocess capped at 1 GB of address
space and 60 s, and must finish: exit 0 with the fallback reason in the record, or exit 2 with a
one-line error. The degree estimate and the bounded runner are checked against hand-derived
degrees and against sympy's own minimal polynomials.
"""
from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
from pathlib import Path

import pytest
import sympy as sp

from kfcrit.errors import InputError
from kfcrit.model.exprparse import parse_expression, parse_with_float
from kfcrit.model.system import MAX_EXPRESSION_TEXT, ParseBudget, System, matrix_and_float
from kfcrit.theory.structure.budget import adopt_imports, field_degree_bound, run_bounded
from kfcrit.theory.structure.eigen import structure_of
from kfcrit.theory.structure.records import Fallback

ROOT = Path(__file__).resolve().parents[2]
CAP_BYTES = 2**30
CAP_SECONDS = 60
PRIMES = [2, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37, 41, 43, 47, 53, 59, 61, 67, 71, 73, 79,
          83, 89, 97]


def _nest(k: int, base: str) -> str:
    text = base
    for _ in range(k):
        text = f"sqrt({text})"
    return text


def _capped() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (CAP_BYTES, CAP_BYTES))


def _run(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    """The CLI in a child capped at CAP_BYTES of memory; ``timeout`` only guards against a
    hang (TimeoutExpired fails the test), it measures nothing."""
    env = dict(os.environ, PYTHONPATH=str(ROOT), KFCRIT_EXACT_TIME_BUDGET="8")
    return subprocess.run([sys.executable, "-m", "kfcrit", *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=CAP_SECONDS,
                          preexec_fn=_capped)


def _system_file(path: Path, A: list[list[str]], p: str = "0.99") -> Path:
    n = len(A)
    rows = ", ".join("[" + ", ".join(f"'{e}'" for e in row) + "]" for row in A)
    path.write_text(f"name: hostile\nA: [{rows}]\nC: [[{', '.join(['1'] + ['0'] * (n - 1))}]]\n"
                    f"Q: 1\nR: 1\nchannel: {{model: bernoulli, arrival_probability: {p}}}\n")
    return path


# --------------------------------------------------------------------------- degree estimate

@pytest.mark.parametrize(("texts", "degree"), [
    # 2^(1/2^30): x^(2^30) − 2 is Eisenstein at 2, so the degree is exactly 2^30
    ([_nest(30, "2")], 2**30),
    ([_nest(16, "3")], 2**16),
    # Q(2^(1/64), 3^(1/63)): coprime degrees 64 and 63 multiply
    (["2**(1/64)+3**(1/63)"], 64 * 63),
    # 25 square roots of distinct primes: degree 2^25 (Besicovitch)
    ([f"sqrt({p})/10" for p in PRIMES], 2**25),
    # sqrt(6) = sqrt(2)·sqrt(3): Q(sqrt 2, sqrt 3) has degree 4
    (["sqrt(2)", "sqrt(3)", "sqrt(6)"], 4),
    (["3 + 2*sqrt(2)", "1/2"], 2),
    (["1/3", "7"], 1),
])
def test_degree_bound_of_the_issue_cases(texts: list[str], degree: int) -> None:
    assert field_degree_bound([parse_expression(t) for t in texts]) == degree


@pytest.mark.parametrize("texts", [
    ["sqrt(1 + sqrt(2))", "sqrt(2)"],
    ["12**(1/4)", "sqrt(3)"],
    ["(2/3)**(1/3)"],
    ["cos(pi/7)"],
    ["2*cos(2*pi/5)", "2*sin(2*pi/5)"],
    ["sqrt(5) + cos(pi/9)"],
])
def test_degree_bound_is_at_least_the_true_degree(texts: list[str]) -> None:
    # the true degree of each entry from sympy's minimal polynomial (an independent method)
    values = [parse_expression(t) for t in texts]
    bound = field_degree_bound(values)
    x = sp.Symbol("x")
    for v in values:
        assert sp.Poly(sp.minimal_polynomial(v, x), x).degree() <= bound


@pytest.mark.parametrize("text", ["cos(1)", "pi", "exp(1/3)", "log(2)"])
def test_degree_bound_is_none_for_transcendental_entries(text: str) -> None:
    assert field_degree_bound([parse_expression(text)]) is None


# --------------------------------------------------------------------------- bounded runner

def _spin() -> None:
    while True:
        pass


def _hog() -> None:
    chunks = []
    while True:
        chunks.append(bytearray(50 * 2**20))


def _boom() -> None:
    raise ValueError("from the child")


def test_bounded_runner_returns_and_reraises() -> None:
    assert run_bounded(divmod, 17, 5, seconds=10, what="t") == (3, 2)
    with pytest.raises(ValueError, match="from the child"):
        run_bounded(_boom, seconds=10, what="t")


def _import_json_tool() -> str:
    import json.tool

    return json.tool.__name__


def test_modules_a_child_imports_are_imported_once_here_too() -> None:
    # sympy imports modules lazily: a child's import would be lost and paid again by every
    # later child; the parent adopts them (json.tool stands in for them: json is imported)
    if "json.tool" in sys.modules:
        pytest.skip("json.tool is already imported in this session")
    assert run_bounded(_import_json_tool, seconds=10, what="t") == "json.tool"
    assert "json.tool" in sys.modules
    assert adopt_imports(["json.tool", "json.no_such_module", "no_such_package.mod"]) == []
    assert "no_such_package" not in sys.modules


def test_bounded_runner_stops_a_spinning_computation() -> None:
    with pytest.raises(Fallback, match="budget"):
        run_bounded(_spin, seconds=1.5, what="spin")


def test_bounded_runner_stops_a_memory_hog() -> None:
    with pytest.raises(Fallback, match="memory"):
        run_bounded(_hog, seconds=30, what="hog", memory=200 * 2**20)


def test_bounded_runner_interrupts_sympy_field_construction() -> None:
    # the issue's case: sympy builds Q(2^(1/2^30)) for minutes; the child is killed on time
    value = parse_expression(_nest(30, "2"))
    with pytest.raises(Fallback):
        run_bounded(sp.QQ.algebraic_field, value, seconds=2, what="field")


def test_hostile_noise_covariance_keeps_the_exact_eigen_structure() -> None:
    # A, C rational; Q = diag(3^(1/65536), 0). By hand: with b = e1, the Krylov matrix
    # [b, A b] = [[1, 2], [0, 0]] has rank 1, so (A, Q^(1/2)) is not controllable; the
    # eigenvalues 2 and 3 stay exact and only controllability is decided in float64.
    system = System([[2, 1], [0, 3]], [[1, 0]], [[_nest(16, "3"), 0], [0, 0]], 1)
    st = structure_of(system)
    assert st.path == "exact" and "float64 PBH" in st.path_reason
    assert sorted(e.expr for e in st.eigen) == [2, 3]
    assert st.controllable_Q is False


# --------------------------------------------------------------------------- the issue's cases

@pytest.mark.parametrize(("case", "A", "degree"), [
    ("30 nested sqrt(2)", [[_nest(30, "2")]], "1073741824"),
    ("16 nested sqrt(3)", [[_nest(16, "3")]], "65536"),
    ("2**(1/64)+3**(1/63)", [["2**(1/64)+3**(1/63)"]], "4032"),
    ("5x5 sqrt(prime)", [[f"sqrt({PRIMES[5 * i + j]})/10" for j in range(5)] for i in range(5)],
     "33554432"),
])
def test_hostile_entries_fall_back_with_the_reason(tmp_path: Path, case: str,
                                                   A: list[list[str]], degree: str) -> None:
    path = _system_file(tmp_path / "hostile.yaml", A)
    proc = _run("analyze", str(path), "--quick", "--json", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-400:]
    reason = json.loads(proc.stdout)["structure"]["path_reason"]
    assert f"degree up to {degree}" in reason
    assert "certified enclosures" in reason or "numeric" in reason


def test_hostile_sweep_grid_value_finishes(tmp_path: Path) -> None:
    (tmp_path / "base.yaml").write_text(
        "name: base\nA: [[1.2, 0], [0, 0.5]]\nC: [[1, 1]]\nQ: 1\nR: 1\n"
        "channel: {model: bernoulli, arrival_probability: 0.6}\n")
    (tmp_path / "sweep.yaml").write_text(
        f"name: hostile sweep\nsystem: base.yaml\ngrid:\n  A[0][0]: ['{_nest(16, '3')}', "
        "'2**(1/64)+3**(1/63)']\n")
    out = tmp_path / "out"
    out.mkdir()
    proc = _run("sweep", "sweep.yaml", "-o", str(out), "--workers", "1", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-400:]
    lines = (out / "sweep.csv").read_text().splitlines()
    assert len(lines) == 3 and all(",ok," in line for line in lines[1:])


# --------------------------------------------------------------------------- loading

def _big_file(path: Path, entry: object, n: int = 400) -> Path:
    with path.open("w") as fh:
        fh.write("name: big\nA: [")
        for i in range(n):
            fh.write(("," if i else "") + "[" + ", ".join(f"'{entry(i, j)}'" for j in range(n))
                     + "]\n")
        fh.write(f"]\nC: [[{', '.join(['1'] * n)}]]\nQ: 1\nR: 1\n"
                 "channel: {model: bernoulli, arrival_probability: 0.6}\n")
    return path


def _one_line_error(proc: subprocess.CompletedProcess[str], field: str) -> None:
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"kfcrit: error: {field}")
    assert "Traceback" not in proc.stderr


def test_distinct_expression_strings_beyond_the_budget_are_refused(tmp_path: Path) -> None:
    # 400×400 distinct sqrt(2)/k: about 2.1 million characters of expressions
    path = _big_file(tmp_path / "big.yaml", lambda i, j: f"sqrt(2)/{400 * i + j + 1}")
    proc = _run("check", str(path), cwd=tmp_path)
    _one_line_error(proc, "A:")
    assert "parsing budget" in proc.stderr and str(MAX_EXPRESSION_TEXT) in proc.stderr


def test_large_file_of_slow_entries_is_refused_at_once(tmp_path: Path) -> None:
    # about 12 MB of 14-fold nested cosines (each ~6 ms to parse: minutes in all)
    path = _big_file(tmp_path / "slow.yaml",
                     lambda i, j: "cos(" * 14 + str(400 * i + j + 2) + ")" * 14)
    assert path.stat().st_size > 11_000_000
    proc = _run("check", str(path), cwd=tmp_path)
    _one_line_error(proc, "A:")


def test_repeated_expression_strings_load(tmp_path: Path) -> None:
    # 200×200 entries but only 200 distinct strings: each is parsed once
    path = _big_file(tmp_path / "rep.yaml", lambda i, j: f"sqrt(2)/{j + 1}", n=200)
    proc = _run("check", str(path), cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-400:]
    assert "n = 200" in proc.stdout


def test_parse_deadline_names_the_entry() -> None:
    with pytest.raises(InputError, match=r"longer than 0 s") as err:
        matrix_and_float([[1, "sqrt(2)"]], "A", budget=ParseBudget(seconds=0))
    assert err.value.field == "A[0][1]"


def test_float_views_match_high_precision_evaluation() -> None:
    # the float view from the ball against sympy's 30-digit evaluation (a second method)
    texts = ["sqrt(2)/7", "cos(pi/7)", "exp(1/3) - log(5)", "2**(1/64)+3**(1/63)",
             "tan(1/3)**3", "(sqrt(2)+sqrt(3))**2 - 5 - 2*sqrt(6) + 1/10**20", "-sqrt(3)/1e5"]
    for text in texts:
        value, view = parse_with_float(text)
        assert view == float(sp.N(value, 30)), text


def test_system_float_views_and_exact_entries() -> None:
    A = [["sqrt(2)/3", "sqrt(2)/3"], ["1/3", "cos(pi/5)"]]
    system = System(A, [[1, 0]], 1, 1)
    assert system.A[0, 0] is system.A[0, 1]          # one parse per distinct string
    assert system.A[1, 1] == (1 + sp.sqrt(5)) / 4    # cos(π/5), the textbook value
    assert system.a[1, 1] == float(sp.N((1 + sp.sqrt(5)) / 4, 30))
    assert system.a[0, 0] == float(sp.N(sp.sqrt(2) / 3, 30))
