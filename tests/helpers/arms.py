"""Robots that are not built in, for the tests: MDH and DH, beta on some joint or none, 4 to 7 joints."""

import json

#: three joints, DH, Hayati beta on joint 2 (compiles in well under a second)
ARM3 = {
    "name": "three-axis test arm", "convention": "dh",
    "joint": [
        {"alpha_deg": 90, "a_m": 0.15, "d_m": 0.4, "min_deg": -170, "max_deg": 170, "mass_kg": 30,
         "com_m": [0, -0.1, 0]},
        {"alpha_deg": 0, "a_m": 0.8, "d_m": 0.0, "beta_deg": 0.0, "min_deg": -10, "max_deg": 170,
         "mass_kg": 25, "com_m": [-0.4, 0, 0]},
        {"alpha_deg": 0, "a_m": 0.6, "d_m": 0.0, "min_deg": -150, "max_deg": 150, "mass_kg": 12,
         "com_m": [-0.3, 0, 0]},
    ],
    "tool": {"a_m": 0.1, "b_m": 0.02, "d_m": 0.05},
}

#: four-axis palletiser, MDH, no Hayati beta
ARM4 = {
    "name": "four-axis palletiser", "convention": "mdh",
    "joint": [
        {"alpha_deg": 0, "a_m": 0.0, "d_m": 0.5, "min_deg": -170, "max_deg": 170, "mass_kg": 40,
         "com_m": [0, 0, -0.2]},
        {"alpha_deg": -90, "a_m": 0.2, "d_m": 0.0, "min_deg": -80, "max_deg": 60, "mass_kg": 25,
         "com_m": [0.4, 0, 0]},
        {"alpha_deg": 0, "a_m": 0.9, "d_m": 0.0, "min_deg": -60, "max_deg": 150, "mass_kg": 15,
         "com_m": [0.3, 0, 0]},
        {"alpha_deg": 0, "a_m": 0.8, "d_m": 0.0, "min_deg": -200, "max_deg": 200, "mass_kg": 3,
         "com_m": [0.05, 0, 0]},
    ],
    "tool": {"a_m": 0.15, "b_m": 0.03, "d_m": 0.05},
    "payload": {"mass_kg": 30},
}

#: five-axis arm, standard DH, beta on joint 3 (axes 3 and 4 parallel)
ARM5 = {
    "name": "five-axis DH arm", "convention": "dh",
    "joint": [
        {"alpha_deg": 90, "a_m": 0.15, "d_m": 0.45, "min_deg": -170, "max_deg": 170, "mass_kg": 30,
         "com_m": [0, -0.1, 0]},
        {"alpha_deg": 0, "a_m": 0.7, "d_m": 0.0, "min_deg": -10, "max_deg": 170, "mass_kg": 20,
         "com_m": [-0.35, 0, 0]},
        {"alpha_deg": 0, "a_m": 0.6, "beta_deg": 0.0, "d_m": 0.0, "min_deg": -150, "max_deg": 150,
         "mass_kg": 12, "com_m": [-0.3, 0, 0]},
        {"alpha_deg": 90, "a_m": 0.0, "d_m": 0.0, "min_deg": -120, "max_deg": 120, "mass_kg": 3,
         "com_m": [0, 0, 0]},
        {"alpha_deg": 0, "a_m": 0.0, "d_m": 0.15, "min_deg": -350, "max_deg": 350, "mass_kg": 1,
         "com_m": [0, 0, 0.05]},
    ],
    "tool": {"a_m": 0.05, "b_m": 0.02, "d_m": 0.1},
    "payload": {"mass_kg": 10},
}

