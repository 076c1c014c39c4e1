"""The disk cache of compiled model functions: hit, miss, damaged entries, concurrent writers, clean-up,
the ``cache`` command, and calibrations that do not depend on whether the code came from the cache."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time

import numpy as np
import pytest

from casadical.calibration import calibrate
from casadical.cli import main
from casadical.data import Effects, simulate
from casadical.model import Model
from casadical.model import _jitcache as jitcache
from casadical.robot import robot_from_dict
from tests.helpers.arms import ARM3

pytestmark = pytest.mark.skipif(jitcache.compiler() is None, reason="no C compiler")

#: five joints, modified DH, no beta
ARM5 = {
    "name": "five-axis test arm", "convention": "mdh",
    "joint": [
        {"alpha_deg": 0, "a_m": 0.0, "d_m": 0.5, "min_deg": -170, "max_deg": 170, "mass_kg": 30,
         "com_m": [0, 0, -0.1]},
        {"alpha_deg": -90, "a_m": 0.2, "d_m": 0.0, "min_deg": -80, "max_deg": 140, "mass_kg": 25,
         "com_m": [0.35, 0, 0]},
        {"alpha_deg": 0, "a_m": 0.7, "d_m": 0.0, "min_deg": -150, "max_deg": 150, "mass_kg": 12,
         "com_m": [0.3, 0, 0]},
        {"alpha_deg": -90, "a_m": 0.1, "d_m": 0.6, "min_deg": -170, "max_deg": 170, "mass_kg": 6,
         "com_m": [0, 0, -0.1]},
        {"alpha_deg": 90, "a_m": 0.0, "d_m": 0.0, "min_deg": -120, "max_deg": 120, "mass_kg": 3,
         "com_m": [0, 0, 0]},
    ],
    "tool": {"a_m": 0.05, "b_m": 0.0, "d_m": 0.12},
}


@pytest.fixture
def cache(tmp_path, monkeypatch):
    folder = tmp_path / "cache"
    monkeypatch.setenv("CASADICAL_CACHE", str(folder))
    return folder


def entries(folder):
    return sorted(p.name for p in folder.iterdir()) if folder.exists() else []


def fk_of(spec="kinematic"):
    model = Model(robot_from_dict(ARM3), spec, jit=False)
    return model, model.per_pose_function("fk", False)


def evaluate(fun, model, seed=0, n=50):
    q = np.random.default_rng(seed).uniform(-1.5, 1.5, (n, model.robot.n))
    F = fun.map(n)
    p = model.parameters.values + np.random.default_rng(seed + 1).normal(0, 1e-3, len(model.parameters))
    return np.array(F(q.T, p, model.default_covariates(n).T, model.base0_nominal()))


def test_miss_then_hit_gives_the_same_numbers(cache):
    model, vm = fk_of()
    assert jitcache.load(vm, compile=False) is None and entries(cache) == []   # a miss compiles nothing
    compiled = jitcache.load(vm)
    assert len(entries(cache)) == 1 and entries(cache)[0].startswith("fk-")
    hit = jitcache.load(vm, compile=False)                                      # cannot compile: the cache
    for seed in (0, 1, 2):
        ref = evaluate(vm, model, seed)
        np.testing.assert_allclose(evaluate(compiled, model, seed), ref, rtol=1e-13, atol=1e-15)
        np.testing.assert_allclose(evaluate(hit, model, seed), ref, rtol=1e-13, atol=1e-15)
    # another model (other terms) is another entry; the same model built again is the same entry
    jitcache.load(Model(robot_from_dict(ARM3), "kinematic+compliance", jit=False).per_pose_function("fk"))
    assert len(entries(cache)) == 2
    assert jitcache.load(fk_of()[1], compile=False) is not None and len(entries(cache)) == 2


@pytest.mark.parametrize("damage", ["truncated", "garbage with a matching name"])
def test_a_damaged_entry_is_compiled_again(cache, damage):
    model, vm = fk_of()
    jitcache.load(vm)
    (entry,) = cache.iterdir()
    if damage == "truncated":
        entry.write_bytes(entry.read_bytes()[:1000])
    else:   # bytes that match the digest in the name but are no library: the loader refuses them
        junk = b"not a shared library" * 50
        entry.unlink()
        entry = cache / f"{entry.name.rsplit('-', 1)[0]}-{jitcache._digest(junk)}.so"
        entry.write_bytes(junk)
    assert jitcache.load(vm, compile=False) is None and not entry.exists()
    again = jitcache.load(vm)
    np.testing.assert_allclose(evaluate(again, model), evaluate(vm, model), rtol=1e-13, atol=1e-15)
    (fresh,) = cache.iterdir()
    assert fresh.stat().st_size > 1000 and jitcache.load(vm, compile=False) is not None


def test_concurrent_writers_end_with_one_valid_entry(cache, tmp_path):
    go = tmp_path / "go"
    code = ("import os, sys, time\n"
            "from pathlib import Path\n"
            "from casadical.model import _jitcache as jitcache\n"
            "from casadical.model import Model\n"
            "from casadical.robot import robot_from_dict\n"
            f"fun = Model(robot_from_dict({ARM3!r}), 'kinematic', jit=False).per_pose_function('fk')\n"
            "Path(sys.argv[1]).touch()\n"
            f"while not os.path.exists({str(go)!r}):\n"
            "    time.sleep(0.002)\n"
            "jitcache.load(fun)\n")
    env = dict(os.environ, CASADICAL_CACHE=str(cache))
    ready = [tmp_path / f"ready{k}" for k in range(2)]
    procs = [subprocess.Popen([sys.executable, "-c", code, str(r)], env=env, stderr=subprocess.PIPE, text=True)
             for r in ready]
    while not all(r.exists() for r in ready):     # both have built the model and wait
        assert all(p.poll() is None for p in procs), [p.stderr.read() for p in procs]
        time.sleep(0.01)
    go.touch()
    for p in procs:
        assert p.wait(timeout=120) == 0, p.stderr.read()
    names = entries(cache)
    assert len(names) == 1 and names[0].endswith(".so"), names   # no partial file, one entry
    model, vm = fk_of()
    hit = jitcache.load(vm, compile=False)
    np.testing.assert_allclose(evaluate(hit, model), evaluate(vm, model), rtol=1e-13, atol=1e-15)


def test_least_recently_used_entries_go_first(cache, monkeypatch):
    model, fk = fk_of()
    jitcache.load(fk)
    size = next(cache.iterdir()).stat().st_size
    old = time.time() - 100
    os.utime(next(cache.iterdir()), (old, old))
    # room for about two entries of this size: the third compile drops the oldest
    monkeypatch.setenv("CASADICAL_CACHE_MAX_MB", str(2.5 * size / 1e6))
    jitcache.load(model.per_pose_function("tau"))
    jitcache.load(model.per_pose_function("dq"))
    names = entries(cache)
    assert len(names) == 2 and not any(n.startswith("fk-") for n in names), names
    jitcache.load(model.per_pose_function("tau"), compile=False)   # a hit makes tau the most recent
    stale = cache / ".x.so.123.part"
    stale.write_bytes(b"half")
    os.utime(stale, (old - 7200, old - 7200))
    jitcache.prune()
    assert not stale.exists() and len(entries(cache)) == 2


def test_cache_command_info_and_clear(cache, capsys):
    assert main(["cache", "--info", "--json", "-"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["entries"] == 0 and doc["folder"] == str(cache) and not cache.exists()
    _, vm = fk_of()
    jitcache.load(vm)
    (cache / "notes.txt").write_text("a user's file")
    assert main(["cache", "--info"]) == 0
    out = capsys.readouterr().out
    assert "1 compiled function" in out and str(cache) in out
    assert main(["cache", "--clear"]) == 0
    assert "removed 1 file" in capsys.readouterr().out
    assert entries(cache) == ["notes.txt"]      # only the cache's own files go
    assert jitcache.load(vm, compile=False) is None
    assert main(["cache"]) == 2 and "--info --clear" in capsys.readouterr().err


@pytest.mark.parametrize("arm, spec, effects", [
    (ARM3, "kinematic+compliance[2]", Effects(stiffness={2: 4e5})),
    (ARM5, "kinematic", Effects()),
])
def test_calibration_is_the_same_with_compiled_cached_code(cache, arm, spec, effects):
    """Hidden geometric errors (and a compliant joint 2): the VM, a fresh compile and the cached code
    calibrate to the same parameters with IPOPT (bounds) and LM, over two seeds; what is compiled is the
    robot's superset (casadical.model._superset), never a function of one model."""
    robot = robot_from_dict(arm)
    for seed in (3, 4):
        data, truth = simulate(robot, 120, effects, seed=seed, floor_z=None)
        for solver in ("ipopt", "lm"):
            runs = []
            for jit in (False, True, True):   # VM, then compiled (first seed: compiled now; then the cache)
                res = calibrate(robot, data, Model(robot, spec, jit=jit), solver, warn=False)
                runs.append(res)
            ref = runs[0].parameters.values
            scale = runs[0].parameters.scales
            for r in runs[1:]:
                assert r.solver.success
                np.testing.assert_allclose(r.parameters.values / scale, ref / scale, rtol=0, atol=1e-7)
            # and the hidden errors are found: the fitted model predicts the truth to well under the noise
            assert runs[2].calibration.rms_mm < 0.05
    jitcache.finish()       # the optimised code compiled in the background, kept as at a process's end
    names = [n.split("-")[0] for n in entries(cache)]
    assert "superset_jac" in names and all(n.startswith("superset_") for n in names), names


