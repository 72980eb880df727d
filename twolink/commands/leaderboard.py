"""``twolink leaderboard``: every controller under every challenge level, in one table.

The shipped fuzzy policies, the classical baselines, the learned agents shipped by name
(ppo_seed0, where its file and Stable-Baselines3 are there) and any --controller of yours
(module:callable, path/to/file.py:callable, a policy .npz or an SB3 agent .zip), under
the levels none, easy, medium and hard, plain and (for controllers that name their
model) compensated, on MuJoCo from the 65 states of the evaluation set: k/n with the
95 % Wilson interval, the worst plant, the median settle time, settle / T* (median and
worst, failures as never settled) and the mean torque. Writes Markdown, JSON and a
figure (success against settle / T*). With --executor ray the rows run as tasks on a Ray
cluster (--address, or a new local Ray), with the same numbers as a local run.
"""
from __future__ import annotations

import contextlib
import json
import sys
from pathlib import Path

from twolink.commands import SUMMARIES
from twolink.sim.challenges import LEVELS

#: --quick: every 13th state of the evaluation set, 4 plants, levels none and medium.
QUICK = {"states": "quick", "plants": 4, "levels": ("none", "medium")}


def add_parser(sub):
    p = sub.add_parser("leaderboard", help=SUMMARIES["leaderboard"],
                       description=" ".join(__doc__.replace("``", "").split("\n\n")[1].split()))
    p.add_argument("--controllers", nargs="+", default=None, metavar="NAME",
                   help="which controllers (default: every shipped two-link policy, "
                        "every baseline and the shipped learned agents such as ppo_seed0; "
                        "no folder is searched for .zip agents)")
    p.add_argument("--controller", action="append", default=[], metavar="SPEC",
                   help="add a controller: module:callable, path/to/file.py:callable, a "
                        "policy .npz or an SB3 agent .zip (repeatable)")
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
    p.add_argument("--out", type=Path, default=None, metavar="DIR",
                   help="folder of leaderboard.md, .json and .png (default "
                        "renders/leaderboard, or renders/leaderboard-quick)")
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
    p.add_argument("--no-save", action="store_true", help="only print the table")
    p.add_argument("--json", action="store_true", help="print the rows as JSON")
    return p


def chosen_specs(names, specs) -> list:
    """The specs a leaderboard runs: ``names`` (default every shipped two-link policy,
    every baseline and the shipped learned agents whose file exists where
    Stable-Baselines3 imports, :func:`twolink.control.learned.default_learned_agents`; no
    folder's ``*.zip`` is loaded unnamed), then the extra ``specs`` (an agent already among
    the defaults is not added twice)."""
    from twolink.control.controllers import baseline_names
    from twolink.control.learned import default_learned_agents
    from twolink.policy.registry import TWO_LINK

    if names is not None:
        return [*names, *specs]
    return [*TWO_LINK, *baseline_names(), *default_learned_agents(exclude=specs), *specs]


def controllers_of(names, specs) -> dict:
    """``{label: checked controller}`` of the chosen names and the extra specs."""
    from twolink.control.controllers import resolve_controller

    out = {}
    for spec in chosen_specs(names, specs):
        c = resolve_controller(spec)
        if c.name in out:
            raise ValueError(f"two controllers are labelled {c.name!r}; give each once")
        out[c.name] = c
    if not out:
        raise ValueError("no controllers to run")
    return out


def run(args) -> int:
    from twolink.sim.cells import states_of
    from twolink.sim.challenges import challenge
    from twolink.studies.leaderboard.limits import state_limits
    from twolink.studies.leaderboard.measure import SEED

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
    names = [] if args.merge and args.controllers is None else args.controllers
    controllers = controllers_of(names, args.controller)
    specs = dict(zip(controllers, chosen_specs(names, args.controller)))
    x0 = states_of(states)
    limits, source = state_limits(x0)
    if limits is None:
        raise ValueError(f"no time-optimal limit for these states ({source})")
    if saved is not None:            # refused before any measurement
        from twolink.studies.leaderboard.merge import check_joinable
        check_joinable(saved, {"states": len(x0), "plants": plants, "seed": seed,
                               "horizon": 5.0, "limits": source}, levels)
    # Ray is connected before any file is made: an address that does not answer leaves none.
    with _ray(args):
        return _measure_and_write(args, controllers, specs, x0, limits, source, levels,
                                  plants, seed, saved)


def _saved(args):
    """The saved report --merge adds to (None without --merge), checked before any work."""
    if not args.merge:
        return None
    from twolink.resources import output_dir
    from twolink.studies.leaderboard.merge import saved_report

    if args.no_save:
        raise ValueError("--merge writes into the saved leaderboard; give no --no-save")
    if args.controllers is None and not args.controller:
        raise ValueError("--merge needs the controllers to add: --controllers or --controller")
    if args.plants is not None or args.seed is not None:
        raise ValueError("--merge takes the saved leaderboard's plants and seed; give no "
                         "--plants or --seed")
    out = args.out or output_dir() / ("leaderboard-quick" if args.quick else "leaderboard")
    return saved_report(out / "leaderboard.json")


def _ray(args):
    """The Ray session of ``--executor ray`` (a null context for local)."""
    if args.executor != "ray":
        return contextlib.nullcontext()
    from twolink.sim.cells import ray_session

    return ray_session(args.address, None, "--address")


def _measure_and_write(args, controllers, specs, x0, limits, source, levels, plants,
                       seed, saved=None) -> int:
    """Run the rows and write or print the report (outputs checked first)."""
    from twolink.artifacts import check_outputs
    from twolink.resources import output_dir
    from twolink.studies.leaderboard.measure import run as measure
    from twolink.studies.leaderboard.report import FILES, markdown, write

    out = None
    if not args.no_save:
        out = args.out or output_dir() / ("leaderboard-quick" if args.quick else "leaderboard")
        if out.exists() and not out.is_dir():
            raise OSError(f"--out {out} is a file; give a folder")
        check_outputs({name: out / f for name, f in FILES.items()}, creatable=[out])
    command = "twolink leaderboard" + (" --quick" if args.quick else "")
    log = None if args.json else (lambda line: print(line, file=sys.stderr, flush=True))
    rows = measure(controllers, x0, limits, levels=levels, plants=plants, seed=seed, log=log,
                   executor=args.executor, address=args.address, specs=specs)
    report = {"command": command, "states": len(x0), "plants": plants, "seed": seed,
              "horizon": 5.0, "limits": source, "levels": levels,
              "rows": [r.as_dict() for r in rows]}
    if saved is not None:
        from twolink.studies.leaderboard.merge import merged
        report = merged(saved, report)
    if out is not None:              # all three files or none (staged, then moved in)
        paths = write(report, out)
    if args.json:
        print(json.dumps(report, indent=2))
    else:
        print(markdown(report))
        if out is not None:
            print(f"wrote {paths['markdown']}, {paths['json'].name}, {paths['figure'].name}")
    return 0
