"""Monte Carlo studies: protocol, task, results folder, Dask backend, summary and command line.

The studies hide joint compliance in robots that are not built in (a 4-joint
DH arm with Hayati's beta on joint 2, a 5-joint MDH arm without) and require
the study to show that the method modelling it wins. The Dask tests run a
tiny study on a local cluster of 2 worker processes and compare it row by
row, floats exactly, with a serial run; one kills a busy worker, one stops
the client midway and resumes.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from casadical.cli import main
from casadical.errors import InputError
from casadical.study import TIME_COLUMNS, ResultStore, differing_columns, load_study, run_study, run_task, summarize

ARM4_DH = """
name = "four-axis DH arm"
convention = "dh"
payload = {mass_kg = 20}
tool = {a_m = 0.1, b_m = 0.02, d_m = 0.05}
[[joint]]
alpha_deg = 90
a_m = 0.15
d_m = 0.4
min_deg = -170
max_deg = 170
mass_kg = 30
com_m = [0, -0.1, 0]
[[joint]]
alpha_deg = 0
a_m = 0.8
d_m = 0.0
beta_deg = 0.0
min_deg = -10
max_deg = 170
mass_kg = 25
com_m = [-0.4, 0, 0]
[[joint]]
alpha_deg = 0
a_m = 0.6
d_m = 0.0
min_deg = -150
max_deg = 150
mass_kg = 12
com_m = [-0.3, 0, 0]
[[joint]]
alpha_deg = -90
a_m = 0.0
d_m = 0.1
min_deg = -170
max_deg = 170
mass_kg = 5
"""

ARM5_MDH = """
name = "five-axis MDH arm"
convention = "mdh"
payload = {mass_kg = 15}
tool = {a_m = 0.05, d_m = 0.12}
[[joint]]
alpha_deg = 0
a_m = 0.0
d_m = 0.45
mass_kg = 40
com_m = [0, 0, -0.1]
min_deg = -170
max_deg = 170
[[joint]]
alpha_deg = -90
a_m = 0.15
d_m = 0.0
mass_kg = 25
com_m = [0.35, 0, 0]
min_deg = -120
max_deg = 30
[[joint]]
alpha_deg = 0
a_m = 0.7
d_m = 0.0
mass_kg = 15
com_m = [0.3, 0, 0]
min_deg = -60
max_deg = 150
[[joint]]
alpha_deg = -90
a_m = 0.1
d_m = 0.6
mass_kg = 6
com_m = [0, 0, -0.2]
min_deg = -170
max_deg = 170
[[joint]]
alpha_deg = 90
a_m = 0.0
d_m = 0.0
mass_kg = 2
min_deg = -120
max_deg = 120
"""

ROBOTS = {"arm4-dh": ARM4_DH, "arm5-mdh": ARM5_MDH}

STUDY = """
name = "tiny"
robot = "{robot}.toml"
seed = {seed}
repetitions = {reps}
validation_poses = 30

[truth]
stiffness = {{2 = 4e5}}
noise_mm = 0.02

[workspace]
floor_z_m = -10.0

[[plan]]
name = "random"
method = "random"
poses = {poses}

[[method]]
method = "KM"

