"""Sweeps: batched path bit-for-bit against the one-rollout loop, Ray == local, resume,
locking, torn lines, workers that die with their run."""
import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from reference_sweeps import reference_cell

from twolink.arm.parameters import TABLE_I
from twolink.policy.fuzzy_policy import load_policy
from twolink.sim.cell_store import SweepFile, SweepLocked
from twolink.sim.cells import Cell, load_results, run_cells, run_sweep, states_of
from twolink.sim.metrics import discounted_return, settle_time, success
from twolink.sim.perturbations import perturbed
from twolink.sim.plants import MujocoPlant
from twolink.sim.rollout import rollout

pytestmark = pytest.mark.robustness

SHORT = 1.5     # seconds: enough for the bit-for-bit and executor checks


def _cells(policy="centralized", duration=SHORT):
    return [Cell(policy, "nominal", states="quick", duration=duration),
            Cell(policy, "parameter", 0.3, "m2", states="quick", duration=duration),
            Cell(policy, "joint", 0.3, draws=2, seed=5, states="quick", duration=duration),
            Cell(policy, "noise", 2.0, seed=3, states="quick", duration=duration),
            Cell(policy, "delay", 1.0, states="quick", duration=duration),
            Cell(policy, "torque_limit", -0.3, states="quick", duration=duration)]


def test_batched_path_equals_one_rollout_loop_bit_for_bit():
    cells = _cells("decentralized_full")
    batched = run_cells(cells, nthread=2)
    for c, rec in zip(cells, batched):
        assert rec == reference_cell(c), c


def test_a_cell_does_not_depend_on_its_batch_mates():
    cells = _cells()
    together = run_cells(cells, nthread=2)
    alone = [run_cells([c], nthread=1)[0] for c in cells]
    assert together == alone


def test_zero_perturbation_reproduces_the_nominal_rollout_exactly():
    policy = load_policy("centralized")
    x0 = states_of("quick")
    plant = MujocoPlant(TABLE_I, nthread=1)
    tr = rollout(policy, plant, x0, duration=SHORT)
    plant.close()
    nominal = run_cells([Cell("centralized", "nominal", states="quick", duration=SHORT)])[0]
    assert nominal["successes"] == success(tr).tolist()
    st = settle_time(tr)
    assert nominal["settle_times"] == [float(v) if np.isfinite(v) else None for v in st]
    zero = [Cell("centralized", "parameter", 0.0, n, states="quick", duration=SHORT)
            for n in ("m1", "b2")] + \
        [Cell("centralized", f, 0.0, states="quick", duration=SHORT)
         for f in ("noise", "delay", "torque_limit", "joint")]
    for rec in run_cells(zero):
        for k in ("successes", "settle_times", "returns", "mean_return"):
            assert rec[k] == nominal[k], rec["cell"]
    assert nominal["returns"] == discounted_return(tr).tolist()
    assert perturbed(TABLE_I, m1=0.0) == TABLE_I


def test_perturbations_change_the_outcome():
    recs = run_cells([Cell("centralized_full", "nominal", states="quick"),
                      Cell("centralized_full", "torque_limit", -0.9, states="quick"),
                      Cell("centralized_full", "delay", 2.0, states="quick"),
                      Cell("centralized_full", "noise", 5.0, states="quick")])
    for rec in recs[1:]:
        assert rec["settle_times"] != recs[0]["settle_times"], rec["cell"]
        assert rec["mean_return"] < recs[0]["mean_return"], rec["cell"]


@pytest.mark.parametrize("bad, match", [
    (dict(family="wind"), "family"), (dict(family="parameter", name="zz"), "parameter"),
    (dict(family="parameter", name="m1", size=1.5), "relative"),
    (dict(family="delay", size=0.5), "delay"), (dict(family="noise", size=-1.0), "noise"),
    (dict(family="nominal", states="tiny"), "state set")])
def test_bad_cells_are_refused(bad, match):
    with pytest.raises(ValueError, match=match):
        Cell("centralized", **bad)


