"""``twolink mismatch``: measure the model mismatch, its closure and robustness; write a report.

Open-loop error of (11) and (6) against MuJoCo, the closed-loop gap of every policy on
every plant, the policies synthesised on (6), robustness sweeps on MuJoCo, and every policy
under every challenge level with and without run-time compensation, written as Markdown +
JSON + figures under twolink-results/mismatch/ (mismatch-quick/ with --quick).
With --links N (3 to 6) a short N-link section instead: each N-link policy on the numpy
full N-link model and on MuJoCo from random poses at rest, success k/n with 95 % Wilson
intervals and median settle times, under twolink-results/mismatch-<N>link/.
"""
from __future__ import annotations

import argparse
import contextlib
import json
import sys
from pathlib import Path

from twolink.artifacts import staged_set, write_json, write_text
from twolink.commands import SUMMARIES
from twolink.commands.grammar import deprecated
from twolink.commands._options import (
    add_arm_options,
    arm_of,
    check_policy_links,
    default_policy,
    policy_label,
)
from twolink.envs.core import horizon
from twolink.policy.fuzzy_policy import load_policy
from twolink.policy.registry import PAPER_DESIGNS
from twolink.resources import output_dir
from twolink.sim.cell_store import CellFile
from twolink.sim.cells import EXECUTORS, ray_session
from twolink.sim.challenges import LEVELS, challenge
from twolink.studies.mismatch.measure import build
from twolink.studies.mismatch.plan import LINKS_SEED, PLANS, plan
from twolink.studies.mismatch.report import summary, write
from twolink.viz.formatting import format_rate


def add_parser(sub):
    p = sub.add_parser("mismatch", help=SUMMARIES["mismatch"],
                       description=__doc__.split("\n\n")[1].replace("\n", " "))
    p.add_argument("--quick", action="store_const", dest="plan", const="quick",
                   default="full",
                   help="5 initial states per sweep cell and fewer sizes (the closed-loop "
                        "table keeps all 65): under a minute, for CI; default: the full plan "
                        "of the committed report")
    deprecated(p, "mismatch", "--plan", "--quick (or nothing: the full plan)", dest="plan",
               choices=list(PLANS))
    p.add_argument("-o", "--out", type=Path, default=None,
                   help="report folder (default twolink-results/mismatch, or ...-quick); "
                        "one run at a time per folder, which resumes from its sweep.jsonl")
    p.add_argument("--policies", nargs="+", default=None, metavar="POLICY",
                   help=f"shipped policy names, reported in registry order "
                        f"(default: {' '.join(PAPER_DESIGNS)}); with --links N: N-link policies, "
                        f"shipped names or .npz files (default: the shipped one)")
    p.add_argument("--executor", choices=EXECUTORS, default="local",
                   help="where sweep cells run: this process, local worker processes "
                        "(default) or a Ray cluster")
    p.add_argument("--address", default=None,
                   help="Ray cluster address (with --executor ray; default: a local Ray)")
    p.add_argument("--workers", type=int, default=None,
                   help="worker processes (default: one per CPU)")
    p.add_argument("--challenge", nargs="+", metavar="LEVEL", default=None,
                   help=f"challenge levels of the robust section ({', '.join(LEVELS)}; "
                        "default: all); each policy runs as it is and behind the run-time "
                        "compensator (the paper's policies only as they are)")
    p.add_argument("--seed", type=int, default=None,
                   help="seed of the robust section's plants and noise (default: the "
                        "plan's, never tuned on); with --links N: of the random poses "
                        f"(default {LINKS_SEED}, never tuned on)")
    p.add_argument("--robust", action=argparse.BooleanOptionalAction, default=True,
                   help="measure the robust section (default on)")
    add_arm_options(p)
    p.add_argument("--force", action="store_true",
                   help="write into a --out folder that holds a report.md of its own (one "
                        "without the sweep.jsonl of an earlier run)")
    p.add_argument("--json", action="store_true",
                   help="print success rates, open-loop errors and margins as JSON")
    return p


def _robust_args(args) -> list:
    """The robust-section options of the command line, as the report names them."""
    out = [] if args.robust else ["--no-robust"]
    if args.challenge is not None:
        out.append("--challenge " + " ".join(args.challenge))
    if args.seed is not None:
        out.append(f"--seed {args.seed}")
    return out


