"""Smoke test of the benchmark suite: every piece runs on a tiny budget and writes its page.

No timing assertions: the numbers of a tiny run on a shared machine mean nothing.
"""

import json
import platform
import types
from pathlib import Path

import gymnasium as gym
import numba
import numpy as np
import pytest

from benchmarks import (
    batched,
    blas_variation,
    blas_worker,
    edge_probe,
    memory,
    native_profile,
    planner_shapes,
    profile_step,
    scripted_speedup,
    step_parts,
    step_times,
    throughput,
    work_precision,
)
from benchmarks.__main__ import main as run_suite
from grasp_env.kernel.batch import HAS_CYCLE_COUNTER


@pytest.mark.parametrize(
    "piece",
    [
        pytest.param(lambda out: throughput.run(True, out, budget=0.05, rounds=1), id="throughput"),
        pytest.param(
            lambda out: work_precision.run(True, out, paths=1, moves=2, fig13=False),
            id="work_precision",
        ),
        pytest.param(lambda out: profile_step.run(True, out, steps=3, closing=False), id="profile"),
        pytest.param(
            lambda out: memory.run(True, out, steps=2, repeat=1, workers=2, cold=False),
            id="memory",
        ),
        pytest.param(
            lambda out: memory.run(True, out, steps=2, repeat=1, workers=2, cold=True),
            id="memory_cold",
            marks=pytest.mark.slow,  # compiles everything in a fresh NUMBA_CACHE_DIR: minutes
        ),
        pytest.param(lambda out: step_parts.run(True, out, steps=30), id="step_parts"),
        pytest.param(lambda out: edge_probe.run(1, 3, 0, out), id="edge_probe"),
        pytest.param(
            lambda out: batched.run(
                True,
                out,
                pool=2,
                ids=("FrictionlessGrasp-v0", "FrictionlessGraspLift-v0"),
                budget=0.02,
                moves=20,
            ),
            id="batched",
        ),
        pytest.param(
            lambda out: scripted_speedup.run(
                Path(scripted_speedup.__file__).parent.parent, budget=0.05, rounds=1, out=out
            ),
            id="scripted_speedup",
        ),
    ],
)
def test_piece_writes_markdown(piece, tmp_path):
    out = tmp_path / "page.md"
    assert piece(out) == out
    text = out.read_text()
    assert text.startswith("# ") and "Machine:" in text and "| ---" in text


#: A report of perf (``--stdio -n --no-children --sort dso,sym``) and gdb's answers to ``info
#: symbol`` for its compiled addresses, in their sorted order, made up for the test below: 80
#: samples in all, so that the shares are the counts over 80 (not perf's rounded percentages,
#: which the test sets off by a little).
PERF_REPORT = """# Overhead       Samples  Shared Object  Symbol
# ........  ............  .............  ......
#
    12.50%            10  [JIT] tid 7                                  [.] 0x00007f0000001000
    10.01%             8  [JIT] tid 7                                  [.] 0x00007f0000002000
     7.50%             6  libc.so.6                                    [.] malloc
     5.00%             4  libm.so.6                                    [.] __sincos_fma
     2.50%             2  [JIT] tid 7                                  [.] 0x00007f0000003000
     2.50%             2  _multiarray_umath.cpython-311-x86_64-linux-gnu.so  [.] PyArray_New
     2.00%             1  [JIT] tid 7                                  [.] 0x00007f0000004000
     1.25%             1  [kernel.kallsyms]                            [k] do_syscall_64
    60.00%            46  libpython3.11.so.1.0                         [.] _PyEval_EvalFrameDefault
"""
GDB_ANSWERS = """warning: could not find '.gnu_debugaltlink' file
NRT_incref + 9 in section .ltext of <in-memory@0x5600>
grasp_env::sim::pose::newton[abi:v248][abi:c8tJ](Array<double, 2, C, mutable, aligned>) + 33 \
in section .text of <in-memory@0x5601>
No symbol matches 0x00007f0000003000.
_ZN9grasp_env6kernel5batch8step_oneB3v17B38c8tJTIeFIjxEx458ListType in section .text of <x>
"""


