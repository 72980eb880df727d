"""Robustness cells: (policy, challenge) pairs, run in batches, saved resumably.

A :class:`Cell` is one policy under one :class:`twolink.sim.challenges.Challenge` of the
MuJoCo plant: ``plants`` plants drawn by the challenge from ``seed``, each run from every
state of an evaluation set (:data:`STATE_SETS`) for ``duration`` seconds, the policy as
it is (no run-time compensation). Whatever the challenge does (offsets of single Table I
parameters, a random joint spread, torque limits, actuation and observation delays,
noise, dropped and stuck readings) a cell does; what a report calls a perturbation
family (e.g. the mismatch report's, :mod:`twolink.studies.mismatch.plan`) is a way of
building the challenge.

Randomness is the challenge's one seeding rule (:mod:`twolink.sim.challenges`): plant i
from ``SeedSequence([seed, PLANT_STREAM], spawn_key=(i,))``, the run of plant p from
state s its noise and faults from ``spawn_key=(p, s)``. So a cell's rows are exactly the
runs of ``twolink.sim.evaluation.evaluate(policy, x0=states_of(states), count=plants,
seed=seed, challenge=challenge, horizon=duration)``, run by run.

Cells of one policy are concatenated into a single batch (many states x many plants),
the policy is evaluated for the whole batch at once and MuJoCo advances it with
``mujoco.rollout`` on a thread pool (:class:`twolink.sim.plants.MujocoPlant`). A result never
depends on which cells share its batch: delays, noise and faults are the per-row
perturbations of :mod:`twolink.sim.perturbations`, each row drawing from its own
generators (held bit-for-bit by tests against a one-rollout-at-a-time reference loop).

Tasks run in this process, on local worker processes (which die with the run), or on a
Ray cluster; every finished task is appended to a locked JSON-lines results file
(:mod:`twolink.sim.cell_store`), so an interrupted sweep resumes without redoing finished
cells and two runs never share one file. A stored record is reused only for a cell of
the same :attr:`Cell.key` (the JSON of :meth:`Cell.as_dict`: the policy, every field of
the challenge, the plant count, seed, state set and duration) and the same policy file;
records of other keys in the file are ignored, and their cells run again.
"""
from __future__ import annotations

import concurrent.futures as cf
import contextlib
import hashlib
import json
import math
import multiprocessing
import os
import socket
import sys
import threading
from dataclasses import dataclass
from typing import Callable, Iterable, Optional, Sequence

import numpy as np

from twolink.arm.parameters import HORIZON, ArmParameters
from twolink.policy.fuzzy_policy import load_policy
from twolink.sim.cell_store import CellFile, load_results  # noqa: F401  (re-exported)
from twolink.sim.challenges import (
    LEVELS,
    MAX_PLANTS,
    PLANT_COUNT,
    Challenge,
    check_horizon,
)
from twolink.sim.challenges import (
    challenge as challenge_named,
)
from twolink.sim.metrics import discounted_return, evaluation_set, settle_time, success
from twolink.sim.perturbations import (  # noqa: F401  (SPEED_PER_DEG re-exported)
    SPEED_PER_DEG,
    ActuationDelay,
    Sensors,
)
from twolink.sim.plants import MujocoPlant
from twolink.sim.progress import progress_bar
from twolink.sim.rollout import rollout, steps_for
from twolink.validate import real, whole

EXECUTORS = ("serial", "local", "ray")
#: Evaluation sets a cell can use: all 65 states of docs/conventions.md, or every 13th (the paper's x0
#: and 4 grid states) for quick runs.
STATE_SETS = ("full", "quick")
#: Rows per batch a task aims for (more rows, fewer Python steps per MuJoCo step).
_ROWS_PER_TASK = 1100


def policy_digest(policy) -> str:
    """A content hash of a policy's Q-tables: a stored cell is reused only for the same one."""
    h = hashlib.sha256(policy.kind.encode())
    for a in policy.agents:
        h.update(a.name.encode())
        h.update(np.ascontiguousarray(a.q).tobytes())
    return h.hexdigest()[:16]


def states_of(name: str) -> np.ndarray:
    """The initial states of an evaluation set named in :data:`STATE_SETS`."""
    if name == "full":
        return evaluation_set()
    if name == "quick":
        return evaluation_set()[::13]
    raise ValueError(f"unknown state set {name!r}; choose one of {', '.join(STATE_SETS)}")


