"""calib's modules import one way: no import cycles, no module importing another module's ``_private`` names, and the
calibration's modules short enough to read in one sitting.

The walk reads every ``import`` and ``from … import`` of calib's source with ``ast`` — at any depth, so an import
inside a function (the way a cycle hides) counts as much as one at the top — and resolves relative imports.  A cycle
is a strongly connected component of that graph; a private import is ``from calib.x import _y`` from a module other
than ``calib.x``.  The walker is itself tested on a small package with both faults, so the checks cannot pass
vacuously.
"""

from __future__ import annotations

import ast
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# the longest a function in the calibration's folders may be (lines, the signature and docstring included); a function
# that must stay longer (none today) is named here with its allowance
MAX_FUNCTION_LINES = 120
LONG_FUNCTION_ALLOWANCE: dict[str, int] = {}
SHORT_FUNCTION_FOLDERS = ("calib/session", "calib/scoring")


def _modules(root: Path, package: str) -> dict[str, Path]:
    """Dotted module name → file for every .py under ``root / package`` (a package is its ``__init__``)."""
    out = {}
    for p in sorted((root / package).rglob("*.py")):
        parts = list(p.relative_to(root).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = p
    return out


def _resolve(name: str, modules: dict[str, Path]) -> str | None:
    """The module ``name`` names, or the nearest enclosing one (``calib.x.attr`` → ``calib.x``); None outside."""
    while name and name not in modules:
        name = name.rpartition(".")[0]
    return name or None


def _absolute(node: ast.ImportFrom, module: str, is_package: bool) -> str:
    """The absolute module of a ``from … import`` (relative ones resolved against ``module``)."""
    if node.level == 0:
        return node.module or ""
    base = module.split(".") if is_package else module.split(".")[:-1]
    base = base[:len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def import_graph(root: Path, package: str) -> tuple[dict[str, set[str]], list[str]]:
    """(module → the package's modules it imports, at any depth; the private imports across modules)."""
    modules = _modules(root, package)
    graph: dict[str, set[str]] = {m: set() for m in modules}
    private = []
    for m, path in modules.items():
        is_package = path.name == "__init__.py"
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), filename=str(path))):
            if isinstance(node, ast.ImportFrom):
                src = _absolute(node, m, is_package)
                for alias in node.names:
                    target = _resolve(f"{src}.{alias.name}", modules)
                    if target and target != m:
                        graph[m].add(target)
                    owner = _resolve(src, modules)
                    if alias.name.startswith("_") and not alias.name.startswith("__") and owner and owner != m:
                        private.append(f"{m}:{node.lineno} from {src} import {alias.name}")
            elif isinstance(node, ast.Import):
                for alias in node.names:
                    target = _resolve(alias.name, modules)
                    if target and target != m:
                        graph[m].add(target)
    return graph, private


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []
    counter = [0]

    def visit(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
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
                found.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_calib_has_no_import_cycles():
    graph, _ = import_graph(ROOT, "calib")
    assert len(graph) > 100 and sum(len(e) for e in graph.values()) > 200   # the walk saw calib
    assert graph["calib.session.paper"] >= {"calib.session.prepare", "calib.session.kernel"}
    found = cycles(graph)
    assert not found, "import cycles in calib (a module must not import, even inside a function, one that imports " \
                      "it back; move the shared part down):\n" + "\n".join(" ↔ ".join(c) for c in found)


def test_calib_imports_no_private_names_across_modules():
    _, private = import_graph(ROOT, "calib")
    assert not private, "a module imports another module's _private names (make the name public in its one module, " \
                        "or move it):\n" + "\n".join(private)


def test_the_import_walk_catches_function_level_cycles_and_private_imports(tmp_path):
    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "sub" / "__init__.py").write_text("")
    (pkg / "a.py").write_text(textwrap.dedent("""
        from pkg.b import helper
        _secret = 1
    """))
    (pkg / "b.py").write_text(textwrap.dedent("""
        def helper():
            from pkg import a          # the lazy import that hides a cycle
            return a
    """))
    (pkg / "sub" / "c.py").write_text(textwrap.dedent("""
        from ..a import _secret        # relative, and private
        import pkg.sub.d
    """))
    (pkg / "sub" / "d.py").write_text("from pkg.a import helper\n")   # a re-exported public name: fine
    graph, private = import_graph(tmp_path, "pkg")
    assert cycles(graph) == [["pkg.a", "pkg.b"]]
    assert private == ["pkg.sub.c:2 from pkg.a import _secret"]
    assert graph["pkg.sub.c"] == {"pkg.a", "pkg.sub.d"}


def test_calibration_functions_are_short_enough_to_read():
    long = []
    for folder in SHORT_FUNCTION_FOLDERS:
        for path in sorted((ROOT / folder).rglob("*.py")):
            module = ".".join(path.relative_to(ROOT).with_suffix("").parts)
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                    name = f"{module}.{node.name}"
                    n = node.end_lineno - node.lineno + 1
                    if n > LONG_FUNCTION_ALLOWANCE.get(name, MAX_FUNCTION_LINES):
                        long.append(f"{name}: {n} lines")
    assert not long, f"functions longer than {MAX_FUNCTION_LINES} lines (split them by step):\n" + "\n".join(long)
