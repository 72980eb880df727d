"""``twolink learners``: Table II for today's learners, a resumable study.

Trains centralized PPO and IPPO / MAPPO (local and neighbours observations), PPO, IPPO
and MAPPO (local) as residuals over the per-joint PD, and PPO on the rigid-body model (6)
instead of MuJoCo, on N = 2..6 tapered links and copied N = 3, 4, three seeds each
(``twolink train`` runs with one hyperparameter set per algorithm), scores every final
agent on 256 poses of the scaling table and 256 fresh poses at 8 s (those also on the
model: the transfer gap), and writes the study's JSON after every finished run,
with its table and learning-curve figure beside it. Run the same command again to
continue: finished runs are kept, an interrupted one resumes from its last checkpoint.
--seeds 0 is the one-seed version; --smoke checks the pipeline in a few thousand steps.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

from twolink.commands import SUMMARIES
from twolink.resources import output_dir
from twolink.studies.learners import plan as P
from twolink.validate import whole

#: The reach study's data, the ceiling of each arm's table poses (read where it exists).
REACH = Path("renders/links_reach/reach.json")
#: Files written beside the study's JSON.
TABLE, FIGURE = "learners.md", "learners.png"


def add_parser(sub):
    p = sub.add_parser("learners", help=SUMMARIES["learners"],
                       description=" ".join(__doc__.split("\n\n")[1].split()))
    p.add_argument("--arms", nargs="+", metavar="ARM", default=None,
                   help="arms: N (tapered) or Nc (copied), e.g. 2 3 6 4c (default "
                        "2 3 4 5 6 3c 4c)")
    p.add_argument("--learners", nargs="+", metavar="L", default=None,
                   help="ppo, ippo-local, ippo-neighbours, mappo-local, mappo-neighbours, "
                        "with -pd the residual over the per-joint PD, ppo-model trained on "
                        "the model (6) (default: those five, ppo-pd, ippo-local-pd, "
                        "mappo-local-pd, ppo-model)")
    p.add_argument("--seeds", nargs="+", type=int, metavar="S", default=None,
                   help="seeds (default 0 1 2; 0 alone is the one-seed version)")
    p.add_argument("--steps", type=float, default=None, metavar="N",
                   help="environment steps of every run (default by links: " + ", ".join(
                       f"N={n}: {s / 1e6:g} M" for n, s in P.STEPS.items()) + ")")
    p.add_argument("--poses", type=int, default=None, metavar="K",
                   help=f"poses of each final score, table and fresh (default {P.POSES})")
    p.add_argument("--smoke", action="store_true",
                   help="the pipeline end to end in a few thousand steps: N = 2, 3, PPO "
                        "(on MuJoCo and on the model) and IPPO (local; N = 3 also over the "
                        "PD), seed 0, 8 poses (learning quality not judged)")
    p.add_argument("--work", type=Path, default=None, metavar="DIR",
                   help="the runs' folders (checkpoints, agents; default "
                        "<output>/learners/runs)")
    p.add_argument("-o", "--out", type=Path, default=None, metavar="FILE",
                   help="the study's JSON, read to skip finished runs, each finished run "
                        "merged into it under a lock (processes running different runs may "
                        "share it; default <output>/learners/learners.json; the committed one is "
                        "renders/learners/learners.json)")
    p.add_argument("--workers", type=int, default=1, metavar="W",
                   help="runs at a time on this machine (default 1; each run uses one core)")
    p.add_argument("--executor", choices=("local", "ray"), default="local",
                   help="local (default) or ray: every run a task on the Ray cluster at "
                        "--address (records come back to this process)")
    p.add_argument("--address", default=None, help="Ray cluster address (ray executor)")
    p.add_argument("--list", action="store_true",
                   help="list the plan's runs and whether each is done, then stop")
    p.add_argument("--json", action="store_true", help="print the table's rows as JSON")
    return p


def _plan(args) -> list:
    if args.smoke:
        if any(v is not None for v in (args.arms, args.learners, args.seeds)):
            raise ValueError("--smoke is its own plan: drop --arms, --learners and --seeds")
        s = P.SMOKE
        return P.plan(arms=s["arms"], learners=s["learners"], seeds=s["seeds"],
                      steps=s["steps"])
    arms = tuple(P.parse_arm(a) for a in args.arms) if args.arms else P.ARMS
    learners = tuple(P.parse_learner(x) for x in args.learners) if args.learners \
        else P.LEARNERS
    steps = None
    if args.steps is not None:
        if args.steps != args.steps or args.steps < 1 or args.steps > 1e9 \
                or args.steps != int(args.steps):
            raise ValueError(f"--steps must be a whole number from 1 to 1e9, got {args.steps:g}")
        steps = int(args.steps)
    return P.plan(arms=arms, learners=learners,
                  seeds=tuple(args.seeds) if args.seeds else P.SEEDS, steps=steps)


def _ceiling() -> dict:
    from twolink.artifacts import read_runs
    from twolink.studies.learners.report import ceilings

    try:
        return ceilings(read_runs(REACH, "twolink.links_reach", 1)) if REACH.is_file() else {}
    except ValueError:
        return {}


def _log(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


def run(args) -> int:
    from twolink.artifacts import read_runs, staged_files
    from twolink.studies.learners import measure, report

    runs = _plan(args)                                       # every check before any work
    poses = whole(args.poses, "--poses", 1, 4096) if args.poses is not None else \
        (P.SMOKE["poses"] if args.smoke else P.POSES)
    whole(args.workers, "--workers", 1, 64)
    if args.executor == "local" and args.address:
        raise ValueError("--address is the ray executor's: add --executor ray")
    base = output_dir() / ("learners-smoke" if args.smoke else "learners")
    out = args.out or base / "learners.json"
    if out.suffix != ".json":
        raise ValueError(f"-o {out}: the study's data is a .json file")
    work = args.work or base / "runs"
    data = read_runs(out, P.SCHEMA, P.VERSION)
    if args.list:
        done = {r["id"] for r in data["runs"]}
        for r in runs:
            state = "done" if r.id in done else measure._state(work / r.id)
            print(f"{r.id:32s} {r.steps:>10,} steps  {state}")
        return 0
    out.parent.mkdir(parents=True, exist_ok=True)
    ceiling = _ceiling()

    def present(data) -> list:                   # the table and figure beside the JSON
        rows = report.rows(data, ceiling)
        with staged_files([out.parent / TABLE, out.parent / FIGURE]) as (table, figure):
            table.write_text(report.table(rows) + "\n")
            report.figure(data, figure, ceiling)
        return rows

    data = measure.study(runs, out, work, poses=poses, workers=args.workers,
                         executor=args.executor, address=args.address, log=_log,
                         after=present)
    rows = present(data)
    if args.json:
        print(json.dumps(rows, indent=2))
    else:
        print(report.table(rows))
        print(f"\nwrote {out}, {out.parent / TABLE}, {out.parent / FIGURE}")
    return 0
