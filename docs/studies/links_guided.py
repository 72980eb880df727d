"""Guided learning at six tapered links: demonstrations, cloned, then fine-tuned by PPO.

The learned residual agents settle nearly every pose within their own motors' reach by
8 s and few beyond it (docs/results/scaling.md, "Failed, or settled late?"); the reach
study's solver brings every such pose home by 7 s. This lever hands the learner the
solver's answers:

1. ``python docs/studies/links_guided.py demos --first 0 --last 40`` solves poses
   0..39 of the demonstration set (:mod:`twolink.studies.guided.demos`: poses beyond the
   own motors' reach from seed 7300001, one JSON file each under
   ``renders/learners/guided/demos/``; minutes a pose; resumable, and several
   processes may share the range).
2. ``python docs/studies/links_guided.py clone --init AGENT.zip -o CLONED.zip`` clones
   every demonstration whose open-loop replay succeeded on MuJoCo into the policy of
   AGENT (the shipped ``ppo_pd_6link_tapered`` by default), keeping its own actions on
   its rollouts from uniform poses (:mod:`twolink.studies.guided.clone`), and saves the
   agent.
3. ``twolink train --links 6 --base pd --start mixed --init CLONED.zip --steps 1e6
   --eval-every 2e5`` fine-tunes it by PPO.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from twolink.control.learned import learned_agent_path  # noqa: E402
from twolink.studies.guided import clone as C  # noqa: E402
from twolink.studies.guided import demos as D  # noqa: E402
from twolink.validate import whole  # noqa: E402

DEMOS = Path(D.DEMOS)
#: The agent cloned into by default: the catalogue's six-link residual PPO.
DEFAULT_INIT = "ppo_pd_6link_tapered"
#: Uniform poses whose rollouts give the init agent's own actions to keep, and their seed
#: (not the table's, the fresh poses', the tuning or the demonstration seeds).
KEEP_POSES, KEEP_SEED = 64, 7_300_002


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="step", required=True)
    d = sub.add_parser("demos", help="solve the demonstration poses FIRST..LAST-1")
    d.add_argument("--first", type=int, default=0)
    d.add_argument("--last", type=int, default=40)
    d.add_argument("--folder", type=Path, default=DEMOS)
    c = sub.add_parser("clone", help="clone the demonstrations into an agent")
    c.add_argument("--init", default=None, help="the agent to start from (default the "
                   "shipped ppo_pd_6link_tapered)")
    c.add_argument("--folder", type=Path, default=DEMOS)
    c.add_argument("--epochs", type=int, default=200)
    c.add_argument("--keep-weight", type=float, default=1.0)
    c.add_argument("-o", "--out", type=Path, required=True, help="the cloned agent .zip")
    args = ap.parse_args(argv)
    try:
        if args.step == "demos":
            whole(args.first, "--first", 0, 10_000)
            whole(args.last, "--last", args.first + 1, 10_000)
            n = D.solve_missing(args.folder, 6, "tapered", D.DEMO_SEED,
                                range(args.first, args.last),
                                log=lambda s: print(s, flush=True))
            print(json.dumps({"solved": n}))
            return 0
        whole(args.epochs, "--epochs", 1, 100_000)
        if args.out.suffix != ".zip":
            raise ValueError(f"-o {args.out}: the cloned agent is a .zip")
        demos = D.load(args.folder)
        if not demos:
            raise ValueError(f"{args.folder}: no demonstration whose replay succeeded")
        return _clone(args, demos)
    except ValueError as exc:
        print(f"links_guided: error: {exc}", file=sys.stderr)
        return 2


def _clone(args, demos) -> int:
    from twolink.control.residual import base_controller
    from twolink.control.sb3_agent import SB3Agent
    from twolink.training.config import TrainConfig
    from twolink.training.run import arm_of, build, save_agent

    init = args.init or str(learned_agent_path(DEFAULT_INIT))
    config = TrainConfig(links=6, base="pd", init=init, start="mixed")
    model, env = build(config)
    try:
        params = arm_of(config)
        demo = C.demo_pairs(demos, params, base_controller("pd", params))
        keep = C.own_pairs(SB3Agent(init), params, poses=KEEP_POSES, seed=KEEP_SEED)
        print(f"{len(demos)} demonstrations ({len(demo[0])} samples), {len(keep[0])} kept "
              f"samples", flush=True)
        result = C.clone(model, demo, keep, keep_weight=args.keep_weight,
                         epochs=args.epochs)
        save_agent(model, args.out, config)
    finally:
        env.close()
    print(json.dumps({"demonstrations": len(demos), "indices": [d["index"] for d in demos],
                      "init": args.init or DEFAULT_INIT, "epochs": args.epochs, "keep_weight": args.keep_weight,
                      "agent": str(args.out), **result}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
