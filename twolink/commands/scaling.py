"""``twolink scaling``: Table II extended to N = 2..6 links, both schemes, both link rules.

For every arm and scheme: Q-values, non-zeros of T, peak memory, synthesis time and
sweeps, and success with median settle time on MuJoCo from random poses at rest; the
centralized problem estimated first and refused over the memory cap. Writes scaling.md,
scaling.png and scaling.json under twolink-results/scaling/ (scaling-quick/ with --quick).
"""
from __future__ import annotations

import json
import math
from pathlib import Path

from twolink.arm.parameters import LINK_RULES, MAX_LINKS, MIN_LINKS
from twolink.artifacts import check_outputs
from twolink.commands import SUMMARIES
from twolink.resources import output_dir
from twolink.studies.scaling.measure import (
    DEFAULT_POSES,
    EVAL_SEED,
    MAX_POSES,
    QUICK_MAX_LINKS,
    QUICK_POSES,
    check_link_list,
    check_max_bytes,
    check_poses,
    check_rules,
    check_seed,
    default_max_bytes,
    machine_bytes,
    plan,
    scaling,
)
from twolink.studies.scaling.report import FILES, tables, write
from twolink.studies.scaling.synthesis import PEAK_METHODS


def add_parser(sub):
    p = sub.add_parser("scaling", help=SUMMARIES["scaling"],
                       description=__doc__.split("\n\n")[1].replace("\n", " "))
    p.add_argument("--quick", action="store_true",
                   help=f"N <= {QUICK_MAX_LINKS}, {QUICK_POSES} poses, no centralized "
                        f"synthesis beyond two links (under a minute on an idle 2-core machine)")
    p.add_argument("--links", type=int, nargs="+", metavar="N", default=None,
                   help=f"arm sizes, {MIN_LINKS} to {MAX_LINKS} (default all; "
                        f"{MIN_LINKS} to {QUICK_MAX_LINKS} with --quick)")
    p.add_argument("--rules", nargs="+", metavar="RULE", default=list(LINK_RULES),
                   help=f"how links beyond the second are made: {', '.join(LINK_RULES)} "
                        f"(default both)")
    p.add_argument("--poses", type=int, default=None,
                   help=f"random evaluation poses per arm, 1 to {MAX_POSES} (default "
                        f"{DEFAULT_POSES}, {QUICK_POSES} with --quick)")
    p.add_argument("--seed", type=int, default=EVAL_SEED,
                   help=f"evaluation seed; N links draw from SEED + N (default {EVAL_SEED}, "
                        f"never tuned on)")
    p.add_argument("--max-memory", type=float, default=None, metavar="GIB",
                   help="refuse a centralized synthesis whose estimated peak exceeds this "
                        "many GiB (default: twolink.synthesis.links_centralized.MAX_BYTES, from this "
                        "machine's memory)")
    p.add_argument("--peak", choices=PEAK_METHODS, default="process",
                   help="how peak memory is measured: a fresh process per synthesis "
                        "(default; resident-set growth) or tracemalloc in this process "
                        "(faster; numpy allocations only)")
    p.add_argument("-o", "--out", type=Path, default=None, metavar="DIR",
                   help="output folder (default twolink-results/scaling, or ...-quick)")
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    return p


def _max_bytes(gib) -> int:
    if gib is None:
        return check_max_bytes(default_max_bytes())
    if not math.isfinite(gib) or gib <= 0 or gib * 2**30 > machine_bytes():
        raise ValueError(f"--max-memory must be more than 0 and at most this machine's "
                         f"{machine_bytes() / 2**30:.1f} GiB, got {gib:g}")
    return check_max_bytes(int(gib * 2**30))


def _command(args) -> str:
    parts = ["twolink scaling"]
    if args.quick:
        parts.append("--quick")
    if args.links is not None:
        parts.append("--links " + " ".join(str(n) for n in args.links))
    if list(args.rules) != list(LINK_RULES):
        parts.append("--rules " + " ".join(args.rules))
    if args.poses is not None:
        parts.append(f"--poses {args.poses}")
    if args.seed != EVAL_SEED:
        parts.append(f"--seed {args.seed}")
    if args.max_memory is not None:
        parts.append(f"--max-memory {args.max_memory:g}")
    if args.peak != "process":
        parts.append(f"--peak {args.peak}")
    return " ".join(parts)


def run(args) -> int:
    if args.links is not None:                       # every check before any work
        check_link_list(args.links)
    check_rules(args.rules)
    if args.poses is not None:
        check_poses(args.poses)
    try:
        check_seed(args.seed)
    except ValueError as exc:                 # "seed must be ...": name the option
        raise ValueError(f"--{exc}") from None
    max_bytes = _max_bytes(args.max_memory)
    plan(args.links or [MIN_LINKS], args.rules, quick=args.quick)
    out = args.out or output_dir() / ("scaling-quick" if args.quick else "scaling")
    check_outputs({f"-o {name}": out / name for name in FILES.values()},
                  creatable=[out] if out.parent.is_dir() else [])
    result = scaling(args.links, args.rules, quick=args.quick, poses=args.poses,
                     seed=args.seed, max_bytes=max_bytes, peak=args.peak,
                     progress=not args.json)
    report = result.report()
    paths = write(report, out, _command(args))        # all three files or none
    if args.json:
        print(json.dumps(json.loads(paths["json"].read_text()), indent=2))
    else:
        print(tables(report))
        print(f"\nwrote {paths['markdown']}, {paths['figure'].name}, {paths['json'].name}")
    return 0
