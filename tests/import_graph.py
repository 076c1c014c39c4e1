"""The import graph of the casadical package, read from the source (no module is imported).

Every ``import`` and ``from ... import`` statement counts, at module level
or inside a function (a lazy import is still a dependency: it runs the
first time the function does), except those under ``if TYPE_CHECKING:``.
``from pkg import x`` counts as an import of ``pkg`` and, when there is one,
of its submodule ``x``. Run as a script, it prints the import cycles (strongly connected
components of more than one module), then those among the packages (a package and top-level module is one
node: ``casadical.diagnosis``, ``casadical.result``) and, without any, each package's floor::

    python tests/import_graph.py
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

PACKAGE = "casadical"
ROOT = Path(__file__).resolve().parent.parent / PACKAGE


def modules(root: Path = ROOT) -> dict[str, Path]:
    """Dotted module name -> file, for every module of the package."""
    out = {}
    for f in sorted(root.rglob("*.py")):
        parts = list(f.relative_to(root.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        out[".".join(parts)] = f
    return out


def _type_checking(node: ast.AST) -> bool:
    test = getattr(node, "test", None)
    return isinstance(node, ast.If) and (
        (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING")
        or (isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"))


def _imports(tree: ast.AST):
    """Import statements of a module, skipping ``if TYPE_CHECKING:`` blocks."""
    stack = [tree]
    while stack:
        node = stack.pop()
        for child in ast.iter_child_nodes(node):
            if _type_checking(child):
                stack.extend(child.orelse)          # the else branch runs
                continue
            if isinstance(child, (ast.Import, ast.ImportFrom)):
                yield child
            stack.append(child)


def graph(root: Path = ROOT) -> dict[str, set[str]]:
    """Module -> the package's modules it imports (directly)."""
    mods = modules(root)
    out: dict[str, set[str]] = {m: set() for m in mods}
    for name, path in mods.items():
        is_pkg = path.name == "__init__.py"
        here = name.split(".") if is_pkg else name.split(".")[:-1]
        for node in _imports(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            else:
                base = here[:len(here) - node.level + 1] if node.level else []
                stem = ".".join(base + ([node.module] if node.module else []))
                # ``from pkg import sub`` runs pkg's __init__ and then the submodule: both count
                targets = [stem] + [f"{stem}.{a.name}" for a in node.names if f"{stem}.{a.name}" in mods]
            for t in targets:
                while t and t not in mods:          # a name inside a module: the module
                    t = t.rpartition(".")[0]
                if t and t != name and t.startswith(PACKAGE):
                    out[name].add(t)
    return out


def closure(g: dict[str, set[str]], start: str) -> set[str]:
    """Every module ``start`` imports, directly or through others."""
    seen, todo = set(), [start]
    while todo:
        for t in g[todo.pop()]:
            if t not in seen:
                seen.add(t)
                todo.append(t)
    return seen


def cycles(g: dict[str, set[str]]) -> list[set[str]]:
    """Strongly connected components of more than one module, largest first (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on, stack, out = set(), [], []
    for v0 in g:
        if v0 in index:
            continue
        work = [(v0, iter(sorted(g[v0])))]
        index[v0] = low[v0] = len(index)
        stack.append(v0)
        on.add(v0)
        while work:
            v, it = work[-1]
            for w in it:
                if w not in index:
                    index[w] = low[w] = len(index)
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(g[w]))))
                    break
                if w in on:
                    low[v] = min(low[v], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    comp = set()
                    while True:
                        w = stack.pop()
                        on.discard(w)
                        comp.add(w)
                        if w == v:
                            break
                    if len(comp) > 1:
                        out.append(comp)
    return sorted(out, key=len, reverse=True)


def unit(module: str) -> str:
    """The package (or top-level module) a module belongs to: ``casadical.diagnosis._words`` -> ``diagnosis``,
    ``casadical.result`` -> ``result``; the package's own ``__init__`` -> ``casadical``."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else PACKAGE


def packages(g: dict[str, set[str]]) -> dict[str, set[str]]:
    """Each package or top-level module -> the others its modules import (lazy imports too). The package's own
    ``__init__`` (``casadical``: its version and lazy public names) is left out: it imports nothing eagerly."""
    out: dict[str, set[str]] = {unit(m): set() for m in g if unit(m) != PACKAGE}
    for a, bs in g.items():
        for b in bs:
            if PACKAGE not in (unit(a), unit(b)) and unit(a) != unit(b):
                out[unit(a)].add(unit(b))
    return out


def floors(p: dict[str, set[str]]) -> dict[str, int]:
    """Each package's floor: 1 for what imports none of the others, else one above the highest it imports (a
    package graph with a cycle has no floors: ValueError)."""
    if cycles(p):
        raise ValueError(f"the packages import each other in a loop: {cycles(p)}")
    out: dict[str, int] = {}

    def floor(u: str) -> int:
        if u not in out:
            out[u] = 1 + max((floor(v) for v in p[u]), default=0)
        return out[u]
    for u in p:
        floor(u)
    return out


def floor_lines(g: dict[str, set[str]]) -> list[str]:
    """The floors in words, top floor first: ``floor 5  terms`` (docs/architecture.md quotes them)."""
    f = floors(packages(g))
    return [f"floor {k:2d}  " + "  ".join(sorted(u for u in f if f[u] == k))
            for k in sorted(set(f.values()), reverse=True)]


if __name__ == "__main__":
    g = graph()
    found = cycles(g)
    print(f"{len(g)} modules, {sum(map(len, g.values()))} imports; {len(found)} cycle(s)")
    for comp in found:
        print(f"{len(comp)} modules: {', '.join(sorted(comp))}")
    p = packages(g)
    found = cycles(p)
    print(f"{len(p)} packages and top-level modules; {len(found)} cycle(s) among them")
    for comp in found:
        print(f"{len(comp)} packages: {', '.join(sorted(comp))}")
    if not found:
        print("\n".join(floor_lines(g)))
    sys.exit(0)
