"""Public and private (issue 46 item 5, scikit-learn's way): every module of a subpackage is private
(``casadical/P/_m.py``) and the package's ``__all__`` says what is public; the tests, examples and benchmarks
import a public name from its package, never through the private module that defines it."""

import ast
import importlib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "casadical"


def subpackages(root: Path = PACKAGE) -> list[Path]:
    """Every package folder below the top-level package (nested ones too)."""
    return sorted(p.parent for p in root.rglob("__init__.py") if p.parent != root and "__pycache__" not in p.parts)


def public_modules(root: Path = PACKAGE) -> list[str]:
    """Modules of a subpackage whose file name does not start with ``_``: none should be."""
    return [str(f.relative_to(root.parent)) for d in subpackages(root) for f in sorted(d.glob("*.py"))
            if not f.name.startswith("_")]


def dotted(d: Path, root: Path = PACKAGE) -> str:
    return ".".join(d.relative_to(root.parent).parts)


def through_private(tree: ast.AST, public: dict[str, set[str]]) -> list[tuple[int, str]]:
    """(line, ``from casadical.P._m import X``) of every public name ``X`` of ``P`` imported through a private
    module of ``P``."""
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and not node.level and node.module:
            pkg, _, leaf = node.module.rpartition(".")
            if pkg in public and leaf.startswith("_"):
                out += [(node.lineno, f"from {node.module} import {a.name}") for a in node.names
                        if a.name in public[pkg]]
    return out


PACKAGES = [dotted(d) for d in subpackages()]


def test_every_module_of_a_subpackage_is_private():
    assert not public_modules(), "modules to rename to _name.py:\n" + "\n".join(public_modules())


@pytest.mark.parametrize("name", PACKAGES)
def test_every_package_says_its_public_names_and_each_resolves(name):
    package = importlib.import_module(name)
    names = getattr(package, "__all__", None)
    assert names is not None, f"{name} has no __all__"
    assert len(names) == len(set(names)), sorted(n for n in names if names.count(n) > 1)
    missing = [n for n in names if not hasattr(package, n)]
    assert not missing, f"{name}.__all__ names what it does not have: {missing}"
    assert not [n for n in names if n.startswith("_")], names


def test_the_tests_import_public_names_from_their_package():
    public = {name: set(importlib.import_module(name).__all__) for name in PACKAGES}
    found = []
    for folder in ("tests", "examples", "benchmarks"):
        for path in sorted((ROOT / folder).rglob("*.py")):
            found += [f"{path.relative_to(ROOT)}:{line}: {what}"
                      for line, what in through_private(ast.parse(path.read_text(encoding="utf-8")), public)]
    assert not found, f"{len(found)} public names imported through a private module:\n" + "\n".join(found)


def test_the_checks_can_fail(tmp_path):
    """The checks above can fail: a public module file is found, and a public name imported through its private
    module is (a private name through it, or the public name from the package, is not)."""
    pkg = tmp_path / "casadical"
    (pkg / "sub").mkdir(parents=True)
    for f in ("__init__.py", "sub/__init__.py", "sub/_ok.py", "sub/open.py"):
        (pkg / f).write_text("")
    assert public_modules(pkg) == ["casadical/sub/open.py"]
    code = ("from casadical.sub._ok import Public, _private\nfrom casadical.sub import Public\n"
            "def f():\n    from casadical.sub._ok import Public as P\n")
    assert through_private(ast.parse(code), {"casadical.sub": {"Public"}}) == [
        (1, "from casadical.sub._ok import Public"), (4, "from casadical.sub._ok import Public")]
