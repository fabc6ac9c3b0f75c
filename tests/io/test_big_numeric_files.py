"""Big numeric system files: the loader's shortcuts (tag resolution of plain numbers, rows of
numbers built directly, each distinct number text converted once) read exactly what PyYAML's
safe loader and the general conversion read, and refuse what they refuse."""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
import yaml
from hypothesis import example, given, settings
from hypothesis import strategies as st

from kfcrit.errors import InputError
from kfcrit.io import systemfile
from kfcrit.io.jsonio import jsonable
from kfcrit.io.systemfile import ExactLoader, YamlNumber, read_system_file
from kfcrit.io.typed import RecordError, from_json
from kfcrit.model.exprparse import general_number_from_text, parse_expression

SCALARS = ["0", "1", "-1", "+1", "007", "00", "-0", "0.5", "-0.5", "1.", "1.e+5", "1.0e5",
           "1.0e+5", "1_0", "1:30", ".5", "1e5", "0x1F", "0o17", "0b11", "+.inf", ".nan",
           "12:30:00.5", "2001-12-14", "+0.0", "1.5E-07", "١٢", "٣.٥", "1.0\n", "9" * 400 + ".5",
           "true", "no", "~", "null", "", "=", "<<", "-", "1e-3", "6.8523015e+5",
           "685.230_15e+03", "-.5", "1.5e", "1.5e+", "0.1.2"]


def resolved(loader_class: type, value: str) -> str:
    return loader_class("").resolve(yaml.ScalarNode, value, (True, False))


@pytest.mark.parametrize("value", SCALARS)
def test_plain_scalars_get_the_safe_resolvers_tag(value: str) -> None:
    assert resolved(ExactLoader, value) == resolved(yaml.SafeLoader, value)


@settings(max_examples=400, deadline=None)
@given(st.text(alphabet="0123456789.eE+-_:x ", max_size=16))
@example("-0.20056088166815003")
def test_generated_scalars_get_the_safe_resolvers_tag(value: str) -> None:
    assert resolved(ExactLoader, value) == resolved(yaml.SafeLoader, value)


def test_quoted_and_tagged_numbers_stay_strings() -> None:
    doc = yaml.load('A: [["1.5", !!str 2.5, 0.25, 3]]', Loader=ExactLoader)
    row = doc["A"][0]
    assert [type(v) for v in row] == [str, str, YamlNumber, YamlNumber]
    assert row == ["1.5", "2.5", "0.25", "3"]


def test_an_alias_inside_a_row_is_refused_even_without_the_scan() -> None:
    with pytest.raises(InputError, match="aliases are not allowed"):
        yaml.load("x: &a 1.5\nA: [[*a, 2.5]]\n", Loader=ExactLoader)
    with pytest.raises(InputError, match="aliases are not allowed"):
        yaml.load("A: [&a [1.5, 2.5], *a]\n", Loader=ExactLoader)


def safe_document(text: str):
    """The reference reading: PyYAML's pure-Python safe loader, every int and float scalar
    kept as its text."""
    class Reference(yaml.SafeLoader):
        pass

    for tag in ("tag:yaml.org,2002:int", "tag:yaml.org,2002:float"):
        Reference.add_constructor(tag, lambda loader, node: ("number", node.value))
    return yaml.load(text, Loader=Reference)


def as_reference(obj):
    if isinstance(obj, YamlNumber):
        return ("number", str(obj))
    if isinstance(obj, list):
        return [as_reference(v) for v in obj]
    if isinstance(obj, dict):
        return {k: as_reference(v) for k, v in obj.items()}
    return obj


ENTRY = st.one_of(
    st.floats(allow_nan=False, allow_infinity=False, width=64).map(repr),
    st.integers(-10**20, 10**20).map(str),
    st.sampled_from(['"sqrt(2)"', '"1/3"', "1e5", "1.0e5", ".5", "-.5", "007", "1_000",
                     "0x1F", "true", "null", ".inf", ".nan", "1e999", "'2.5'"]),
)