def test_local_processes_equal_serial(tmp_path):
    cells = _cells(duration=0.5)
    serial = run_sweep(cells, tmp_path / "a.jsonl", executor="serial")
    local = run_sweep(cells, tmp_path / "b.jsonl", executor="local", workers=2)
    assert serial == local and len(serial) == len(cells)


@pytest.mark.slow
def test_ray_equals_local(tmp_path):
    ray = pytest.importorskip("ray")
    cells = _cells(duration=0.5)
    local = run_sweep(cells, tmp_path / "local.jsonl", executor="serial")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        remote = run_sweep(cells, tmp_path / "ray.jsonl", executor="ray")
    finally:
        ray.shutdown()
    assert remote == local
    assert load_results(tmp_path / "ray.jsonl") == load_results(tmp_path / "local.jsonl")


def test_interrupted_sweep_resumes_without_redoing_cells(tmp_path):
    path = tmp_path / "sweep.jsonl"
    cells = _cells(duration=0.5) + _cells("decentralized", duration=0.5)

    class Stop(Exception):
        pass

    def stop_after_first(records):
        raise Stop

    with pytest.raises(Stop):
        run_sweep(cells, path, executor="serial", on_task=stop_after_first)
    first = load_results(path)
    assert 0 < len(first) < len(cells)         # a valid file holding the finished task
    done_keys = set(first)
    redone = []
    results = run_sweep(cells, path, executor="serial",
                        on_task=lambda recs: redone.extend(r["key"] for r in recs))
    assert not done_keys & set(redone)
    assert set(redone) | done_keys == {c.key for c in cells}
    assert results == run_sweep(cells, None, executor="serial")
    lines = path.read_text().splitlines()
    assert json.loads(lines[0])["format"] == "twolink-sweep" and len(lines) == len(cells) + 1
    assert [p.name for p in tmp_path.iterdir()] == ["sweep.jsonl"]   # no temporary left


def test_changed_policy_invalidates_stored_cells(tmp_path):
    path = tmp_path / "sweep.jsonl"
    cells = _cells(duration=0.5)[:2]
    run_sweep(cells, path, executor="serial")
    redone = []
    run_sweep(cells, path, executor="serial", digests={"centralized": "other"},
              on_task=lambda recs: redone.extend(recs))
    assert len(redone) == len(cells)


def test_a_bad_line_in_the_middle_is_refused(tmp_path):
    path = tmp_path / "sweep.jsonl"
    path.write_text('{"format": "twolink-sweep", "format_version": 3}\n{"key": 1\n{}\n')
    with pytest.raises(ValueError, match="line 2"):
        run_sweep(_cells()[:1], path, executor="serial")
    (tmp_path / "x.jsonl").write_text("hello\n")
    with pytest.raises(ValueError, match="not a twolink sweep"):
        load_results(tmp_path / "x.jsonl")
    with pytest.raises(ValueError, match="executor"):
        run_sweep(_cells()[:1], None, executor="mpi")


@pytest.mark.parametrize("tail", ['{"key": "torn", "cel', '{"key": "torn"}\n', "\x00\x00"])
def test_a_torn_last_line_is_dropped_reported_and_its_cell_rerun(tmp_path, capsys, tail):
    path = tmp_path / "sweep.jsonl"
    cells = _cells(duration=0.5)[:3]
    whole = run_sweep(cells, path, executor="serial")
    lines = path.read_text().splitlines(keepends=True)
    path.write_text("".join(lines[:-1]) + tail)          # the last record torn mid-write
    redone = []
    again = run_sweep(cells, path, executor="serial", on_task=redone.extend)
    assert again == whole
    assert [r["key"] for r in redone] == [cells[-1].key]
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "torn last line (line 4" in err[0] and str(path) in err[0]
    assert path.read_text() == "".join(lines)            # cut back, then appended to
    assert load_results(path) == whole


