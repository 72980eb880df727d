"""``twolink rollout``: run policies on plants from x0, summarise, save and plot.

Several ``--policy`` or ``--plant`` values run every combination and overlay them in one
Fig. 3-style figure (one column per policy, one line style per plant). ``--challenge``
(or ``--delay`` / ``--angle-noise``) runs them under a challenge level, ``--compensate``
behind the run-time compensator (:mod:`twolink.estimation`). ``--links N`` (with
``--rule``) runs an N-link arm (:func:`twolink.parameters.chain`) on MuJoCo or the numpy
full N-link model; the simplified model (11) and the challenges are the two-link arm's.
"""
from __future__ import annotations

import json
import math
import os
import re
from pathlib import Path

import numpy as np

from twolink.artifacts import check_outputs
from twolink.challenges import LEVELS, challenge
from twolink.metrics import compare
from twolink.parameters import (HORIZON, LINK_RULES, MAX_LINKS, MIN_LINKS, PAPER_X0, TABLE_I,
                                chain, check_links, state_names)
from twolink.plants import MAX_ANGLE, PLANTS, SPEED_BOUND, check_states
from twolink.plots import fig3
from twolink.policy import check_links_match, load_policy, shipped_policies
from twolink.registry import SHIPPED
from twolink.resources import output_dir
from twolink.robustness_study import challenged_rollouts, check_horizon, level
from twolink.rollout import MAX_DURATION, rollout_grid, steps_for
from twolink.tasks import horizon         # the default duration: 5 s, 8 s beyond two links
from twolink.trajectory_io import save_csv, save_npz

_X0_HELP = ("initial state theta1 theta2 dtheta1 dtheta2: four numbers in radians and "
            "rad/s (degrees and deg/s with --degrees), separated by spaces or commas, or "
            "'random' (angles uniform in [-pi, pi), at rest, drawn with --seed); "
            f"|angles| <= {MAX_ANGLE:g} rad, |speeds| <= {SPEED_BOUND:g} x the speed limit; "
            "default: the paper's -1 -3 0 0. With --links N: 2N numbers (theta1..thetaN "
            "dtheta1..dthetaN), default random")
#: The simplified model (11) and the challenges exist for the paper's two-link arm only.
_TWO_LINK_PLANTS = ("simplified",)


def add_arm_options(p) -> None:
    """--links and --rule: the arm (rollout, render, synthesize, mismatch)."""
    p.add_argument("--links", type=int, default=2, metavar="N",
                   help=f"links of the arm, {MIN_LINKS} to {MAX_LINKS} (default 2: Table I, "
                        f"the paper's arm); links beyond the second follow --rule")
    p.add_argument("--rule", choices=LINK_RULES, default=LINK_RULES[0],
                   help="how links beyond the second are made: tapered (each the previous "
                        "one with half its mass, inertia and torque limit; the default) or "
                        "copied (copies of link 2)")


def arm_of(args) -> tuple:
    """(N, parameters) of ``--links`` / ``--rule``: Table I for two links, else
    :func:`twolink.parameters.chain`; a ValueError naming the supported range."""
    try:
        links = check_links(args.links)
    except ValueError:
        raise ValueError(f"--links must be a whole number from {MIN_LINKS} to {MAX_LINKS}, "
                         f"got {args.links}") from None
    return links, (TABLE_I if links == 2 else chain(links, args.rule))


def default_policy(links: int, rule: str) -> str:
    """The shipped policy a command runs without ``--policy``: ``centralized`` for two
    links, else the first shipped policy of the registry for this arm; a ValueError if
    none is shipped."""
    if links == 2:
        return "centralized"
    for name, entry in SHIPPED.items():
        if (entry.links, entry.rule) == (links, rule) and entry.file.is_file():
            return name
    extra = "" if rule == LINK_RULES[0] else f" --rule {rule}"
    raise ValueError(f"no policy for a {links}-link arm ({rule} links) is shipped; give "
                     f"--policy FILE (twolink synthesize decentralized --links {links}"
                     f"{extra} makes one)")


def check_policy_links(label: str, policy, links: int) -> None:
    """:func:`twolink.policy.check_links_match`'s one line, naming the option."""
    try:
        check_links_match(policy, links, name=label)
    except ValueError as exc:
        raise ValueError(f"{exc}; give --links {policy.links} for it") from None


