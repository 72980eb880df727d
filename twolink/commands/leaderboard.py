"""``twolink leaderboard``: every controller under every challenge level, in one table.

By default the benchmark rows of the controller catalogue (its tag benchmark: the paper's
three policies, the best fuzzy design of each kind, the five classical baselines and the
learned agents ppo_medium and ppo_hard, trained for those levels, where their files and
Stable-Baselines3 are there); --tag T the
entries of another tag, --all every two-link entry, and --controller (repeatable; with
--only, instead of the benchmark rows) any controller of yours (module:callable, path/to/file.py:callable, a policy .npz or an
SB3 agent .zip). Each runs under the levels none, easy, medium and hard, plain and (for
controllers that name their model) compensated, on MuJoCo from the 65 states of the
evaluation set: k/n with the 95 % Wilson interval, the worst plant, the median settle
time, settle / T* (median and worst, failures as never settled) and the mean torque, ranked
per level and mode by one rule (success, ties within overlapping Wilson intervals broken by
median settle / T*); for a shipped learned agent, what learning it cost (every seed
trained: env steps, CPU and wall time). Writes Markdown, JSON and a figure into twolink-results/leaderboard
($TWOLINK_OUTPUT, or --out); prints a compact table, or for --controller and --merge where
each ranks. --from-json re-renders a saved report without measuring. With --executor ray
the rows run as tasks on a Ray cluster, with the same numbers as a local run.
"""
from __future__ import annotations

import contextlib
import json
import sys
from pathlib import Path

from twolink.commands import SUMMARIES
from twolink.commands.grammar import deprecated
from twolink.sim.challenges import LEVELS

#: --quick: every 13th state of the evaluation set, 4 plants, levels none and medium.
QUICK = {"states": "quick", "plants": 4, "levels": ("none", "medium")}
#: The catalogue tag of the default rows.
DEFAULT_TAG = "benchmark"


def add_parser(sub):
    p = sub.add_parser("leaderboard", help=SUMMARIES["leaderboard"],
                       description=" ".join(__doc__.replace("``", "").split("\n\n")[1].split()))
    which = p.add_mutually_exclusive_group()
    which.add_argument("--only", action="store_const", const=[], dest="controllers",
                       default=None,
                       help="run only the --controller values (default: the catalogue's "
                            "benchmark tag, `twolink controllers --tag benchmark`, beside "
                            "them; no folder is searched for .zip agents)")
    which.add_argument("--tag", default=None, metavar="TAG",
                       help="the two-link catalogue entries with this tag (paper, benchmark, "
                            "baseline, tuned, fuzzy, learned, user or one of your catalogue)")
    which.add_argument("--all", action="store_true",
                       help="every two-link catalogue entry (every shipped two-link policy, "
                            "baseline and learned agent, and those of your catalogue)")
    deprecated(p, "leaderboard", "--controllers", "--only --controller NAME (repeatable)",
               dest="controllers", nargs="+")
    p.add_argument("--controller", action="append", default=[], metavar="SPEC",
                   help="add a controller: module:callable, path/to/file.py:callable, a "
                        "policy .npz or an SB3 agent .zip (repeatable); the output says "
                        "where it ranks")
    p.add_argument("--levels", nargs="+", default=None, metavar="LEVEL",
                   help=f"challenge levels (default: {' '.join(LEVELS)})")
    p.add_argument("--plants", type=int, default=None, metavar="K",
                   help="plants per level that perturbs the plant (default 32; 4 with "
                        "--quick)")
    p.add_argument("--seed", type=int, default=None, metavar="S",
                   help="seed of the plants, noise and faults (default: the leaderboard's, "
                        "never tuned on)")
    p.add_argument("--quick", action="store_true",
                   help="5 states, 4 plants, levels none and medium: about a minute")
    p.add_argument("--timeout", type=float, default=None, metavar="SECONDS",
                   help="end the run (exit status 2) when one call of a controller takes "
                        "longer than this (default: no limit)")
    p.add_argument("--worst-case", action="store_true",
                   help="also run every row of a perturbing level on the level's grid of "
                        "plants (its parameter box's centre and 24 corners, "
                        "twolink.sim.plant_grid): a grid column with the worst plant "
                        "(about doubles the time)")
    p.add_argument("-o", "--out", type=Path, default=None, metavar="DIR",
                   help="folder of leaderboard.md, .json and .png (default "
                        "leaderboard, or leaderboard-quick, in twolink-results/ or "
                        "$TWOLINK_OUTPUT)")
    p.add_argument("--executor", choices=("local", "ray"), default="local",
                   help="where the rows run: this process (local, the default) or tasks on "
                        "Ray (the same numbers; a controller file must exist at the same "
                        "path on every Ray node)")
    p.add_argument("--address", default=None,
                   help="Ray cluster address, HOST:PORT or ray://HOST:PORT (with --executor "
                        "ray; default: a new local Ray)")
    p.add_argument("--merge", action="store_true",
                   help="run only the given controllers with the settings of the leaderboard "
                        "saved in --out and put their rows into it (replacing theirs), "
                        "keeping every other row")
    p.add_argument("--from-json", type=Path, default=None, metavar="FILE",
                   help="measure nothing: re-render the saved leaderboard.json FILE, writing "
                        "leaderboard.md and leaderboard.png into --out (default FILE's folder)")
    p.add_argument("--no-save", action="store_true", help="only print")
    p.add_argument("--table", action="store_true",
                   help="print the whole table (every row with k/n and intervals)")
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    return p


