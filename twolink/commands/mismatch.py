"""``twolink mismatch``: measure the model mismatch, its closure and robustness; write a report.

Open-loop error of (11) and (6) against MuJoCo, the closed-loop gap of every policy on
every plant, the policies synthesised on (6), robustness sweeps on MuJoCo, and every policy
under every challenge level with and without run-time compensation, written as Markdown +
JSON + figures under renders/mismatch/ (renders/mismatch-quick/ with --quick).
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from twolink.challenges import LEVELS, challenge
from twolink.mismatch import build
from twolink.formatting import format_rate
from twolink.mismatch_plan import PLANS, plan
from twolink.mismatch_report import summary, write
from twolink.policy import load_policy
from twolink.registry import SHIPPED
from twolink.resources import output_dir
from twolink.sweep_store import SweepFile
from twolink.sweeps import EXECUTORS


def add_parser(sub):
    p = sub.add_parser("mismatch", help="model mismatch, its closure and robustness sweeps",
                       description=__doc__.split("\n\n")[1].replace("\n", " "))
    p.add_argument("--plan", choices=list(PLANS), default="full",
                   help="what to measure: full (the committed report) or quick (5 initial "
                        "states per sweep cell, fewer sizes; the closed-loop table keeps "
                        "all 65): under a minute, for CI")
    p.add_argument("--quick", action="store_const", dest="plan", const="quick",
                   help="the same as --plan quick")
    p.add_argument("--out", type=Path, default=None,
                   help="report folder (default renders/mismatch, or renders/mismatch-quick); "
                        "one run at a time per folder, which resumes from its sweep.jsonl")
    p.add_argument("--policies", nargs="+", default=list(SHIPPED), metavar="POLICY",
                   help=f"shipped policy names, reported in registry order "
                        f"(default: {' '.join(SHIPPED)})")
    p.add_argument("--executor", choices=EXECUTORS, default="local",
                   help="where sweep cells run: this process, local worker processes "
                        "(default) or a Ray cluster")
    p.add_argument("--address", default=None,
                   help="Ray cluster address (with --executor ray; default: a local Ray)")
    p.add_argument("--workers", type=int, default=None,
                   help="worker processes (default: one per CPU)")
    p.add_argument("--challenge", nargs="+", metavar="LEVEL", default=None,
                   help=f"challenge levels of the robust section ({', '.join(LEVELS)}; "
                        "default: all); each policy runs as it is and behind the run-time "
                        "compensator (the paper's policies only as they are)")
    p.add_argument("--seed", type=int, default=None,
                   help="seed of the robust section's plants and noise (default: the "
                        "plan's, never tuned on)")
    p.add_argument("--robust", action=argparse.BooleanOptionalAction, default=True,
                   help="measure the robust section (default on)")
    p.add_argument("--json", action="store_true",
                   help="print success rates, open-loop errors and margins as JSON")
    return p


def _robust_args(args) -> list:
    """The robust-section options of the command line, as the report names them."""
    out = [] if args.robust else ["--no-robust"]
    if args.challenge is not None:
        out.append("--challenge " + " ".join(args.challenge))
    if args.seed is not None:
        out.append(f"--seed {args.seed}")
    return out


def run(args) -> int:
    chosen = plan(args.plan)
    if args.workers is not None and args.workers < 1:
        raise ValueError(f"--workers must be at least 1, got {args.workers}")
    if args.address and args.executor != "ray":
        raise ValueError("--address needs --executor ray")
    for name in args.policies:                       # fail before anything is written
        load_policy(name)
    levels = None if args.challenge is None else [challenge(n).name for n in args.challenge]
    if not args.robust and (args.challenge is not None or args.seed is not None):
        raise ValueError("--challenge and --seed choose what the robust section measures; "
                         "drop --no-robust or them")
    out = args.out or output_dir() / chosen.folder
    if not out.parent.is_dir():
        raise OSError(f"cannot write {out}: directory {out.parent} does not exist")
    out.mkdir(exist_ok=True)
    progress = not args.json and sys.stderr.isatty()
    with SweepFile(out / "sweep.jsonl") as store:    # a second run on `out` stops here
        if store.note:
            print(f"twolink mismatch: {store.note}", file=sys.stderr)
        report, data = build(chosen, args.policies, store=store, executor=args.executor,
                             workers=args.workers, address=args.address,
                             log=(lambda m: print(m, file=sys.stderr, flush=True))
                             if progress else None, progress=progress,
                             robust=args.robust, levels=levels, seed=args.seed)
        command = "twolink mismatch" + ("" if chosen.name == "full" else f" --plan {chosen.name}")
        command += "".join(f" {a}" for a in _robust_args(args))
        report = write(report, data, out, command)
    if args.json:
        print(json.dumps(summary(report), indent=2))
    else:
        for p, d in summary(report)["successes"].items():
            print(f"{p:26s} " + "  ".join(f"{pl} {format_rate(*kn):<24s}" for pl, kn in d.items()))
        for t in (report.get("robust") or {}).get("targets", []):
            print(f"target {'met   ' if t['met'] else 'MISSED'} {t['target']}: {t['value']}")
        print(f"wrote {out / 'report.md'}")
    return 0