def check_two_link_options(args, links: int) -> None:
    """The options that exist for the two-link arm only, refused in one line for N > 2."""
    if links == 2:
        return
    given = [o for o, v in (("--challenge", args.challenge), ("--delay", args.delay),
                            ("--angle-noise", args.angle_noise),
                            ("--compensate", args.compensate)) if v]
    if given:
        verb = "applies" if len(given) == 1 else "apply"
        raise ValueError(f"{', '.join(given)} {verb} to the two-link arm only (challenges, "
                         f"delays, noise and compensation are built on Table I); drop "
                         f"{'it' if len(given) == 1 else 'them'} or use --links 2")
    plants = getattr(args, "plant", None)
    asked = plants if isinstance(plants, list) else [plants]
    bad = [p for p in asked if p in _TWO_LINK_PLANTS]
    if bad:
        raise ValueError(f"--plant {bad[0]}: the simplified model (11) is the paper's "
                         f"two-link model; with --links {links} choose mujoco or full")


def add_parser(sub):
    p = sub.add_parser("rollout", help="run policies on plants; summary, trajectories, Fig. 3",
                       description="Run policies on plants from x0, print a summary, save "
                                   "the trajectories (CSV, NPZ) and a Fig. 3-style figure. "
                                   "Several --policy or --plant values run every combination "
                                   "and overlay them in one figure (one column per policy, "
                                   "one line style per plant).")
    p.add_argument("--policy", action="append", metavar="NAME|FILE",
                   help=f"shipped policy ({', '.join(shipped_policies())}) or a policy .npz; "
                        f"repeat to overlay (default: centralized; with --links N the shipped "
                        f"N-link policy)")
    p.add_argument("--plant", action="append", choices=PLANTS,
                   help="plant to run on; repeat to overlay (default: mujoco; simplified "
                        "is the two-link model (11) only)")
    p.add_argument("--x0", nargs="+", metavar="X", help=_X0_HELP)
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
    p.add_argument("-o", "--output", default=None, metavar="PREFIX",
                   help="write PREFIX.csv, PREFIX.npz and PREFIX_fig3.png; a directory "
                        "writes DIR/rollout.* (default renders/rollout)")
    p.add_argument("--csv", type=Path, help="trajectory CSV path (overrides the prefix)")
    p.add_argument("--npz", type=Path, help="trajectory NPZ path (overrides the prefix)")
    p.add_argument("--figure", type=Path, help="Fig. 3 PNG path (overrides the prefix)")
    p.add_argument("--no-save", action="store_true", help="only print the summary")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    return p


def add_challenge_options(p) -> None:
    """--challenge, --delay, --angle-noise and --compensate (rollout and render)."""
    p.add_argument("--challenge", metavar="LEVEL", default=None,
                   help=f"run under a challenge level ({', '.join(LEVELS)}): the plant is "
                        "its first random plant of --seed, with its delays, noise and "
                        "faulty readings (twolink.challenges)")
    p.add_argument("--delay", type=int, default=0, metavar="SAMPLES",
                   help="without --challenge: torques reach the plant this many sample "
                        "periods late (default 0)")
    p.add_argument("--angle-noise", type=float, default=0.0, metavar="DEG",
                   help="without --challenge: Gaussian noise on the measured angles, std in "
                        "degrees, with speed noise 0.02 rad/s per degree (default 0)")
    p.add_argument("--compensate", action="store_true",
                   help="drive the policy through the run-time delay predictor and state "
                        "observer (twolink.estimation) for the challenge's delays and noise")


def challenge_of(args):
    """The challenge ``args`` ask for (None: the plain plant), checked against the horizon."""
    if args.seed < 0:
        raise ValueError(f"--seed must be a non-negative whole number, got {args.seed}")
    ch = level(args.challenge, delay=args.delay, angle_noise_deg=args.angle_noise)
    check_horizon(ch, args.duration)
    return ch


def parse_x0(values, *, degrees: bool = False, seed: int = 0, links: int = 2,
             speed_max=None) -> np.ndarray:
    """The initial state from the ``--x0`` words, or a clear ValueError. Two links: the
    paper's x0 by default; N links: 2N numbers, or a random pose at rest by default."""
    if links != 2:
        return _parse_chain_x0(values, degrees=degrees, seed=seed, links=links,
                               speed_max=speed_max)
    if not values:
        return np.asarray(PAPER_X0, dtype=float)
    words = [w for v in values for w in re.split(r"[,\s]+", v.strip()) if w]
    if words == ["random"]:
        rng = np.random.default_rng(seed)
        return np.concatenate([rng.uniform(-math.pi, math.pi, 2), np.zeros(2)])
    try:
        x0 = np.array([float(w) for w in words])
    except ValueError:
        raise ValueError(f"--x0 must be four numbers (theta1 theta2 dtheta1 dtheta2) or "
                         f"'random', got {' '.join(values)!r}") from None
    if x0.shape != (4,):
        raise ValueError(f"--x0 must be four numbers (theta1 theta2 dtheta1 dtheta2), got "
                         f"{len(x0)}: {' '.join(values)!r}")
    x0 = check_states(np.deg2rad(x0) if degrees else x0, what="--x0",
                      speed_max=TABLE_I.speed_max)
    return x0


