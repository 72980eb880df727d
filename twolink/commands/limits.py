"""``twolink limits``: the physical limit T*(x), the fewest samples in which any admissible
torque sequence brings the arm into the goal band to stay (twolink.limits).

Without states it prints the shipped table of the 65 evaluation states (``data/limits.json``,
no CasADi needed); ``--x0`` or ``--evaluation-set`` computes (CasADi and IPOPT: ``pip install
'twolink[limits]'``), and ``-o/--out FILE`` saves what was computed in the shipped format
(``twolink limits --evaluation-set --ship`` re-creates the shipped file; ``-o`` never
writes into the package or its shipped data). The solver is silent unless ``--verbose``;
Ctrl-C stops a computation within an IPOPT iteration and writes nothing.
"""
from __future__ import annotations

import json
import sys
import time
from pathlib import Path

from twolink.commands import SUMMARIES
from twolink.commands.grammar import deprecated
from twolink.commands._options import X0_HELP

MODEL_CHOICES = ("full", "simplified", "both")


def add_parser(sub):
    p = sub.add_parser("limits", help=SUMMARIES["limits"],
                       description="The physical limit T*(x): the fewest samples of Ts in "
                                   "which admissible zero-order-hold torques (|tau_i| <= "
                                   "tau_max_i, speeds within 2 pi rad/s) bring the arm from x "
                                   "into the goal band to stay, on the full model (6)-(8) and "
                                   "the simplified model (11): a lower bound (the reach NLP "
                                   "infeasible one sample earlier from every start) and an "
                                   "upper bound (a sequence replayed on the numpy model). "
                                   "Prints the shipped table of the 65 evaluation states "
                                   "unless states are given.")
    p.add_argument("--model", choices=MODEL_CHOICES, default="both",
                   help="full (6)-(8), simplified (11) or both (default)")
    p.add_argument("--x0", nargs="+", action="append", metavar="X",
                   help=f"compute the limit of this state (repeat for more); {X0_HELP}")
    p.add_argument("--degrees", action="store_true",
                   help="read --x0 angles in degrees and speeds in deg/s")
    p.add_argument("--evaluation-set", action="store_true",
                   help="compute the 65 evaluation states (twolink.sim.metrics.evaluation_set)")
    p.add_argument("--json", action="store_true", help="print JSON instead of the table")
    p.add_argument("-o", "--out", dest="write", type=Path, default=None, metavar="FILE",
                   help="write the computed tables with their provenance to FILE (the "
                        "format of the shipped data/limits.json)")
    p.add_argument("--ship", action="store_true",
                   help="write the computed tables over the shipped data/limits.json (the "
                        "only way to write into the package's data)")
    deprecated(p, "limits", "--write", "-o/--out", dest="write", type=Path)
    p.add_argument("--verbose", action="store_true",
                   help="let IPOPT and CasADi print their iterations and warnings")
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="worker processes (default: one per CPU)")
    p.add_argument("--starts", type=int, default=None, metavar="N",
                   help="initial guesses per winding at N - 1 (default 3)")
    p.add_argument("--max-samples", type=int, default=None, metavar="N",
                   help="largest N tried (default 60, at most 100)")
    p.add_argument("--windings", choices=("all", "nearest"), default="all",
                   help="the bands tried: around 0 and 2 pi k of each angle (all, the "
                        "default) or around 0 of the wrapped angles only (nearest)")
    p.add_argument("--no-mujoco", action="store_true",
                   help="do not replay the torques on the MuJoCo plant")
    p.add_argument("--seed", type=int, default=0, help="seed of --x0 random")
    return p


def _states(args):
    import numpy as np

    from twolink.commands._options import parse_x0, seed_option
    from twolink.sim.metrics import evaluation_set

    seed_option(args.seed)
    rows = [parse_x0(words, degrees=args.degrees, seed=args.seed) for words in args.x0 or ()]
    if args.evaluation_set:
        rows += list(evaluation_set())
    return np.array(rows, float).reshape(-1, 4) if rows else None


def _command_line(args) -> str:
    """The command that computes these tables again (for the provenance)."""
    words = ["twolink", "limits", "--model", args.model]
    for x0 in args.x0 or ():
        words += ["--x0", *x0]
    if args.windings != "all":
        words += ["--windings", args.windings]
    flags = (("--degrees", args.degrees), ("--evaluation-set", args.evaluation_set),
             ("--no-mujoco", args.no_mujoco))
    words += [flag for flag, on in flags if on]
    for flag, value in (("--starts", args.starts), ("--max-samples", args.max_samples),
                        ("--seed", args.seed if args.x0 else None)):
        if value is not None:
            words += [flag, str(value)]
    if args.write is not None:
        words += ["-o", str(args.write)]
    if args.ship:
        words += ["--ship"]
    return " ".join(words)


def _printable(tables: dict, provenance: dict) -> dict:
    """The JSON of the tables without the torque sequences."""
    out = {"provenance": provenance, "models": {}}
    for model, table in tables.items():
        d = table.to_dict()
        for row in d["rows"]:
            row.pop("torques", None)
        out["models"][model] = d
    return out


def run(args) -> int:
    from twolink.artifacts import check_outputs, write_text
    from twolink import limits as to

    models = list(to.MODELS) if args.model == "both" else [args.model]
    states = _states(args)
    if args.ship and args.write is not None:
        raise ValueError("--ship writes the shipped data/limits.json; give no -o/--out")
    if args.ship:
        from twolink.resources import limits_file
        args.write = limits_file()
    if states is None:
        if args.write is not None:
            raise ValueError(f"{'--ship' if args.ship else '-o/--out'} saves computed tables: "
                             f"give --x0 or --evaluation-set")
        shipped = to.shipped_tables()
        tables = {m: shipped[m] for m in models}
        provenance = dict(next(iter(tables.values())).provenance)
        source = "shipped data/limits.json"
    else:
        if args.write is not None:
            check_outputs({"--ship" if args.ship else "-o/--out": args.write}, ship=args.ship)
        options = {k: v for k, v in (("starts", args.starts),
                                     ("max_samples", args.max_samples)) if v is not None}
        t0 = time.perf_counter()
        tables = {}
        for m in models:
            print(f"limits: solving {len(states)} state{'s' * (len(states) != 1)} on the "
                  f"{m} model", file=sys.stderr, flush=True)
            tables[m] = to.limit_table(states, m, workers=args.workers,
                                       mujoco=not args.no_mujoco, windings=args.windings,
                                       verbose=args.verbose, **options)
        provenance = {**to.provenance(), "command": _command_line(args),
                      "time_s": round(time.perf_counter() - t0, 2),
                      "time_s_by_model": {m: t.provenance.get("time_s") for m, t in
                                          tables.items()}}
        source = "computed"
        if args.write is not None:
            write_text(args.write, to.tables_to_json(list(tables.values()), provenance))
    if args.json:
        print(json.dumps(_printable(tables, provenance), indent=1, sort_keys=True,
                         allow_nan=False))
    else:
        print(f"T*(x) in samples of Ts = 0.05 s ({source}; N = lower..upper where they "
              f"differ; wind: the band reached around 2 pi k; mujoco: settle time of the "
              f"torques replayed open loop on MuJoCo)")
        print(to.format_table(tables))
        if args.write is not None:
            print(f"wrote {args.write}")
    return 0
