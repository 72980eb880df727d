"""``twolink rollout``: run policies on plants from x0, summarise, save and plot.

Several ``--policy`` or ``--plant`` values run every combination and overlay them in one
Fig. 3-style figure (one column per policy, one line style per plant). ``--controller``
adds any controller (``module:callable``, ``path/to/file.py:callable``, a baseline name
or a policy file, :func:`twolink.control.controllers.resolve_controller`) to the same
closed loop. ``--challenge``
(or ``--delay`` / ``--angle-noise-deg``) runs them under a challenge level, ``--compensate``
behind the run-time compensator (:mod:`twolink.sim.estimation`). ``--links N`` (with
``--rule``) runs an N-link arm (:func:`twolink.arm.parameters.links_parameters`) on MuJoCo
or the numpy full N-link model; the simplified model (11) and the challenges are the two-link arm's.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

from twolink.arm.parameters import (
    HORIZON,
)
from twolink.artifacts import check_outputs, make_folders, output_file
from twolink.commands import SUMMARIES
from twolink.commands.grammar import add_out
from twolink.commands._controllers import add_controller_option, context_of, kind_of
from twolink.commands._controllers import controllers_of as command_controllers
from twolink.commands._options import (
    X0_HELP,
    add_arm_options,
    add_challenge_options,
    arm_of,
    challenge_of,
    check_two_link_options,
    parse_x0,
)
from twolink.envs.core import horizon  # the default duration: 5 s, 8 s beyond two links
from twolink.policy.fuzzy_policy import shipped_policies
from twolink.resources import output_dir
from twolink.sim.challenges import challenge
from twolink.sim.evaluation import challenged_rollouts
from twolink.sim.metrics import compare
from twolink.sim.plants import PLANTS
from twolink.sim.rollout import MAX_DURATION, rollout_grid, steps_for
from twolink.sim.trajectory_file import save_csv, save_npz
from twolink.viz.plots import fig3


def add_parser(sub):
    p = sub.add_parser("rollout", help=SUMMARIES["rollout"],
                       description="Run policies on plants from x0, print a summary, save "
                                   "the trajectories (CSV, NPZ) and a Fig. 3-style figure. "
                                   "Several --policy or --plant values run every combination "
                                   "and overlay them in one figure (one column per policy, "
                                   "one line style per plant).")
    p.add_argument("--policy", action="append", metavar="NAME|FILE",
                   help=f"shipped policy ({', '.join(shipped_policies())}) or a policy .npz; "
                        f"repeat to overlay (default: centralized; with --links N the shipped "
                        f"N-link policy)")
    add_controller_option(p)
    p.add_argument("--plant", action="append", choices=PLANTS,
                   help="plant to run on; repeat to overlay (default: mujoco; simplified "
                        "is the two-link model (11) only)")
    p.add_argument("--x0", nargs="+", metavar="X", help=X0_HELP)
    p.add_argument("--degrees", action="store_true",
                   help="read --x0 angles in degrees and speeds in deg/s")
    p.add_argument("--duration", type=float, default=None,
                   help=f"seconds to simulate (default {HORIZON:g}, with --links 3 or more "
                        f"{horizon(3):g}; at most {MAX_DURATION:g})")
    p.add_argument("--seed", type=int, default=0,
                   help="seed of --x0 random and of the challenge's plant, noise and faults "
                        "(default 0)")
    add_arm_options(p)
    add_challenge_options(p)
    add_out(p, "rollout", default=None, metavar="DIR",
            help="folder of rollout.csv, rollout.npz and rollout_fig3.png (DIR/, with a "
                 "trailing /, is made if missing; default twolink-results/)")
    p.add_argument("--prefix", default=None, metavar="PREFIX",
                   help="write PREFIX.csv, PREFIX.npz and PREFIX_fig3.png instead")
    p.add_argument("--csv", type=Path, help="trajectory CSV path (overrides the prefix)")
    p.add_argument("--npz", type=Path, help="trajectory NPZ path (overrides the prefix)")
    p.add_argument("--figure", type=Path, help="Fig. 3 PNG path (overrides the prefix)")
    p.add_argument("--no-save", action="store_true", help="only print the summary")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    return p


def _outputs(args) -> tuple[dict, list]:
    """(the files to write keyed by kind, the folders to make first), all checked before
    any work: ``-o DIR/`` (a trailing slash) writes ``DIR/rollout.*``, ``DIR`` among the
    folders made (:func:`twolink.artifacts.make_folders`) once the run succeeded."""
    if args.no_save:
        return {}, []
    default = output_dir(create=False)
    if args.prefix is not None and args.output is not None:
        raise ValueError("give -o/--out DIR or --prefix PREFIX, not both")
    prefix, folders = output_file(args.output, "rollout")
    if args.prefix is not None:
        prefix, folders = Path(args.prefix), []
    elif not args.output:
        prefix = default / "rollout"
    elif not folders and prefix.is_dir():
        prefix = prefix / "rollout"
    elif not folders:       # -o PREFIX, the old meaning: still a prefix, with a warning
        print(f"twolink rollout: warning: -o {args.output} (a file prefix) is deprecated and "
              f"goes in the next release; give --prefix {args.output}, or -o "
              f"{args.output}/ for a folder", file=sys.stderr)
    out = {"csv": args.csv or prefix.with_name(prefix.name + ".csv"),
           "npz": args.npz or prefix.with_name(prefix.name + ".npz"),
           "figure": args.figure or prefix.with_name(prefix.name + "_fig3.png")}
    if out["figure"].suffix.lower() not in (".png", ".pdf", ".svg"):
        raise ValueError(f"--figure {out['figure']}: use a .png, .pdf or .svg file name")
    checked = check_outputs({f"--{k}": v for k, v in out.items()},
                            creatable=[default, *folders])
    return {k: checked[f"--{k}"] for k in out}, folders


def run(args) -> int:
    links, params = arm_of(args)
    check_two_link_options(args, links)
    if args.duration is None:
        args.duration = horizon(links)
    policies = command_controllers(args, links)
    plants = list(dict.fromkeys(args.plant or ["mujoco"]))
    x0 = parse_x0(args.x0, degrees=args.degrees, seed=args.seed, links=links,
                  speed_max=params.speed_max)
    steps_for(args.duration)
    ch = challenge_of(args)
    outputs, folders = _outputs(args)
    reference = "simplified" if links == 2 else "full"

    if ch is None and not args.compensate:
        everything = rollout_grid(policies, plants + [reference], x0[None],  # a batch of 1
                                  duration=args.duration, params=None if links == 2 else params)
        everything = {k: tr[0] for k, tr in everything.items()}
    else:
        everything = challenged_rollouts(policies, plants + ["simplified"], x0,
                                         ch or challenge("none"), seed=args.seed,
                                         compensate=args.compensate, duration=args.duration)
    runs = {k: tr for k, tr in everything.items() if k[1] in plants}
    arm = {} if links == 2 else {"links": links, "rule": args.rule}
    report = {"x0": x0.tolist(), "duration": args.duration, "seed": args.seed, **arm,
              "challenge": None if ch is None else ch.as_dict(),
              "compensate": args.compensate,
              "runs": compare(everything, plants, reference=reference)}

    if outputs:
        if any(p.parent == output_dir(create=False) for p in outputs.values()):
            output_dir()                         # the default folder, made on demand
        make_folders(folders)
        meta = {"x0": x0.tolist(), "duration": args.duration, "seed": args.seed, **arm,
                "challenge": report["challenge"], "compensate": args.compensate,
                "policies": {k: (kind_of(v), context_of(v)) for k, v in policies.items()}}
        save_csv(outputs["csv"], runs)
        save_npz(outputs["npz"], runs, meta=meta)
        panels = {pname: {plant: runs[(pname, plant)] for plant in plants}
                  for pname in policies}
        x0s = ", ".join(f"{v:.3g}" for v in x0)
        styles = ", ".join(f"{s} {p}" for s, p in zip(("solid", "dashed", "dotted",
                                                          "dash-dot"), plants))
        fig3(panels, outputs["figure"],
             title=f"Closed-loop runs from x0 = [{x0s}] ({args.duration:g} s"
                   + ("" if links == 2 else f", {links} links, {args.rule}") + f"): {styles}"
                   + ("" if ch is None else f"; challenge {ch.name}, seed {args.seed}")
                   + ("; compensated" if args.compensate else ""))
        report["outputs"] = {k: str(v) for k, v in outputs.items()}

    if args.json:
        print(json.dumps(report, indent=2))
        return 0
    print(("" if links == 2 else f"{links} links ({args.rule}), ")
          + f"x0 = [{', '.join(f'{v:+.4g}' for v in x0)}], {args.duration:g} s"
          + ("" if ch is None else f", challenge {ch.name} (seed {args.seed})")
          + (", compensated" if args.compensate else ""))
    for e in report["runs"]:
        st = "never" if e["settle_time"] is None else f"{e['settle_time']:.2f} s"
        off = ", ".join(f"{v:+.2f}" for v in e["final_offsets_deg"])
        line = (f"{e['policy']:<24} on {e['plant']:<10} settle {st:>7}  "
                f"success {'yes' if e['success'] else 'no ':<3}  return {e['return']:+.3f}  "
                f"final offsets [{off}] deg")
        if f"gap_to_{reference}" in e:
            g = e[f"gap_to_{reference}"]
            line += (f"  gap to {reference}: {g['angle_rms']:.3g} rad, "
                     f"{g['speed_rms']:.3g} rad/s RMS")
        print(line)
    for v in report.get("outputs", {}).values():
        print(f"wrote {v}")
    return 0