def _parse_chain_x0(values, *, degrees: bool, seed: int, links: int, speed_max) -> np.ndarray:
    from twolink.metrics import random_poses

    words = [w for v in values or () for w in re.split(r"[,\s]+", v.strip()) if w]
    if not words or words == ["random"]:
        return random_poses(links, 1, seed)[0]
    names = " ".join(state_names(links))
    try:
        x0 = np.array([float(w) for w in words])
    except ValueError:
        raise ValueError(f"--x0 must be {2 * links} numbers ({names}) or 'random', got "
                         f"{' '.join(values)!r}") from None
    if x0.shape != (2 * links,):
        raise ValueError(f"--x0 must be {2 * links} numbers for {links} links ({names}), got "
                         f"{len(x0)}: {' '.join(values)!r}")
    return check_states(np.deg2rad(x0) if degrees else x0, what="--x0", speed_max=speed_max,
                        links=links)


def _outputs(args) -> dict:
    """The files to write, keyed by kind, all checked before any work."""
    if args.no_save:
        return {}
    default = output_dir(create=False)
    prefix = Path(args.output) if args.output else default / "rollout"
    if prefix.is_dir() or (args.output or "").endswith(("/", os.sep)):
        prefix = prefix / "rollout"
    out = {"csv": args.csv or prefix.with_name(prefix.name + ".csv"),
           "npz": args.npz or prefix.with_name(prefix.name + ".npz"),
           "figure": args.figure or prefix.with_name(prefix.name + "_fig3.png")}
    if out["figure"].suffix.lower() not in (".png", ".pdf", ".svg"):
        raise ValueError(f"--figure {out['figure']}: use a .png, .pdf or .svg file name")
    checked = check_outputs({f"--{k}": v for k, v in out.items()}, creatable=[default])
    return {k: checked[f"--{k}"] for k in out}


def _label(name: str) -> str:
    return Path(name).stem if name.endswith(".npz") or os.sep in name else name


def run(args) -> int:
    links, params = arm_of(args)
    check_two_link_options(args, links)
    if args.duration is None:
        args.duration = horizon(links)
    names = list(dict.fromkeys(args.policy or [default_policy(links, args.rule)]))
    labels = [_label(n) for n in names]
    twice = [label for i, label in enumerate(labels) if label in labels[:i]]
    if twice:
        raise ValueError(f"two --policy values share the label {twice[0]!r} "
                         f"(a file's stem); rename one")
    policies = {label: load_policy(n) for label, n in zip(labels, names)}
    for label, policy in policies.items():
        check_policy_links(label, policy, links)
    plants = list(dict.fromkeys(args.plant or ["mujoco"]))
    x0 = parse_x0(args.x0, degrees=args.degrees, seed=args.seed, links=links,
                  speed_max=params.speed_max)
    steps_for(args.duration)
    ch = challenge_of(args)
    outputs = _outputs(args)
    reference = "simplified" if links == 2 else "full"

    if ch is None and not args.compensate:
        everything = rollout_grid(policies, plants + [reference], x0, duration=args.duration,
                                  params=None if links == 2 else params)
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
        meta = {"x0": x0.tolist(), "duration": args.duration, "seed": args.seed, **arm,
                "challenge": report["challenge"], "compensate": args.compensate,
                "policies": {k: (v.kind, v.meta.get("context")) for k, v in policies.items()}}
        save_csv(outputs["csv"], runs)
        save_npz(outputs["npz"], runs, meta=meta)
        panels = {pname: {plant: runs[(pname, plant)] for plant in plants}
                  for pname in policies}
        x0s = ", ".join(f"{v:.3g}" for v in x0)
        fig3(panels, outputs["figure"],
             title=f"x0 = [{x0s}]" + ("; " if links == 2 else f", {links} links ({args.rule})\n")
                   + f"line styles: {', '.join(plants)}"
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
    for k, v in report.get("outputs", {}).items():
        print(f"wrote {v}")
    return 0
