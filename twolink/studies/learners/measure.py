"""Running the learners' study: each run a ``twolink train`` process, resumed where it
stopped, its final agent scored, its record merged into the study's JSON at once.

:func:`run_one` trains one :class:`~.plan.Run` in its own process (``python -m twolink
train ... -o WORK/<id>``; ``--resume`` when the folder holds an interrupted run, so an
interruption loses at most one evaluation period), reads the child's peak resident
memory from the kernel (``os.wait4``), then scores the final agent with ``twolink
evaluate AGENT --links N --rule R --poses K --seed S --json`` on the scaling table's poses
and on fresh ones (:data:`~.plan.FRESH_SEED`), those again on the rigid-body model (6)
(``--plant model``: the transfer gap of a model-trained agent, the model's error seen from
a MuJoCo-trained one), the fresh ones once more run for :data:`LATE_HORIZON` seconds
(``--horizon``: a pose missed at 8 s that is settled by then was late, not lost), and
counts the parameters the agent file
holds (read with ``torch.load(weights_only=True)``). :func:`study` runs a plan, ``workers``
runs at a time on this machine (``executor="local"``) or as tasks on a Ray cluster
(``executor="ray"``), skipping every run the JSON already holds, and rewrites the JSON
(atomically) after each finished run: a finished run is never lost, and the study
continues with the same command.
"""
from __future__ import annotations

import io
import json
import os
import signal
import subprocess
import sys
import threading
import time
import zipfile
from pathlib import Path

from twolink.artifacts import merge_run, provenance, read_runs
from twolink.studies.learners.plan import FRESH_SEED, POSES, SCHEMA, TABLE_SEED, VERSION, Run

#: Where a run stops being one: executors of :func:`study`.
EXECUTORS = ("local", "ray")
#: Seconds of the fresh poses' second scoring (``fresh_late``): failed, or settled late?
LATE_HORIZON = 16.0
#: The fields a run's record keeps from its curve.json.
CURVE_FIELDS = ("steps", "successes", "n", "rate", "median_settle", "wall_s", "cpu_s")


def _state(folder: Path) -> str:
    """``new``, ``interrupted`` (a checkpoint, no final agent) or ``finished``."""
    try:
        record = json.loads((folder / "curve.json").read_text())
        if record.get("done") and (folder / record["agent"]).is_file():
            return "finished"
    except (OSError, ValueError, KeyError, TypeError):
        pass
    return "interrupted" if (folder / "checkpoint.pt").is_file() else "new"


class RunInterrupted(RuntimeError):
    """A run's process ended by a signal, or the study told to stop: no further run
    starts (the interrupted one resumes from its checkpoint when the study is rerun)."""


#: The study's live child processes, and whether it is stopping: a study that is
#: interrupted (SIGTERM, Ctrl-C, a run killed) ends every child and starts no new one.
_children: set = set()
_lock = threading.Lock()
_stopping = threading.Event()


def _stop_children() -> None:
    """Start no new child; SIGTERM every live one (a ``twolink train`` checkpoints and
    exits) and wait for it."""
    _stopping.set()
    with _lock:
        live = list(_children)
    for proc in live:
        if proc.poll() is None:
            proc.terminate()
    for proc in live:
        try:
            proc.wait(timeout=60)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def _child(cmd: list, log, prefix: str) -> tuple:
    """Run ``cmd``; its stderr lines go to ``log`` with ``prefix``; (stdout text, return
    code, peak resident memory of the child in bytes). Refused with
    :class:`RunInterrupted` once the study is stopping; the child is terminated when this
    call is interrupted."""
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    with _lock:
        if _stopping.is_set():
            raise RunInterrupted("the study is stopping")
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                text=True, env=env)
        _children.add(proc)
    try:
        out = []
        reader = threading.Thread(target=lambda: out.append(proc.stdout.read()),
                                  daemon=True)
        reader.start()
        for line in proc.stderr:
            if line.strip():
                log(f"{prefix}{line.rstrip()}")
        reader.join()
        _, status, usage = os.wait4(proc.pid, 0)
        proc.returncode = os.waitstatus_to_exitcode(status)
    except BaseException:
        if proc.poll() is None:
            proc.terminate()
            proc.wait()
        raise
    finally:
        with _lock:
            _children.discard(proc)
    return "".join(out), proc.returncode, usage.ru_maxrss * 1024