def _links_section(args, links: int, params) -> int:
    """``twolink mismatch --links N`` (N >= 3): the N-link section, checked before any work
    or file."""
    from twolink.studies.mismatch.figures import links_markdown
    from twolink.studies.mismatch.links import measure

    chosen = plan(args.plan)
    two_link = [o for o, given in (("--challenge", args.challenge is not None),
                                   ("--no-robust", not args.robust),
                                   ("--executor", args.executor != "local"),
                                   ("--address", args.address is not None),
                                   ("--workers", args.workers is not None)) if given]
    if two_link:
        raise ValueError(f"{', '.join(two_link)} apply to the two-link report only; the "
                         f"{links}-link section takes --plan, --policies, --seed, --rule, "
                         f"--out and --json")
    seed = LINKS_SEED if args.seed is None else args.seed
    if seed < 0:
        raise ValueError(f"--seed must be a non-negative whole number, got {seed}")
    names = list(dict.fromkeys(args.policies or [default_policy(links, args.rule)]))
    labels = [policy_label(n) for n in names]
    if len(set(labels)) < len(labels):
        raise ValueError("two --policies values share a label (a file's stem); rename one")
    policies = {label: load_policy(n) for label, n in zip(labels, names)}
    for label, policy in policies.items():
        check_policy_links(label, policy, links)
    suffix = "" if args.rule == "tapered" else f"-{args.rule}"
    suffix += "" if chosen.name == "full" else f"-{chosen.name}"
    out = args.out or output_dir(create=False) / f"mismatch-{links}link{suffix}"
    if out.parent != output_dir(create=False) or out.parent.is_dir():
        check_report_folder(out, force=args.force)
    section = measure(policies, params, poses=chosen.links_poses, seed=seed,
                      duration=horizon(links))
    command = (f"twolink mismatch --links {links}"
               + ("" if args.rule == "tapered" else f" --rule {args.rule}")
               + ("" if chosen.name == "full" else f" --plan {chosen.name}")
               + ("" if args.policies is None else " --policies " + " ".join(names))
               + ("" if args.seed is None else f" --seed {seed}"))
    with staged_set(out) as stage:                  # both files or neither
        write_json(stage / "report.json", {"command": command, **section})
        write_text(stage / "report.md", links_markdown(section, command))
    if args.json:
        print(json.dumps(section, indent=2))
        return 0
    for label, by in section["results"].items():
        print(f"{label:26s} " + "  ".join(
            f"{pl} {format_rate(r['successes'], r['n']):<24s} median settle "
            + ("never" if r["median_settle"] is None else f"{r['median_settle']:.2f} s")
            for pl, r in by.items()))
    print(f"wrote {out / 'report.md'}")
    return 0


def _written_by_mismatch(out: Path) -> bool:
    """Whether ``out`` holds an earlier run's report (its sweep file, or a report.json
    whose command is twolink mismatch)."""
    if (out / "sweep.jsonl").exists():
        return True
    try:
        command = json.loads((out / "report.json").read_text()).get("command", "")
    except (OSError, ValueError, AttributeError):
        return False
    return isinstance(command, str) and command.startswith("twolink mismatch")


def check_report_folder(out: Path, *, force: bool) -> None:
    """A folder the report may be written into: it does not resolve (through symlinks
    too) into the package or its shipped data, its parent exists, it is not a file, and a
    report.md in it was written by an earlier run (:func:`_written_by_mismatch`) unless
    ``force``; a one-line OSError otherwise, before anything is written."""
    from twolink.resources import protected_target

    if protected_target(out) is not None:
        raise OSError(f"cannot write {out}: it resolves into twolink's shipped files "
                      f"({protected_target(out)}); write elsewhere")
    if out.exists() and not out.is_dir():
        raise OSError(f"-o/--out {out} is a file; give a folder")
    if not out.parent.is_dir():
        raise OSError(f"cannot write {out}: directory {out.parent} does not exist")
    if (out / "report.md").exists() and not force and not _written_by_mismatch(out):
        raise OSError(f"{out} already holds a report.md that no twolink mismatch run wrote; "
                      f"give --force to replace it, or --out another folder")


def run(args) -> int:
    links, params = arm_of(args)
    if links != 2:
        return _links_section(args, links, params)
    if args.policies is None:
        args.policies = list(PAPER_DESIGNS)
    chosen = plan(args.plan)
    if args.workers is not None and args.workers < 1:
        raise ValueError(f"--workers must be at least 1, got {args.workers}")
    if args.address and args.executor != "ray":
        raise ValueError("--address needs --executor ray")
    for name in args.policies:                       # fail before anything is written
        check_policy_links(name, load_policy(name), 2)
    levels = None if args.challenge is None else [challenge(n).name for n in args.challenge]
    if not args.robust and (args.challenge is not None or args.seed is not None):
        raise ValueError("--challenge and --seed choose what the robust section measures; "
                         "drop --no-robust or them")
    if args.seed is not None and (args.seed < 0 or args.seed >= 2**63):
        raise ValueError(f"--seed must be a whole number from 0 to 2**63 - 1, got {args.seed}")
    out = args.out or output_dir(create=False) / chosen.folder
    if out.parent.is_dir():                          # checked again once it is made
        check_report_folder(out, force=args.force)
    # Ray is connected before any file is made: an address that does not answer leaves none.
    with ray_session(args.address, args.workers, "--address") if args.executor == "ray" \
            else contextlib.nullcontext():
        return _report(args, chosen, levels)


def _report(args, chosen, levels) -> int:
    """Measure and write the two-link report into --out (checked first)."""
    out = args.out or output_dir() / chosen.folder
    check_report_folder(out, force=args.force)
    out.mkdir(exist_ok=True)
    progress = not args.json          # bars on a terminal, periodic lines in a log
    with CellFile(out / "sweep.jsonl") as store:    # a second run on `out` stops here
        if store.note:
            print(f"twolink mismatch: {store.note}", file=sys.stderr)
        report, data = build(chosen, args.policies, store=store, executor=args.executor,
                             workers=args.workers, address=args.address,
                             log=(lambda m: print(m, file=sys.stderr, flush=True))
                             if progress else None, progress=progress,
                             robust=args.robust, levels=levels, seed=args.seed)
        command = "twolink mismatch" + ("" if chosen.name == "full" else f" --plan {chosen.name}")
        command += "".join(f" {a}" for a in _robust_args(args))
        report = write(report, data, out, command)
    if args.json:
        print(json.dumps(summary(report), indent=2))
    else:
        for p, d in summary(report)["successes"].items():
            print(f"{p:26s} " + "  ".join(f"{pl} {format_rate(*kn):<24s}" for pl, kn in d.items()))
        print(f"wrote {out / 'report.md'}")
    return 0
