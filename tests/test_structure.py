"""The package's structure, read from its source with ast: functions a reader can hold, no private
imports across subpackages, one definition of the noise-free rule, the layers of
docs/reference/layout.md (no import back up, no circle, none hidden in a function), no ``Any`` dodge."""

from __future__ import annotations

import ast
import re
import subprocess
import sys
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
    """One constant (regression/problem.py NOISE_FREE), read in one function (rounding_level, which
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
    assert assigned == ["regression/problem.py"]
    assert read_in == ["regression/problem.py:rounding_level"]
    assert rule_functions == ["regression/problem.py:is_noise_free"]


# ----------------------------------------------------------------- layers and circles
LAYOUT = PACKAGE.parent / "docs" / "reference" / "layout.md"
#: ``python -m casep``: the entry point, above every layer (it runs the command line).
ENTRY_POINT = "__main__.py"


def _layers() -> dict[str, int]:
    """The layer of each subpackage (``cli``) and root module (``units.py``) from the table of
    docs/reference/layout.md (``| 7 | `casep/cli/` | ...``)."""
    layers: dict[str, int] = {}
    for line in LAYOUT.read_text().splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) < 3 or not cells[0].isdigit():
            continue
        for name in re.findall(r"`([^`]+)`", cells[1]):
            name = name.removeprefix("casep/")
            layers[name.rstrip("/")] = int(cells[0])
    return layers


LAYERS = _layers()


def _unit(path: str) -> str:
    """The unit a layer is given to: the subpackage of a module (``cli``), or a root module itself (``units.py``)."""
    return path.split("/")[0] if "/" in path else path


def _target(module: str) -> str:
    """The unit an imported module belongs to (``casep.cli.app`` -> ``cli``, ``casep.units`` -> ``units.py``)."""
    parts = module.split(".")
    return parts[1] if len(parts) > 2 or (PACKAGE / parts[1]).is_dir() else f"{parts[1]}.py"


def _all_imports(tree: ast.Module):
    """Every import of casep in a module, at any depth (in functions, under TYPE_CHECKING): (node, module)."""
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and (node.level or (node.module or "").split(".")[0] == "casep"):
            yield node, ("." * node.level) + (node.module or "")
            if node.module and node.level == 0:
                for a in node.names:  # `from casep.regression import linalg`: the module linalg
                    if (PACKAGE.parent / (node.module + "." + a.name).replace(".", "/")).with_suffix(".py").exists():
                        yield node, f"{node.module}.{a.name}"
        elif isinstance(node, ast.Import):
            yield from ((node, a.name) for a in node.names if a.name.split(".")[0] == "casep")


def test_layout_lists_every_subpackage_and_root_module():
    units = {_unit(path) for path, _ in MODULES} - {"__init__.py", ENTRY_POINT}
    assert not units - set(LAYERS), f"not in the table of docs/reference/layout.md: {sorted(units - set(LAYERS))}"
    assert not set(LAYERS) - units, f"in docs/reference/layout.md but not in casep: {sorted(set(LAYERS) - units)}"


def _upward_imports(modules: list[tuple[str, ast.Module]], layers: dict[str, int]) -> list[str]:
    top = max(layers.values()) + 1
    bad = []
    for path, tree in modules:
        mine = _unit(path)
        here = top if mine == ENTRY_POINT else 0 if mine == "__init__.py" else layers[mine]
        for node, module in _all_imports(tree):
            if module.startswith("."):
                bad.append(f"{path}:{node.lineno} a relative import ({module}): write it absolute")
                continue
            if module == "casep":
                bad.append(f"{path}:{node.lineno} imports casep itself: import the module that defines the name")
                continue
            there = layers.get(_target(module), top)
            if there > here:
                bad.append(f"{path}:{node.lineno} ({mine}, layer {here}) imports {module} (layer {there})")
    return bad


def test_no_import_runs_back_up():
    """A package imports only from its own layer or below (docs/reference/layout.md), also inside
    functions and under TYPE_CHECKING: a lazy import is for start-up time, never a way up."""
    bad = _upward_imports(MODULES, LAYERS)
    assert not bad, "imports against the layers of docs/reference/layout.md: " + "; ".join(bad)


def test_the_layer_rule_sees_function_level_imports():
    tree = ast.parse("def f():\n    from casep.cli.app import main\n")
    assert _upward_imports([("noise/x.py", tree)], {"noise": 2, "cli": 10}) == \
        ["noise/x.py:2 (noise, layer 2) imports casep.cli.app (layer 10)"]
    assert _upward_imports([("cli/x.py", tree)], {"noise": 2, "cli": 10}) == []


def _module_name(path: str) -> str:
    name = "casep." + path.removesuffix(".py").replace("/", ".")
    return name.removesuffix(".__init__")


def _circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one node (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
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
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def _graphs(modules: list[tuple[str, ast.Module]]) -> tuple[dict[str, set[str]], dict[str, set[str]]]:
    """(module -> modules it imports, subpackage -> subpackages it imports), every import counted."""
    names = {_module_name(path) for path, _ in modules}
    mods: dict[str, set[str]] = {n: set() for n in names}
    packages: dict[str, set[str]] = {}
    for path, tree in modules:
        me = _module_name(path)
        for _, module in _all_imports(tree):
            while module and module not in names:  # `from casep.x.y import name`: the module casep.x.y
                module = module.rpartition(".")[0]
            if module and module != me:
                mods[me].add(module)
                a, b = _unit(path), _target(module)
                if a != b and "." not in a + b:  # two subpackages (a root module is "units.py")
                    packages.setdefault(a, set()).add(b)
    return mods, packages


def test_no_import_circle_between_subpackages_or_modules():
    """No two subpackages import each other, directly or through others; nor two modules, imports
    inside functions and under TYPE_CHECKING counted, so that no import sits in a function to hide
    a circle (a lazy import is for start-up time only)."""
    mods, packages = _graphs(MODULES)
    assert not _circles(packages), f"subpackages in a circle: {_circles(packages)}"
    assert not _circles(mods), f"modules in a circle: {_circles(mods)}"


def test_the_circle_rule_sees_an_import_hidden_in_a_function():
    a = ast.parse("from casep.b.y import g\n")
    b = ast.parse("def g():\n    from casep.a.x import f\n")
    mods, packages = _graphs([("a/x.py", a), ("b/y.py", b)])
    assert _circles(mods) == [["casep.a.x", "casep.b.y"]]
    assert _circles(packages) == [["a", "b"]]


def test_no_type_is_dodged_with_any():
    """No alias of ``Any`` (``Problem = Any``): a type that cannot be imported without a circle is a
    layering mistake, not a typing one."""
    bad = []
    for path, tree in MODULES:
        for node in ast.walk(tree):
            value = node.value if isinstance(node, (ast.Assign, ast.AnnAssign)) else None
            if (isinstance(value, ast.Name) and value.id == "Any") or \
                    (isinstance(value, ast.Attribute) and value.attr == "Any"):
                bad.append(f"{path}:{node.lineno}")
    assert not bad, "names bound to Any: " + "; ".join(bad)


def test_casep_analysis_is_a_deprecated_reexport_nothing_in_casep_imports():
    """casep 0.3's ``casep.analysis`` names still resolve for one release, with a DeprecationWarning."""
    users = [f"{path}:{node.lineno}" for path, tree in MODULES for node, module in _all_imports(tree)
             if module == "casep.analysis" or module.startswith("casep.analysis.")]
    assert not users, f"casep imports its deprecated casep.analysis: {users}"
    code = ("import warnings\n"
            "with warnings.catch_warnings(record=True) as w:\n"
            "    warnings.simplefilter('always')\n"
            "    import casep.analysis as a\n"
            "import casep.regression, casep.checks, casep.noise\n"
            "assert any(issubclass(x.category, DeprecationWarning) and 'casep.regression' in str(x.message)\n"
            "           for x in w)\n"
            "assert a.Problem is casep.regression.Problem and a.check_fit is casep.checks.check_fit\n"
            "assert a.fit_noise is casep.noise.fit_noise and all(getattr(a, n) is not None for n in a.__all__)\n")
    subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True)


