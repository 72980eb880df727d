"""Options several commands share: the arm (--links, --rule), initial states (--x0),
challenges (--challenge, --delay, --angle-noise-deg, --compensate) and policy labels."""
from __future__ import annotations

import math
import os
import re
from pathlib import Path

import numpy as np

from twolink.arm.parameters import (
    LINK_RULES,
    MAX_LINKS,
    MIN_LINKS,
    PAPER_X0,
    TABLE_I,
    check_links,
    links_parameters,
    state_names,
)
from twolink.policy.fuzzy_policy import check_links_match
from twolink.policy.registry import SHIPPED
from twolink.sim.challenges import LEVELS, check_horizon, requested
from twolink.sim.plants import MAX_ANGLE, SPEED_BOUND, check_states
from twolink.sim.rollout import steps_for
from twolink.validate import whole

X0_HELP = ("initial state theta1 theta2 dtheta1 dtheta2: four numbers in radians and "
           "rad/s (degrees and deg/s with --degrees), separated by spaces or commas, or "
           "'random' (angles uniform in [-pi, pi), at rest, drawn with --seed); "
           f"|angles| <= {MAX_ANGLE:g} rad, |speeds| <= {SPEED_BOUND:g} x the speed limit; "
           "default: the paper's -1 -3 0 0. With --links N: 2N numbers (theta1..thetaN "
           "dtheta1..dthetaN), default random")
#: The simplified model (11) and the challenges exist for the paper's two-link arm only.
TWO_LINK_PLANTS = ("simplified",)


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
    :func:`twolink.arm.parameters.links_parameters`; a ValueError naming the supported range."""
    try:
        links = check_links(args.links)
    except ValueError:
        raise ValueError(f"--links must be a whole number from {MIN_LINKS} to {MAX_LINKS}, "
                         f"got {args.links}") from None
    return links, (TABLE_I if links == 2 else links_parameters(links, args.rule))


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
    """:func:`twolink.policy.fuzzy_policy.check_links_match`'s one line, naming the option."""
    try:
        check_links_match(policy, links, name=label)
    except ValueError as exc:
        raise ValueError(f"{exc}; give --links {policy.links} for it") from None


def check_two_link_options(args, links: int) -> None:
    """The options that exist for the two-link arm only, refused in one line for N > 2."""
    if links == 2:
        return
    given = [o for o, v in (("--challenge", args.challenge), ("--delay", args.delay),
                            ("--angle-noise-deg", args.angle_noise),
                            ("--compensate", args.compensate)) if v]
    if given:
        verb = "applies" if len(given) == 1 else "apply"
        raise ValueError(f"{', '.join(given)} {verb} to the two-link arm only (challenges, "
                         f"delays, noise and compensation are built on Table I); drop "
                         f"{'it' if len(given) == 1 else 'them'} or use --links 2")
    plants = getattr(args, "plant", None)
    asked = plants if isinstance(plants, list) else [plants]
    bad = [p for p in asked if p in TWO_LINK_PLANTS]
    if bad:
        raise ValueError(f"--plant {bad[0]}: the simplified model (11) is the paper's "
                         f"two-link model; with --links {links} choose mujoco or full")


def add_challenge_options(p) -> None:
    """--challenge, --delay, --angle-noise-deg and --compensate (rollout and render)."""
    p.add_argument("--challenge", metavar="LEVEL", default=None,
                   help=f"run under a challenge level ({', '.join(LEVELS)}): the plant is "
                        "its first random plant of --seed, with its delays, noise and "
                        "faulty readings (twolink.sim.challenges)")
    p.add_argument("--delay", type=int, default=0, metavar="SAMPLES",
                   help="without --challenge: torques reach the plant this many sample "
                        "periods late (default 0)")
    p.add_argument("--angle-noise-deg", dest="angle_noise", type=float, default=0.0,
                   metavar="DEG",
                   help="without --challenge: Gaussian noise on the measured angles, std in "
                        "degrees, with speed noise 0.02 rad/s per degree (default 0)")
    p.add_argument("--compensate", action="store_true",
                   help="drive the policy through the run-time delay predictor and state "
                        "observer (twolink.sim.estimation) for the challenge's delays and noise")
    from twolink.commands.grammar import deprecated

    deprecated(p, p.prog.split()[-1], "--angle-noise", "--angle-noise-deg", dest="angle_noise",
               type=float)


#: The largest seed a command takes (numpy's generators take any, the JSON files int64).
MAX_SEED = 2**63 - 1


def seed_option(value, option: str = "--seed", high: int = MAX_SEED) -> int:
    """``value`` as an int if it is a whole number from 0 to ``high``, else a one-line
    ValueError naming ``option``: every command's seed is checked by this before any work."""
    return whole(value, option, 0, high, message="{what} must be a non-negative whole number "
                 "(at most " + ("2**63 - 1" if high == MAX_SEED else "{high}")
                 + "), got {value!r}")


def challenge_of(args):
    """The challenge ``args`` ask for (None: the plain plant), checked against the horizon."""
    seed_option(args.seed)
    ch = requested(args.challenge, delay=args.delay, angle_noise_deg=args.angle_noise)
    check_horizon(ch, steps_for(args.duration), args.duration)
    return ch


def parse_x0(values, *, degrees: bool = False, seed: int = 0, links: int = 2,
             speed_max=None) -> np.ndarray:
    """The initial state from the ``--x0`` words, or a clear ValueError. Two links: the
    paper's x0 by default; N links: 2N numbers, or a random pose at rest by default.
    A negative or too large ``seed`` is refused first, as ``--seed``."""
    seed_option(seed)
    if links != 2:
        return _parse_links_x0(values, degrees=degrees, seed=seed, links=links,
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


def _parse_links_x0(values, *, degrees: bool, seed: int, links: int, speed_max) -> np.ndarray:
    from twolink.sim.metrics import random_poses

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


def policy_label(name: str) -> str:
    """How a ``--policy`` value is labelled: a file by its stem, a shipped policy by name."""
    return Path(name).stem if name.endswith(".npz") or os.sep in name else name
