"""Simulate a robot with known errors, calibrate it, and compare what was found with the truth.

What it teaches: casadical.data._simulate draws a "true" robot (nominal geometry plus random
link errors, and whatever Effects you give it: compliance, gear errors, encoder scale,
backlash, thermal expansion, drift) and measures it with tracker noise. Because the truth
is known, you can check an identification parameter by parameter, and see that its
standard errors are honest (|identified - true| within about 2 std). The same simulator
is behind `casadical simulate PROTOCOL` and the tests.

Run from the repository root:  python examples/06_simulate.py
"""

from casadical import calibrate, load_robot
from casadical.data import Effects, simulate

robot = load_robot("ys100")
effects = Effects(stiffness={2: 2e6, 3: 1.5e6},   # N m/rad; every other joint is rigid
                  length_sigma=0.5e-3,            # std of the link-length errors (m)
                  noise=20e-6)                    # tracker noise per axis (m)

cal, truth = simulate(robot, 100, effects, seed=0)           # 100 poses to calibrate on
val, _ = simulate(robot, 300, truth=truth, seed=1)           # the same robot, 300 other poses

res = calibrate(robot, cal, "kinematic+compliance", solver="lm", warn=False)
print(f"held-out error: {res.stats(val).line()}  (tracker noise 0.020 mm per axis)")

# Stiffness k = 1/c: identified (with its standard error) against the truth.
print("\njoint stiffness:")
for joint, (k, std) in res.stiffness().items():
    if joint in effects.stiffness:
        print(f"  joint {joint}: identified {k:.4g} +- {std:.2g} N m/rad, true {effects.stiffness[joint]:.4g}")

# Link parameters the poses identify (the base pose is where the tracker stood: no truth to compare).
# A parameter the poses cannot tell from another stays nominal, and that other one takes its error too:
# d2 holds d2 + d3 (parallel axes), tool_* hold d6 and theta6. Those differ from their own truth.
holds = {}
for u in res.identifiability.unidentifiable:      # e.g. d3: "structurally a combination of d2"
    for other in u.confounded_with:
        holds.setdefault(other, []).append(u.name)
print("\nlink parameters (display units):")
print(f"  {'name':<8} {'true':>10} {'identified':>11} {'std':>8} {'(id-true)/std':>14}")
within = total = 0
for p in res.parameters:
    if p.fixed or p.term != "geometric" or p.group == "base":
        continue
    true, value, std = p.to_display(truth.value(p.name)), p.to_display(p.value), p.to_display(p.std)
    z = (value - true) / std
    note = f"  (holds {', '.join(holds[p.name])} too)" if p.name in holds else ""
    if not note:
        within, total = within + (abs(z) < 2), total + 1
    print(f"  {p.name:<8} {true:>10.4f} {value:>11.4f} {std:>8.4f} {z:>+14.2f}  {p.display_unit}{note}")
print(f"\n{within} of the {total} others within 2 std of the truth")
