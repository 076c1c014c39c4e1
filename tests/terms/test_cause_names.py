"""No cause's name is compared as a string outside its own module (issue 46): what a cause is lives in one object
of its term's module (:mod:`casadical.terms._cause`); the rest of the package asks it."""

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[2] / "casadical"


def _cause_names() -> set[str]:
    from casadical.terms import CAUSES

    return set(CAUSES)


def comparisons(tree: ast.AST, names: set[str]) -> list[tuple[int, str]]:
    """(line, name) of every cause name written as a string in a comparison (``==``, ``!=``, ``in``), in a
    collection of two or more of them (a tuple, list or set: the causes written again), or as a dict's key."""
    out = []

    def strings(node):
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value in names:
            yield node
        elif isinstance(node, (ast.Tuple, ast.List, ast.Set)):
            for e in node.elts:
                yield from strings(e)

    for node in ast.walk(tree):
        if isinstance(node, ast.Compare):
            for part in [node.left, *node.comparators]:
                out += [(c.lineno, c.value) for c in strings(part)]
        elif isinstance(node, (ast.Tuple, ast.List, ast.Set)):
            found = list(strings(node))
            if len(found) > 1:
                out += [(c.lineno, c.value) for c in found]
        elif isinstance(node, ast.Dict):
            out += [(k.lineno, k.value) for k in node.keys if k is not None and next(strings(k), None) is not None]
    return sorted(set(out))


def test_no_cause_name_compared_outside_the_terms():
    names = _cause_names()
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        if path.relative_to(PACKAGE).parts[0] == "terms":
            continue
        for line, name in comparisons(ast.parse(path.read_text()), names):
            found.append(f"{path.relative_to(PACKAGE.parent)}:{line}: {name!r}")
    assert not found, f"{len(found)} cause names compared as strings outside casadical/terms:\n" + "\n".join(found)


def test_the_count_sees_a_comparison():
    """The test can fail: it finds each kind of comparison it looks for."""
    code = ("a = c.cause == 'drift'\nb = c.cause in ('warmup', 'x')\nd = {'backlash': 1}\n"
            "e = ['encoder_scale', 'drift']\nf = make('drift')\ng = ('a phrase', 'backlash')\n")
    assert [n for _, n in comparisons(ast.parse(code), _cause_names())] == ["drift", "warmup", "backlash",
                                                                            "drift", "encoder_scale"]


def test_the_diagnosis_makes_its_models_from_terms_never_from_a_string():
    """A candidate becomes terms (its cause's ``terms``, ``compose_terms``): no module of the diagnosis reads a
    model specification back (``parse_spec``)."""
    hits = []
    for path in sorted((PACKAGE / "diagnosis").glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            name = node.id if isinstance(node, ast.Name) else node.name if isinstance(node, ast.alias) else None
            if name == "parse_spec":
                hits.append(f"{path.name}:{getattr(node, 'lineno', '?')}")
    assert hits == []
    text = "from ..model import parse_spec\nterms = parse_spec('kinematic')\n"     # the check can fail
    assert sum(isinstance(n, ast.Name) and n.id == "parse_spec" for n in ast.walk(ast.parse(text))) == 1
