"""``twolink controllers``: the controller catalogue, the one list of named controllers.

Every name the other commands take (``evaluate NAME``, ``leaderboard --controller NAME``,
``rollout --controller NAME``) is an entry here: the shipped fuzzy policies, the
classical baselines, the shipped learned agents, and the entries of your catalogue files
(--catalogue FILE or the TWOLINK_CATALOGUE variable). Filter by --tag and --links;
--json prints the entries with their entry points and data.
"""
from __future__ import annotations

import json

from twolink.commands import SUMMARIES


def add_parser(sub):
    p = sub.add_parser("controllers", help=SUMMARIES["controllers"],
                       description=" ".join(__doc__.replace("``", "").split("\n\n")[1].split()))
    p.add_argument("--tag", metavar="TAG",
                   help="only entries with this tag (paper, benchmark, baseline, tuned, "
                        "fuzzy, learned, n-link, user, or a tag of your catalogue)")
    p.add_argument("--links", type=int, metavar="N", help="only controllers of N-link arms")
    p.add_argument("--catalogue", action="append", default=[], metavar="FILE",
                   help="a catalogue file of your own (JSON; repeatable; see the controllers "
                        "guide), read after the shipped entries")
    p.add_argument("--json", action="store_true", help="print the entries as JSON")
    return p


def _table(entries, width: int = 60) -> str:
    rows = [("name", "kind", "links", "tags", "what it is")]
    for e in entries:
        text = " ".join(e.description.split())
        rows.append((e.name, e.kind, str(e.links), ",".join(e.tags),
                     text if len(text) <= width else text[:width - 3] + "..."))
    w = [max(len(r[i]) for r in rows) for i in range(4)]
    lines = [f"{a:<{w[0]}}  {b:<{w[1]}}  {c:>{w[2]}}  {d:<{w[3]}}  {e}" for a, b, c, d, e in rows]
    lines.insert(1, "-" * len(lines[0]))
    return "\n".join(lines)


def run(args) -> int:
    from twolink.control.catalogue import TAGS, entries

    if args.links is not None and not 2 <= args.links <= 12:
        raise ValueError(f"--links must be in [2, 12], got {args.links}")
    found = entries(tag=args.tag, links=args.links, files=args.catalogue)
    if args.json:
        print(json.dumps({"controllers": [e.as_dict() for e in found], "tags": TAGS},
                         indent=2))
        return 0
    print(_table(found))
    shown = sorted({t for e in found for t in e.tags})
    print(f"\n{len(found)} controllers. Tags: " + "; ".join(
        f"{t}: {TAGS.get(t, 'your own')}" for t in shown) + ".")
    return 0