@settings(max_examples=150, deadline=None)
@given(st.lists(st.lists(ENTRY, min_size=1, max_size=5), min_size=1, max_size=5))
def test_matrices_read_as_the_safe_loader_reads_them(rows: list[list[str]]) -> None:
    text = "A: [" + ", ".join("[" + ", ".join(r) + "]" for r in rows) + "]\n"
    assert as_reference(yaml.load(text, Loader=ExactLoader)) == safe_document(text)


def general_numbers(obj, where: str):
    """The general conversion, entry by entry: the reference for ``_exact_numbers``."""
    if isinstance(obj, YamlNumber):
        return general_number_from_text(str(obj), where)
    if isinstance(obj, list):
        return [general_numbers(v, f"{where}[{i}]") for i, v in enumerate(obj)]
    return obj


def converted(fn, doc, where: str):
    try:
        return ("ok", fn(doc, where))
    except Exception as exc:  # noqa: BLE001 - the outcome is what is compared
        return ("error", type(exc), str(exc), getattr(exc, "field", None))


NUMBER_TEXT = st.one_of(
    st.floats(allow_nan=False, allow_infinity=False, width=64).map(repr),
    st.sampled_from(["0", "0.5", "-0.0", "1e301", "1e-301", "1.5e+400", "0.5", "1" * 61,
                     "0.1", "0.1", "7", "-7", ".nan", "1_0"]))


@settings(max_examples=150, deadline=None)
@given(st.lists(st.lists(NUMBER_TEXT, min_size=1, max_size=4), min_size=1, max_size=4))
def test_exact_numbers_are_the_general_conversion(rows: list[list[str]]) -> None:
    doc = [[YamlNumber(v) for v in row] for row in rows]
    fast = converted(systemfile._exact_numbers, doc, "A")
    general = converted(general_numbers, doc, "A")
    assert fast == general
    if fast[0] == "ok":
        assert [type(v) for row in fast[1] for v in row] == \
            [type(v) for row in general[1] for v in row]


def test_a_bad_entry_after_a_repeated_one_is_named() -> None:
    doc = [[YamlNumber("0.5"), YamlNumber("0.5")], [YamlNumber("0.5"), YamlNumber("1e999")]]
    with pytest.raises(Exception) as info:
        systemfile._exact_numbers(doc, "Q")
    assert info.value.field == "Q[1][1]"


def write(path: Path, A, C, Q, R) -> Path:
    def mat(M):
        return "[" + ", ".join("[" + ", ".join(v for v in row) + "]" for row in M) + "]"

    path.write_text(f"name: t\nA: {mat(A)}\nC: {mat(C)}\nQ: {mat(Q)}\nR: {mat(R)}\n"
                    "channel:\n  model: bernoulli\n  arrival_probability: 0.9\n")
    return path


def test_a_random_numeric_file_is_the_system_of_its_exact_numbers(tmp_path: Path) -> None:
    # the reference system is built from the numbers' texts by the expression parser
    rng = np.random.default_rng(5)
    n, m = 7, 3
    A = [[repr(float(v)) for v in row] for row in rng.normal(size=(n, n)) / 3]
    C = [[repr(float(v)) for v in row] for row in rng.normal(size=(m, n))]
    G = rng.normal(size=(n, n))
    Q = [[repr(float(v)) for v in row] for row in G @ G.T + np.eye(n)]
    Q = [[Q[min(i, j)][max(i, j)] for j in range(n)] for i in range(n)]   # exactly symmetric
    R = [["2" if i == j else "0" for j in range(m)] for i in range(m)]
    spec = read_system_file(write(tmp_path / "s.yaml", A, C, Q, R))
    s = spec.system
    for name, texts in (("A", A), ("C", C), ("Q", Q), ("R", R)):
        exact = sp.ImmutableMatrix([[parse_expression(t) for t in row] for row in texts])
        assert getattr(s, name) == exact
        assert getattr(s, name.lower()).tolist() == [[float(v) for v in row]
                                                    for row in exact.tolist()]
    assert s.exact is True
    assert s.matrices_text()["A"][0][0] == sp.sstr(parse_expression(A[0][0]))