@dataclass(frozen=True)
class Cell:
    """One policy under one challenge (a :class:`Challenge` or a level name of
    :data:`twolink.sim.challenges.LEVELS`): ``plants`` plants drawn from ``seed``, each
    from every state of ``states``, for ``duration`` seconds."""

    policy: str
    challenge: Challenge = LEVELS["none"]
    plants: int = 1
    seed: int = 0
    states: str = "full"
    duration: float = HORIZON

    def __post_init__(self):
        if not isinstance(self.policy, str) or not self.policy:
            raise ValueError(f"a cell's policy must be a name, got {self.policy!r}")
        object.__setattr__(self, "challenge", challenge_named(self.challenge))
        object.__setattr__(self, "plants", whole(self.plants, "plants", 1, MAX_PLANTS,
                                                 message=PLANT_COUNT))
        object.__setattr__(self, "seed", whole(self.seed, "seed", 0, 2**63 - 1))
        if self.states not in STATE_SETS:
            raise ValueError(f"unknown state set {self.states!r}; choose one of "
                             f"{', '.join(STATE_SETS)}")
        duration = real(self.duration, "duration", 0.0, open_low=True)
        object.__setattr__(self, "duration", duration)
        check_horizon(self.challenge, steps_for(duration), duration)

    def as_dict(self) -> dict:
        """The cell, JSON-ready (the challenge as :meth:`Challenge.as_dict`)."""
        return {"policy": self.policy, "challenge": self.challenge.as_dict(),
                "plants": self.plants, "seed": self.seed, "states": self.states,
                "duration": self.duration}

    @classmethod
    def from_dict(cls, d: dict) -> "Cell":
        """The cell :meth:`as_dict` gave ``d``."""
        d = dict(d)
        return cls(**{**d, "challenge": Challenge(**d["challenge"])})

    @property
    def key(self) -> str:
        return json.dumps(self.as_dict(), sort_keys=True)

    def params(self) -> list[ArmParameters]:
        """The cell's plants: :meth:`Challenge.plants` of ``plants`` from ``seed``."""
        return self.challenge.plants(self.plants, self.seed)

    def rows(self) -> tuple[list[ArmParameters], np.ndarray, list[tuple[int, int]]]:
        """Per-row plant parameters, initial states and (plant, state) keys (plants outer,
        states inner)."""
        x0 = states_of(self.states)
        plist = self.params()
        keys = [(p, s) for p in range(len(plist)) for s in range(len(x0))]
        return [p for p in plist for _ in x0], np.tile(x0, (len(plist), 1)), keys


# --------------------------------------------------------------------------- running
def _per_row(cells: Sequence[Cell], counts: Sequence[int], field: str) -> np.ndarray:
    return np.concatenate([np.full(n, getattr(c.challenge, field)) for c, n in zip(cells, counts)])


def run_cells(cells: Sequence[Cell], *, nthread: int = 1, policies: Optional[dict] = None
              ) -> list[dict]:
    """Run cells of one policy as one batch on MuJoCo; one result record per cell."""
    cells = list(cells)
    if not cells:
        return []
    names = {c.policy for c in cells}
    durations = {c.duration for c in cells}
    if len(names) != 1 or len(durations) != 1:
        raise ValueError("a batch holds cells of one policy and one duration")
    name = names.pop()
    duration = durations.pop()
    policy = (policies or {}).get(name) or load_policy(name)
    plist, x0, counts, rngs, fault_rngs = [], [], [], [], []
    for c in cells:
        p, x, keys = c.rows()
        noise, faults = c.challenge.generators(c.seed, keys)
        plist += p
        x0.append(x)
        counts.append(len(x))
        rngs += noise
        fault_rngs += faults
    x0 = np.concatenate(x0)
    row = {f: _per_row(cells, counts, f) for f in
           ("angle_std", "speed_noise", "dropout", "stuck", "observation_delay", "action_delay")}
    sensors = Sensors(row["angle_std"], row["speed_noise"], row["dropout"], row["stuck"],
                      row["observation_delay"], rngs=rngs, fault_rngs=fault_rngs,
                      block=steps_for(duration))
    with MujocoPlant(plist, nthread=nthread) as plant:
        traj = rollout(ActuationDelay(policy, row["action_delay"]), plant, x0,
                       duration=duration, observe=lambda k, x: sensors(x))
    st, ok, ret = settle_time(traj), success(traj), discounted_return(traj)
    out, start = [], 0
    for c, n in zip(cells, counts):
        rows = slice(start, start + n)
        start += n
        out.append(cell_record(c, st[rows], ok[rows], ret[rows], policy_digest(policy)))
    return out


