"""Which N-link poses a joint's own motor cannot bring home in time, and who settles them.

``python docs/studies/links_own_motor.py --links N [--rule tapered|copied] [--agent FILE
...] [--json FILE]`` runs the scaling table's N-link controllers (the default
decentralized agents, the 5-level agents plain and read through the argmax of Q, and the
tuned per-joint PD, built as ``twolink scaling`` builds them), the catalogue's learned
agents of that arm (tag ``learned``, e.g. ``ppo_pd_6link_tapered``) and the saved agents
given by ``--agent`` (a ``.zip`` or ``.marl.pt`` of ``twolink train``, e.g. a run of
``twolink learners``, named by its file's stem) on
the table's 256 poses (``random_poses(N, 256, 20061122 + N)``) for 16 s on MuJoCo, and
records each pose's success at 8 s (the table's horizon) and at the longer horizons of
:data:`LATER` (the same rollout cut there, :func:`twolink.sim.pose_scoring.truncated`:
settled 1 s before the cut) beside its own-motor time: the largest over the joints of
:func:`twolink.arm.task.own_motor_seconds`, the time joint i's own motor needs at the
least to turn it home with every other joint held (its speed stays below tau_i max / b_i).
It also records how far each controller swings the inner joints away from the goal within
8 s (:func:`twolink.arm.task.inner_excursion`).
A pose whose own-motor time exceeds 7 s (settled 1 s before the end of 8 s) can be
settled in time only if the other joints' motion turns that joint too; a controller whose
joints act each on their own reading does not plan that. The runs merge into the JSON file
(one per arm; an arm measured again replaces its run); the docs generator writes the
result into ``docs/results/scaling.md``. About 3 min per arm on this machine (the 5-level
agents' synthesis is most of it). Version 1 files (8 s only, no learned agents) are
refused: run the arms again.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import numpy as np  # noqa: E402

from twolink.arm.task import inner_excursion, own_motor_seconds  # noqa: E402
from twolink.arm.parameters import LINK_RULES, LINKS_HORIZON, links_parameters  # noqa: E402
from twolink.artifacts import provenance, read_runs, write_json  # noqa: E402
from twolink.control import catalogue  # noqa: E402
from twolink.control.controllers import resolve_controller  # noqa: E402
from twolink.control.links_pd import tuned  # noqa: E402
from twolink.sim.metrics import random_poses, success  # noqa: E402
from twolink.sim.pose_scoring import truncated  # noqa: E402
from twolink.sim.plants import make_plant  # noqa: E402
from twolink.sim.rollout import rollout  # noqa: E402
from twolink.studies.scaling.measure import EVAL_SEED  # noqa: E402
from twolink.studies.scaling.synthesis import cell_policy  # noqa: E402
from twolink.validate import whole  # noqa: E402

SCHEMA, VERSION = "twolink.links_own_motor", 2
#: The scaling table's poses per arm.
POSES = 256
#: The controllers, by the scaling table's row names.
CONTROLLERS = ("decentralized", "decentralized_levels", "decentralized_argmax", "pd")
#: Horizons (s) beyond the table's 8 s at which every pose's success is also recorded:
#: does a controller fail a pose or only settle it late?
LATER = (12.0, 16.0)
DEFAULT_JSON = Path("renders/links_reach/own_motor.json")
#: The files ``--agent`` takes: a saved SB3 agent, a multi-agent save.
AGENT_SUFFIXES = (".marl.pt", ".zip")


def check_agents(agents, links: int, rule: str) -> None:
    """A one-line ValueError for an ``--agent`` that is not a file of a saved agent of this
    arm, or whose name repeats another's (a table controller's, the catalogue's, or another
    file's)."""
    taken = set(CONTROLLERS) | set(learned(links, rule))
    for path in agents:
        name = agent_name(path)
        if not Path(path).is_file():
            raise ValueError(f"--agent {path}: no such file")
        if name in taken:
            raise ValueError(f"--agent {path}: the name {name!r} is taken; rename the file")
        taken.add(name)
        resolve_controller(str(path), links=links)      # a foreign or broken file: one line


def learned(links: int, rule: str) -> tuple:
    """The names of the catalogue's learned agents of this arm (tag ``learned``)."""
    return tuple(e.name for e in catalogue.entries(tag="learned", links=links)
                 if e.rule == rule)


def agent_name(path) -> str:
    """The name an ``--agent`` file is recorded under: its file name without ``.zip`` or
    ``.marl.pt``."""
    name = Path(path).name
    for suffix in AGENT_SUFFIXES:
        if name.endswith(suffix):
            return name[:-len(suffix)]
    raise ValueError(f"{path}: an agent is a .zip or .marl.pt file of `twolink train`")