def test_a_file_of_the_older_format_starts_over(tmp_path, capsys):
    """Version 2 files hold no per-row returns: not reused."""
    path = tmp_path / "sweep.jsonl"
    cells = _cells(duration=0.5)[3:4]
    run_sweep(cells, path, executor="serial")
    lines = path.read_text().splitlines(keepends=True)
    path.write_text(lines[0].replace('"format_version": 3', '"format_version": 2') + lines[1])
    with pytest.raises(ValueError, match="older format version 2"):
        load_results(path)
    redone = []
    run_sweep(cells, path, executor="serial", on_task=redone.extend)
    assert len(redone) == 1 and path.read_text() == "".join(lines)
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "older format version 2; every cell runs again" in err[0]
    path.write_text(lines[0].replace('"format_version": 3', '"format_version": 4'))
    with pytest.raises(ValueError, match="unsupported sweep results version 4"):
        run_sweep(cells, path, executor="serial")


def test_a_whole_last_record_missing_its_newline_is_kept(tmp_path):
    path = tmp_path / "sweep.jsonl"
    cells = _cells(duration=0.5)[:2]
    whole = run_sweep(cells, path, executor="serial")
    path.write_text(path.read_text().rstrip("\n"))
    redone = []
    assert run_sweep(cells, path, executor="serial", on_task=redone.extend) == whole
    assert not redone and path.read_text().endswith("}\n")


def test_a_second_run_on_a_locked_file_refuses_at_once(tmp_path):
    path = tmp_path / "sweep.jsonl"
    cells = _cells(duration=0.5)[:2]
    with SweepFile(path):
        t0 = time.perf_counter()
        with pytest.raises(SweepLocked, match=f"{path}.*in use by another run \\(pid {os.getpid()}\\)"):
            run_sweep(cells, path, executor="serial")
        assert time.perf_counter() - t0 < 1.0
        assert load_results(path) == {}                    # nothing computed, nothing written
    run_sweep(cells, path, executor="serial")            # released on leaving the block
    assert len(load_results(path)) == 2


def test_results_come_back_in_cell_order_whatever_the_completion_order(tmp_path):
    cells = _cells(duration=0.5)
    done = run_sweep(cells[::-1], tmp_path / "s.jsonl", executor="serial")
    again = run_sweep(cells, tmp_path / "s.jsonl", executor="serial")
    assert list(again) == [c.key for c in cells]
    assert list(done) == [c.key for c in cells[::-1]]


def test_the_lock_names_the_process_that_holds_it(tmp_path):
    path = tmp_path / "sweep.jsonl"
    holder = subprocess.Popen(
        [sys.executable, "-c", "import sys, time\nfrom twolink.sim.cell_store import SweepFile\n"
         "f = SweepFile(sys.argv[1]); f.open(); print('held', flush=True); time.sleep(60)",
         str(path)], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        with pytest.raises(SweepLocked, match=f"in use by another run \\(pid {holder.pid}\\)"):
            SweepFile(path).open()
    finally:
        holder.kill()
        holder.wait()
    with SweepFile(path) as store:                       # free once its holder is gone
        assert store.records == {}


_KILL_SCRIPT = """
from twolink.sim.cells import Cell, run_sweep
cells = [Cell("centralized", "parameter", s / 100, "m1") for s in range(-40, 41)]
run_sweep(cells, None, executor="local", workers=2)
"""


def _children(pid):
    out = []
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                with open(f"/proc/{d}/stat") as f:
                    fields = f.read().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == pid and fields[0] != "Z":
                out.append(int(d))
    return out


def _alive(pid):
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_workers_die_with_a_killed_run():
    run = subprocess.Popen([sys.executable, "-c", _KILL_SCRIPT])
    try:
        deadline = time.monotonic() + 60
        while len(_children(run.pid)) < 3 and time.monotonic() < deadline:   # 2 + tracker
            time.sleep(0.2)
        workers = _children(run.pid)
        assert len(workers) >= 2, "the sweep started no workers"
        time.sleep(2.0)                                   # workers initialised, computing
    finally:
        run.send_signal(signal.SIGKILL)
        run.wait()
    deadline = time.monotonic() + 15
    while any(_alive(w) for w in workers) and time.monotonic() < deadline:
        time.sleep(0.2)
    survivors = [w for w in workers if _alive(w)]
    for w in survivors:                                   # do not leave them behind
        os.kill(w, signal.SIGKILL)
    assert not survivors
