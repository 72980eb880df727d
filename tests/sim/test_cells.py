"""Sweeps: batched path bit-for-bit against the one-rollout loop and the evaluation call,
Ray == local, resume, locking, torn lines, workers that die with their run."""
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
from twolink.sim.cell_store import CellFile, CellFileLocked
from twolink.sim.cells import Cell, load_results, run_cells, evaluate_cells, states_of
from twolink.sim.challenges import LEVELS, Challenge
from twolink.sim.evaluation import evaluate
from twolink.sim.metrics import discounted_return, settle_time, success
from twolink.sim.perturbations import perturbed
from twolink.sim.plants import MujocoPlant
from twolink.sim.rollout import rollout

pytestmark = pytest.mark.robustness

SHORT = 1.5     # seconds: enough for the bit-for-bit and executor checks


_NOISE = Challenge("noise", angle_noise_deg=2.0, speed_noise=0.04)


def _cells(policy="centralized", duration=SHORT):
    def cell(ch, **kw):
        return Cell(policy, ch, states="quick", duration=duration, **kw)
    return [cell("none"), cell(Challenge("m2", offsets={"m2": 0.3})),
            cell(Challenge("joint", spread=0.3), plants=2, seed=5),
            cell(_NOISE, seed=3), cell(Challenge("delay", action_delay=1)),
            cell(Challenge("torque", torque_limit=-0.3)),
            cell(Challenge("mixed", spread=0.2, offsets={"b1": -0.4}, action_delay=1,
                           angle_noise_deg=1.0, speed_noise=0.03), plants=2, seed=7)]


def test_batched_path_equals_one_rollout_loop_bit_for_bit():
    cells = _cells("decentralized_full")
    batched = run_cells(cells, nthread=2)
    for c, rec in zip(cells, batched):
        assert rec == reference_cell(c), c


@pytest.mark.parametrize("level", ["medium", "hard"])
def test_a_cell_is_the_evaluation_call_of_its_challenge_and_seed(level):
    """One seeding rule: the same challenge and seed give the same plants, the same
    noise and faults, so the same outcomes run by run, through either path."""
    ch = LEVELS[level]
    cell = Cell("centralized_full", ch, plants=3, seed=11, states="quick", duration=2.0)
    rec = run_cells([cell, Cell("centralized_full", _NOISE, states="quick", duration=2.0)],
                    nthread=2)[0]
    ev = evaluate("centralized_full", x0=states_of("quick"), count=3, seed=11,
                  challenge=ch, horizon=2.0, nthread=1)
    assert list(ev.params) == cell.params() == ch.plants(3, 11)
    assert rec["successes"] == ev.success.ravel().tolist()
    assert rec["returns"] == ev.returns.ravel().tolist()
    assert rec["settle_times"] == [v if np.isfinite(v) else None for v in ev.settle.ravel()]
    other = run_cells([Cell("centralized_full", ch, plants=3, seed=12, states="quick",
                            duration=2.0)])[0]
    assert other["returns"] != rec["returns"]


def test_cells_are_keyed_by_their_whole_challenge():
    a = Cell("centralized", Challenge("x", offsets={"m1": 0.1, "b2": -0.2}))
    b = Cell("centralized", Challenge("x", offsets=(("b2", -0.2), ("m1", 0.1))))
    assert a == b and a.key == b.key and hash(a) == hash(b)
    assert a.challenge.offsets == (("m1", 0.1), ("b2", -0.2))
    assert Cell.from_dict(json.loads(a.key)) == a
    assert Cell("centralized", "none").key == Cell("centralized").key
    assert Cell("centralized", "medium").key != Cell("centralized", "medium", seed=1).key
    assert a.params() == [TABLE_I.scaled(m1=1.1, b2=0.8)]


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
    nominal = run_cells([Cell("centralized", states="quick", duration=SHORT)])[0]
    assert nominal["successes"] == success(tr).tolist()
    st = settle_time(tr)
    assert nominal["settle_times"] == [float(v) if np.isfinite(v) else None for v in st]
    zero = [Cell("centralized", Challenge(n, **kw), states="quick", duration=SHORT)
            for n, kw in (("m1", dict(offsets={"m1": 0.0})), ("b2", dict(offsets={"b2": 0.0})),
                          ("noise", dict(angle_noise_deg=0.0)), ("delay", dict(action_delay=0)),
                          ("torque", dict(torque_limit=0.0)), ("joint", dict(spread=0.0)))]
    for rec in run_cells(zero):
        for k in ("successes", "settle_times", "returns", "mean_return"):
            assert rec[k] == nominal[k], rec["cell"]
    assert nominal["returns"] == discounted_return(tr).tolist()
    assert perturbed(TABLE_I, m1=0.0) == TABLE_I


