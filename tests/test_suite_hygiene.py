"""The suite asserts no machine's figure (issue 47): no test asserts an iteration or evaluation count of a
solver, or a time, except the places below, each with the reason it holds on any CPU.

An iterative solver's count is the CPU's arithmetic near the optimum (where the objective's rounding decides a
line search or a stopping test: on a 2-core AMD EPYC IPOPT took 15 objective evaluations for 7 iterations where a
Xeon took fewer, and the README's test command failed there); a time is the machine's speed and its load. A test
asserts what a user relies on instead: the optimum reached, to a tolerance derived from the problem. A premise
about the machine (that IPOPT backtracks here) is a skip with its reason, not a failure.

The search reads every ``assert`` statement and every ``assert_*`` call (``np.testing.assert_allclose``, ...) in
the files under tests/, and the names each reads: variables, attributes and string keys. A ``pytest.skip``'s
condition is not an assertion, nor is the text of a message.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: a name an assertion must not read, by what it is (the whole name must match)
PATTERNS = {
    "an iteration or evaluation count": re.compile(
        r"iterations?|n_?iters?|nit|nfev|njev|n_?evals?|evaluations|iter_count|n_call_\w+|it"),
    # a result's time (r.time_s, solve_time_s) and the clocks; the string "time_s" alone is the measurements' column
    "a time": re.compile(r"\w+_time_s|perf_counter|process_time|monotonic|elapsed\w*|seconds|timeit"),
}

#: (file, function) -> why the count or time it asserts is no machine's figure
ALLOWED = {
    ("tests/calibration/test_calibrate.py", "test_lm_and_ipopt_agree_without_active_bounds"):
        "iterations > 0 and solve_time_s > 0: the result says that IPOPT ran and how long it took",
    ("tests/calibration/test_calibrate.py", "test_json_round_trip_and_predict"):
        "the JSON's keys (iterations, solve_time_s), not their values",
    ("tests/calibration/test_calibrate.py", "test_ipopt_line_search_trials_evaluate_the_loss_alone"):
        "the premise (IPOPT backtracks here) is a skip; the linearisations are counted against IPOPT's own "
        "requests (at most one per gradient and one per iteration: the code's rule), two solves of one machine "
        "compared",
    ("tests/calibration/test_calibrate.py", "test_auto_hands_max_iter_to_ipopt"):
        "max_iter = 3 is the option's figure, not the machine's (the premise that IPOPT needs more is a skip)",
    ("tests/calibration/test_full_pose.py", "test_lm_and_ipopt_agree_on_the_full_pose_objective"):
        "iterations > 0: IPOPT ran",
    ("tests/calibration/test_std_tol.py", "test_stops_within_a_hundredth_of_a_standard_error"):
        "the same solve stopped by one more rule, on the same machine: it never takes more iterations",
    ("tests/optim/test_optimizers.py", "test_result_bookkeeping"):
        "nit, nfev: the generations and population the settings fix; time_s >= 0: the field is filled",
    ("tests/optim/test_optimizers.py", "test_x0_several_points_and_zero_generations"):
        "nit == 0: zero generations asked for",
    ("tests/optim/test_optimizers.py", "test_callback_sees_every_generation_and_can_stop"):
        "nit == 7: the callback stops at generation 7",
    ("tests/optim/test_optimizers.py", "test_stall_generations_stops_early"):
        "nit < 500: stopped early by the stall rule on a staircase objective (whole numbers: no rounding)",
    ("tests/optim/test_optimizers.py", "test_subset_ga_finds_brute_force_optimum_small_pool"):
        "nfev < 495: the evaluations the settings fix (35 + 10 x 42), fewer than the brute force's",
    ("tests/optim/test_optimizers.py", "test_subset_ga_finds_brute_force_optimum_larger_pool"):
        "nfev: the evaluations the settings fix (35 + 100 x 42)",
    ("tests/compensators/test_networks.py", "test_mlp_tlbo_reduces_training_error"):
        "nfev: TLBO's evaluations the settings fix (40 + 2 x 40 x 400)",
    ("tests/methods/test_methods.py", "test_each_method_runs"):
        "time_s > 0: the result says how long it took",
    ("tests/methods/test_methods.py", "test_two_phase_recovers_planted_stiffness"):
        "nfev > 100: the metaheuristic ran (its settings fix more)",
    ("tests/methods/test_methods.py", "test_global_start_matches_skcm"):
        "nfev > 0: the global start ran",
    ("tests/test_common.py", "test_method_result_interface"):
        "time_s > 0: the result says how long it took",
    ("tests/runtime/test_interrupts.py", "_none_outlives"):
        "a bound against a hang (30 s), not a speed: the processes end with the command",
    ("tests/runtime/test_interrupts.py", "_waiting"):
        "a bound against a hang (120 s) for the process to reach its checkpoint, not a speed",
}


def _names(node: ast.AST):
    """The names an assertion reads: variables, attributes, string constants that are names (a key)."""
    for n in ast.walk(node):
        if isinstance(n, ast.Name):
            yield n.id
        elif isinstance(n, ast.Attribute):
            yield n.attr
            if n.attr == "time_s" or (n.attr == "time" and getattr(n.value, "id", None) == "time"):
                yield "run_time_s"              # r.time_s, time.time()
        elif isinstance(n, ast.Constant) and isinstance(n.value, str) and n.value.isidentifier():
            yield n.value


def _asserting(node: ast.AST) -> bool:
    if isinstance(node, ast.Assert):
        return True
    if isinstance(node, ast.Call):
        name = getattr(node.func, "attr", None) or getattr(node.func, "id", None) or ""
        return name.startswith("assert")
    return False


def findings(paths) -> list[tuple[str, str, int, str, str]]:
    """(file, function, line, what, source) of every assertion that reads a count or a time."""
    out = []
    for path in map(Path, paths):
        text = path.read_text(encoding="utf-8")
        rel = path.resolve().relative_to(ROOT).as_posix() if path.resolve().is_relative_to(ROOT) else path.name
        stack: list[str] = []

        def visit(node):
            named = isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))
            if named:
                stack.append(node.name)
            if _asserting(node):
                # the message of an assert is text for the reader, not what is asserted
                checked = node.test if isinstance(node, ast.Assert) else node
                names = set(_names(checked))
                for what, pattern in PATTERNS.items():
                    if any(pattern.fullmatch(n) for n in names):
                        source = " ".join((ast.get_source_segment(text, node) or "").split())
                        out.append((rel, stack[-1] if stack else "<module>", node.lineno, what, source[:160]))
            else:
                for child in ast.iter_child_nodes(node):
                    visit(child)
            if named:
                stack.pop()

        visit(ast.parse(text))
    return out


def test_no_assertion_on_a_count_or_a_time_but_the_allowed():
    found = findings(p for p in sorted((ROOT / "tests").rglob("*.py")) if p.name != Path(__file__).name)
    new = [f for f in found if (f[0], f[1]) not in ALLOWED]
    assert not new, ("assertions on a machine's figure (assert what a user relies on instead, or allow the place "
                     "in ALLOWED with why no CPU changes it):\n"
                     + "\n".join(f"{f}:{n} ({fn}): {what}: {src}" for f, fn, n, what, src in new))
    stale = set(ALLOWED) - {(f[0], f[1]) for f in found}
    assert not stale, f"allowed places that no longer assert a count or a time (remove them): {sorted(stale)}"


SAMPLE = '''
import time
import numpy as np
import pytest


def test_counts(res, solves, stats):
    """IPOPT takes 7 iterations here."""
    assert res.solver.iterations <= 12
    assert 15 <= (2 * res.iterations)
    assert sum(nf for _, _, nf in solves) <= 2 * sum(it for _, it, _ in solves)
    assert stats["n_call_nlp_f"] < 30
    np.testing.assert_array_less(res.nfev, 500)


def test_times(run):
    t0 = time.perf_counter()
    run()
    assert time.perf_counter() - t0 < 2.0
    assert run.solve_time_s < 0.5
    assert run.result.time_s < 3


def test_not_these(res, solves, data):
    if res.iterations < 12:
        pytest.skip("IPOPT does not stall on this machine's arithmetic")
    solves.append(res.iterations)
    assert res.solver.success, f"it did not converge in {res.iterations} iterations"
    assert data.columns["time_s"].tolist() == [0, 30, 60]
'''


def test_the_search_finds_counts_and_times(tmp_path):
    """The search can fail: it finds what issue 47 removed, in an assert statement or an assert_* call, and
    leaves the rest alone (a skip's premise, a count recorded, an assertion's message, the time_s column)."""
    path = tmp_path / "test_sample.py"
    path.write_text(SAMPLE)
    count, time = PATTERNS
    assert [(fn, n, what) for _, fn, n, what, _ in findings([path])] == [
        ("test_counts", 9, count), ("test_counts", 10, count), ("test_counts", 11, count), ("test_counts", 12, count),
        ("test_counts", 13, count), ("test_times", 19, time), ("test_times", 20, time), ("test_times", 21, time)]
