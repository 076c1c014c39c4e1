"""The package's import structure: no import cycle at all, and robot descriptions below the readers of robot files.

``casadical.robot`` (the robot and its TOML form) must not import the URDF
reader, not even lazily inside a function: the URDF package builds on it,
and the way back tied the model, the terms and both URDF modules into one
import cycle. Loading by file type lives above both, in ``casadical.loading``.
The graph is read from the source (``tests/import_graph.py``), so a lazy
import counts as much as one at the top of a module.
"""

from __future__ import annotations

import pytest

from casadical.errors import InputError, RobotFileError
from tests import import_graph


@pytest.fixture(scope="module")
def graph():
    return import_graph.graph()


def test_the_package_has_no_import_cycle(graph):
    """No module reaches itself through its imports (lazy ones included): each cycle that came back (the
    diagnosis package through ``from . import decision``, the compensators through their package, checks and
    sessions, accuracy and calibration) was broken by moving code to where it belongs."""
    assert import_graph.cycles(graph) == []


def test_the_packages_form_floors_and_the_architecture_doc_draws_them(graph):
    """The packages (and top-level modules) import each other in no loop, lazy imports counted: each stands on
    a floor above all it imports; docs/architecture.md quotes the floors the code has (issue 46: ten packages
    were one loop, twenty imports running from a lower layer up)."""
    from pathlib import Path
    assert import_graph.cycles(import_graph.packages(graph)) == []
    doc = (Path(__file__).resolve().parents[1] / "docs" / "architecture.md").read_text()
    block = doc.split("<!-- floors: python tests/import_graph.py -->\n```text\n", 1)[1].split("```", 1)[0]
    assert block.strip().splitlines() == import_graph.floor_lines(graph)


def test_the_package_floors_see_a_loop_through_a_lazy_import(tmp_path):
    """The test above can fail: a lazy import from a low package up to a high one closes a loop of packages
    even where no module imports itself."""
    pkg = tmp_path / "casadical"
    for sub in ("low", "high"):
        (pkg / sub).mkdir(parents=True)
        (pkg / sub / "__init__.py").write_text("")
    (pkg / "__init__.py").write_text("")
    (pkg / "low" / "a.py").write_text("def f():\n    from ..high.b import g\n    return g\n")
    (pkg / "low" / "c.py").write_text("x = 1\n")
    (pkg / "high" / "b.py").write_text("from ..low.c import x\ng = x\n")
    g = import_graph.graph(pkg)
    assert import_graph.cycles(g) == []
    assert import_graph.cycles(import_graph.packages(g)) == [{"low", "high"}]
    with pytest.raises(ValueError, match="loop"):
        import_graph.floors(import_graph.packages(g))


def test_the_graph_reader_counts_the_package_a_from_import_runs(tmp_path):
    """The test above can fail: ``from . import decision`` inside a method imports the package (its
    ``__init__``, which imports the module back), an edge a reader that maps it to the submodule alone (grimp)
    misses; a lazy import in a function is an edge too."""
    pkg = tmp_path / "casadical"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("from .report import Report\nfrom .run import go\n")
    (pkg / "report.py").write_text("class Report:\n    def text(self):\n        from . import decision as d\n"
                                   "        return d.words\n")
    (pkg / "decision.py").write_text("words = 'w'\n")
    (pkg / "run.py").write_text("def go():\n    from .later import y\n    return y\n")
    (pkg / "later.py").write_text("from .run import go\ny = 2\n")
    g = import_graph.graph(pkg)
    assert g["casadical.report"] == {"casadical", "casadical.decision"}
    assert sorted(map(sorted, import_graph.cycles(g))) == [["casadical", "casadical.report"],
                                                          ["casadical.later", "casadical.run"]]


def test_robot_imports_no_reader_of_other_file_types(graph):
    below = import_graph.closure(graph, "casadical.robot")
    assert not [m for m in below if m.startswith(("casadical.urdf", "casadical.loading"))], sorted(below)
    # (signals: the standard library)
    assert below <= {"casadical.errors", "casadical.runtime._files", "casadical.runtime._interrupts"}


def test_the_urdf_package_depends_on_robot_one_way(graph):
    for module in ("casadical.urdf._read", "casadical.urdf._write"):     # (the package's __init__ is lazy)
        assert "casadical.robot" in import_graph.closure(graph, module)
        assert module not in import_graph.closure(graph, "casadical.robot")
    # no cycle holds the robot, the model, the terms or the URDF package
    for comp in import_graph.cycles(graph):
        assert not comp & {"casadical.robot", "casadical.model._symbolic", "casadical.kinematics",
                           "casadical.terms", "casadical.urdf", "casadical.loading"}, sorted(comp)


def test_the_graph_reader_sees_lazy_imports(tmp_path):
    """The test above can fail: a lazy import inside a function is an edge, a TYPE_CHECKING one is not."""
    pkg = tmp_path / "casadical"
    (pkg / "urdf").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "robot.py").write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from .model import M\n"
                                  "def load(p):\n    from .urdf import _read\n    return _read.read(p)\n")
    (pkg / "model.py").write_text("from .robot import load\n")
    (pkg / "urdf" / "__init__.py").write_text("from ._read import read\n")
    (pkg / "urdf" / "_read.py").write_text("from ..robot import load\n")
    g = import_graph.graph(pkg)
    assert g["casadical.robot"] == {"casadical.urdf", "casadical.urdf._read"}
    assert import_graph.cycles(g) == [{"casadical.robot", "casadical.urdf", "casadical.urdf._read"}]


def test_load_robot_by_file_type(tmp_path):
    """casadical.load_robot, the one load_robot, reads every type; Robot.load built-ins and TOML, and says where
    URDF is."""
    import casadical
    from casadical import loading, robot
    from casadical.robot import Robot

    assert casadical.load_robot is loading.load_robot
    assert not hasattr(robot, "load_robot")
    assert Robot.load("ur10").n == loading.load_robot("ur10").n == 6
    urdf = tmp_path / "arm.urdf"
    urdf.write_text('<robot name="arm"><link name="a"/><link name="b"/><joint name="j" type="revolute">'
                    '<parent link="a"/><child link="b"/><axis xyz="0 0 1"/>'
                    '<limit lower="-1" upper="1" effort="1" velocity="1"/></joint></robot>')
    assert loading.load_robot(urdf).n == 1
    with pytest.raises(RobotFileError, match=r"arm.urdf: Robot.load reads built-in robots and TOML files; read a "
                                             r"URDF with casadical.load_robot"):
        Robot.load(urdf)
    with pytest.raises(InputError, match="chooses the chain of a URDF file"):
        loading.load_robot("ur10", tip="tool0")


def test_the_truth_is_apart_from_the_package():
    """The tests' independent truth (tests/truth) and casadical never import each other: data made by the
    truth share no code with the model that fits them."""
    import ast
    from pathlib import Path

    def imported(files):
        out = set()
        for f in files:
            for node in ast.walk(ast.parse(f.read_text())):
                if isinstance(node, ast.Import):
                    out.update(a.name.split(".")[0] for a in node.names)
                elif isinstance(node, ast.ImportFrom) and node.level == 0:
                    out.add(node.module.split(".")[0])
        return out

    truth = sorted((Path(__file__).parent / "truth").glob("*.py"))
    assert len(truth) >= 4
    assert "casadical" not in imported(truth), imported(truth)
    package = import_graph.modules().values()
    assert not imported(package) & {"truth", "tests", "arms"}, imported(package) & {"truth", "tests", "arms"}
