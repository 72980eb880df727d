"""The levers of the tuned fuzzy designs, each measured on tuning seeds only.

``python docs/studies/fuzzy_design.py [--only LABEL ...] [--json FILE] [--markdown FILE]``
synthesises every variant of :data:`VARIANTS` on the full model (6) and scores it on
MuJoCo with :func:`twolink.sim.evaluation.evaluate` on states and plants that no reported
figure uses (:data:`twolink.policy.registry.TUNING_SEEDS`):

* nominal: 48 random poses at rest, ``random_poses(2, 48, seed=9301)``;
* ``medium`` and ``hard``: the first 32 of those poses on 8 plants of the level drawn from
  seed 9302 (its noise and faults too), plain and compensated.

Each cell is k/n with the 95 % Wilson interval and the median settle time (failures
never settle). The settle / T* column runs every variant nominally from the 64 states of a
tuning grid (:func:`ratio_grid`, built as the evaluation set's grid at other angles): the
median and worst settle time over the time-optimal limit T* of each state. Every shipped
design marked ``tuned`` in the registry was chosen from this table; the leaderboard
(``twolink leaderboard``) reports them on the evaluation set and its own seed. Beside the levers the package offers (``levels``, ``bins``,
``refine``, ``readout``) others that it does not ship are measured here as study-only
controllers: the expectation over the reading noise inside the transition model
(:func:`noise_expectation`), agents that know their torque is one sample late
(:func:`delay_aware`), per-agent grids (:func:`per_agent`), agent 2 as the worst case
over link 1's motion (:func:`agent2_worst_over_link1`), a hold region that zeroes a
joint's torque near the goal (:class:`Hold`), the same with hysteresis
(:class:`Hysteresis`), a one-step look-ahead on the model far from the goal
(:class:`LookAhead`) and the read-out's near-goal gain (the gains
``docs/studies/near_gain.py`` chose). About 15 minutes on two cores; ``--merge --only LABEL ...``
measures some variants again and puts them into an existing ``--json`` table.

This file is the command line only: the tuning set, the study-only controllers, the
variants, the measurement and the table are the package's
:mod:`twolink.studies.fuzzy_design`, under its layer contract and size rule.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from twolink.policy.registry import TUNING_SEEDS  # noqa: E402
from twolink.studies.fuzzy_design.measure import measure  # noqa: E402
from twolink.studies.fuzzy_design.table import markdown  # noqa: E402
from twolink.studies.fuzzy_design.tuning_set import POSES  # noqa: E402
from twolink.studies.fuzzy_design.variants import VARIANTS  # noqa: E402


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--only", nargs="+", default=None, choices=list(VARIANTS),
                        metavar="LABEL")
    parser.add_argument("--json", type=Path, default=None)
    parser.add_argument("--merge", action="store_true",
                        help="measure the --only variants and put their rows into the --json "
                             "file's table (kept in the order of VARIANTS)")
    parser.add_argument("--markdown", type=Path, default=None)
    args = parser.parse_args(argv)
    if args.merge and (args.json is None or not args.json.is_file() or not args.only):
        parser.error("--merge needs --only and an existing --json file")
    kept = json.loads(args.json.read_text())["rows"] if args.merge else []
    rows = []
    for k, label in enumerate(args.only or VARIANTS, 1):
        rows.append(measure(label))
        print(f"[{k}/{len(args.only or VARIANTS)}] {label}: nominal "
              f"{rows[-1]['none']['successes']}/{rows[-1]['none']['n']}", file=sys.stderr,
              flush=True)
    if args.merge:
        new = {r["variant"]: r for r in rows}
        old = {r["variant"]: r for r in kept if r["variant"] in VARIANTS}
        rows = [new.get(label) or old[label] for label in VARIANTS if label in new or label in old]
    table = markdown(rows)
    print(table)
    if args.json:
        args.json.write_text(json.dumps({"poses": len(POSES), "seeds": list(TUNING_SEEDS),
                                         "rows": rows}, indent=2))
    if args.markdown:
        args.markdown.write_text(table + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
