"""The package's structure, read from its source with ast: functions a reader can hold, no private
imports across subpackages, one definition of the noise-free rule."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "casep"
MAX_FUNCTION_LINES = 100

#: Private *modules* of another subpackage imported today (their public names): the layout change makes
#: these modules public (the atomic writing of :mod:`casep.io`; ``ErrorModel`` is in casep.model.error_model). This
#: list may only shrink: a new import of another subpackage's private module fails the test.
KNOWN_PRIVATE_MODULE_IMPORTS = {
    "casep.io._atomic": {"cli/app.py", "cli/montecarlo.py", "cli/outputs.py", "montecarlo/result.py",
                         "montecarlo/store.py", "reporting/plots.py", "reporting/radar.py", "reporting/report.py",
                         "simulation/earth_fixed.py", "simulation/radar.py", "simulation/simulate.py",
                         "workflows/demo.py"},
    "casep.estimators._base": {"cli/types.py"},
}


def _modules() -> list[tuple[str, ast.Module]]:
    return [(p.relative_to(PACKAGE).as_posix(), ast.parse(p.read_text(), str(p)))
            for p in sorted(PACKAGE.rglob("*.py"))]


MODULES = _modules()


def _code_lines(fn: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    """Lines of a function from its ``def`` to its end, its docstring excluded."""
    n = fn.end_lineno - fn.lineno + 1
    first = fn.body[0]
    if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant) and isinstance(first.value.value, str):
        n -= first.end_lineno - first.lineno + 1
    return n


def _long_functions(modules: list[tuple[str, ast.Module]]) -> list[str]:
    return [f"{path}:{node.lineno} {node.name} ({_code_lines(node)} lines)"
            for path, tree in modules for node in ast.walk(tree)
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and _code_lines(node) > MAX_FUNCTION_LINES]


def test_no_function_over_100_lines():
    long = _long_functions(MODULES)
    assert not long, "functions over 100 lines (docstring excluded): " + "; ".join(long)


def test_the_length_rule_counts_code_not_docstrings():
    """101 lines of code fail, 100 pass, however long the docstring."""
    doc = '    """' + "\n".join(["Doc."] * 50) + '"""\n'
    assert _long_functions([("fake.py", ast.parse("def f():\n" + doc + "    x = 1\n" * 100))]) == \
        ["fake.py:1 f (101 lines)"]
    assert _long_functions([("fake.py", ast.parse("def f():\n" + doc + "    x = 1\n" * 99))]) == []


def _subpackage(path: str) -> str:
    """``cli`` for ``cli/app.py``; ``""`` for a module of casep itself."""
    return path.split("/")[0] if "/" in path else ""


def _imports(tree: ast.Module):
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0 and node.module.startswith("casep."):
            yield node, node.module, [a.name for a in node.names]
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith("casep."):
                    yield node, a.name, []


def test_no_private_name_imported_across_subpackages():
    """``from casep.<other>.x import _name`` (a leading underscore: the other subpackage's own) is refused;
    a private module of another subpackage only where :data:`KNOWN_PRIVATE_MODULE_IMPORTS` lists it."""
    bad, known_seen = [], set()
    for path, tree in MODULES:
        mine = _subpackage(path)
        for node, module, names in _imports(tree):
            parts = module.split(".")
            other = parts[1] if len(parts) > 2 else ""  # casep.<sub>.<module>; casep._version etc. are the root's
            if not other or other == mine:
                continue
            bad += [f"{path}:{node.lineno} imports {module}.{n}" for n in names if n.startswith("_")
                    and not n.startswith("__")]
            if any(p.startswith("_") and not p.startswith("__") for p in parts[2:]):
                if path in KNOWN_PRIVATE_MODULE_IMPORTS.get(module, set()):
                    known_seen.add((module, path))
                else:
                    bad.append(f"{path}:{node.lineno} imports the private module {module}")
    assert not bad, "; ".join(bad)
    stale = {(m, p) for m, ps in KNOWN_PRIVATE_MODULE_IMPORTS.items() for p in ps} - known_seen
    assert not stale, f"no longer imported, remove from KNOWN_PRIVATE_MODULE_IMPORTS: {sorted(stale)}"


def test_one_noise_free_rule():
    """One constant (analysis/problem.py NOISE_FREE), read in one function (rounding_level, which
    is_rounding_level compares with); no other function decides noise-free data on its own."""
    assigned, read_in, rule_functions = [], [], []
    for path, tree in MODULES:
        for node in ast.walk(tree):
            if isinstance(node, (ast.Assign, ast.AnnAssign)):
                targets = node.targets if isinstance(node, ast.Assign) else [node.target]
                assigned += [path for t in targets if isinstance(t, ast.Name) and t.id == "NOISE_FREE"]
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                if "noise_free" in node.name.lower():
                    rule_functions.append(f"{path}:{node.name}")
                if any(isinstance(n, ast.Name) and n.id == "NOISE_FREE" for n in ast.walk(node)):
                    read_in.append(f"{path}:{node.name}")
    assert assigned == ["analysis/problem.py"]
    assert read_in == ["analysis/problem.py:rounding_level"]
    assert rule_functions == ["analysis/problem.py:is_noise_free"]