def _signalled(code: int) -> bool:
    """Whether a child's exit status says a signal ended it: killed (negative) or a
    ``twolink`` command that caught SIGINT or SIGTERM (128 + its number)."""
    return code < 0 or code in (128 + signal.SIGINT, 128 + signal.SIGTERM)


def _twolink(*args) -> list:
    return [sys.executable, "-m", "twolink.cli", *map(str, args)]


def parameter_count(path: Path) -> int:
    """The numbers the agent file holds (policy and value networks as saved): an SB3
    zip's ``policy.pth`` or a ``.marl.pt`` save, read with ``weights_only=True``."""
    import torch

    if path.suffix == ".zip":
        with zipfile.ZipFile(path) as z:
            tree = torch.load(io.BytesIO(z.read("policy.pth")), weights_only=True,
                              map_location="cpu")
    else:
        tree = torch.load(path, weights_only=True, map_location="cpu")

    def count(node) -> int:
        if isinstance(node, torch.Tensor):
            return int(node.numel())
        if isinstance(node, dict):
            return sum(count(v) for v in node.values())
        if isinstance(node, (list, tuple)):
            return sum(count(v) for v in node)
        return 0

    return count(tree)


def score_agent(agent: Path, run: Run, poses: int, seed: int, log=print,
                plant: str = "mujoco", horizon: float | None = None) -> dict:
    """``twolink evaluate AGENT --links N [--rule R] --poses K --seed S --json`` (on
    ``plant``; over ``horizon`` seconds instead of the arm's when given) in a child
    process: the score's poses seed, successes, n, rate, interval and median settle."""
    rule = ["--rule", run.rule] if run.links > 2 else []     # two links: Table I's arm
    late = [] if horizon is None else ["--horizon", f"{horizon:g}"]
    text, code, _ = _child(_twolink("evaluate", agent, "--links", run.links, *rule,
                                    "--poses", poses, "--seed", seed, "--plant", plant,
                                    *late, "--json"),
                           log, f"  {run.id} evaluate: ")
    if code != 0:
        raise RuntimeError(f"scoring {agent} failed (exit {code})")
    r = json.loads(text)
    return {k: r[k] for k in ("poses_seed", "successes", "n", "rate", "wilson_95",
                              "median_settle")}


def run_one(run: Run, work, *, poses: int = POSES, log=print) -> dict:
    """Train ``run`` into ``work/<id>`` (resuming an interrupted run, reusing a finished
    one) and score its final agent; the run's record for the study's JSON."""
    folder = Path(work) / run.id
    state = _state(folder)
    peak = None
    if state != "finished":
        cmd = _twolink("train", *run.train_args(), "-o", folder)
        if state == "interrupted":
            cmd.append("--resume")
        log(f"{run.id}: {'resuming' if state == 'interrupted' else 'training'} "
            f"({run.steps:,} steps)")
        _, code, peak = _child(cmd, log, "  ")
        if _signalled(code):
            raise RunInterrupted(f"run {run.id} was interrupted (twolink train exit "
                                 f"{code}); its folder {folder} keeps the last "
                                 f"checkpoint: rerun the study to resume it")
        if code != 0:
            raise RuntimeError(f"run {run.id} failed (twolink train exit {code}); its "
                               f"folder {folder} keeps the last checkpoint")
    record = json.loads((folder / "curve.json").read_text())
    agent = folder / record["agent"]
    return {"id": run.id, "run": run.as_dict(),
            "curve": [{k: p.get(k) for k in CURVE_FIELDS} for p in record["curve"]],
            "steps": record["steps"], "wall_s": record["wall_s"], "cpu_s": record["cpu_s"],
            "steps_per_s": record["steps_per_s"], "peak_rss_bytes": peak,
            "parameters": parameter_count(agent),
            "hyperparameters": record.get("hyperparameters"),
            "versions": record.get("versions"),
            "table": score_agent(agent, run, poses, TABLE_SEED, log),
            "fresh": score_agent(agent, run, poses, FRESH_SEED, log),
            "fresh_model": score_agent(agent, run, poses, FRESH_SEED, log, plant="model"),
            "fresh_late": score_agent(agent, run, poses, FRESH_SEED, log,
                                      horizon=LATE_HORIZON)}