def test_casep_builds_a_flights_problem_after_its_checks():
    """``Problem.from_flight`` judges nothing: casep's own code builds a flight's problem through
    ``casep.checks.flight.flight_problem`` (the checks before estimation, then the problem)."""
    calls = [f"{path}:{node.lineno}" for path, tree in MODULES for node in ast.walk(tree)
             if isinstance(node, ast.Attribute) and node.attr == "from_flight"
             and path not in ("regression/problem.py", "checks/flight.py")]
    assert not calls, "Problem.from_flight called without the checks (use flight_problem): " + "; ".join(calls)


#: Where a registered method may be dispatched by its registry entry: the one entry point of every fit
#: (``fit`` and what it calls), and the registry that defines the dispatch (``Method.solve``, ``run_method``).
DISPATCHERS = ("estimators/solve.py", "estimators/registry.py", "estimators/_options.py")


def _method_dispatches(modules: list[tuple[str, ast.Module]]) -> list[str]:
    """Calls of ``.solve``/``.core`` on a registry entry (``METHODS[...]`` under any name it is imported as, or a
    name bound to one in the same module) and of ``run_method``, outside :data:`DISPATCHERS`."""
    bad = []
    for path, tree in modules:
        if path in DISPATCHERS:
            continue
        registry = {a.asname or a.name for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)
                    and n.module == "casep.estimators.registry" for a in n.names if a.name == "METHODS"}

        def entry(v: ast.AST, registry: set[str] = registry) -> bool:
            return isinstance(v, ast.Subscript) and isinstance(v.value, ast.Name) and v.value.id in registry

        bound = {t.id for n in ast.walk(tree) if isinstance(n, ast.Assign) and entry(n.value)
                 for t in n.targets if isinstance(t, ast.Name)}
        for n in ast.walk(tree):
            if not isinstance(n, ast.Call):
                continue
            f = n.func
            if isinstance(f, ast.Attribute) and f.attr in ("solve", "core") and (
                    entry(f.value) or (isinstance(f.value, ast.Name) and f.value.id in bound)):
                bad.append(f"{path}:{n.lineno}")
            elif (isinstance(f, ast.Name) and f.id == "run_method") or \
                    (isinstance(f, ast.Attribute) and f.attr == "run_method"):
                bad.append(f"{path}:{n.lineno}")
    return bad


def test_every_path_solves_a_request_through_fit():
    """One flight, several flights, radar, Monte Carlo, the demo and calibration solve the request's method through
    ``casep.estimators.solve.fit`` only: no other module dispatches a method by its registry entry. (The public
    solvers, ``solve_ols`` & co., stay: a check's own least-squares fit, e.g. the Chow test of several flights, is
    not a fit request. ``tests/estimators/test_one_entry_point.py`` shows the same while each path runs.)"""
    bad = _method_dispatches(MODULES)
    assert not bad, "a method dispatched outside fit() (call casep.estimators.solve.fit): " + "; ".join(bad)


def test_the_dispatch_rule_sees_a_method_solved_by_its_entry():
    tree = ast.parse("from casep.estimators.registry import METHODS as R\n"
                     "def f(p):\n    m = R['ols']\n    m.solve(p)\n    R['gls'].solve(p)\n    m.required\n")
    assert _method_dispatches([("workflows/x.py", tree)]) == ["workflows/x.py:4", "workflows/x.py:5"]
    assert _method_dispatches([("estimators/solve.py", tree)]) == []
