"""Does the learners' reward pay for the swing? The time-optimal answers' returns beside
each controller's own, from the same poses.

``python docs/studies/swing_returns.py [AGENT ...] [--demos FOLDER] [--json FILE]``
takes the demonstrations of ``docs/studies/links_guided.py`` (poses beyond the own
motors' reach, each brought home by 7 s by the reach study's solver;
:mod:`twolink.studies.guided.demos`) whose open-loop replay succeeded, and runs on MuJoCo
from each pose for 8 s:

* the time-optimal answer: its torques replayed open loop, then no torque;
* each AGENT (a catalogue name, e.g. the default ``pd_6link_tapered``,
  ``ppo_pd_6link_tapered`` and ``mappo_6link_tapered``, or a saved agent of ``twolink
  train``).

On the states reached x_1, x_2, ... it adds up the rewards the deep learners train on,
discounted from the start by each gamma of :data:`GAMMAS` (0.98 is every recipe's
discount, 0.995 the ``--gamma`` lever's, 1 the plain sum), over each window of
:data:`WINDOWS` (8 s, a training episode; 16 s, long enough for the slow approaches to
settle):

* team rewards (:data:`TEAM`): the shaped reward (:func:`twolink.envs.core.shaped_reward`,
  what PPO and MAPPO maximise), the same with the minimum-time term
  (:func:`twolink.envs.core.shaped_time_reward`, ``--reward shaped_time``) and the
  paper's (15) (:func:`twolink.arm.task.centralized_reward`):
  ``G = sum_k gamma^k r(x_{k+1})``;
* each link's shaped reward (:func:`twolink.envs.multi_agent.shaped_link_rewards`, what
  IPPO's agent of that link maximises).

Where an agent's own trajectory earns more than the time-optimal answer from the same
pose, that reward, at that discount, does not ask for the answer's manoeuvre: a learner
that maximised it would have no reason to find it. Where the answer earns more, the
reward pays for it and what the learner misses is found by search, not asked for.

A missing or foreign file, or an agent of another arm: one line, exit 2, nothing written.
About 15 s for six agents on 80 poses.
"""
from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import numpy as np  # noqa: E402

#: The discounts the returns are added up with: every recipe's, the ``--gamma`` lever's,
#: and none (the plain sum over the horizon).
GAMMAS = (0.98, 0.995, 1.0)
#: The controllers run by default: the per-joint PD and the catalogue's learned agents of
#: six tapered links.
DEFAULT_AGENTS = ("pd_6link_tapered", "ppo_pd_6link_tapered", "mappo_6link_tapered")
#: The windows the returns are added up over, seconds: a training episode (the scaling
#: table's 8 s) and twice that; the rollouts run for the longest.
WINDOWS = (8.0, 16.0)
#: The team rewards, by their ``twolink train --reward`` name (``paper``: (15)).
TEAM = ("shaped", "shaped_time", "paper")
SCHEMA, VERSION = "twolink.studies.swing_returns", 1


def _team_reward(name: str):
    from twolink.arm.task import centralized_reward
    from twolink.envs.core import shaped_reward, shaped_time_reward

    return {"shaped": shaped_reward, "shaped_time": shaped_time_reward,
            "paper": centralized_reward}[name]


def returns(states, window_s: float, gammas=GAMMAS) -> dict:
    """The discounted returns of trajectories ``states`` (B, K+1, 2N) over their first
    ``window_s`` seconds, rewards on the states reached: ``{reward: (B, G)}`` for each
    team reward of :data:`TEAM` and ``"links": (B, G, N)`` for the per-link shaped
    reward, for the gammas ``gammas``."""
    from twolink.arm.parameters import TS
    from twolink.envs.multi_agent import shaped_link_rewards

    k = int(round(window_s / TS))
    reached = np.asarray(states, dtype=float)[:, 1:k + 1, :]
    if reached.shape[1] != k:
        raise ValueError(f"trajectories of {reached.shape[1]} samples, not {k}")
    weights = np.array([[g ** j for j in range(k)] for g in gammas])
    out = {name: np.asarray(_team_reward(name)(reached), dtype=float) @ weights.T
           for name in TEAM}
    out["links"] = np.einsum("bkn,gk->bgn", shaped_link_rewards(reached), weights)
    return out