#: seven-axis arm, MDH, beta on joint 4 (axes 3 and 4 parallel)
ARM7 = {
    "name": "seven-axis arm", "convention": "mdh",
    "joint": [
        {"alpha_deg": 0, "a_m": 0.0, "d_m": 0.34, "min_deg": -170, "max_deg": 170, "mass_kg": 4,
         "com_m": [0, 0, -0.1]},
        {"alpha_deg": -90, "a_m": 0.0, "d_m": 0.0, "min_deg": -120, "max_deg": 120, "mass_kg": 4,
         "com_m": [0, -0.1, 0]},
        {"alpha_deg": 90, "a_m": 0.0, "d_m": 0.4, "min_deg": -170, "max_deg": 170, "mass_kg": 3,
         "com_m": [0, 0, -0.15]},
        {"alpha_deg": 0, "a_m": 0.05, "beta_deg": 0.0, "d_m": 0.0, "min_deg": -120, "max_deg": 120,
         "mass_kg": 3, "com_m": [0, 0.1, 0]},
        {"alpha_deg": -90, "a_m": 0.0, "d_m": 0.4, "min_deg": -170, "max_deg": 170, "mass_kg": 2,
         "com_m": [0, 0, -0.15]},
        {"alpha_deg": 90, "a_m": 0.0, "d_m": 0.0, "min_deg": -120, "max_deg": 120, "mass_kg": 1.5,
         "com_m": [0, 0, 0]},
        {"alpha_deg": -90, "a_m": 0.0, "d_m": 0.126, "min_deg": -175, "max_deg": 175, "mass_kg": 0.5,
         "com_m": [0, 0, 0.02]},
    ],
    "tool": {"a_m": 0.02, "b_m": 0.01, "d_m": 0.1},
    "payload": {"mass_kg": 5},
}

ARMS = {"arm4": ARM4, "arm5": ARM5, "arm7": ARM7}

#: four-axis arm, MDH, beta on joint 3
ARM4_BETA = {
    "name": "four-axis test arm", "convention": "mdh",
    "joint": [
        {"alpha_deg": 0, "a_m": 0.0, "d_m": 0.5, "min_deg": -170, "max_deg": 170, "mass_kg": 20,
         "com_m": [0, 0, -0.1]},
        {"alpha_deg": -90, "a_m": 0.2, "d_m": 0.0, "min_deg": -120, "max_deg": 60, "mass_kg": 18,
         "com_m": [0.3, 0, 0]},
        {"alpha_deg": 0, "a_m": 0.7, "beta_deg": 0.0, "d_m": 0.0, "min_deg": -150, "max_deg": 150,
         "mass_kg": 10, "com_m": [0.3, 0, 0]},
        {"alpha_deg": -90, "a_m": 0.1, "d_m": 0.6, "min_deg": -180, "max_deg": 180, "mass_kg": 4,
         "com_m": [0, 0, -0.1]},
    ],
    "tool": {"a_m": 0.05, "b_m": 0.0, "d_m": 0.12},
    "payload": {"mass_kg": 8},
}

#: seven-axis arm, standard DH, beta on joint 4
ARM7_DH = {
    "name": "seven-axis test arm", "convention": "dh",
    "joint": [
        {"alpha_deg": -90, "a_m": 0.0, "d_m": 0.34, "min_deg": -170, "max_deg": 170, "mass_kg": 4,
         "com_m": [0, 0.03, 0]},
        {"alpha_deg": 90, "a_m": 0.0, "d_m": 0.0, "min_deg": -120, "max_deg": 120, "mass_kg": 4,
         "com_m": [0, 0, 0.05]},
        {"alpha_deg": 90, "a_m": 0.0, "d_m": 0.4, "min_deg": -170, "max_deg": 170, "mass_kg": 3,
         "com_m": [0, -0.03, 0]},
        {"alpha_deg": -90, "a_m": 0.0, "beta_deg": 0.0, "d_m": 0.0, "min_deg": -120, "max_deg": 120,
         "mass_kg": 2.7, "com_m": [0, 0, 0.05]},
        {"alpha_deg": -90, "a_m": 0.0, "d_m": 0.4, "min_deg": -170, "max_deg": 170, "mass_kg": 1.7,
         "com_m": [0, 0.02, 0]},
        {"alpha_deg": 90, "a_m": 0.0, "d_m": 0.0, "min_deg": -120, "max_deg": 120, "mass_kg": 1.8,
         "com_m": [0, 0, 0.02]},
        {"alpha_deg": 0, "a_m": 0.0, "d_m": 0.126, "min_deg": -175, "max_deg": 175, "mass_kg": 0.3},
    ],
    "tool": {"a_m": 0.02, "b_m": 0.01, "d_m": 0.1},
    "payload": {"mass_kg": 5},
}

