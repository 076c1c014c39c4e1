"""The diagnosis' stages share what they judge by through modules of their own, not through each other's
internals (issue 46): no module of the package imports a private name of another, and no stage module imports
the rules of the worst case from another stage (they live in :mod:`casadical.diagnosis._worst`)."""

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[2] / "casadical" / "diagnosis"


def imports(path: Path):
    """(line, module, name) of every ``from .module import name`` of ``path``."""
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.level == 1:
            for alias in node.names:
                yield node.lineno, node.module or "", alias.name


def test_no_module_imports_another_ones_private_names():
    found = [f"{p.name}:{line}: from .{module} import {name}" for p in sorted(PACKAGE.glob("*.py"))
             for line, module, name in imports(p) if name.startswith("_")]
    assert not found, "private names imported from another module of casadical.diagnosis:\n" + "\n".join(found)


def test_stages_import_no_stage_for_its_rules():
    from casadical.diagnosis import STAGES

    stages = {f.__module__.rsplit(".", 1)[1] for f in STAGES}
    shared = {"WORST_SHARE", "SET_ASIDE_WEIGHT", "noise_band", "validation_note", "Held", "own_parameters"}
    found = [f"{p.name}:{line}: from .{module} import {name}" for p in sorted(PACKAGE.glob("*.py"))
             if p.stem != "_pipeline" for line, module, name in imports(p) if module in stages and name in shared]
    assert not found, "a stage's rules imported from another stage:\n" + "\n".join(found)


def test_the_search_sees_an_import():
    """The test can fail: a private name and a stage's rule imported are both found."""
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "x.py"
        p.write_text("from .never_worse import noise_band\nfrom .search import _private\n")
        assert [(m, n) for _, m, n in imports(p)] == [("never_worse", "noise_band"), ("search", "_private")]