def test_native_profile_groups_what_perf_sampled_by_gdb_names():
    rows = native_profile.parse_report(PERF_REPORT)
    assert len(rows) == 9 and rows[0] == (10, "[JIT] tid 7", "0x00007f0000001000")
    assert rows[7] == (1, "[kernel.kallsyms]", "do_syscall_64")
    addresses = sorted(s for _, _, s in rows if s.startswith("0x"))
    names = native_profile.parse_symbols(GDB_ANSWERS)
    assert len(names) == len(addresses) and names[2] is None
    groups, functions = native_profile.aggregate(rows, dict(zip(addresses, names, strict=True)))
    expected = {  # samples of 80
        native_profile.REFCOUNT: 10,
        "compiled: grasp_env.sim.pose": 8,
        native_profile.ALLOCATION: 6,
        native_profile.MATH: 4,
        native_profile.UNNAMED: 2,
        native_profile.PYTHON: 2 + 46,
        "compiled: grasp_env.kernel.batch": 1,
        native_profile.KERNEL: 1,
    }
    assert groups.keys() == expected.keys()
    for group, samples in expected.items():
        assert groups[group] == pytest.approx(100.0 * samples / 80, rel=1e-12), group
    assert functions[("grasp_env.sim.pose.newton", "compiled: grasp_env.sim.pose")] == 10.0
    assert functions[
        ("grasp_env.kernel.batch.step_one", "compiled: grasp_env.kernel.batch")
    ] == pytest.approx(1.25)


def test_native_profile_writes_its_page_or_says_why_not(tmp_path):
    """Where perf and gdb can sample this process's child the page has its tables; where
    they cannot, it says why (a missing tool, or perf or gdb refused) and measures nothing."""
    out = native_profile.run(True, tmp_path / "page.md", envs=2, seconds=0.3)
    text = out.read_text()
    assert text.startswith("# ") and "Machine:" in text
    if "not measured here" in text:
        assert "Traceback" not in text and (
            "not found" in text or "failed" in text or "gdb" in text
        )
    else:
        assert "## By group" in text and native_profile.REFCOUNT in text
        assert "compiled: grasp_env.sim." in text


def test_move_costs_put_each_move_in_one_kind():
    rows = batched.move_costs("FrictionlessGraspLift-v0", 40, reps=1, pool=2)
    kinds = [row[0] for row in rows]
    assert kinds[0] == "touch nothing" and len(set(kinds)) == len(kinds)
    assert sum(row[1] for row in rows) == 40  # each move in exactly one kind
    assert all(row[2] == row[1] / 40 for row in rows)
    assert sum(row[3] for row in rows) == pytest.approx(1.0)
    assert all(row[4] > 0.0 for row in rows)


def test_thread_use_runs_the_same_steps_in_each_set_up():
    """One thread and all, both orders; every set-up does work where the processor has a
    cycle counter (elsewhere the batch reads 0 and keeps the index order)."""
    rows = batched.thread_use("FrictionlessGrasp-v0", 4, batched.WARM_UP + 5, pool=2)
    threads = numba.config.NUMBA_NUM_THREADS
    assert [row[1:3] for row in rows] == [
        [1, "costliest first"], [threads, "index order"], [threads, "costliest first"]
    ]  # fmt: skip
    if HAS_CYCLE_COUNTER:
        assert batched.cycles_per_second(0.01) > 0.0
        assert all(float(row[4]) > 0.0 for row in rows)


def test_timing_adds_each_calls_time_and_restores_what_it_wrapped():
    """A class's inherited method and a module's function: every call counted (an exception
    included), its result returned, the owner as it was after the block."""

    class Base:
        def f(self, x):
            return 2 * x

    class Child(Base):
        pass

    module = types.ModuleType("module")

    def g(x):
        raise KeyError(x)

    module.g = g
    seconds = {"f": 0.0, "g": 0.0}
    child = Child()
    with batched.timing(Child, "f", seconds, "f"), batched.timing(module, "g", seconds, "g"):
        assert child.f(3) == 6
        with pytest.raises(KeyError):
            module.g(1)
    assert seconds["f"] > 0.0 and seconds["g"] > 0.0
    assert "f" not in vars(Child) and Child.f is Base.f
    assert module.g is g