def study(runs, path, work, *, poses: int = POSES, workers: int = 1, executor="local",
          address=None, log=print, after=None) -> dict:
    """Run the ``runs`` the study's JSON at ``path`` does not hold yet, ``workers`` at a
    time, merging each record into it as it finishes (:func:`twolink.artifacts.merge_run`:
    other processes' runs in the same file are kept; then ``after(data)``, e.g. the table
    and figure beside it); the study's data."""
    if executor not in EXECUTORS:
        raise ValueError(f"unknown executor {executor!r}; choose one of {', '.join(EXECUTORS)}")
    data = read_runs(path, SCHEMA, VERSION)
    done = {r["id"] for r in data["runs"]}
    todo = [r for r in runs if r.id not in done]
    log(f"learners study: {len(runs) - len(todo)} of {len(runs)} runs in {path} already, "
        f"{len(todo)} to run ({workers} at a time, {executor})")
    started = time.perf_counter()

    def keep(record) -> None:
        nonlocal data                    # another process may have added runs meanwhile
        data = merge_run(path, SCHEMA, VERSION, record, provenance=provenance(), poses=poses,
                         table_seed=TABLE_SEED, fresh_seed=FRESH_SEED)
        if after is not None:
            after(data)
        f = record["fresh"]
        log(f"{record['id']}: {f['successes']}/{f['n']} fresh poses, {record['steps']:,} "
            f"steps in {record['wall_s']:.0f} s ({len(data['runs'])} runs in {path}, "
            f"{time.perf_counter() - started:.0f} s)")

    failed = []

    def outcome(run, get) -> None:
        try:
            keep(get())
        except RunInterrupted:
            raise
        except (RuntimeError, OSError, ValueError) as exc:
            failed.append(run.id)
            log(f"{run.id}: {exc}")

    _stopping.clear()
    if executor == "ray":
        from twolink.sim.cells import ray_session

        with ray_session(address, workers) as ray:
            remote = ray.remote(num_cpus=1)(run_one)
            pending = {remote.remote(r, str(work), poses=poses): r for r in todo}
            while pending:
                (ready,), _ = ray.wait(list(pending), num_returns=1)
                outcome(pending.pop(ready), lambda: ray.get(ready))
    elif workers <= 1:
        for r in todo:
            outcome(r, lambda: run_one(r, work, poses=poses, log=log))
    else:
        from concurrent.futures import ThreadPoolExecutor, as_completed

        pool = ThreadPoolExecutor(workers)
        try:
            futures = {pool.submit(run_one, r, work, poses=poses, log=log): r for r in todo}
            for f in as_completed(futures):
                outcome(futures[f], f.result)
        except BaseException:                # interrupted: no new run; end the live ones
            pool.shutdown(wait=False, cancel_futures=True)
            _stop_children()
            raise
        finally:
            pool.shutdown(wait=True)
    if failed:
        raise RuntimeError(f"{len(failed)} run(s) failed ({', '.join(failed)}); the "
                           f"{len(data['runs'])} finished are in {path}; rerun to retry")
    return data
