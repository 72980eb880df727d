"""Score the learners study's finished runs at the late horizon where their records lack it.

``python docs/studies/learners_late.py [--json renders/learners/learners.json]
[--work twolink-results/learners/runs]`` adds ``fresh_late`` (the fresh poses run for
:data:`twolink.studies.learners.measure.LATE_HORIZON` seconds: ``twolink evaluate AGENT
--links N --poses 256 --seed 4180000 --horizon 16``) to every run of the study's JSON
recorded before the study scored it, whose agent is still in its work folder
(``WORK/<run id>``, as ``twolink learners`` left it). Runs whose agent is gone keep no
such score and are listed. The JSON is rewritten (atomically) after each run, so an
interruption loses at most one score; a run that already has it is skipped. About 20 s a
run at six links on this machine.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from twolink.artifacts import read_runs, write_json  # noqa: E402
from twolink.studies.learners.measure import LATE_HORIZON, score_agent  # noqa: E402
from twolink.studies.learners.plan import FRESH_SEED, POSES, SCHEMA, VERSION, Run  # noqa: E402

DEFAULT_JSON = Path("renders/learners/learners.json")
DEFAULT_WORK = Path("twolink-results/learners/runs")


def agent_of(work: Path, run_id: str) -> Path | None:
    """The final agent of run ``run_id`` in ``work``, or None where it is gone."""
    try:
        record = json.loads((work / run_id / "curve.json").read_text())
        agent = work / run_id / record["agent"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return agent if agent.is_file() else None


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", type=Path, default=DEFAULT_JSON, help=f"default {DEFAULT_JSON}")
    ap.add_argument("--work", type=Path, default=DEFAULT_WORK,
                    help=f"the study's run folders (default {DEFAULT_WORK})")
    args = ap.parse_args(argv)
    try:
        if not args.json.is_file():
            raise ValueError(f"{args.json}: no such study file")
        data = read_runs(args.json, SCHEMA, VERSION)
    except ValueError as exc:
        print(f"learners_late: error: {exc}", file=sys.stderr)
        return 2
    scored, gone = 0, []
    for record in data["runs"]:
        if "fresh_late" in record:
            continue
        agent = agent_of(args.work, record["id"])
        if agent is None:
            gone.append(record["id"])
            continue
        run = Run(**record["run"])
        record["fresh_late"] = score_agent(agent, run, record["fresh"]["n"] or POSES,
                                           FRESH_SEED, horizon=LATE_HORIZON)
        write_json(args.json, data)
        scored += 1
        late = record["fresh_late"]
        print(f"{record['id']}: {record['fresh']['successes']}/{record['fresh']['n']} at "
              f"8 s, {late['successes']}/{late['n']} by {LATE_HORIZON:g} s", flush=True)
    print(json.dumps({"scored": scored, "agent_gone": gone}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
