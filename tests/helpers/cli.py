"""The command line run in-process, its one-line errors, and files of the test arms for it."""

from __future__ import annotations

import functools
from pathlib import Path

from casadical.cli import main
from casadical.data import Effects, simulate
from casadical.robot import robot_from_dict
from tests.helpers.arms import ARM4, ARM5, to_toml


def cli(capsys, *args):
    """The command line in-process: exit code, stdout, stderr lines."""
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, [line for line in err.strip().splitlines() if line]


def one_error(err, *parts):
    """Exactly one line, an error, naming every part."""
    assert len(err) == 1, err
    assert err[0].startswith("casadical: error: ") and "Traceback" not in err[0], err
    for p in parts:
        assert p in err[0], (p, err[0])


@functools.cache
def arm_files(folder: str, name: str, n: int, seed: int) -> tuple[str, str]:
    """(robot TOML, simulated poses CSV) of the test arm ``name`` ("arm4" or "arm5") in ``folder``, made once."""
    arm = {"arm5": ARM5, "arm4": ARM4}[name]
    robot_file = Path(folder) / f"{name}.toml"
    robot_file.write_text(to_toml(arm))
    data, _ = simulate(robot_from_dict(arm, name), n, Effects(), seed=seed)
    data_file = Path(folder) / f"{name}-{n}-{seed}.csv"
    data.write_csv(data_file, overwrite=True)
    return str(robot_file), str(data_file)