def test_random_actions_are_seeded_draws_within_the_space():
    venv = batched.make("FrictionlessGrasp-v0", 3, pool=2)
    a, b = batched.random_actions(venv, 5, seed=1), batched.random_actions(venv, 5, seed=1)
    space = venv.single_action_space
    assert a.shape == (5, 3, *space.shape) and np.array_equal(a, b)
    assert np.all(a >= space.low) and np.all(a <= space.high)
    assert not np.array_equal(a, batched.random_actions(venv, 5, seed=2))
    cartpole = gym.make_vec("CartPole-v1", num_envs=2, vectorization_mode="sync")
    assert batched.random_actions(cartpole, 4).shape == (4, 2)


def test_paired_ratios_divide_ours_by_the_baseline_whichever_runs_first(monkeypatch):
    ours, baseline = object(), object()
    order = []
    speeds = iter([10.0, 5.0, 4.0, 12.0, 9.0, 3.0])  # rates in the order they are measured

    def rate(venv, budget, seed):
        order.append((venv, seed))
        return next(speeds)

    monkeypatch.setattr(batched, "rate", rate)
    ratios = batched.paired_ratios(ours, baseline, 3, 0.1)
    # pair 0: ours then baseline, pair 1: baseline then ours, pair 2: ours then baseline
    assert order == [(ours, 0), (baseline, 0), (baseline, 1), (ours, 1), (ours, 2), (baseline, 2)]
    assert ratios == [10.0 / 5.0, 12.0 / 4.0, 9.0 / 3.0]


def test_profile_baseline_columns(tmp_path):
    first = profile_step.run(True, tmp_path / "a.md", steps=2, closing=False)
    second = profile_step.run(
        True, tmp_path / "b.md", steps=2, baseline=first.with_suffix(".json"), closing=False
    )
    assert "after / before" in second.read_text()
    record = json.loads(first.with_suffix(".json").read_text())
    assert set(profile_step.CONFIGS) <= set(record)


def test_planner_shapes_page_counts_each_plan_and_episode(tmp_path):
    page = planner_shapes.run(
        tmp_path / "shapes.md", shapes=2, suites=("heldout",), env=True, timeout=120, workers=1
    )
    text = page.read_text()
    assert text.startswith("# ") and "Machine:" in text
    row = next(line for line in text.splitlines() if line.startswith("| heldout | 2 |"))
    assert "timeout" not in text  # the worker processes ran every plan and episode
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert int(cells[2]) + int(cells[3]) == 2  # not tippable + tippable


def _forced_core_type() -> str | None:
    """An OpenBLAS core type this CPU can run other than its own (None: not an x86-64 CPU with
    AVX2 and FMA, or numpy without OpenBLAS)."""
    from threadpoolctl import threadpool_info

    if platform.machine() not in ("x86_64", "AMD64"):
        return None
    if not any(i.get("internal_api") == "openblas" for i in threadpool_info()):
        return None
    try:
        flags = Path("/proc/cpuinfo").read_text().split()
    except OSError:
        return None
    return "Haswell" if {"avx2", "fma"} <= set(flags) else None


def test_blas_environ_sets_or_removes_both_variables():
    base = {"PATH": "/bin", "OPENBLAS_CORETYPE": "Zen", "OPENBLAS_L2_SIZE": "1024"}
    assert blas_variation.blas_environ("unset", base) == {"PATH": "/bin"}
    env = blas_variation.blas_environ("Sandybridge", base)
    assert env["OPENBLAS_CORETYPE"] == "Sandybridge"
    assert env["OPENBLAS_L2_SIZE"] == blas_variation.L2_SIZE and env["PATH"] == "/bin"


def test_blas_variation_report(tmp_path):
    """One short episode a suite under ``unset`` and a forced core type: each worker process
    really runs the kernel asked for, and every suite gets its comparison row."""
    core = _forced_core_type()
    if core is None:
        pytest.skip("needs OpenBLAS on an x86-64 CPU with AVX2")
    report = blas_variation.run(tmp_path, episodes=1, steps=5, core_types=[core], workers=2)
    assert set(report["suites"]) == set(blas_variation.SUITES)
    for name in blas_variation.SUITES:
        forced = report["workers"][core][name]
        assert forced.get("error") is None, forced
        assert forced["environ"]["OPENBLAS_CORETYPE"] == core
        assert forced["blas"] and {lib["architecture"] for lib in forced["blas"]} == {core}
        unset = report["workers"]["unset"][name]
        assert unset["environ"] == dict.fromkeys(blas_worker.BLAS_VARS)
        assert forced["steps"] == unset["steps"] > 0
        row = report["suites"][name][core]
        assert row["episodes"] == 1
        assert 0 <= row["discrete_different"] <= row["bit_different"] <= 1
        assert row["discrete_different"] == len(row["discrete"])
        assert row["max_pose_diff_all"] >= row["max_pose_diff_same"] >= 0.0
    text = (tmp_path / "blas_variation.md").read_text()
    assert text.startswith("# ") and "Machine:" in text and f"| default | {core} | 1 |" in text
    assert json.loads((tmp_path / "blas_variation.json").read_text())["episodes"] == 1


