"""``twolink mismatch``: measure the model mismatch, its closure and robustness; write a report.

Open-loop error of (11) and (6) against MuJoCo, the closed-loop gap of every policy on
every plant, the policies synthesised on (6), and robustness sweeps on MuJoCo, written
as Markdown + JSON + figures under renders/mismatch/ (renders/mismatch-quick/ with --quick).
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

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
    p.add_argument("--json", action="store_true",
                   help="print success rates, open-loop errors and margins as JSON")
    return p


def run(args) -> int:
    chosen = plan(args.plan)
    if args.workers is not None and args.workers < 1:
        raise ValueError(f"--workers must be at least 1, got {args.workers}")
    if args.address and args.executor != "ray":
        raise ValueError("--address needs --executor ray")
    for name in args.policies:                       # fail before anything is written
        load_policy(name)
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
                             if progress else None, progress=progress)
        command = "twolink mismatch" + ("" if chosen.name == "full" else f" --plan {chosen.name}")
        report = write(report, data, out, command)
    if args.json:
        print(json.dumps(summary(report), indent=2))
    else:
        for p, d in summary(report)["successes"].items():
            print(f"{p:26s} " + "  ".join(f"{pl} {format_rate(*kn):<24s}" for pl, kn in d.items()))
        print(f"wrote {out / 'report.md'}")
    return 0