def controller(links: int, rule: str, scheme: str, agents=None):
    """The scaling table's controller of row ``scheme`` for this arm, the agent file
    ``agents[scheme]``, or the catalogue's agent of that name."""
    if agents and scheme in agents:
        return resolve_controller(str(agents[scheme]), links=links)
    if scheme not in CONTROLLERS:
        return catalogue.load(scheme)
    if scheme == "pd":
        return tuned(links_parameters(links, rule))
    return cell_policy(links, rule, scheme, 2 * 2**30)[0]


def measure(links: int, rule: str, poses: int = POSES, agents=()) -> dict:
    """Every controller's success on the first ``poses`` poses of the table's set at 8 s,
    with each pose's own-motor time and the joint that sets it; ``agents``: agent files
    run beside the catalogue's, recorded by :func:`agent_name`."""
    files = {agent_name(a): Path(a) for a in agents}
    t0 = time.perf_counter()
    p = links_parameters(links, rule)
    x0 = random_poses(links, POSES, EVAL_SEED + links)[:poses]
    own = own_motor_seconds(p, x0[:, :links])
    out = {"links": links, "rule": rule, "poses": poses, "seed": EVAL_SEED + links,
           "horizon_s": LINKS_HORIZON,
           "own_motor_s": [round(float(v), 4) for v in own.max(axis=1)],
           "slowest_joint": [int(j) + 1 for j in own.argmax(axis=1)], "success": {},
           "later": {f"{h:g}": {} for h in LATER}, "excursion": {},
           "learned": list(learned(links, rule)) + list(files),
           "agent_files": {k: str(v) for k, v in files.items()}}
    for scheme in CONTROLLERS + tuple(out["learned"]):
        print(f"  {scheme}: building", flush=True)
        policy = controller(links, rule, scheme, files)
        with make_plant("mujoco", p) as plant:
            traj = rollout(policy, plant, x0, duration=max(LATER))
        eight = truncated(traj, LINKS_HORIZON)
        ok = success(eight)
        out["success"][scheme] = [int(v) for v in ok]
        swing = inner_excursion(eight.x[..., :links])
        out["excursion"][scheme] = [round(float(v), 4) for v in swing]
        for h in LATER:
            out["later"][f"{h:g}"][scheme] = [int(v) for v in success(truncated(traj, h))]
        print(f"  {scheme}: {int(ok.sum())}/{poses} settled by {LINKS_HORIZON:g} s, "
              + ", ".join(f"{sum(out['later'][f'{h:g}'][scheme])} by {h:g} s"
                          for h in LATER), flush=True)
    out["seconds"] = round(time.perf_counter() - t0, 1)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--links", type=int, required=True, help="links N, 3 to 6")
    ap.add_argument("--rule", choices=LINK_RULES, default="tapered")
    ap.add_argument("--poses", type=int, default=POSES,
                    help=f"the first K poses of the {POSES} of the scaling table "
                         f"(default {POSES})")
    ap.add_argument("--agent", action="append", default=[], metavar="FILE",
                    help="a saved agent of this arm (.zip or .marl.pt of `twolink train`) "
                         "to run beside the catalogue's; repeatable")
    ap.add_argument("--json", type=Path, default=DEFAULT_JSON, help=f"default {DEFAULT_JSON}")
    args = ap.parse_args(argv)
    try:
        whole(args.links, "--links", 3, 6)
        whole(args.poses, "--poses", 1, POSES)
        check_agents(args.agent, args.links, args.rule)
        data = read_runs(args.json, SCHEMA, VERSION)
    except ValueError as exc:
        print(f"links_own_motor: error: {exc}", file=sys.stderr)
        return 2
    print(f"{args.links} {args.rule} links, {args.poses} poses, {LINKS_HORIZON:g} s",
          flush=True)
    run = measure(args.links, args.rule, args.poses, args.agent)
    runs = [r for r in data["runs"] if (r["links"], r["rule"]) != (args.links, args.rule)]
    runs.append(run)
    runs.sort(key=lambda r: (r["rule"], r["links"]))
    args.json.parent.mkdir(parents=True, exist_ok=True)
    write_json(args.json, {"schema": SCHEMA, "version": VERSION, "runs": runs,
                           "provenance": provenance()})
    late = int(np.sum(np.asarray(run["own_motor_s"]) > LINKS_HORIZON - 1))
    print(json.dumps({"links": run["links"], "rule": run["rule"], "poses": run["poses"],
                      "own_motor_over_deadline": late,
                      **{k: sum(v) for k, v in run["success"].items()}}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