def test_errors_of_a_numeric_file_name_the_entry(tmp_path: Path) -> None:
    A = [["0.5", "0.25"], ["0.25", "1e999"]]
    path = write(tmp_path / "s.yaml", A, [["1", "0"]], [["1", "0"], ["0", "1"]], [["1"]])
    with pytest.raises(InputError) as info:
        read_system_file(path)
    assert info.value.field == "A[1][1]" and "out of range" in str(info.value)


@dataclasses.dataclass(frozen=True)
class Rows:
    texts: list[list[str]]
    values: tuple[float, ...]
    counts: list[int]
    matrix: list[list[float | None]]
    labels: list[str | None]


def test_typed_lists_of_plain_items_read_as_item_by_item() -> None:
    good = {"texts": [["1/2", "3"], []], "values": [1, 2.5, -0.0], "counts": [1, 2],
            "matrix": [[1.5, None, 2]], "labels": ["a", None]}
    out = from_json(Rows, good)
    assert out == Rows([["1/2", "3"], []], (1, 2.5, -0.0), [1, 2], [[1.5, None, 2]], ["a", None])
    assert type(out.values) is tuple and type(out.counts) is list
    for bad, message in (({**good, "values": [1.0, True]}, "record.values[1]: must be a number"),
                         ({**good, "values": [1.0, "x"]}, "record.values[1]: must be a number"),
                         ({**good, "counts": [1, 2.0]}, "record.counts[1]: must be an integer"),
                         ({**good, "counts": [False]}, "record.counts[0]: must be an integer"),
                         ({**good, "texts": [["a", 1]]}, "record.texts[0][1]: must be a string"),
                         ({**good, "texts": [["a"], None]}, "record.texts[1]: must not be null"),
                         ({**good, "matrix": [[1.0, False]]},
                          "record.matrix[0][1]: must be a number"),
                         ({**good, "labels": [None, 3]}, "record.labels[1]: must be a string")):
        with pytest.raises(RecordError) as info:
            from_json(Rows, bad)
        assert str(info.value) == message


JSON_ITEM = st.one_of(st.floats(), st.integers(), st.text(max_size=3), st.none(), st.booleans(),
                      st.floats().map(np.float64), st.integers(-5, 5).map(np.int64))


@settings(max_examples=300, deadline=None)
@given(st.lists(JSON_ITEM, max_size=8), st.booleans())
def test_lists_become_json_as_their_items_do(items: list, as_tuple: bool) -> None:
    # the reference: each item converted on its own (the scalar rules: non-finite → None)
    value = tuple(items) if as_tuple else items
    out = jsonable(value)
    assert type(out) is list
    assert out == [jsonable(v) for v in items]
    assert [type(v) for v in out] == [type(jsonable(v)) for v in items]
    assert jsonable([items, items]) == [out, out]


def test_reading_pauses_the_collector_and_restores_it(tmp_path: Path) -> None:
    import gc

    good = write(tmp_path / "good.yaml", [["0.5"]], [["1"]], [["1"]], [["1"]])
    bad = write(tmp_path / "bad.yaml", [["1e999"]], [["1"]], [["1"]], [["1"]])
    seen = []
    with systemfile.paused_gc():
        seen.append(gc.isenabled())
    assert seen == [False] and gc.isenabled()
    read_system_file(good)
    assert gc.isenabled()
    with pytest.raises(InputError):
        read_system_file(bad)
    assert gc.isenabled()
    gc.disable()
    try:
        read_system_file(good)
        assert not gc.isenabled()   # a caller's choice is kept
    finally:
        gc.enable()