def test_step_times_report(tmp_path):
    report = step_times.run(tmp_path, episodes=1, steps=5, workers=2)
    for name in step_times.SUITES:
        s = report["suites"][name]
        assert 0 < s["steps"] <= 5
        assert 0 < s["median"] <= s["p99"] <= s["p99.9"] <= s["max"]
    assert report["all"]["steps"] == sum(s["steps"] for s in report["suites"].values())
    slow = report["slowest"]
    assert slow and slow[0]["time"] == report["all"]["max"]
    assert {"suite", "seed", "step", "start", "kind", "events"} <= set(slow[0])
    text = (tmp_path / "step_times.md").read_text()
    assert text.startswith("# ") and "Machine:" in text and "| all |" in text
    times = step_times.replay(slow[0]["suite"], slow[0]["seed"], slow[0]["step"], repeat=1)
    assert len(times) == 2


def test_suite_refuses_a_bad_out_before_running(tmp_path, capsys):
    not_a_dir = tmp_path / "file"
    not_a_dir.write_text("")
    for out in (not_a_dir, not_a_dir / "sub"):
        with pytest.raises(SystemExit) as info:
            run_suite(["--only", "memory", "--out", str(out)])
        assert info.value.code == 2
        last = capsys.readouterr().err.splitlines()[-1]
        assert last.startswith("python -m benchmarks: error: --out") and str(out) in last
    assert not (tmp_path / "memory.md").exists()


def test_scripted_speedup_exports_a_commit(tmp_path):
    """The earlier commit's tree is exported beside the work tree, not over it."""
    tree = scripted_speedup.export("HEAD", tmp_path)
    assert (tree / "grasp_env" / "__init__.py").is_file()
    assert (tree / "agents" / "scripted.py").is_file()


def test_step_parts_classes_moves_by_their_work():
    # (seconds, pose solves, untouched, allocations)
    moves = [(1e-6, 0, True, 27), (3e-6, 0, False, 100), (2e-6, 2, False, 200),
             (4e-6, 3, False, 240), (10e-6, 12, False, 900)]  # fmt: skip
    res = step_parts.classify(moves)
    assert set(res) == set(step_parts.CLASSES)
    assert res["hand clear of a resting object"]["share"] == pytest.approx(0.2)
    assert res["no pose solve"]["allocations"] == 100
    one_to_three = res["1-3 pose solves"]
    assert one_to_three["share"] == pytest.approx(0.4)
    assert one_to_three["time_share"] == pytest.approx(6 / 20)
    assert one_to_three["median_us"] == pytest.approx(3.0)
    assert one_to_three["allocations"] == pytest.approx(220)
    assert res["4-9 pose solves"]["share"] == 0.0
    assert res[">= 10 pose solves"]["time_share"] == pytest.approx(0.5)


def test_touched_parts_time_each_part_of_touching_moves():
    parts = batched.touched_parts("FrictionlessGrasp-v0", 60, reps=1, pool=2)
    assert len(parts) == len(batched.PART_NAMES)
    # every part was timed: random actions from fig13's start touch the object (no timing
    # is compared: the numbers of a tiny run on a shared machine mean nothing)
    assert all(t > 0.0 for t in parts)


def test_step_parts_time_the_resets_the_batch_makes():
    """Each part is the time of what the batched step calls: the episodes that end start
    new ones (the first 100 random-action steps of 16 lifting episodes end some)."""
    parts = batched.step_parts("FrictionlessGraspLift-v0", 16, 100, pool=4)
    assert parts["compiled step"] > 0.0
    assert parts["resets"] > 0.0