def chosen_specs(names, specs, *, tag: str | None = None, every: bool = False) -> list:
    """The specs a leaderboard runs: ``names``, else the two-link catalogue entries of
    ``tag`` (default :data:`DEFAULT_TAG`), or every two-link entry with ``every``; then
    the extra ``specs``. A shipped learned agent runs only where its file exists and
    Stable-Baselines3 imports (:func:`twolink.control.learned.default_learned_agents`),
    and not twice when ``specs`` names its file; no folder's ``*.zip`` is loaded
    unnamed."""
    from twolink.control.catalogue import entries
    from twolink.control.learned import LEARNED_AGENTS, default_learned_agents

    if names is not None:
        return [*names, *specs]
    found = [e.name for e in entries(tag=None if every else (tag or DEFAULT_TAG), links=2)]
    present = set(default_learned_agents(exclude=specs))
    return [*(n for n in found if n not in LEARNED_AGENTS or n in present), *specs]


def controllers_of(names, specs, *, tag=None, every=False) -> dict:
    """``{label: checked controller}`` of the chosen names and the extra specs (a
    catalogue name, or the ``name`` of the object a spec makes)."""
    from twolink.control.controllers import resolve_controller

    out = {}
    for spec in chosen_specs(names, specs, tag=tag, every=every):
        c = resolve_controller(spec)
        if c.name in out:
            raise ValueError(f"two controllers are labelled {c.name!r}; give each once")
        out[c.name] = c
    if not out:
        raise ValueError("no controllers to run")
    return out


def _default_out(args) -> Path:
    from twolink.resources import output_dir

    return output_dir(create=False) / ("leaderboard-quick" if args.quick else "leaderboard")


def run(args) -> int:
    from twolink.sim.cells import states_of
    from twolink.sim.challenges import challenge
    from twolink.sim.controller import check_timeout
    from twolink.studies.leaderboard.limits import state_limits
    from twolink.studies.leaderboard.measure import SEED

    if args.from_json is not None:
        return _rerender(args)
    check_timeout(args.timeout, "--timeout")
    states = QUICK["states"] if args.quick else "full"
    plants = args.plants if args.plants is not None else (QUICK["plants"] if args.quick else 32)
    if not 1 <= plants <= 10_000:
        raise ValueError(f"--plants must be from 1 to 10000, got {plants}")
    seed = SEED if args.seed is None else args.seed
    if not 0 <= seed < 2**63:
        raise ValueError(f"--seed must be a whole number from 0 to 2**63 - 1, got {seed}")
    saved = _saved(args)
    if saved is not None:
        plants, seed = saved["plants"], saved["seed"]
    levels = args.levels or (saved["levels"] if saved is not None else
                             QUICK["levels"] if args.quick else tuple(LEVELS))
    levels = [challenge(n).name for n in levels]
    if args.address is not None and args.executor != "ray":
        raise ValueError("--address needs --executor ray")
    # --merge runs only the controllers given (--controller alone: just those).
    names = [] if args.merge and args.controllers is None and args.tag is None \
        and not args.all else args.controllers
    controllers = controllers_of(names, args.controller, tag=args.tag, every=args.all)
    specs = dict(zip(controllers, chosen_specs(names, args.controller, tag=args.tag,
                                               every=args.all)))
    x0 = states_of(states)
    limits, source = state_limits(x0)
    if limits is None:
        raise ValueError(f"no time-optimal limit for these states ({source})")
    if saved is not None:            # refused before any measurement
        from twolink.studies.leaderboard.merge import check_joinable
        check_joinable(saved, {"states": len(x0), "plants": plants, "seed": seed,
                               "horizon": 5.0, "limits": source}, levels)
    # The controllers whose standing is printed: those merged, or the --controller ones.
    n_extra = len(args.controller)
    focus = list(controllers) if saved is not None else \
        (list(controllers)[-n_extra:] if n_extra else [])
    # Ray is connected before any file is made: an address that does not answer leaves none.
    with _ray(args):
        return _measure_and_write(args, controllers, specs, x0, limits, source, levels,
                                  plants, seed, saved, focus)