def test_perturbations_change_the_outcome():
    recs = run_cells([Cell("centralized_full", ch, states="quick") for ch in (
        Challenge("none"), Challenge("torque", torque_limit=-0.85),
        Challenge("delay", action_delay=2),
        Challenge("noise", angle_noise_deg=5.0, speed_noise=0.1))])
    for rec in recs[1:]:
        assert rec["settle_times"] != recs[0]["settle_times"], rec["cell"]
        assert rec["mean_return"] < recs[0]["mean_return"], rec["cell"]


@pytest.mark.parametrize("bad, match", [
    (dict(challenge="wind"), "unknown challenge 'wind'; choose one of none"),
    (dict(plants=0), "plants must be a whole number of plants from 1 to 10000, got 0"),
    (dict(seed=-1), "seed must be a whole number from 0 to"),
    (dict(states="tiny"), "unknown state set 'tiny'; choose one of full, quick"),
    (dict(duration=0.0), "duration must be a finite positive number"),
    (dict(challenge=Challenge("d", action_delay=30), duration=1.0),
     "a delay of 30 samples is not shorter than the horizon of 20 samples")])
def test_bad_cells_are_refused(bad, match):
    with pytest.raises(ValueError, match=__import__("re").escape(match)):
        Cell("centralized", **bad)
    with pytest.raises(ValueError, match="policy must be a name"):
        Cell("")


def test_local_processes_equal_serial(tmp_path):
    cells = _cells(duration=0.5)
    serial = evaluate_cells(cells, tmp_path / "a.jsonl", executor="serial")
    local = evaluate_cells(cells, tmp_path / "b.jsonl", executor="local", workers=2)
    assert serial == local and len(serial) == len(cells)


@pytest.mark.slow
def test_ray_equals_local(tmp_path):
    ray = pytest.importorskip("ray")
    cells = _cells(duration=0.5)
    local = evaluate_cells(cells, tmp_path / "local.jsonl", executor="serial")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        remote = evaluate_cells(cells, tmp_path / "ray.jsonl", executor="ray")
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
        evaluate_cells(cells, path, executor="serial", on_task=stop_after_first)
    first = load_results(path)
    assert 0 < len(first) < len(cells)         # a valid file holding the finished task
    done_keys = set(first)
    redone = []
    results = evaluate_cells(cells, path, executor="serial",
                        on_task=lambda recs: redone.extend(r["key"] for r in recs))
    assert not done_keys & set(redone)
    assert set(redone) | done_keys == {c.key for c in cells}
    assert results == evaluate_cells(cells, None, executor="serial")
    lines = path.read_text().splitlines()
    assert json.loads(lines[0])["format"] == "twolink-sweep" and len(lines) == len(cells) + 1
    assert [p.name for p in tmp_path.iterdir()] == ["sweep.jsonl"]   # no temporary left


def test_changed_policy_invalidates_stored_cells(tmp_path):
    path = tmp_path / "sweep.jsonl"
    cells = _cells(duration=0.5)[:2]
    evaluate_cells(cells, path, executor="serial")
    redone = []
    evaluate_cells(cells, path, executor="serial", digests={"centralized": "other"},
              on_task=lambda recs: redone.extend(recs))
    assert len(redone) == len(cells)


def test_a_bad_line_in_the_middle_is_refused(tmp_path):
    path = tmp_path / "sweep.jsonl"
    path.write_text('{"format": "twolink-sweep", "format_version": 4}\n{"key": 1\n{}\n')
    with pytest.raises(ValueError, match="line 2"):
        evaluate_cells(_cells()[:1], path, executor="serial")
    (tmp_path / "x.jsonl").write_text("hello\n")
    with pytest.raises(ValueError, match="not a twolink sweep"):
        load_results(tmp_path / "x.jsonl")
    with pytest.raises(ValueError, match="executor"):
        evaluate_cells(_cells()[:1], None, executor="mpi")


@pytest.mark.parametrize("tail", ['{"key": "torn", "cel', '{"key": "torn"}\n', "\x00\x00"])
def test_a_torn_last_line_is_dropped_reported_and_its_cell_rerun(tmp_path, capsys, tail):
    path = tmp_path / "sweep.jsonl"
    cells = _cells(duration=0.5)[:3]
    whole = evaluate_cells(cells, path, executor="serial")
    lines = path.read_text().splitlines(keepends=True)
    path.write_text("".join(lines[:-1]) + tail)          # the last record torn mid-write
    redone = []
    again = evaluate_cells(cells, path, executor="serial", on_task=redone.extend)
    assert again == whole
    assert [r["key"] for r in redone] == [cells[-1].key]
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "torn last line (line 4" in err[0] and str(path) in err[0]
    assert path.read_text() == "".join(lines)            # cut back, then appended to
    assert load_results(path) == whole