#: a six-axis arm with three parallel axes (2, 3, 4; Hayati's beta on links 2 and 3), standard DH: not built in
ARM6 = {
    "name": "six-axis collaborative arm", "convention": "dh",
    "joint": [
        {"alpha_deg": 90, "a_m": 0.0, "d_m": 0.1625, "min_deg": -360, "max_deg": 360, "mass_kg": 3.7,
         "com_m": [0, -0.02, 0]},
        {"alpha_deg": 0, "a_m": -0.425, "beta_deg": 0.0, "d_m": 0.0, "min_deg": -360, "max_deg": 360, "mass_kg": 8.4,
         "com_m": [0.2, 0, 0.11]},
        {"alpha_deg": 0, "a_m": -0.3922, "beta_deg": 0.0, "d_m": 0.0, "min_deg": -360, "max_deg": 360,
         "mass_kg": 2.3, "com_m": [0.15, 0, 0.02]},
        {"alpha_deg": 90, "a_m": 0.0, "d_m": 0.1333, "min_deg": -360, "max_deg": 360, "mass_kg": 1.2,
         "com_m": [0, 0, 0]},
        {"alpha_deg": -90, "a_m": 0.0, "d_m": 0.0997, "min_deg": -360, "max_deg": 360, "mass_kg": 1.2,
         "com_m": [0, 0, 0]},
        {"alpha_deg": 0, "a_m": 0.0, "d_m": 0.0996, "min_deg": -360, "max_deg": 360, "mass_kg": 0.25,
         "com_m": [0, 0, 0]},
    ],
    "tool": {"a_m": 0.0, "b_m": 0.0, "d_m": 0.08},
}

#: a six-axis industrial arm (an offset shoulder and elbow), modified DH, beta on link 3: not built in
ARM6_MDH = {
    "name": "six-axis arm (MDH)", "convention": "mdh",
    "joint": [
        {"alpha_deg": 0, "a_m": 0.0, "d_m": 0.4, "min_deg": -170, "max_deg": 170, "mass_kg": 20,
         "com_m": [0, 0, -0.1]},
        {"alpha_deg": -90, "a_m": 0.15, "d_m": 0.0, "min_deg": -100, "max_deg": 80, "mass_kg": 12,
         "com_m": [0.3, 0, 0.05]},
        {"alpha_deg": 0, "a_m": 0.6, "beta_deg": 0.0, "d_m": 0.0, "min_deg": -150, "max_deg": 150, "mass_kg": 8,
         "com_m": [0.05, 0, 0]},
        {"alpha_deg": -90, "a_m": 0.12, "d_m": 0.62, "min_deg": -180, "max_deg": 180, "mass_kg": 4,
         "com_m": [0, 0, -0.2]},
        {"alpha_deg": 90, "a_m": 0.0, "d_m": 0.0, "min_deg": -120, "max_deg": 120, "mass_kg": 2,
         "com_m": [0, 0, 0]},
        {"alpha_deg": -90, "a_m": 0.0, "d_m": 0.0, "min_deg": -350, "max_deg": 350, "mass_kg": 0.5,
         "com_m": [0, 0, 0]},
    ],
    "tool": {"a_m": 0.0, "b_m": 0.0, "d_m": 0.15},
    "payload": {"mass_kg": 6},
}

