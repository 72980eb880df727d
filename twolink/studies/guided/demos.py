"""Demonstrations for guided learning: poses beyond the own motors' reach, each brought to
rest in the goal band by the reach study's solver (:func:`twolink.limits.links.reach`).

Pose i of a demonstration set is :func:`twolink.envs.starts.slow_pose` drawn from
``np.random.default_rng([seed, i])`` (one stream per pose, so poses can be solved in any
order, by several processes, and a set grows without changing its first poses). Its
demonstration is the solver's torque sequence (one per sample, each held for
:data:`twolink.limits.links.HOLD` samples) that brings it to rest in the band by
:data:`DEADLINE` samples (7 s: settled 1 s before the end of 8 s), replayed open loop on
MuJoCo: the states it passes, the torques, and whether the replay succeeded at 8 s. Each
pose is one JSON file ``pose_<i>.json`` in the set's folder, written atomically when
solved; a pose already on disk is never solved again.
"""
from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from twolink.arm.parameters import TS, links_parameters
from twolink.artifacts import write_json
from twolink.envs.starts import slow_pose

SCHEMA, VERSION = "twolink.guided_demo", 1
#: 7 s in samples: the reach study's deadline.
DEADLINE = 140
#: The seed of the demonstration poses (used by nothing else: not the scaling table's
#: 20061122, the fresh 4180000, the tuning seeds or the training seeds 0-3).
DEMO_SEED = 7_300_001
#: The committed demonstration set, relative to the repository root: poses of six tapered
#: links (``docs/studies/links_guided.py demos``; the scaling page reads it).
DEMOS = "renders/learners/guided/demos"


def pose(params, seed: int, i: int) -> np.ndarray:
    """Pose i of the set of ``seed``: a state at rest beyond the own motors' reach."""
    return slow_pose(params, np.random.default_rng([int(seed), int(i)]))


def path_of(folder, i: int) -> Path:
    return Path(folder) / f"pose_{i:04d}.json"


class Replay:
    """A controller that replays open-loop torques (B, K, N), one row per sample, then
    none (how a demonstration is run on a plant)."""

    def __init__(self, torques):
        self.torques = np.asarray(torques, dtype=float)
        self.k = 0

    def reset(self, rows=None):
        self.k = 0

    def __call__(self, x):
        k, self.k = self.k, self.k + 1
        if k < self.torques.shape[1]:
            return self.torques[:, k, :]
        return np.zeros((len(x), self.torques.shape[2]))


def solve(links: int, rule: str, seed: int, i: int, step=None) -> dict:
    """The demonstration of pose i (module docstring)."""
    from twolink.limits.links import reach
    from twolink.sim.metrics import success
    from twolink.sim.plants import make_plant
    from twolink.sim.rollout import rollout

    p = links_parameters(links, rule)
    x0 = pose(p, seed, i)
    t0 = time.perf_counter()
    answer = reach(p, x0, DEADLINE, step=step)
    out = {"schema": SCHEMA, "version": VERSION, "links": links, "rule": rule, "seed": seed,
           "index": i, "x0": x0.tolist(), "reachable": bool(answer.reachable),
           "solve_s": round(time.perf_counter() - t0, 2), "torques": None, "states": None,
           "replay_success": None}
    if answer.torques is None:
        return out
    torques = np.asarray(answer.torques, float)
    with make_plant("mujoco", p) as plant:
        traj = rollout(Replay(torques[None]), plant, x0[None], duration=8.0)
    out.update(torques=torques.tolist(), states=traj.x[0, :len(torques)].tolist(),
               replay_success=bool(success(traj)[0]), ts=TS)
    return out


def solve_missing(folder, links: int, rule: str, seed: int, indices, log=print) -> int:
    """Solve every pose of ``indices`` not yet in ``folder``; the count solved now."""
    from twolink.limits.links import HOLD, NLP_SUBSTEPS, step_function

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    step = step_function(links_parameters(links, rule), ts=HOLD * TS, substeps=NLP_SUBSTEPS)
    done = 0
    for i in indices:
        if path_of(folder, i).is_file():
            continue
        demo = solve(links, rule, seed, i, step=step)
        write_json(path_of(folder, i), demo)
        done += 1
        log(f"pose {i}: reachable {demo['reachable']}, replay "
            f"{demo['replay_success']}, {demo['solve_s']:.0f} s")
    return done


def load(folder) -> list:
    """Every demonstration in ``folder`` whose replay succeeded, by index; a ValueError
    naming a file that is not one."""
    out = []
    for path in sorted(Path(folder).glob("pose_*.json")):
        try:
            d = json.loads(path.read_text())
        except ValueError as exc:
            raise ValueError(f"{path}: not JSON ({exc})") from None
        if not isinstance(d, dict) or (d.get("schema"), d.get("version")) != (SCHEMA, VERSION):
            raise ValueError(f"{path} is not a {SCHEMA} version {VERSION} file")
        if d["replay_success"]:
            out.append(d)
    return out