def cell_record(c: Cell, st, ok, ret, digest: str) -> dict:
    """A cell's result: per-row settle times, successes, discounted returns, and their
    summaries (JSON-ready)."""
    return {"key": c.key, "cell": c.as_dict(), "rows": int(len(ok)),
            "policy_digest": digest,
            "success_rate": float(np.mean(ok)),
            "settle_times": [float(v) if math.isfinite(v) else None for v in st],
            "successes": [bool(v) for v in ok],
            "returns": [float(v) for v in ret],
            "mean_return": math.fsum(float(v) for v in ret) / len(ret)}


# --------------------------------------------------------------------------- executors
def _tasks(cells: Sequence[Cell]) -> list[list[Cell]]:
    """Cells grouped by policy and duration, chunked to about _ROWS_PER_TASK rows."""
    groups: dict = {}
    for c in cells:
        groups.setdefault((c.policy, c.duration), []).append(c)
    tasks = []
    for group in groups.values():
        chunk, rows = [], 0
        for c in group:
            n = len(states_of(c.states)) * c.plants
            if chunk and rows + n > _ROWS_PER_TASK:
                tasks.append(chunk)
                chunk, rows = [], 0
            chunk.append(c)
            rows += n
        tasks.append(chunk)
    return tasks


#: Seconds :func:`check_ray_address` waits for a Ray cluster's port to answer.
RAY_PROBE_SECONDS = 3.0


def check_ray_address(address: Optional[str], what: str = "address") -> None:
    """Refuse, in one line and before any work, a Ray ``address`` at which nothing
    answers: ``HOST:PORT`` or ``ray://HOST:PORT`` gets a TCP connection within
    :data:`RAY_PROBE_SECONDS`, or a RuntimeError naming ``what``; None, ``auto`` and
    ``local`` (Ray finds or starts the cluster itself) are not probed. A ValueError for an
    address of another form. A RuntimeError too if Ray is not installed."""
    import importlib.util

    if importlib.util.find_spec("ray") is None:
        raise RuntimeError("the ray executor needs Ray: pip install ray")
    if address is None or address in ("auto", "local"):
        return
    if not isinstance(address, str):
        raise ValueError(f"{what} must be HOST:PORT, ray://HOST:PORT, auto or local, got "
                         f"{address!r}")
    rest = address[len("ray://"):] if address.startswith("ray://") else address
    host, _, port = rest.rpartition(":")
    host = host.strip("[]")
    if not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise ValueError(f"{what} must be HOST:PORT, ray://HOST:PORT, auto or local, got "
                         f"{address!r}")
    try:
        socket.create_connection((host, int(port)), timeout=RAY_PROBE_SECONDS).close()
    except OSError as exc:
        why = (f"no answer within {RAY_PROBE_SECONDS:g} s" if isinstance(exc, TimeoutError)
               else (exc.strerror or str(exc)).lower())
        raise RuntimeError(f"{what} {address}: no Ray cluster answers there ({why}); start "
                           f"one (ray start --head) or give its address") from None


def _check_executor(executor: str, workers: int) -> None:
    if executor not in EXECUTORS:
        raise ValueError(f"unknown executor {executor!r}; choose one of {', '.join(EXECUTORS)}")
    if workers < 1:
        raise ValueError(f"workers must be at least 1, got {workers}")


