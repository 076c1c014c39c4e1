"""Each field of a diagnosis run has one writer (issue 46): a field is set by the one stage whose field it is, or,
where several stages change it (the notes, the steps, the findings, the model under way, the final model), only by
the pipeline installing what each stage returns (:meth:`casadical.diagnosis._state.DiagnosisRun.install`).

The modules of :mod:`casadical.diagnosis` are read with ``ast``: a write is an assignment to ``run.<field>`` (or to
an item or attribute of it, ``+=`` too), a call of a method that changes it in place (``run.notes.append``,
``run.unexplained.excluded_causes.add``), or a call of a method of the run that writes it (``run.install``, the
fields its body sets on ``self``, read from state.py). What a function does to a field it is handed as an argument
is not seen: hand a stage's helper its own lists, not the run's."""

import ast
from collections import defaultdict
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[2] / "casadical" / "diagnosis"
#: methods that change a list, dict or set in place
MUTATORS = {"append", "extend", "insert", "pop", "remove", "clear", "add", "update", "setdefault", "discard",
            "popitem", "sort", "reverse"}


def _field(node: ast.AST, root: str) -> str | None:
    """The field of ``root`` an expression reaches (``run.a.b[0]``: ``a``), or None."""
    while isinstance(node, (ast.Attribute, ast.Subscript)):
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id == root:
            return node.attr
        node = node.value
    return None


def _targets(node: ast.AST):
    if isinstance(node, (ast.Tuple, ast.List)):
        for t in node.elts:
            yield from _targets(t)
    elif isinstance(node, ast.Starred):
        yield from _targets(node.value)
    else:
        yield node


def writes(tree: ast.AST, root: str = "run", methods: dict | None = None):
    """(line, field) of every write of a field of ``root`` in ``tree`` (``methods``: the fields each method of the
    run writes); private fields (caches) left out."""
    methods = methods or {}
    for node in ast.walk(tree):
        targets = []
        if isinstance(node, ast.Assign):
            targets = [t for tt in node.targets for t in _targets(tt)]
        elif isinstance(node, (ast.AugAssign, ast.AnnAssign)):
            targets = [node.target]
        elif isinstance(node, ast.Delete):
            targets = node.targets
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
            f = node.func
            if isinstance(f.value, ast.Name) and f.value.id == root:
                for name in methods.get(f.attr, ()):
                    yield node.lineno, name
            elif f.attr in MUTATORS:
                targets = [f.value]
        for t in targets:
            name = _field(t, root)
            if name is not None and not name.startswith("_"):
                yield node.lineno, name


def run_methods(state: Path) -> dict[str, set[str]]:
    """The fields each method of ``DiagnosisRun`` writes (on ``self``)."""
    cls = next(n for n in ast.parse(state.read_text()).body if isinstance(n, ast.ClassDef) and n.name == "DiagnosisRun")
    return {m.name: found for m in cls.body if isinstance(m, ast.FunctionDef)
            if (found := {name for _, name in writes(m, "self")})}


def writers(paths, methods: dict) -> dict[str, dict[str, list[int]]]:
    """Field -> module -> the lines that write it."""
    out = defaultdict(lambda: defaultdict(list))
    for p in paths:
        for line, name in writes(ast.parse(p.read_text()), methods=methods):
            out[name][p.stem].append(line)
    return out


def several(found: dict) -> list[str]:
    return [f"{name}: " + "; ".join(f"{m}.py:{','.join(map(str, lines))}" for m, lines in sorted(by.items()))
            for name, by in sorted(found.items()) if len(by) > 1]


def test_each_field_of_the_run_has_one_writer():
    methods = run_methods(PACKAGE / "_state.py")
    found = writers([p for p in sorted(PACKAGE.glob("*.py")) if p.stem != "_state"], methods)
    bad = several(found)
    assert not bad, "fields of the run written by more than one module of casadical.diagnosis:\n" + "\n".join(bad)


def test_the_shared_fields_are_the_pipelines():
    """What several stages change is installed by the pipeline, from what each stage returns."""
    methods = run_methods(PACKAGE / "_state.py")
    shared = {"notes", "steps", "findings", "fits_of_steps", "history", "current", "accepted", "geometric",
              "support", "before", "parametric", "final", "final_spec"}
    assert methods["install"] == shared
    found = writers(sorted(PACKAGE.glob("*.py")), methods)
    assert {name: set(by) for name, by in found.items() if name in shared} == {name: {"_pipeline"} for name in shared}


def test_the_check_sees_a_second_writer():
    """The test can fail: direct writes, writes in place and through a method of the run are all found, and a field
    two modules write is named."""
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        a, b = Path(d) / "a.py", Path(d) / "b.py"
        a.write_text("def s(run):\n    run.notes.append('x')\n    run.current, x = 1, 2\n"
                     "    run.unexplained.excluded_causes.add(3)\n    run.val_errors(4)\n")
        b.write_text("def t(run):\n    run.drop(5)\n    run._cache[6] = 7\n")
        methods = {"drop": {"current", "support"}, "val_errors": set()}
        found = writers([a, b], methods)
        assert {n: {m: lines for m, lines in by.items()} for n, by in found.items()} == {
            "notes": {"a": [2]}, "current": {"a": [3], "b": [2]}, "unexplained": {"a": [4]}, "support": {"b": [2]}}
        assert several(found) == ["current: a.py:3; b.py:2"]
    assert run_methods(PACKAGE / "_state.py")["install"] >= {"notes", "current"}
