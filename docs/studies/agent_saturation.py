"""Which joint a learned agent holds at its torque limit once the arm should have settled.

``python docs/studies/agent_saturation.py AGENT [AGENT ...] [--links 6] [--rule tapered]
[--poses 64] [--seed 4180000] [--json FILE]`` runs each controller (a saved agent, ``.zip``
or ``.marl.pt`` of ``twolink train``, or a catalogue name) on the scaling table's protocol
(:func:`twolink.sim.pose_scoring.poses_for`: random poses at rest, MuJoCo, 8 s) and
prints, beside its successes, per joint:

* ``at_limit``: the fraction of the last 2 s's samples, over all poses, in which the
  joint's torque is within 1 % of its limit (the deterministic policy's command, clipped);
* ``speed``: the median over poses of the joint's |speed| at the end (rad/s);
* ``angle``: the median over poses of the joint's |angle| from the goal at the end (rad,
  wrapped to [0, pi]).

A joint its agent keeps turning shows a final speed far beyond the goal band's 0.1 rad/s,
with ``at_limit`` near 1 where the agent's mean action lies beyond the torque limit. A
missing or foreign file, or an agent of
another arm: one line, exit 2, nothing written. About 5 s an agent at six links.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import numpy as np  # noqa: E402

#: The last seconds of each run in which ``at_limit`` is counted.
TAIL_S = 2.0
#: A torque within this fraction of its limit counts as at the limit.
AT_LIMIT = 0.99


def measure(controller: str, *, links: int, rule: str | None, poses: int,
            seed: int) -> dict:
    """The record of one controller (see the module docstring)."""
    from twolink.arm.parameters import TS, horizon
    from twolink.control.controllers import resolve_controller
    from twolink.envs.core import arm
    from twolink.sim.controller import checked
    from twolink.sim.metrics import success
    from twolink.sim.plants import make_plant
    from twolink.sim.pose_scoring import poses_for
    from twolink.sim.rollout import rollout

    params = arm(links=links, rule=rule)
    c = resolve_controller(controller, links=links)
    own = getattr(c.controller, "links", None)
    if isinstance(own, int) and not isinstance(own, bool) and own != links:
        raise ValueError(f"{controller} controls an arm of {own} links, not {links}")
    c = checked(c, name=c.name, links=links)
    x0 = poses_for(links, poses, seed)
    with make_plant("mujoco", params) as plant:
        traj = rollout(c, plant, x0, duration=horizon(links))
    tau_max = np.asarray(params.torque_limits, dtype=float)
    tail = traj.u[:, -int(round(TAIL_S / TS)):, :]
    at_limit = (np.abs(tail) >= AT_LIMIT * tau_max).mean(axis=(0, 1))
    speed = np.median(np.abs(traj.x[:, -1, links:]), axis=0)
    angle = np.median(np.abs(np.angle(np.exp(1j * traj.x[:, -1, :links]))), axis=0)
    ok = success(traj)
    return {"controller": c.name, "file": controller, "successes": int(ok.sum()),
            "n": int(len(ok)), "at_limit": [round(float(v), 4) for v in at_limit],
            "speed": [round(float(v), 4) for v in speed],
            "angle": [round(float(v), 4) for v in angle]}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("agents", nargs="+", metavar="AGENT")
    ap.add_argument("--links", type=int, default=6)
    ap.add_argument("--rule", default="tapered", help="tapered or copied (default tapered)")
    ap.add_argument("--poses", type=int, default=64)
    ap.add_argument("--seed", type=int, default=4180000,
                    help="poses drawn from seed + links (default 4180000: the learners "
                         "study's fresh poses)")
    ap.add_argument("--json", type=Path, default=None, help="also write the records here")
    args = ap.parse_args(argv)
    from twolink.artifacts import write_json
    from twolink.validate import whole

    try:
        whole(args.poses, "--poses", 1, 4096)
        for a in args.agents:
            if a.endswith((".zip", ".pt")) and not Path(a).is_file():
                raise ValueError(f"{a}: no such agent file")
        records = [measure(a, links=args.links, rule=args.rule, poses=args.poses,
                           seed=args.seed) for a in args.agents]
    except (ValueError, OSError) as exc:
        print(f"agent_saturation: error: {exc}", file=sys.stderr)
        return 2
    for r in records:
        print(f"{r['file']}: {r['successes']}/{r['n']} settled; at the limit over the last "
              f"{TAIL_S:g} s {r['at_limit']}; final |speed| {r['speed']}; final |angle| "
              f"{r['angle']}")
    if args.json is not None:
        write_json(args.json, {"schema": "twolink.studies.agent_saturation", "version": 1,
                               "links": args.links, "rule": args.rule, "poses": args.poses,
                               "seed": args.seed, "tail_s": TAIL_S, "records": records})
    return 0


if __name__ == "__main__":
    sys.exit(main())