#: five-axis arm, MDH, beta on joint 3, whose joint 3 is driven through a parallelogram (a linear coupling): its
#: reading q3 is the forearm's direction, the chain angle q3 - q2; joint 2's drive leaves the forearm's direction
ARM5_COUPLED = {
    "name": "five-axis parallelogram arm", "convention": "mdh",
    "joint": [
        {"alpha_deg": 0, "a_m": 0.0, "d_m": 0.45, "min_deg": -170, "max_deg": 170, "mass_kg": 35,
         "com_m": [0, 0, -0.15]},
        {"alpha_deg": -90, "a_m": 0.25, "d_m": 0.0, "min_deg": -140, "max_deg": -40, "mass_kg": 25,
         "com_m": [0.4, 0, 0]},
        {"alpha_deg": 0, "a_m": 0.85, "beta_deg": 0.0, "d_m": 0.0, "min_deg": -60, "max_deg": 60, "mass_kg": 15,
         "com_m": [0.3, 0, 0], "coupling": [0, -1, 1, 0, 0], "coupling_offset_deg": 0.0},
        {"alpha_deg": -90, "a_m": 0.1, "d_m": 0.7, "min_deg": -180, "max_deg": 180, "mass_kg": 4,
         "com_m": [0, 0, -0.1]},
        {"alpha_deg": 90, "a_m": 0.0, "d_m": 0.0, "min_deg": -120, "max_deg": 120, "mass_kg": 2,
         "com_m": [0, 0, 0.02]},
    ],
    "tool": {"a_m": 0.05, "b_m": 0.02, "d_m": 0.15},
    "payload": {"mass_kg": 20},
}

#: a four-axis arm on a 4 m linear track (joint 1, prismatic, MDH): the track runs along the base's y axis
#: (alpha1 -90), joint 2 stands vertical on the carriage (alpha2 90)
ARM4_TRACK = {
    "name": "four-axis arm on a track", "convention": "mdh",
    "joint": [
        {"type": "prismatic", "alpha_deg": -90, "a_m": 0.0, "d_m": 0.0, "theta_deg": 0.0, "min_mm": 0.0,
         "max_mm": 4000.0, "mass_kg": 120, "com_m": [0, 0, 0]},
        {"alpha_deg": 90, "a_m": 0.0, "d_m": 0.5, "min_deg": -170, "max_deg": 170, "mass_kg": 40,
         "com_m": [0, 0, -0.2]},
        {"alpha_deg": -90, "a_m": 0.2, "d_m": 0.0, "min_deg": -80, "max_deg": 60, "mass_kg": 25,
         "com_m": [0.4, 0, 0]},
        {"alpha_deg": 0, "a_m": 0.9, "beta_deg": 0.0, "d_m": 0.0, "min_deg": -60, "max_deg": 150, "mass_kg": 15,
         "com_m": [0.3, 0, 0]},
        {"alpha_deg": 0, "a_m": 0.8, "beta_deg": 0.0, "d_m": 0.0, "min_deg": -200, "max_deg": 200, "mass_kg": 3,
         "com_m": [0.05, 0, 0]},
    ],
    "tool": {"a_m": 0.15, "b_m": 0.03, "d_m": 0.05},
    "payload": {"mass_kg": 30},
}

#: a three-axis arm on a lifting column (standard DH): the waist turns (joint 1), the column lifts the arm
#: (joint 2, prismatic, 1.2 m), shoulder and elbow (joints 3 and 4, parallel: beta on link 3)
ARM_COLUMN = {
    "name": "arm on a lifting column", "convention": "dh",
    "joint": [
        {"alpha_deg": 0, "a_m": 0.0, "beta_deg": 0.0, "d_m": 0.3, "min_deg": -170, "max_deg": 170, "mass_kg": 40,
         "com_m": [0, 0, -0.1]},
        {"type": "prismatic", "alpha_deg": 90, "a_m": 0.2, "d_m": 0.2, "theta_deg": 0.0, "min_mm": 0.0,
         "max_mm": 1200.0, "mass_kg": 30, "com_m": [0, 0, 0]},
        {"alpha_deg": 0, "a_m": 0.7, "beta_deg": 0.0, "d_m": 0.0, "min_deg": -80, "max_deg": 80, "mass_kg": 15,
         "com_m": [-0.3, 0, 0]},
        {"alpha_deg": 0, "a_m": 0.5, "d_m": 0.0, "min_deg": -120, "max_deg": 120, "mass_kg": 5,
         "com_m": [-0.2, 0, 0]},
    ],
    "tool": {"a_m": 0.1, "b_m": 0.02, "d_m": 0.05},
    "payload": {"mass_kg": 10},
}