def evaluate_cells(cells: Iterable[Cell], path: Optional[os.PathLike] = None, *,
                   store: Optional[CellFile] = None,
                   executor: str = "local", workers: Optional[int] = None, nthread: int = 1,
                   address: Optional[str] = None, progress: bool = False,
                   digests: Optional[dict] = None,
                   on_task: Optional[Callable[[list], None]] = None) -> dict:
    """Run every cell not already stored; returns all results by key, in ``cells`` order.

    Results go to an open ``store`` (:class:`twolink.sim.cell_store.CellFile`), or to the
    file ``path`` (opened and locked for the run), or nowhere. ``executor``: ``serial``
    (this process), ``local`` (worker processes) or ``ray`` (the cluster at ``address``,
    or an already initialised Ray, or a new local one). Stored cells are reused only when
    their policy's digest matches ``digests`` (by default the digests of the policies as
    they are now). Every finished task is appended to the file at once.
    """
    cells = list(dict.fromkeys(cells))
    workers = workers or max(1, (os.cpu_count() or 1) // nthread)
    _check_executor(executor, workers)
    if executor == "ray" and store is None:        # before the sweep file is made
        check_ray_address(address)
    if store is None and path is not None:
        with CellFile(path) as opened:
            if opened.note:
                print(f"twolink: {opened.note}", file=sys.stderr)
            return evaluate_cells(cells, store=opened, executor=executor, workers=workers,
                                  nthread=nthread, address=address, progress=progress,
                                  digests=digests, on_task=on_task)
    if digests is None:
        digests = {n: policy_digest(load_policy(n)) for n in {c.policy for c in cells}}
    stored = store.records if store is not None else {}
    results = {k: r for k, r in stored.items()      # policies changed since: redo those
               if digests.get(r["cell"].get("policy"), r.get("policy_digest"))
               == r.get("policy_digest")}
    pending = [c for c in cells if c.key not in results]
    tasks = _tasks(pending)
    bar = progress_bar(total=len(pending), desc="sweep cells", unit=" cells",
                       enabled=progress, leave=False)

    def done(records):
        if store is not None:
            store.append(records)
        for r in records:
            results[r["key"]] = r
        bar.update(len(records))
        if on_task is not None:
            on_task(records)

    try:
        if executor == "serial" or not tasks:
            for t in tasks:
                done(run_cells(t, nthread=nthread))
        elif executor == "local":
            _run_local(tasks, done, nthread=nthread, workers=workers)
        else:
            _run_ray(tasks, done, nthread=nthread, address=address, workers=workers)
    finally:
        bar.close()
    return {c.key: results[c.key] for c in cells}


def _die_with_parent(parent: int) -> None:
    """Worker initializer: end this worker when the run that started it ends, even by
    SIGKILL (Linux: PR_SET_PDEATHSIG; elsewhere a thread watching the parent)."""
    if sys.platform.startswith("linux"):
        import ctypes
        import signal
        pr_set_pdeathsig = 1
        ctypes.CDLL(None, use_errno=True).prctl(pr_set_pdeathsig, int(signal.SIGKILL), 0, 0, 0)
    if os.getppid() != parent:                     # the parent died before we asked
        os._exit(1)

    def watch():
        while os.getppid() == parent:
            threading.Event().wait(1.0)
        os._exit(1)

    threading.Thread(target=watch, daemon=True, name="twolink-parent-watch").start()


def _run_local(tasks, done, *, nthread, workers) -> None:
    ctx = multiprocessing.get_context("spawn")
    with cf.ProcessPoolExecutor(max_workers=min(workers, len(tasks)), mp_context=ctx,
                                initializer=_die_with_parent,
                                initargs=(os.getpid(),)) as pool:
        futures = [pool.submit(run_cells, t, nthread=nthread) for t in tasks]
        try:
            for f in cf.as_completed(futures):
                done(f.result())
        except BaseException:
            for f in futures:
                f.cancel()
            raise


@contextlib.contextmanager
def ray_session(address: Optional[str] = None, workers: Optional[int] = None,
                what: str = "address"):
    """Ray connected for the ``with`` block: the cluster at ``address``
    (:func:`check_ray_address` first), or an already initialised Ray, or a new local one
    of ``workers`` CPUs (default: all); shut down afterwards if this call started it. A
    command enters it before writing any file, so a cluster that does not answer leaves
    none behind."""
    check_ray_address(address, what)
    import ray

    started = False
    if not ray.is_initialized():
        if address:
            ray.init(address=address, log_to_driver=False)
        else:
            ray.init(num_cpus=workers or os.cpu_count() or 1, include_dashboard=False,
                     log_to_driver=False)
        started = True
    try:
        yield ray
    finally:
        if started:
            ray.shutdown()


def _run_ray(tasks, done, *, nthread, address, workers) -> None:
    with ray_session(address, workers) as ray:
        remote = ray.remote(num_cpus=nthread)(run_cells)
        pending = [remote.remote(t, nthread=nthread) for t in tasks]
        while pending:
            ready, pending = ray.wait(pending, num_returns=1)
            done(ray.get(ready[0]))
