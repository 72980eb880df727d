"""``twolink render``: headless EGL videos (MP4 or GIF) of policies driving the arm.

The arm is seen from the top camera with the goal region marked, a translucent ghost
arm following the simplified-model (11) rollout of the same policy from the same x0,
and a text overlay with time, torques and reward. Two ``--policy`` values render side
by side; ``--controller`` takes any controller (``module:callable``,
``path/to/file.py:callable``, a baseline name or a policy file) in their place or beside
one. ``--challenge`` (or ``--delay`` / ``--angle-noise-deg``) and ``--compensate`` run them as
``twolink rollout`` does. ``--links N`` renders an N-link arm, its ghost then the
numpy full N-link model's rollout. Rendering speed is measured by the benchmarks
(``make bench``).
"""
from __future__ import annotations

import argparse
import json
import re
import time

import numpy as np

from twolink.arm.parameters import HORIZON, TS
from twolink.artifacts import check_outputs, make_folders, output_file
from twolink.commands import SUMMARIES
from twolink.commands.grammar import add_out
from twolink.commands._controllers import add_controller_option
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
from twolink.envs.core import horizon
from twolink.policy.fuzzy_policy import shipped_policies
from twolink.resources import output_dir
from twolink.sim.challenges import challenge
from twolink.sim.evaluation import challenged_rollouts
from twolink.sim.plants import PLANTS
from twolink.sim.progress import progress_bar
from twolink.sim.rollout import MAX_DURATION, rollout_grid, steps_for
from twolink.viz.video import (
    MAX_FRAMES,
    check_budget,
    check_fps,
    check_size,
    video_format,
    write_video,
)


def add_parser(sub):
    p = sub.add_parser("render", help=SUMMARIES["render"],
                       description=" ".join(__doc__.replace("``", "").split("\n\n")[1].split()))
    p.add_argument("--policy", action="append", metavar="NAME|FILE",
                   help=f"shipped policy ({', '.join(shipped_policies())}) or a policy .npz; "
                        f"give two for a side-by-side video (default: centralized; with "
                        f"--links N the shipped N-link policy)")
    add_controller_option(p, extra=" (two in all for a side-by-side video)")
    p.add_argument("--plant", choices=PLANTS, default="mujoco",
                   help="plant whose rollout is shown (default mujoco)")
    p.add_argument("--x0", nargs="+", metavar="X", help=X0_HELP)
    p.add_argument("--degrees", action="store_true",
                   help="read --x0 angles in degrees and speeds in deg/s")
    p.add_argument("--seed", type=int, default=0,
                   help="seed of --x0 random and of the challenge's plant, noise and faults "
                        "(default 0)")
    add_arm_options(p)
    add_challenge_options(p)
    p.add_argument("--duration", type=float, default=None,
                   help=f"simulated seconds (default {HORIZON:g}, with --links 3 or more "
                        f"{horizon(3):g}; at most {MAX_DURATION:g}; a video has at most "
                        f"{MAX_FRAMES} frames)")
    p.add_argument("--fps", type=float, default=round(1 / TS),
                   help=f"frames per second of the video (default {round(1 / TS)}, one per "
                        f"sample period)")
    p.add_argument("--speed", type=float, default=1.0,
                   help="simulated seconds per video second (default 1: real time)")
    p.add_argument("--size", default="640x480", metavar="WxH",
                   help="frame size of one panel in pixels (default 640x480)")
    p.add_argument("--ghost", action=argparse.BooleanOptionalAction, default=True,
                   help="show the simplified-model rollout (with --links 3 or more: the "
                        "full N-link model's) as a translucent ghost arm (default on)")
    p.add_argument("--overlay", action=argparse.BooleanOptionalAction, default=True,
                   help="draw time, torques and reward on the frames (default on)")
    p.add_argument("--antialias", action="store_true",
                   help="4x multisample anti-aliasing (about 3x slower without a GPU)")
    add_out(p, "render", default=None, metavar="FILE",
            help="video to write, .mp4 (H.264) or .gif; DIR/ (a trailing /) writes the "
                 "default name in DIR, made if missing (default "
                 "twolink-results/<policy>[_vs_<policy>]_<plant>.mp4)")
    p.add_argument("--no-progress", action="store_true",
                   help="hide the progress bar (printed as lines when stderr is not a "
                        "terminal; --json hides it too)")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    return p


