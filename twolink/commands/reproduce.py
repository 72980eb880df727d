"""``twolink reproduce``: the paper's experiment end to end, beside the paper's figures.

Synthesises the centralized policy and the decentralized agents (both readings of agent
1's context) on the simplified model (11), runs them from x0 = [-1, -3, 0, 0] on the
simplified plant and on MuJoCo, prints the comparison table and writes the Fig. 3
counterpart under twolink-results/.
"""
from __future__ import annotations

import json
from pathlib import Path

from twolink.arm.parameters import HORIZON
from twolink.artifacts import check_outputs, staged_files, write_json
from twolink.commands import SUMMARIES
from twolink.resources import output_dir
from twolink.studies.reproduce.measure import (
    MAX_DURATION,
    PLANTS,
    check_duration,
    reproduce,
)
from twolink.studies.reproduce.table import table, verdict, verdict_block
from twolink.viz.plots import paper_fig3

_FIGURE_SUFFIXES = (".png", ".pdf", ".svg")


def add_parser(sub):
    p = sub.add_parser("reproduce", help=SUMMARIES["reproduce"],
                       description=__doc__.split("\n\n")[1].replace("\n", " "))
    p.add_argument("--duration", type=float, default=HORIZON,
                   help=f"rollout horizon in seconds (default {HORIZON:g}, at most "
                        f"{MAX_DURATION:g})")
    p.add_argument("--figure", type=Path, default=None,
                   help="Fig. 3 counterpart to write, .png, .pdf or .svg "
                        "(default twolink-results/fig3.png)")
    p.add_argument("--report", type=Path, default=None, help="also write the JSON report here")
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    return p


def run(args) -> int:
    check_duration(args.duration)
    default = output_dir(create=False)
    figure = args.figure or default / "fig3.png"
    if figure.suffix.lower() not in _FIGURE_SUFFIXES:
        raise ValueError(f"--figure {figure}: use a .png, .pdf or .svg file name")
    check_outputs({"--figure": figure, "--report": args.report}, creatable=[default])
    if figure.parent == default:
        output_dir()                         # the default folder, made on demand

    result = reproduce(args.duration, progress=not args.json)
    report = result.report()
    report["figure"] = str(figure)
    targets = [figure] + ([args.report] if args.report else [])
    with staged_files(targets) as temps:            # the figure and report, or neither
        paper_fig3(result.trajectories, temps[0], plants=PLANTS)
        if args.report:
            write_json(temps[1], report)
    if args.json:
        print(json.dumps(report, indent=2))
    else:
        print(table(report))
        print(verdict(report))
        print()
        print(verdict_block(report))
        print(f"\nwrote {figure}")
    return 0