def _record(label: str, traj, gammas) -> dict:
    """One controller's record: per window, each pose's success (settled 1 s before the
    window's end, on the trajectory cut there) and returns."""
    from twolink.arm.parameters import TS
    from twolink.sim.metrics import success

    out = {"controller": label, "n": int(traj.x.shape[0])}
    for w in WINDOWS:
        key = f"{w:g}s"
        short = dataclasses.replace(traj, t=traj.t[:int(round(w / TS)) + 1],
                                    x=traj.x[:, :int(round(w / TS)) + 1])
        out[f"success_{key}"] = [bool(v) for v in success(short)]
        g = returns(traj.x, w, gammas)
        out[f"returns_{key}"] = {name: np.round(v, 5).tolist() for name, v in g.items()}
    return out


def measure(agents, demos, gammas=GAMMAS) -> dict:
    """Every record (the time-optimal answers first) on the demonstrations' poses."""
    from twolink.control.controllers import resolve_controller
    from twolink.envs.core import arm
    from twolink.sim.controller import checked
    from twolink.sim.plants import make_plant
    from twolink.sim.rollout import rollout
    from twolink.studies.guided.demos import Replay

    (links, rule), = {(d["links"], d["rule"]) for d in demos}
    params = arm(links=links, rule=rule)
    x0 = np.array([d["x0"] for d in demos], dtype=float)
    controllers = []
    for a in agents:
        c = resolve_controller(a, links=links)
        own = getattr(c.controller, "links", None)
        if isinstance(own, int) and not isinstance(own, bool) and own != links:
            raise ValueError(f"{a} controls an arm of {own} links, not {links}")
        controllers.append((a, checked(c, name=c.name, links=links)))
    torques = np.array([d["torques"] for d in demos], dtype=float)
    records = []
    with make_plant("mujoco", params) as plant:
        records.append(_record("time-optimal answers",
                               rollout(Replay(torques), plant, x0, duration=max(WINDOWS)),
                               gammas))
        for name, c in controllers:
            records.append(_record(name, rollout(c, plant, x0, duration=max(WINDOWS)),
                                   gammas))
    return {"schema": SCHEMA, "version": VERSION, "links": links, "rule": rule,
            "poses": len(demos), "demo_seed": demos[0]["seed"],
            "indices": [d["index"] for d in demos], "windows_s": list(WINDOWS),
            "gammas": list(gammas), "team": list(TEAM), "records": records}


def main(argv=None) -> int:
    from twolink.studies.guided.demos import DEMOS, load

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("agents", nargs="*", metavar="AGENT",
                    help=f"catalogue names or saved agents (default: "
                         f"{' '.join(DEFAULT_AGENTS)})")
    ap.add_argument("--demos", type=Path, default=Path(DEMOS),
                    help=f"the demonstrations' folder (default {DEMOS})")
    ap.add_argument("--json", type=Path, default=None, help="also write the records here")
    args = ap.parse_args(argv)
    from twolink.artifacts import write_json

    agents = args.agents or list(DEFAULT_AGENTS)
    try:
        for a in agents:
            if a.endswith((".zip", ".pt")) and not Path(a).is_file():
                raise ValueError(f"{a}: no such agent file")
        if not args.demos.is_dir():
            raise ValueError(f"{args.demos}: no such folder of demonstrations")
        demos = load(args.demos)
        if not demos:
            raise ValueError(f"{args.demos}: no demonstration whose replay succeeded")
        if len({(d["links"], d["rule"]) for d in demos}) != 1:
            raise ValueError(f"{args.demos}: demonstrations of more than one arm")
        data = measure(agents, demos)
    except (ValueError, OSError, KeyError) as exc:
        print(f"swing_returns: error: {exc}", file=sys.stderr)
        return 2
    first = data["records"][0]
    for r in data["records"]:
        print(f"{r['controller']}: " + "; ".join(
            f"{sum(r[f'success_{w:g}s'])}/{r['n']} settled by {w:g} s" for w in WINDOWS))
        for w in WINDOWS:
            key = f"returns_{w:g}s"
            for name in (*TEAM, "links"):
                mine, theirs = np.asarray(r[key][name]), np.asarray(first[key][name])
                more = (theirs > mine).sum(axis=0)
                if name == "links":      # the inner links' agents, every pose
                    mine, more = mine[..., :-1], (theirs > mine)[..., :-1].sum(axis=(0, 2))
                print(f"  {w:g} s, {name}: " + ", ".join(
                    f"gamma {g:g} mean {m:.2f} (the answer more on {h})"
                    for g, m, h in zip(data["gammas"], mine.reshape(
                        mine.shape[0], len(data["gammas"]), -1).mean(axis=(0, 2)), more)))
    if args.json is not None:
        write_json(args.json, data)
    return 0


if __name__ == "__main__":
    sys.exit(main())