def _saved(args):
    """The saved report --merge adds to (None without --merge), checked before any work."""
    if not args.merge:
        return None
    from twolink.studies.leaderboard.merge import saved_report

    if args.no_save:
        raise ValueError("--merge writes into the saved leaderboard; give no --no-save")
    if args.controllers is None and args.tag is None and not args.all and not args.controller:
        raise ValueError("--merge needs the controllers to add: --controller NAME (repeatable)")
    if args.plants is not None or args.seed is not None:
        raise ValueError("--merge takes the saved leaderboard's plants and seed; give no "
                         "--plants or --seed")
    return saved_report((args.out or _default_out(args)) / "leaderboard.json")


def _ray(args):
    """The Ray session of ``--executor ray`` (a null context for local)."""
    if args.executor != "ray":
        return contextlib.nullcontext()
    from twolink.sim.cells import ray_session

    return ray_session(args.address, None, "--address")


def _rerender(args) -> int:
    """--from-json: the saved report re-rendered (Markdown and figure), nothing measured."""
    from twolink.artifacts import check_outputs
    from twolink.studies.leaderboard.merge import saved_report
    from twolink.studies.leaderboard.report import FILES, write

    given = [o for o, v in (("--merge", args.merge), ("--only", args.controllers),
                            ("--controller", args.controller), ("--tag", args.tag),
                            ("--all", args.all), ("--levels", args.levels),
                            ("--plants", args.plants), ("--seed", args.seed),
                            ("--quick", args.quick), ("--timeout", args.timeout),
                            ("--worst-case", args.worst_case),
                            ("--address", args.address)) if v]
    if given:
        raise ValueError(f"--from-json measures nothing; give no {', '.join(given)}")
    report = saved_report(args.from_json)
    paths = None
    if not args.no_save:
        out = args.out or args.from_json.parent
        if out.exists() and not out.is_dir():
            raise OSError(f"--out {out} is a file; give a folder")
        files = ("markdown", "figure")
        check_outputs({k: out / FILES[k] for k in files}, creatable=[out])
        paths = write(report, out, files=files)
    _print(args, report, [], paths)
    return 0


def _print(args, report, focus, paths) -> None:
    """The command's output: JSON, the whole table (--table), where each ``focus``
    controller ranks, or the compact table; then the files written."""
    from twolink.studies.leaderboard.ranking import RULE
    from twolink.studies.leaderboard.report import compact, markdown, standing_lines

    if args.json:
        print(json.dumps(report, indent=2))
        return
    if args.table:
        print(markdown(report))
    elif focus:
        for name in focus:
            print("\n".join(standing_lines(report, name)))
        print(RULE)
        print("The whole table: --table (or --json), or the files below.")
    else:
        print(compact(report, code=False))
        print("\n" + RULE)
    if paths:
        print("wrote " + ", ".join(str(p) if i == 0 else p.name
                                   for i, p in enumerate(paths.values())))


def _measure_and_write(args, controllers, specs, x0, limits, source, levels, plants,
                       seed, saved=None, focus=()) -> int:
    """Run the rows and write or print the report (outputs checked first)."""
    from twolink.artifacts import check_outputs
    from twolink.resources import output_dir
    from twolink.studies.leaderboard.measure import run as measure
    from twolink.studies.leaderboard.report import FILES, write

    out = None
    if not args.no_save:
        out = args.out or output_dir() / _default_out(args).name
        if out.exists() and not out.is_dir():
            raise OSError(f"--out {out} is a file; give a folder")
        check_outputs({name: out / f for name, f in FILES.items()}, creatable=[out])
    command = "twolink leaderboard" + (" --quick" if args.quick else "")
    log = None if args.json else (lambda line: print(line, file=sys.stderr, flush=True))
    rows = measure(controllers, x0, limits, levels=levels, plants=plants, seed=seed, log=log,
                   executor=args.executor, address=args.address, specs=specs,
                   timeout=args.timeout, worst_case=args.worst_case)
    report = {"command": command, "states": len(x0), "plants": plants, "seed": seed,
              "horizon": 5.0, "limits": source, "levels": levels,
              "rows": [r.as_dict() for r in rows]}
    from twolink.control.learned import learning_cost

    learning = {name: cost for name in controllers if (cost := learning_cost(name))}
    if learning:
        report["learning"] = learning
    if saved is not None:
        from twolink.studies.leaderboard.merge import merged
        report = merged(saved, report)
    paths = None
    if out is not None:              # all three files or none (staged, then moved in)
        paths = write(report, out)
    _print(args, report, focus, paths)
    return 0