def parse_size(text: str) -> tuple[int, int]:
    m = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", text or "")
    if not m:
        raise ValueError(f"--size must look like 640x480, got {text!r}")
    return int(m.group(1)), int(m.group(2))


def run(args) -> int:
    links, params = arm_of(args)
    check_two_link_options(args, links)
    if args.duration is None:
        args.duration = horizon(links)
    width, height = parse_size(args.size)
    x0 = parse_x0(args.x0, degrees=args.degrees, seed=args.seed, links=links,
                  speed_max=params.speed_max)
    steps_for(args.duration)
    ch = challenge_of(args)
    check_fps(args.fps)
    if not np.isfinite(args.speed) or args.speed <= 0:
        raise ValueError(f"--speed must be a positive number, got {args.speed}")
    given = [*(args.policy or []), *args.controller]
    if len(given) == 2 and given[0] == given[1]:
        raise ValueError(f"the two --policy or --controller values name the same policy "
                         f"{given[0]!r}")
    policies = command_controllers(args, links, most=2)
    labels = list(policies)
    default = output_dir(create=False)
    name = f"{'_vs_'.join(labels)}_{args.plant}.mp4"
    out, folders = output_file(args.output, name) if args.output else (default / name, [])
    fmt = video_format(out)
    check_size(width * len(labels), height, fmt)
    check_budget(args.duration / args.speed * args.fps + 1, width * len(labels), height)
    check_outputs({"--output": out}, creatable=[default, *folders])

    ghost = "simplified" if links == 2 else "full"
    shown = [args.plant] + ([ghost] if args.ghost else [])
    if ch is None and not args.compensate:
        runs = rollout_grid(policies, shown, x0[None], duration=args.duration,  # a batch of 1
                            params=None if links == 2 else params)
        runs = {k: tr[0] for k, tr in runs.items()}
    else:
        runs = challenged_rollouts(policies, shown, x0, ch or challenge("none"), seed=args.seed,
                                   compensate=args.compensate, duration=args.duration)
    under = ("" if ch is None else f", {ch.name}") + (", compensated" if args.compensate else "")
    panels = [(f"{label} on {args.plant}{under}"
               + (f" (ghost: {ghost})" if args.ghost else ""),
               runs[(label, args.plant)], runs.get((label, ghost)) if args.ghost else None)
              for label in policies]
    if out.parent == default:
        output_dir()                             # the default folder, made on demand

    from twolink.viz.render import Renderer, frame_count, trajectory_frames

    n = frame_count(args.duration / args.speed, args.fps)
    t0 = time.perf_counter()
    with Renderer(width=width, height=height, ghost=args.ghost, overlay=args.overlay,
                  samples=4 if args.antialias else 0, params=params) as r:
        frames = trajectory_frames(r, panels, fps=args.fps, speed=args.speed,
                                   duration=args.duration)
        make_folders(folders)                    # -o DIR/: once the renderer is up
        with progress_bar(frames, total=n, unit=" frames", desc=f"render {out.name}",
                          enabled=not (args.no_progress or args.json), leave=False) as bar:
            count = write_video(out, bar, args.fps)
    seconds = time.perf_counter() - t0
    result = {"path": str(out), "frames": count, "fps": args.fps, "width": width * len(labels),
              "height": height, "video_seconds": count / args.fps,
              "render_seconds": seconds, "policies": labels, "plant": args.plant,
              **({} if links == 2 else {"links": links, "rule": args.rule}),
              "ghost": args.ghost, "x0": x0.tolist(),
              "challenge": None if ch is None else ch.as_dict(), "compensate": args.compensate,
              "seed": args.seed}
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        print(f"wrote {out} ({count} frames, {width * len(labels)}x{height}, {args.fps:g} fps, "
              f"rendered in {seconds:.1f} s)")
    return 0
