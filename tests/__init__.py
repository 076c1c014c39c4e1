"""casadical's tests, one folder per package or role of the code they test (as scikit-learn arranges its tests).

calibration/, cli/, compensators/, diagnosis/, importers/, methods/, optim/, planning/, report/, study/, urdf/
test the subpackages of those names; model/ the robot file, kinematics, model, simulator and superset
(robot.py, kinematics.py, model.py, simulate.py, superset.py); measurements/ the measurement files and their
checks (data.py, checks.py); runtime/ how commands run (compiled-code cache, threads, signals, start-up imports);
docs/ the commands and figures the documents quote. test_common.py runs every registered error term and every
method through the same checks; test_import_graph.py keeps the package's layers apart.

helpers/ holds what the tests share (test arms, hidden effects, the planning loop, the command line in-process);
truth/ is the independent forward model (plain numpy, no casadical code); data/ the fixture files.
The tests import these by one path: ``from tests.helpers.arms import ARM4``, ``from tests.truth import Arm``.
"""