def test_no_compiler_means_the_vm_and_no_cache_folder(cache, tmp_path):
    code = ("import numpy as np\n"
            "from casadical.model import _jitcache as jitcache\n"
            "from casadical.model._symbolic import Model, compiler_available\n"
            "from casadical.loading import load_robot\n"
            "m = Model(load_robot('ys100'), 'kinematic')\n"
            "m.predict(np.zeros((400, 6)))\n"
            "assert not compiler_available() and jitcache.compiler() is None\n")
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    env = {"PATH": str(bin_dir), "CASADICAL_CACHE": str(cache), "HOME": str(tmp_path)}
    r = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    assert r.returncode == 0 and r.stderr == "", r.stderr
    assert not cache.exists()


def test_the_cache_folder_follows_the_environment(monkeypatch, tmp_path):
    monkeypatch.delenv("CASADICAL_CACHE", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert jitcache.cache_dir() == tmp_path / "xdg" / "casadical"
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path))
    assert jitcache.cache_dir() == tmp_path / ".cache" / "casadical"
    monkeypatch.setenv("CASADICAL_CACHE", str(tmp_path / "mine"))
    assert jitcache.cache_dir() == tmp_path / "mine"


def test_an_unwritable_cache_still_compiles(monkeypatch, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("a file where the folder should be")
    monkeypatch.setenv("CASADICAL_CACHE", str(blocker / "cache"))
    model, vm = fk_of()
    compiled = jitcache.load(vm)
    np.testing.assert_allclose(evaluate(compiled, model), evaluate(vm, model), rtol=1e-13, atol=1e-15)
    assert blocker.read_text().startswith("a file")


def test_ipopt_exact_hessian_on_a_compiled_model(cache):
    """IPOPT's exact Hessian differentiates the objective: it must work when the model is compiled."""
    robot = robot_from_dict(ARM3)
    data, _ = simulate(robot, 120, Effects(stiffness={2: 4e5}), seed=5, floor_z=None)
    spec = "kinematic+compliance[2]"
    opts = {"hessian": "exact"}
    ref = calibrate(robot, data, Model(robot, spec, jit=False), "ipopt", solver_options=opts, warn=False)
    got = calibrate(robot, data, Model(robot, spec, jit=True), "ipopt", solver_options=opts, warn=False)
    assert got.solver.success
    scale = ref.parameters.scales
    np.testing.assert_allclose(got.parameters.values / scale, ref.parameters.values / scale, rtol=0, atol=1e-7)


def test_a_quick_compile_now_and_the_optimised_code_in_the_background(cache, monkeypatch):
    """``quick``: the code a run waits for is compiled without optimisation (nothing kept), the optimised code
    compiles in the background and goes into the cache once collected; both give the VM's bits. Killed
    (a process ending on an error or a signal), it leaves nothing. A small Function is optimised at once."""
    small, vm0 = fk_of("kinematic+encoder_scale")
    assert vm0.n_instructions() < jitcache.QUICK_MIN_INSTRUCTIONS
    at_once = jitcache.load_all([vm0], quick=True)[0]
    assert at_once.class_name() == "External" and not jitcache.pending(vm0)
    (first,) = entries(cache)
    cache_entries = [first]
    assert np.array_equal(evaluate(at_once, small), evaluate(vm0, small))
    monkeypatch.setattr(jitcache, "QUICK_MIN_INSTRUCTIONS", 0)      # the test arm's Functions are small
    model, vm = fk_of("kinematic+compliance")
    quick = jitcache.load_all([vm], quick=True)[0]
    assert quick.class_name() == "External" and jitcache.pending(vm)
    assert entries(cache) == cache_entries                       # the quick code is never kept
    for seed in (0, 1):
        assert np.array_equal(evaluate(quick, model, seed), evaluate(vm, model, seed))
    best = jitcache.upgraded(vm, wait=True)
    assert best is not None and not jitcache.pending(vm)
    (entry,) = set(entries(cache)) - {first}
    assert entry.startswith("fk-")
    for seed in (0, 1):
        assert np.array_equal(evaluate(best, model, seed), evaluate(vm, model, seed))
    assert jitcache.load(vm, compile=False) is not None          # a later run loads it
    # a second Function, its optimised compile killed: no entry, no compiler left, no folder
    model2, vm2 = fk_of("kinematic+compliance+encoder_scale")
    jitcache.load_all([vm2], quick=True)
    job = jitcache._PENDING[id(vm2)]
    assert jitcache.finish(kill=True) == 0
    assert job.process.poll() is not None and not os.path.exists(job.folder)
    assert entries(cache) == sorted([first, entry]) and jitcache.upgraded(vm2) is None


def test_a_calibration_without_a_compiler_is_the_compiled_ones(cache, tmp_path):
    """The compiler hidden (PATH without gcc or cc): the calibration runs on CasADi's VM, warns nothing,
    writes no cache, and gives the parameters of the compiled run."""
    robot = robot_from_dict(ARM5)
    data, _ = simulate(robot, 400, Effects(stiffness={2: 3e5}), seed=7, floor_z=None)
    data.write_csv(tmp_path / "d.csv")
    code = ("import json, sys\n"
            "from casadical import calibrate\n"
            "from casadical.data import Measurements\n"
            "from casadical.model import _jitcache as jitcache\n"
            "from casadical.robot import robot_from_dict\n"
            "assert jitcache.compiler() is None\n"
            f"res = calibrate(robot_from_dict({ARM5!r}), Measurements.read_csv(sys.argv[1], n_joints=5), "
            "'kinematic+compliance', 'lm', warn=False)\n"
            "print(json.dumps(res.parameters.values.tolist()))\n")
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    hidden = tmp_path / "hidden-cache"
    env = {"PATH": str(bin_dir), "CASADICAL_CACHE": str(hidden), "HOME": str(tmp_path), "CASADICAL_JIT": "1",
           "PYTHONPATH": os.pathsep.join(sys.path)}
    r = subprocess.run([sys.executable, "-c", code, str(tmp_path / "d.csv")], env=env, capture_output=True,
                       text=True)
    assert r.returncode == 0 and r.stderr == "", r.stderr
    assert not hidden.exists()
    from casadical.data import Measurements

    ref = calibrate(robot, Measurements.read_csv(tmp_path / "d.csv", n_joints=5), Model(robot, "kinematic+compliance",
                    jit=True), "lm", warn=False)
    jitcache.finish()
    assert any(n.startswith("superset_jac") for n in entries(cache))   # the reference was compiled
    scale = ref.parameters.scales
    np.testing.assert_allclose(np.array(json.loads(r.stdout)) / scale, ref.parameters.values / scale, rtol=0,
                               atol=1e-9)