#: the four-axis arm on a track in standard DH: the base frame's z runs along the track (DH moves joint 1 along
#: z0), gravity along its -y; alpha1 -90 turns z1 up, the turret (joint 2) turns about it; shoulder and elbow
#: parallel (beta on link 3)
ARM4_TRACK_DH = {
    "name": "four-axis arm on a track (DH)", "convention": "dh",
    "gravity": {"direction": [0.0, -1.0, 0.0]},
    "joint": [
        {"type": "prismatic", "alpha_deg": -90, "a_m": 0.0, "d_m": 0.0, "theta_deg": 0.0, "min_mm": 0.0,
         "max_mm": 4000.0, "mass_kg": 120, "com_m": [0, 0, 0]},
        {"alpha_deg": 90, "a_m": 0.2, "d_m": 0.5, "min_deg": -170, "max_deg": 170, "mass_kg": 40,
         "com_m": [-0.1, 0, 0]},
        {"alpha_deg": 0, "a_m": 0.9, "beta_deg": 0.0, "d_m": 0.0, "min_deg": -80, "max_deg": 80, "mass_kg": 25,
         "com_m": [-0.45, 0, 0]},
        {"alpha_deg": 0, "a_m": 0.8, "d_m": 0.0, "min_deg": -150, "max_deg": 150, "mass_kg": 15,
         "com_m": [-0.35, 0, 0]},
    ],
    "tool": {"a_m": 0.15, "b_m": 0.03, "d_m": 0.05},
    "payload": {"mass_kg": 30},
}

#: the arm on a lifting column in modified DH: the waist turns (joint 1), the column lifts the arm along the
#: same vertical line (joint 2, prismatic, 1.2 m: parallel to the waist, so beta on its row, or the geometry cannot
#: tilt the column against the waist about y), shoulder and elbow (joints 3 and 4, parallel: beta on link 4)
ARM_COLUMN_MDH = {
    "name": "arm on a lifting column (MDH)", "convention": "mdh",
    "joint": [
        {"alpha_deg": 0, "a_m": 0.0, "d_m": 0.3, "min_deg": -170, "max_deg": 170, "mass_kg": 40,
         "com_m": [0, 0, -0.1]},
        {"type": "prismatic", "alpha_deg": 0, "a_m": 0.0, "beta_deg": 0.0, "d_m": 0.2, "theta_deg": 0.0,
         "min_mm": 0.0, "max_mm": 1200.0, "mass_kg": 30, "com_m": [0, 0, 0]},
        {"alpha_deg": 90, "a_m": 0.2, "d_m": 0.0, "min_deg": -80, "max_deg": 80, "mass_kg": 15,
         "com_m": [0.35, 0, 0]},
        {"alpha_deg": 0, "a_m": 0.7, "beta_deg": 0.0, "d_m": 0.0, "min_deg": -120, "max_deg": 120, "mass_kg": 5,
         "com_m": [0.25, 0, 0]},
    ],
    "tool": {"a_m": 0.5, "b_m": 0.02, "d_m": 0.05},
    "payload": {"mass_kg": 10},
}


def to_toml(doc: dict) -> str:
    """The robot dict as TOML text (the subset these robots use: scalars, tables, [[joint]])."""
    out = [f"{k} = {json.dumps(v)}" for k, v in doc.items() if not isinstance(v, (dict, list))]
    for k, v in doc.items():
        if isinstance(v, dict):
            out += [f"[{k}]"] + [f"{kk} = {json.dumps(vv)}" for kk, vv in v.items()]
    for j in doc["joint"]:
        out += ["[[joint]]"] + [f"{kk} = {json.dumps(vv)}" for kk, vv in j.items()]
    return "\n".join(out) + "\n"