[[method]]
name = "SKCM"
model = "kinematic+compliance[2]"
solver = "lm"
"""


def write_study(folder, robot="arm4-dh", seed=1, reps=4, poses="25", extra="") -> str:
    (folder / f"{robot}.toml").write_text(textwrap.dedent(ROBOTS[robot]))
    path = folder / f"study-{robot}-{seed}.toml"
    path.write_text(STUDY.format(robot=robot, seed=seed, reps=reps, poses=poses) + textwrap.dedent(extra))
    return str(path)


def assert_same_rows(a, b):
    """Two results tables hold the same rows, floats bit for bit (NaN equal to NaN), times aside."""
    assert a.num_rows > 0 and differing_columns(a, b) == []


def raw_repetitions(folder) -> list[int]:
    """Repetition of every row in every part file, duplicates included."""
    import pyarrow.parquet as pq
    return [r for p in ResultStore.open(folder).parts()
            for r in pq.read_table(p, columns=["repetition"]).column(0).to_pylist()]


# --- protocol --------------------------------------------------------------------


@pytest.mark.parametrize("edit, column", [
    (("repetitions = 4", "repetitions = 0"), "repetitions"),
    (("validation_poses = 30", "validation_poses = 'x'"), "validation_poses"),
    (("noise_mm = 0.02", "noise_mm = -1"), "truth.noise_mm"),
    (("stiffness = {2 = 4e5}", "stiffness = {7 = 4e5}"), "truth.stiffness.7"),
    (("floor_z_m = -10.0", "floor_z = 0"), "workspace.floor_z"),
    (('method = "random"', 'method = "best"'), "plan[1].method"),
    (("poses = 25", "poses = [25, 0]"), "plan[1].poses"),
    (('method = "random"', 'method = "ga"'), "plan[1].pool"),
    (('method = "KM"', 'method = "CA-SKCM"'), "method[1].method"),
    (('method = "KM"', 'method = "KM"\nsettings = {nope = 1}'), "method[1].method"),
    (('model = "kinematic+compliance[2]"', 'model = "kinematic+compliance[9]"'), "method[2].model"),
    (('solver = "lm"', 'solver = "newton"'), "method[2].solver"),
    (('name = "SKCM"', 'name = "KM"'), "method[2].name"),
    (('robot = "arm4-dh.toml"', 'robot = "arm4-dh.toml"\nprotocol = "ca-ys100"'), "robot"),
])
def test_protocol_errors_name_the_key(tmp_path, edit, column):
    path = write_study(tmp_path)
    text = open(path).read()
    assert edit[0] in text
    open(path, "w").write(text.replace(edit[0], edit[1], 1))
    with pytest.raises(InputError) as e:
        load_study(path)
    assert e.value.column == column and e.value.file == path


def test_bad_protocol_is_one_line(tmp_path):
    path = write_study(tmp_path)
    open(path, "a").write("\n[[plan]]\nmethod = 'random'\nposes = 10\n")   # a second plan named "random"
    r = subprocess.run([sys.executable, "-m", "casadical", "study", path, "--out", str(tmp_path / "r"), "--serial"],
                       capture_output=True, text=True)
    lines = [x for x in r.stderr.strip().splitlines() if "has no beta_deg" not in x]   # arm4-dh's warning
    assert r.returncode == 2 and len(lines) == 1 and "plan[2].name" in lines[0] and path in lines[0]
    assert not (tmp_path / "r").exists()


def test_bundled_studies_load():
    from casadical.study import STUDY_DIR
    names = sorted(p.stem for p in STUDY_DIR.glob("*.toml"))
    assert names
    for n in names:
        s = load_study(n)
        assert s.repetitions >= 1 and s.cells() and s.methods


# --- the task finds what is hidden ------------------------------------------------


@pytest.mark.parametrize("robot", ["arm4-dh", "arm5-mdh"])
@pytest.mark.parametrize("seed", [1, 2])
def test_study_shows_the_hidden_compliance(tmp_path, robot, seed):
    study = load_study(write_study(tmp_path, robot, seed, reps=3))
    report = run_study(study, tmp_path / "r", backend="serial")
    assert (report.computed, report.error_rows) == (3, 0)
    s = summarize(tmp_path / "r", baseline="KM", metric="val_true_mean_mm")
    km, skcm = s.rows
    assert (km.method, skcm.method) == ("KM", "SKCM") and km.ok == skcm.ok == 3
    assert skcm.win_rate == 1.0 and skcm.pairs == 3
    # compliance of joint 2 is what KM cannot absorb: modelled, the error falls to the noise
    assert skcm.median < km.median / 5 and skcm.median < 0.05
    assert skcm.stiffness_error_median < 5.0 and np.isnan(km.stiffness_error_median)
    table = ResultStore.open(tmp_path / "r").read()
    errs = table.filter(table.column("method").to_numpy(zero_copy_only=False) == "SKCM").column("parameter_errors")
    assert all(abs(dict(e)["c2"]) < 0.05 / 4e5 for e in errs.to_pylist())


def test_failures_are_rows_and_the_study_goes_on(tmp_path):
    # 5 poses cannot give a D-optimal design for kinematic+compliance: every row of that plan fails
    path = write_study(tmp_path, reps=2, extra="""
        [[plan]]
        name = "too-few"
        method = "d-optimal"
        poses = 5
        pool = 40
        """)
    report = run_study(load_study(path), tmp_path / "r", backend="serial")
    assert report.computed == 2 and report.error_rows == 4
    t = ResultStore.open(tmp_path / "r").read().to_pylist()
    assert len(t) == 8
    bad = [r for r in t if r["plan"] == "too-few"]
    assert all(r["status"] == "error" and "IdentifiabilityError" in r["error"] and np.isnan(r["val_mean_mm"])
               for r in bad)
    assert all(r["status"] == "ok" and r["error"] == "" for r in t if r["plan"] == "random")
    rows = {(r.plan, r.method): r for r in summarize(tmp_path / "r").rows}
    assert rows[("too-few", "SKCM")].ok == 0 and rows[("random", "SKCM")].ok == 2


def test_task_is_deterministic_and_streams_are_independent(tmp_path):
    study = load_study(write_study(tmp_path, poses="[20, 25]"))
    a, b = run_task(study, 3), run_task(study, 3)

    def result(row):   # NaN != NaN: compare the text of floats
        return {k: repr(v) for k, v in row.items() if k not in TIME_COLUMNS}

    assert len(a) == 4 and [result(x) for x in a] == [result(y) for y in b]
    # another repetition is another robot; dropping a method leaves the other rows as they were
    assert run_task(study, 4)[0]["val_mean_mm"] != a[0]["val_mean_mm"]
    study.methods = study.methods[1:]
    c = run_task(study, 3)
    assert [r["val_mean_mm"] for r in c] == [r["val_mean_mm"] for r in a if r["method"] == "SKCM"]


# --- the results folder ------------------------------------------------------------


def test_results_folder_resumes_extends_and_refuses(tmp_path):
    path = write_study(tmp_path, reps=2)
    out = tmp_path / "r"
    assert run_study(load_study(path), out, backend="serial").computed == 2
    first = ResultStore.open(out).read()
    # the same protocol resumes: nothing to do; more repetitions extend it
    assert run_study(load_study(path), out, backend="serial").skipped == 2
    text = open(path).read()
    open(path, "w").write(text.replace("repetitions = 2", "repetitions = 3"))
    r = run_study(load_study(path), out, backend="serial")
    assert (r.skipped, r.computed) == (2, 1) and sorted(set(raw_repetitions(out))) == [0, 1, 2]
    assert_same_rows(ResultStore.open(out).read().slice(0, first.num_rows), first)
    # another protocol is refused without --force; the rows stay
    other = write_study(tmp_path, seed=7, reps=1)
    with pytest.raises(InputError, match="another protocol"):
        run_study(load_study(other), out, backend="serial")
    assert sorted(set(raw_repetitions(out))) == [0, 1, 2]
    assert run_study(load_study(other), out, backend="serial", force=True).computed == 1
    assert raw_repetitions(out) == [0, 0]
    # never into a file or a folder of other things
    (tmp_path / "notes").mkdir()
    (tmp_path / "notes" / "mine.txt").write_text("keep")
    for target in (tmp_path / "notes", tmp_path / "notes" / "mine.txt"):
        with pytest.raises(InputError):
            run_study(load_study(path), target, backend="serial", force=True)
    assert [p.name for p in (tmp_path / "notes").iterdir()] == ["mine.txt"]
    assert (tmp_path / "notes" / "mine.txt").read_text() == "keep"


def test_one_run_per_folder(tmp_path):
    from casadical.study import ResultStore as Store
    study = load_study(write_study(tmp_path, reps=1))
    with Store.for_study(tmp_path / "r", study):
        with pytest.raises(InputError, match="another casadical study"):
            run_study(study, tmp_path / "r", backend="serial")


# --- Dask --------------------------------------------------------------------------


@pytest.fixture(scope="module")
def cluster():
    import logging

    from distributed import Client, LocalCluster
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0",
                      silence_logs=logging.CRITICAL) as c, Client(c) as client:
        yield client


REPS = 5
EACH_ONCE = sorted(list(range(REPS)) * 2)    # every repetition's 2 rows, once


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """A small study and its serial results."""
    folder = tmp_path_factory.mktemp("reference")
    path = write_study(folder, "arm5-mdh", seed=3, reps=REPS, poses="20")
    run_study(load_study(path), folder / "serial", backend="serial")
    return path, ResultStore.open(folder / "serial").read()


def test_dask_equals_serial(cluster, reference, tmp_path):
    path, serial = reference
    report = run_study(load_study(path), tmp_path / "r", client=cluster, flush_s=0)
    assert (report.computed, report.workers, report.error_rows) == (REPS, 2, 0)
    assert sorted(raw_repetitions(tmp_path / "r")) == EACH_ONCE
    assert_same_rows(ResultStore.open(tmp_path / "r").read(), serial)
    # the comparison sees a difference in the last bit
    import pyarrow as pa
    i = serial.column_names.index("val_mean_mm")
    nudged = pa.array(np.nextafter(serial.column(i).to_numpy(), np.inf))
    assert differing_columns(serial.set_column(i, "val_mean_mm", nudged), serial) == ["val_mean_mm"]


def test_killed_worker_loses_nothing(cluster, reference, tmp_path):
    path, serial = reference
    killed = []

    def kill_a_busy_worker(rep, rows):
        if killed:
            return
        busy = [w for w, keys in cluster.processing().items() if keys]
        assert busy, "no task running to kill"
        pid = cluster.run(os.getpid, workers=busy[:1])[busy[0]]
        os.kill(pid, signal.SIGKILL)
        killed.append(pid)

    report = run_study(load_study(path), tmp_path / "r", client=cluster, progress=kill_a_busy_worker, flush_s=0)
    assert killed and report.computed == REPS and report.error_rows == 0
    assert sorted(raw_repetitions(tmp_path / "r")) == EACH_ONCE   # each once
    assert_same_rows(ResultStore.open(tmp_path / "r").read(), serial)
    cluster.wait_for_workers(2, timeout=30)


def test_a_task_that_kills_its_worker_is_lost_and_resumed(cluster, reference, tmp_path):
    path, serial = reference
    killed = []

    def kill_a_busy_worker(rep, rows):
        busy = [w for w, keys in cluster.processing().items() if keys]
        if not killed and busy:
            killed.append(cluster.run(os.getpid, workers=busy[:1])[busy[0]])
            os.kill(killed[0], signal.SIGKILL)

    # with no second chance, the tasks on the killed worker fail as a whole (Dask: KilledWorker)
    old = cluster.run_on_scheduler(lambda dask_scheduler: dask_scheduler.allowed_failures)
    cluster.run_on_scheduler(lambda dask_scheduler: setattr(dask_scheduler, "allowed_failures", 0))
    try:
        report = run_study(load_study(path), tmp_path / "r", client=cluster, progress=kill_a_busy_worker)
    finally:
        cluster.run_on_scheduler(lambda dask_scheduler, n=old: setattr(dask_scheduler, "allowed_failures", n))
        cluster.wait_for_workers(2, timeout=30)
    assert killed and report.computed == REPS and report.error_rows > 0
    assert sorted(raw_repetitions(tmp_path / "r")) == EACH_ONCE
    rows, ref = ResultStore.open(tmp_path / "r").read().to_pylist(), serial.to_pylist()
    failed = {r["repetition"] for r in rows if r["status"] == "lost"}
    assert failed and all("KilledWorker" in r["error"] for r in rows if r["status"] == "lost")
    assert not any(r["status"] == "error" for r in rows)
    assert [r["val_mean_mm"] for r in rows if r["repetition"] not in failed] == \
        [r["val_mean_mm"] for r in ref if r["repetition"] not in failed]
    # a resumed run computes the lost repetitions again, and the table is the serial one
    report = run_study(load_study(path), tmp_path / "r", client=cluster)
    assert (report.skipped, report.computed) == (REPS - len(failed), len(failed))
    assert_same_rows(ResultStore.open(tmp_path / "r").read(), serial)


def test_interrupted_run_resumes_to_the_same_table(cluster, reference, tmp_path):
    path, serial = reference
    seen = []

    def stop_after_two(rep, rows):
        seen.append(rep)
        if len(seen) == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_study(load_study(path), tmp_path / "r", client=cluster, progress=stop_after_two)
    assert sorted(set(raw_repetitions(tmp_path / "r"))) == sorted(seen)   # finished work was kept
    report = run_study(load_study(path), tmp_path / "r", client=cluster)
    assert (report.skipped, report.computed) == (2, REPS - 2)
    assert sorted(raw_repetitions(tmp_path / "r")) == EACH_ONCE
    assert_same_rows(ResultStore.open(tmp_path / "r").read(), serial)


# --- command line ----------------------------------------------------------------


def test_cli_run_resume_summary_and_plots(tmp_path, capsys):
    path = write_study(tmp_path, reps=2, poses="[20, 30]")
    out = str(tmp_path / "r")
    assert main(["study", path, "--out", out, "--serial", "--quiet"]) == 0
    text = capsys.readouterr().out
    assert "2 repetitions in" in text and "| random | 30 | SKCM | 2/2 |" in text and "100 % of 2" in text
    assert main(["study", path, "--out", out, "--serial", "--quiet"]) == 0
    assert "0 repetitions in" in capsys.readouterr().out
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        return
    plots = str(tmp_path / "plots")
    assert main(["study", "--summary", out, "--baseline", "skcm", "--plot-dir", plots]) == 0
    assert "win rate vs SKCM" in capsys.readouterr().out
    for name in ("errors.png", "poses.png"):
        assert (tmp_path / "plots" / name).read_bytes()[:4] == b"\x89PNG"
    assert main(["study", "--summary", out, "--plot-dir", plots]) == 2          # plots exist: --force
    assert "exists already" in capsys.readouterr().err
    # a run's --force discards the results: an output that exists is refused there even with --force
    assert main(["study", path, "--out", out, "--serial", "--quiet", "--plot-dir", plots, "--force"]) == 2
    assert "study --summary RESULTS ... --force" in capsys.readouterr().err
    assert sorted(set(raw_repetitions(out))) == [0, 1]                           # the results are still there


def test_cli_summary_as_json(tmp_path, capsys):
    path = write_study(tmp_path, reps=2, poses="[20, 30]")
    out, doc = str(tmp_path / "r"), tmp_path / "s.json"
    assert main(["study", path, "--out", out, "--serial", "--quiet", "--json", str(doc)]) == 0
    run = json.loads(doc.read_text())
    assert run["run"]["computed"] == 2 and run["results"] == out
    assert main(["study", path, "--out", out, "--serial", "--quiet", "--json", str(doc), "--force"]) == 2
    assert main(["study", "--summary", out, "--json", str(doc), "--force"]) == 0
    summary = json.loads(doc.read_text())
    assert "run" not in summary and summary["rows"] == run["rows"]
    table = capsys.readouterr().out
    for row in summary["rows"]:                 # the JSON holds what the table shows
        assert f"| {row['plan']} | {row['n_poses']} | {row['method']} | {row['ok']}/{row['runs']} |" in table


@pytest.mark.parametrize("args, words", [
    (["--serial", "--workers", "2"], "--serial"),
    (["--workers", "2", "--scheduler", "tcp://127.0.0.1:1"], "--scheduler"),
    (["--baseline", "NN"], "no method 'NN'"),
    (["--metric", "status"], "unknown column"),
])
def test_cli_usage_errors(tmp_path, capsys, args, words):
    path = write_study(tmp_path, reps=1)
    assert main(["study", path, "--out", str(tmp_path / "r"), *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0]
    assert main(["study", "--summary", str(tmp_path / "r"), "--out", "x"]) == 2
    assert main(["study", "--summary", str(tmp_path / "nothing")]) == 2


def test_without_dask_or_pyarrow(tmp_path):
    """casadical and every other command work without the optional extra; study says what is missing."""
    path = write_study(tmp_path, reps=1)
    code = textwrap.dedent(f"""
        import sys
        for m in ("dask", "distributed", "pyarrow"):
            sys.modules[m] = None          # as if not installed
        import casadical, casadical.study
        from casadical.cli import main
        assert main(["split", {str(tmp_path / "d.csv")!r}, "-n", "2", "--out-cal", {str(tmp_path / "c.csv")!r},
                     "--out-val", {str(tmp_path / "v.csv")!r}]) == 0
        assert main(["study", {path!r}, "--out", {str(tmp_path / "r1")!r}]) == 2
        assert main(["study", {path!r}, "--out", {str(tmp_path / "r2")!r}, "--serial"]) == 2
        assert not [m for m in ("dask", "distributed", "pyarrow") if sys.modules.get(m)]
        """)
    (tmp_path / "d.csv").write_text("q1_deg,q2_deg,x_mm,y_mm,z_mm\n" + "1,2,3,4,5\n" * 4)
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    err = [line for line in r.stderr.splitlines() if line.startswith("casadical: error")]
    assert len(err) == 2 and "dask" in err[0] and "pyarrow" in err[1], r.stderr