def test_a_file_of_the_older_format_starts_over(tmp_path, capsys):
    """Version 3 files hold cells of perturbation families drawn by their own seeds: not
    reused."""
    path = tmp_path / "sweep.jsonl"
    cells = _cells(duration=0.5)[3:4]
    evaluate_cells(cells, path, executor="serial")
    lines = path.read_text().splitlines(keepends=True)
    path.write_text(lines[0].replace('"format_version": 4', '"format_version": 3') + lines[1])
    with pytest.raises(ValueError, match="older format version 3"):
        load_results(path)
    redone = []
    evaluate_cells(cells, path, executor="serial", on_task=redone.extend)
    assert len(redone) == 1 and path.read_text() == "".join(lines)
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "older format version 3; every cell runs again" in err[0]
    path.write_text(lines[0].replace('"format_version": 4', '"format_version": 5'))
    with pytest.raises(ValueError, match="unsupported sweep results version 5"):
        evaluate_cells(cells, path, executor="serial")


def test_records_of_other_keys_are_kept_and_ignored(tmp_path):
    """A record whose key no cell has (another vocabulary's cell) is never reused."""
    path = tmp_path / "sweep.jsonl"
    cells = _cells(duration=0.5)[:1]
    foreign = {"key": "old", "cell": {"policy": "centralized", "family": "nominal"},
               "policy_digest": "x", "successes": [True]}
    path.write_text('{"format": "twolink-sweep", "format_version": 4}\n'
                    + json.dumps(foreign) + "\n" + json.dumps({"key": "k", "cell": {}}) + "\n")
    redone = []
    got = evaluate_cells(cells, path, executor="serial", on_task=redone.extend)
    assert list(got) == [cells[0].key] and len(redone) == 1
    assert set(load_results(path)) == {"old", "k", cells[0].key}


def test_a_whole_last_record_missing_its_newline_is_kept(tmp_path):
    path = tmp_path / "sweep.jsonl"
    cells = _cells(duration=0.5)[:2]
    whole = evaluate_cells(cells, path, executor="serial")
    path.write_text(path.read_text().rstrip("\n"))
    redone = []
    assert evaluate_cells(cells, path, executor="serial", on_task=redone.extend) == whole
    assert not redone and path.read_text().endswith("}\n")


def _not_measured(*args, **kwargs):
    raise AssertionError("a cell was measured")


def test_a_second_run_on_a_locked_file_refuses_at_once(tmp_path, monkeypatch):
    path = tmp_path / "sweep.jsonl"
    cells = _cells(duration=0.5)[:2]
    with CellFile(path), monkeypatch.context() as m:
        m.setattr("twolink.sim.cells.run_cells", _not_measured)
        with pytest.raises(CellFileLocked, match=f"{path}.*in use by another run \\(pid {os.getpid()}\\)"):
            evaluate_cells(cells, path, executor="serial")
        assert load_results(path) == {}                    # nothing computed, nothing written
    evaluate_cells(cells, path, executor="serial")            # released on leaving the block
    assert len(load_results(path)) == 2


def test_results_come_back_in_cell_order_whatever_the_completion_order(tmp_path):
    cells = _cells(duration=0.5)
    done = evaluate_cells(cells[::-1], tmp_path / "s.jsonl", executor="serial")
    again = evaluate_cells(cells, tmp_path / "s.jsonl", executor="serial")
    assert list(again) == [c.key for c in cells]
    assert list(done) == [c.key for c in cells[::-1]]


def test_the_lock_names_the_process_that_holds_it(tmp_path):
    path = tmp_path / "sweep.jsonl"
    holder = subprocess.Popen(
        [sys.executable, "-c", "import sys, time\nfrom twolink.sim.cell_store import CellFile\n"
         "f = CellFile(sys.argv[1]); f.open(); print('held', flush=True); time.sleep(60)",
         str(path)], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        with pytest.raises(CellFileLocked, match=f"in use by another run \\(pid {holder.pid}\\)"):
            CellFile(path).open()
    finally:
        holder.kill()
        holder.wait()
    with CellFile(path) as store:                       # free once its holder is gone
        assert store.records == {}


_KILL_SCRIPT = """
from twolink.sim.cells import Cell, evaluate_cells
from twolink.sim.challenges import Challenge
cells = [Cell("centralized", Challenge("m1", offsets={"m1": s / 100})) for s in range(-40, 41)]
evaluate_cells(cells, None, executor="local", workers=2)
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
