"""When the report says unexplained: from the finding to a cause of your own.

What it teaches: the diagnosis knows a catalogue of causes; a real robot always has something the catalogue
lacks. Here joint 3's gear error follows joint 2's reading (twice per turn of joint 2): no catalogue cause
describes it. The diagnosis names no stand-in for it, and its structure screen says where it lives:
"joint 3's angle error varies with joint 2's reading". You then state that cause yourself in a terms file
(data, never code: docs/formats.md section 10), give it to the diagnosis, and it is named like any cause.

Run from the repository root:  python examples/07_unexplained.py
"""

import tempfile
from pathlib import Path

import numpy as np

from casadical import load_robot
from casadical.data import Effects, simulate
from casadical.diagnosis import DiagnosisSettings, diagnose
from casadical.model import Model
from casadical.terms import read_terms_file

robot = load_robot("ys100")

# The cause you will state, once the report has said where to look: joint 3's angle error as a function of
# joint 2's reading, with two parameters, each with its typical size and physical bounds.
TERMS = """
[[term]]
name = "gear32"
joint = 3
angle = "a * sin(2 * q2) + b * cos(2 * q2)"
[term.parameters.a]
scale = 1e-4
lower = -0.01
upper = 0.01
unit = "rad"
[term.parameters.b]
scale = 1e-4
lower = -0.01
upper = 0.01
unit = "rad"
"""
folder = Path(tempfile.mkdtemp(prefix="casadical-example-"))
(folder / "gear32.toml").write_text(TERMS)
terms = read_terms_file(folder / "gear32.toml")

# A simulated robot (random link errors, 20 um noise) whose joint 3 really has that error: 0.01 deg.
cal, truth = simulate(robot, 100, Effects(), seed=0)
val, _ = simulate(robot, 300, truth=truth, seed=1)
model = Model(robot, "gear32", user_terms=terms)
on = model.parameters.values.copy()
on[model.parameters.names.index("gear32.a")] = np.radians(0.01)
cal, val = (d.with_positions(d.xyz + model.predict(d.q, on) - model.predict(d.q)) for d in (cal, val))
print("hidden: joint 3's angle error 0.01 deg sin(2 q2): no catalogue cause describes it")

# 1. The diagnosis without the term: nothing is named for it, and the structure screen locates it.
report = diagnose(robot, cal, val, DiagnosisSettings(seed=0))
named = [f.label() for f in report.findings if f.in_model and f.candidate.kind.named]
print("named causes:", ", ".join(named) or "none")
for f in report.findings:
    if f.structure:
        print(f"unexplained: {f.where} ({f.structure['size_mm']:.3f} mm on the validation poses)")

# 2. With the term of your own: the diagnosis screens it beside the catalogue, by the same tests.
report = diagnose(robot, cal, val, DiagnosisSettings(seed=0, terms=terms))
named = [f.label() for f in report.findings if f.in_model and f.candidate.kind.named]
print("with gear32.toml, named causes:", ", ".join(named) or "none")
print(f"final model: validation mean {report.final_validation.mean_mm:.4f} mm "
      f"(kinematic {report.kinematic_validation.mean_mm:.4f} mm)")
