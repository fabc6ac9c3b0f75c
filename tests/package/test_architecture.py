"""The package's architecture, enforced: layers, no cycles, no private imports, small modules.

Layers, lowest first (README, "Architecture"): errors/version → model → io, records → theory → sim, link →
analysis → views → api, cli → bench. The import graph is read with ``ast`` from every module of
``kfcrit/`` — function-level imports included, since they are imports all the same.
"""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "kfcrit"

LAYERS = {"errors": 0, "version": 0, "defaults": 0, "model": 1, "io": 2, "records": 2, "theory": 3,
          "sim": 4, "link": 4, "analysis": 5, "views": 6, "api": 7, "cli": 7, "bench": 8}
"""Rank of each top-level part of the package; a module may import only ranks ≤ its own, and
the two rank-4 siblings (sim, link) not each other."""
FACADE = {"kfcrit", "kfcrit.__main__"}
"""The package's public face (lazy re-exports by name, and ``python -m kfcrit``): above all."""
MAX_LINES = 1000


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def modules() -> dict[str, Path]:
    return {module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def imports_of(name: str, path: Path) -> list[tuple[str, list[str], int]]:
    """(imported module, imported names, line) for every import in the module, anywhere."""
    tree = ast.parse(path.read_text(), filename=str(path))
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.extend((a.name, [], node.lineno) for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            out.append((target, [a.name for a in node.names], node.lineno))
    return out


def resolve(target: str, names: list[str], known: dict[str, Path]) -> list[str]:
    """The kfcrit modules an import statement loads (``from pkg import mod`` included)."""
    if not target.startswith("kfcrit"):
        return []
    found = [target] if target in known else []
    found += [f"{target}.{n}" for n in names if f"{target}.{n}" in known]
    return found


def graph() -> dict[str, set[str]]:
    known = modules()
    edges: dict[str, set[str]] = {m: set() for m in known}
    for name, path in known.items():
        for target, names, _ in imports_of(name, path):
            edges[name].update(m for m in resolve(target, names, known) if m != name)
    return edges


def layer(module: str) -> int | None:
    if module in FACADE:
        return None
    part = module.split(".")[1]
    return LAYERS[part]


def test_every_module_is_in_a_layer() -> None:
    unknown = [m for m in modules() if m not in FACADE and m.split(".")[1] not in LAYERS]
    assert not unknown, f"modules outside the layers: {unknown}"


def test_lower_layers_never_import_higher_ones() -> None:
    bad = []
    for src, targets in graph().items():
        for dst in targets:
            if dst in FACADE and src not in FACADE:
                if dst == "kfcrit":
                    continue  # ``from kfcrit import __version__``-style package attributes
                bad.append((src, dst))
                continue
            ls, ld = layer(src), layer(dst)
            if ls is None or ld is None:
                continue
            sibling = ls == ld == 4 and src.split(".")[1] != dst.split(".")[1]
            if ld > ls or sibling:
                bad.append((src, dst))
    assert not bad, "upward (or sideways sim ↔ link) imports: " + ", ".join(
        f"{s} → {d}" for s, d in sorted(bad))


def test_no_import_cycles() -> None:
    edges = {m: {d for d in ds if d not in FACADE} for m, ds in graph().items()
             if m not in FACADE}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    cycles: list[list[str]] = []
    counter = [0]

    def visit(v: str) -> None:  # Tarjan's strongly connected components
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in edges.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                cycles.append(sorted(comp))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    assert not cycles, f"import cycles: {cycles}"


def test_no_private_names_imported_across_modules() -> None:
    known = modules()
    bad = []
    for name, path in known.items():
        for target, names, line in imports_of(name, path):
            if not target.startswith("kfcrit"):
                continue
            for n in names:
                if n.startswith("_") and not n.startswith("__"):
                    bad.append(f"{name}:{line} imports {target}.{n}")
            if target.rpartition(".")[2].startswith("_") and target not in ("kfcrit.__main__",):
                bad.append(f"{name}:{line} imports private module {target}")
    assert not bad, "\n".join(bad)


def test_tests_use_public_names_only() -> None:
    bad = []
    for path in sorted((ROOT / "tests").rglob("*.py")) + sorted((ROOT / "proofs_checks").glob("*.py")):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("kfcrit"):
                bad += [f"{path.name}:{node.lineno} {node.module}.{a.name}" for a in node.names
                        if a.name.startswith("_") and not a.name.startswith("__")]
    assert not bad, "\n".join(bad)


@pytest.mark.parametrize("name", sorted(modules()))
def test_module_size(name: str) -> None:
    lines = modules()[name].read_text().count("\n")
    assert lines <= MAX_LINES, f"{name} has {lines} lines (limit {MAX_LINES}): split by concern"


def test_nothing_outside_the_repository_is_read() -> None:
    """Tests, proof checks and the package never name the folders beside the repository."""
    needles = ("../shared", "/work/shared", "parents[3]", "ROOT.parent")
    bad = []
    for folder in ("tests", "proofs_checks", "kfcrit"):
        for path in sorted((ROOT / folder).rglob("*.py")):
            if path.name == "test_architecture.py" or "bench" in path.parts:
                continue
            text = path.read_text()
            bad += [f"{path.relative_to(ROOT)}: {n}" for n in needles if n in text]
    assert not bad, "\n".join(bad)


def test_the_checker_sees_a_known_upward_import(tmp_path: Path) -> None:
    """The import reader itself: a function-level upward import is an import."""
    src = tmp_path / "m.py"
    src.write_text("def f():\n    from kfcrit.views.text.terminal import summary\n    return summary\n")
    found = imports_of("kfcrit.model.m", src)
    assert ("kfcrit.views.text.terminal", ["summary"], 2) in found


MAX_MODULES_PER_FOLDER = 12
"""A package folder with more modules than this is split into subpackages by concern."""


def test_no_folder_holds_more_than_twelve_modules() -> None:
    crowded = {}
    for folder in [PACKAGE, *sorted(p for p in PACKAGE.rglob("*") if p.is_dir())]:
        if folder.name == "__pycache__":
            continue
        count = len([p for p in folder.glob("*.py") if p.name != "__init__.py"])
        if count > MAX_MODULES_PER_FOLDER:
            crowded[str(folder.relative_to(ROOT))] = count
    assert not crowded, f"folders over {MAX_MODULES_PER_FOLDER} modules: {crowded}"


def test_the_python_api_never_imports_the_command_line() -> None:
    bad = [(src, dst) for src, dsts in graph().items() if src.startswith("kfcrit.api")
           for dst in dsts if dst.startswith("kfcrit.cli")]
    assert not bad, f"the API imports the CLI: {bad}"



def public_definitions() -> dict[str, list[str]]:
    """Module-level public classes and functions of the package, by name."""
    found: dict[str, list[str]] = {}
    for name, path in modules().items():
        tree = ast.parse(path.read_text())
        for node in tree.body:
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)) \
                    and not node.name.startswith("_"):
                found.setdefault(node.name, []).append(name)
    return found


def test_one_name_per_thing() -> None:
    dups = {k: v for k, v in public_definitions().items() if len(v) > 1}
    assert not dups, f"public names defined in more than one module: {dups}"


def test_the_name_checker_sees_a_duplicate() -> None:
    found = public_definitions()
    assert found["analyze"] == ["kfcrit.api.notebook"]
    assert "AnalysisRecord" in found and "Analysis" in found
