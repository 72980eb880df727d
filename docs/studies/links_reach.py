"""Which N-link poses any controller could settle within the scaling table's 8 s.

``python docs/studies/links_reach.py --links N [--rule tapered|copied] [--poses K]
[--json FILE]`` asks :func:`twolink.limits.links.reach` of the first K poses
of the scaling table's evaluation set (``random_poses(N, 256, 20061122 + N)``) whether
admissible torques bring the arm to rest in the goal band by 7 s (140 samples: settled
1 s before the end of 8 s, the table's success rule), and merges the answers into the
JSON file (one run per arm). It resumes: poses already answered in the file are kept and
only the missing ones up to K are solved, ``--chunk`` poses at a time, the file rewritten
(atomically) after each chunk, so an interrupted run loses at most one chunk. The
count of reachable poses is a lower bound on the ceiling of every controller's success
rate at that N (IPOPT is a local solver). The docs generator writes the result into
``docs/results/scaling.md``. About 25 s per pose at six links on this machine;
``--workers W`` shares the poses among W processes.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from twolink.arm.parameters import LINK_RULES, TS, links_parameters  # noqa: E402
from twolink.artifacts import provenance, read_runs, write_json  # noqa: E402
from twolink.limits import casadi_version  # noqa: E402
from twolink.limits.links import HOLD, NLP_SUBSTEPS, reach_all  # noqa: E402
from twolink.sim.metrics import random_poses, wilson_interval  # noqa: E402
from twolink.validate import whole  # noqa: E402

SCHEMA, VERSION = "twolink.links_reach", 1
#: The scaling table's poses: 256 per arm from this seed plus N.
POSE_SEED, POSES = 20061122, 256
#: 7 s: settled 1 s before the end of the scaling table's 8 s horizon.
DEADLINE = 140
DEFAULT_JSON = Path("renders/links_reach/reach.json")


def _chunk(links: int, rule: str, rows: list) -> list:
    """:func:`reach_all` of the poses ``rows`` of the table's set (a worker's share)."""
    x0 = random_poses(links, POSES, POSE_SEED + links)[rows]

    def report(i, r):
        print(f"  pose {rows[i] + 1}: {'reachable' if r.reachable else 'not found'} "
              f"({r.status}, defect {r.defect:.1e}, {r.seconds:.0f} s)", flush=True)

    return reach_all(links_parameters(links, rule), x0, DEADLINE, on_pose=report)


def measure(links: int, rule: str, rows: list, workers: int = 1) -> list:
    """The reach answers (dicts) of the poses ``rows`` of the table's set, in ``workers``
    processes (each takes every ``workers``-th of them)."""
    shares = [rows[w::workers] for w in range(min(workers, len(rows)))]
    if len(shares) == 1:
        parts = [_chunk(links, rule, shares[0])]
    else:
        from concurrent.futures import ProcessPoolExecutor

        with ProcessPoolExecutor(len(shares)) as pool:
            parts = list(pool.map(_chunk, [links] * len(shares), [rule] * len(shares), shares))
    answers = dict()
    for share, part in zip(shares, parts):
        for i, a in zip(share, part):
            answers[i] = a.as_dict()
    return [answers[i] for i in rows]


def summary(links: int, rule: str, answers: list, seconds: float) -> dict:
    """The run of an arm: its answers for the first ``len(answers)`` poses, the count of
    reachable ones with its Wilson interval, and the seconds spent on them in all."""
    k = sum(bool(a["reachable"]) for a in answers)
    low, high = wilson_interval(k, len(answers))
    return {"links": links, "rule": rule, "poses": len(answers), "reachable": k,
            "wilson95": [low, high], "deadline_s": DEADLINE * TS, "hold": HOLD,
            "substeps": NLP_SUBSTEPS, "seconds": round(seconds, 1), "answers": answers}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--links", type=int, required=True, help="links N, 3 to 6")
    ap.add_argument("--rule", choices=LINK_RULES, default="tapered")
    ap.add_argument("--poses", type=int, default=16,
                    help=f"the first K poses of the {POSES} of the scaling table (default 16)")
    ap.add_argument("--workers", type=int, default=1, help="processes (default 1)")
    ap.add_argument("--chunk", type=int, default=8,
                    help="poses measured between two writes of the JSON (default 8)")
    ap.add_argument("--json", type=Path, default=DEFAULT_JSON, help=f"default {DEFAULT_JSON}")
    args = ap.parse_args(argv)
    try:
        whole(args.links, "--links", 3, 6)
        whole(args.poses, "--poses", 1, POSES)
        whole(args.workers, "--workers", 1, 64)
        whole(args.chunk, "--chunk", 1, POSES)
        if casadi_version() is None:
            raise ValueError("this study needs CasADi: pip install 'twolink[limits]'")
        data = read_runs(args.json, SCHEMA, VERSION)
    except ValueError as exc:
        print(f"links_reach: error: {exc}", file=sys.stderr)
        return 2
    mine = [r for r in data["runs"] if (r["links"], r["rule"]) == (args.links, args.rule)]
    done = list(mine[0]["answers"]) if mine else []
    spent = float(mine[0]["seconds"]) if mine else 0.0
    print(f"{args.links} {args.rule} links: poses 1-{args.poses}, {min(len(done), args.poses)} "
          f"answered already, deadline {DEADLINE * TS:g} s, {args.chunk} poses a chunk",
          flush=True)
    while len(done) < args.poses:        # each chunk is written before the next begins
        rows = list(range(len(done), min(len(done) + args.chunk, args.poses)))
        t0 = time.perf_counter()
        done += measure(args.links, args.rule, rows, args.workers)
        spent += time.perf_counter() - t0
        run = summary(args.links, args.rule, done, spent)
        runs = [r for r in data["runs"] if (r["links"], r["rule"]) != (args.links, args.rule)]
        data["runs"] = sorted([*runs, run], key=lambda r: (r["rule"], r["links"]))
        args.json.parent.mkdir(parents=True, exist_ok=True)
        write_json(args.json, {"schema": SCHEMA, "version": VERSION, "runs": data["runs"],
                               "casadi": casadi_version(), "provenance": provenance()})
        print(f"  wrote {args.json}: {run['reachable']}/{run['poses']} reachable", flush=True)
    run = summary(args.links, args.rule, done, spent)
    print(json.dumps({k: v for k, v in run.items() if k != "answers"}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
