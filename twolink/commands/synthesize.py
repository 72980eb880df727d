"""``twolink synthesize``: fuzzy Q-iteration of a policy, saved as a policy file.

By default the policy goes to a new file in the current directory, named after what was
synthesised (``./<kind>[_<model>][_<context>][_serial][_refine<K>].npz``), and an existing
file is kept unless ``--force``. ``--sweeps`` picks Alg. 1's sweeps (synchronous as printed,
or serial, in place, as ApproxRL's ``fuzzyqi.m``), ``--refine K`` subdivides every bin of
the paper's grid K times; both are recorded in the policy's provenance.
``--robust worst|mean --draws K --spread P --seed S`` solves every agent over K models (the
centre and K - 1 joint draws of the physical parameters within +-P): the worst case or the
mean (:func:`twolink.synthesis.synthesize.synthesize`). ``--params FILE`` takes the centre from a
parameter file (:mod:`twolink.arm.parameter_file`); ``--model identified`` is the full model (6)
with them. ``--ship NAME`` (repeatable, or ``all``) re-synthesises a shipped policy of
:data:`twolink.policy.registry.SHIPPED` into the source checkout's ``policies/``, with everything
its registry entry records: the file of its table, ``policies/<table>.npz`` named by the
synthesis settings (:func:`twolink.policy.registry.table_stem`). ``--links N`` (with
``--rule``) synthesises the agents of an N-link arm
(:mod:`twolink.synthesis.links_decentralized`) into ``./decentralized_<N>link[_<rule>].npz``;
the centralized policy of N >= 3 links is refused before any work, with its estimate
(:func:`twolink.synthesis.links_centralized.check_size`): over the memory cap, or over what a policy
file may hold.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

from twolink._imports import renamed
from twolink.arm.parameters import DELTA, GAMMA, GOAL_SPEED, TABLE_I
from twolink.arm.task import MAX_LEVELS, PAPER_LEVELS
from twolink.artifacts import check_outputs, output_file
from twolink.commands import SUMMARIES
from twolink.commands.grammar import add_out, deprecated
from twolink.commands._options import add_arm_options, arm_of
from twolink.synthesis.problems import (
    CONTEXTS,
    IDENTIFIED_MODELS,
    KINDS,
    LINK1_READINGS,
    SWEEPS,
    SYNTHESIS_MODELS,
)
from twolink.synthesis.settings import SynthesisSettings
from twolink.synthesis.synthesize import synthesize
from twolink.fqi.fuzzy import BIN_LAYOUTS
from twolink.fqi.iteration import ROBUST_MODES
from twolink.policy.fuzzy_policy import (
    MAX_Q_BYTES,  # what Policy.load accepts per Q-table
)
from twolink.policy.readout import MIN_ARGMAX_DEG, NEAR_DEG_RANGE, Readout
from twolink.policy.registry import SHIPPED, shipped
from twolink.resources import source_checkout
from twolink.sim.perturbations import MAX_SPREAD

#: Defaults of a robust synthesis (those of the shipped robust policies).
DEFAULT_DRAWS = 8
DEFAULT_SPREAD = 0.2
DEFAULT_SEED = 0


def default_file_name(kind: str, model: str = "simplified", context: str = "frozen",
                      sweeps: str = "synchronous", refine: int = 1,
                      robust: str | None = None, levels: int = PAPER_LEVELS,
                      bins: str = "paper", agent2_link1: str = "free") -> str:
    """``<kind>[_<model>][_<context>][_<sweeps>][_refine<K>][_<L>levels][_<bins>bins]
    [_locked][_robust|_mean].npz``, each part
    only when not the default (so the five shipped nominal combinations get their registry
    names)."""
    name = kind + ("" if model == "simplified" else f"_{model}")
    if kind == "decentralized" and context != "frozen":
        name += f"_{context}"
    if sweeps != "synchronous":
        name += f"_{sweeps}"
    if refine != 1:
        name += f"_refine{refine}"
    if levels != PAPER_LEVELS:
        name += f"_{levels}levels"
    if bins != "paper":
        name += f"_{bins}bins"
    if agent2_link1 != "free":
        name += f"_{agent2_link1}"
    if robust is not None:
        name += "_robust" if robust == "worst" else f"_{robust}"
    return f"{name}.npz"


def _refine(text: str) -> int:
    try:
        k = int(text)
    except ValueError:
        k = 0
    if k < 1:
        raise argparse.ArgumentTypeError(f"must be a positive whole number, got {text!r}")
    return k


def add_parser(sub):
    p = sub.add_parser(
        "synthesize", help=SUMMARIES["synthesize"],
        description="Synthesise the centralized policy (16) or the decentralized agents (18) "
                    "with fuzzy Q-iteration and save them as a policy file: by default "
                    "./<kind>[_<model>][_<context>][_robust|_mean].npz in the current "
                    "directory (an existing file is kept unless --force); --robust solves "
                    "every agent over --draws parameter draws (worst case or mean); --ship "
                    "NAME rewrites a shipped policy under policies/ of a source checkout.")
    p.add_argument("kind", nargs="?", choices=KINDS, help="policy kind (not with --ship)")
    p.add_argument("--model", choices=SYNTHESIS_MODELS + tuple(IDENTIFIED_MODELS), default=None,
                   help="model used for the transitions (default: simplified, the paper's (11)); "
                        "identified: the full model (6) with the parameters of --params")
    p.add_argument("--context", choices=CONTEXTS, default=None,
                   help="agent 1's reading of link 2 over a transition (decentralized only; "
                        "default: frozen)")
    p.add_argument("--sweeps", choices=SWEEPS, default=None,
                   help="Alg. 1's sweeps: synchronous (as printed, the default) or serial "
                        "(each Q(m, u) overwritten at once, bins in Matlab's order, as "
                        "ApproxRL's fuzzyqi.m)")
    p.add_argument("--refine", type=_refine, default=None, metavar="K",
                   help="subdivide every bin of the paper's grid K times (default 1: the "
                        "paper's grid; see the README's 'Finer grids')")
    p.add_argument("--levels", default=None, metavar="L",
                   help=f"torque levels per joint, evenly spaced over [-tau_max, tau_max], "
                        f"2 to {MAX_LEVELS} (default 3: the paper's -tau_max, 0, tau_max)")
    p.add_argument("--bins", default=None, metavar="LAYOUT",
                   help=f"bin layout of the angles and speeds: {', '.join(BIN_LAYOUTS)} "
                        f"(default paper; goal: concentrated around the goal band; edge: "
                        f"no centre on the band's edge, 4 and 9 deg around it)")
    p.add_argument("--speed-dead-zone", default=None, metavar="W",
                   help=f"read every speed through a dead zone of W rad/s, 0 <= W <= "
                        f"{GOAL_SPEED} (twolink.policy.readout; default 0: none), recorded "
                        f"in the file")
    p.add_argument("--argmax-beyond-deg", dest="argmax_beyond", default=None, metavar="DEG",
                   help=f"where an agent reads an angle beyond DEG degrees ({MIN_ARGMAX_DEG:g} "
                        f"to 180), act by the argmax of the interpolated Q instead of (14)'s "
                        f"weighted greedy actions (twolink.policy.readout; default: (14) "
                        f"everywhere), recorded in the file")
    p.add_argument("--near-gain", default=None, metavar="G",
                   help="lower the torque near the goal: joint i's torque times G + (1 - G) "
                        "min(|theta_i| / A, 1), 0 < G <= 1, A from --near-deg "
                        "(twolink.policy.readout; default 1: (14)'s torque), recorded in "
                        "the file")
    p.add_argument("--near-deg", default=None, metavar="A",
                   help=f"the angle (degrees, {NEAR_DEG_RANGE[0]:g} to {NEAR_DEG_RANGE[1]:g}) "
                        f"beyond which --near-gain leaves the torque full; needed with it")
    p.add_argument("--agent2-link1", choices=LINK1_READINGS, default=None,
                   help="how agent 2's transitions read link 1 (decentralized, full model "
                        "only): free (the paper's: link 1 at rest, recoiling under link "
                        "2's reaction; the default) or locked (joint 1 held), recorded in "
                        "the file")
    p.add_argument("--robust", choices=ROBUST_MODES, default=None,
                   help="robust synthesis over --draws models: worst (Q = min over the "
                        "models of rho_k + gamma T_k V) or mean (their average)")
    p.add_argument("--draws", default=None, metavar="K",
                   help=f"models of a robust synthesis: the centre and K - 1 random draws "
                        f"(default {DEFAULT_DRAWS}; memory is estimated and capped first)")
    p.add_argument("--spread", default=None, metavar="P",
                   help=f"relative spread of the draws: every physical parameter (l, m, I, "
                        f"c, b of both links) uniform in +-P jointly, 0 <= P < {MAX_SPREAD} "
                        f"(default {DEFAULT_SPREAD})")
    p.add_argument("--seed", default=None, metavar="S",
                   help=f"seed of the draws (default {DEFAULT_SEED}); recorded in the file")
    p.add_argument("--params", type=Path, default=None, metavar="FILE",
                   help="take the model's parameters (the centre of the draws) from a "
                        "parameter file (twolink.arm.parameter_file, e.g. identified ones) "
                        "instead of Table I")
    p.add_argument("--gamma", type=float, default=GAMMA, help=f"discount factor (default {GAMMA})")
    p.add_argument("--delta", type=float, default=DELTA,
                   help=f"stop when max |Q_l - Q_(l-1)| <= delta (default {DELTA})")
    deprecated(p, "synthesize", "--argmax-beyond", "--argmax-beyond-deg", dest="argmax_beyond")
    add_out(p, "synthesize", default=None, metavar="FILE",
            help="policy file to write (default: "
                 "./<kind>[_<model>][_<context>][_robust|_mean].npz)")
    p.add_argument("--force", action="store_true", help="overwrite an existing output file")
    p.add_argument("--ship", action="append", metavar="NAME", default=None,
                   help="re-synthesise the shipped policy NAME into policies/ of the source "
                        f"checkout (repeatable; 'all' for every one: {', '.join(SHIPPED)})")
    add_arm_options(p)
    p.add_argument("--json", action="store_true", help="print the synthesis summary as JSON")
    return p


def links_file_name(kind: str, links: int, rule: str, context: str | None = None) -> str:
    """``<kind>_<N>link[_<rule>][_<context>].npz``: the rule when not tapered, the
    context when given and not the N-link default (so the shipped one gets its name)."""
    from twolink.synthesis.links_decentralized import LINKS_DEFAULT

    name = f"{kind}_{links}link" + ("" if rule == "tapered" else f"_{rule}")
    if context is not None and context != LINKS_DEFAULT.context:
        name += f"_{context}"
    return f"{name}.npz"


#: The option of each settings field whose one-line error names the field first.
_OPTION_OF = {"gamma": "--gamma", "delta": "--delta", "draws": "--draws",
              "spread": "--spread", "seed": "--seed", "levels": "--levels",
              "refine": "--refine", "links": "--links"}


def settings_of(**fields) -> SynthesisSettings:
    """The :class:`SynthesisSettings` of ``fields``; a one-line error that names a field
    first names its option instead (``draws must ...`` reads ``--draws must ...``)."""
    try:
        return SynthesisSettings(**fields)
    except ValueError as e:
        text = str(e)
        word = text.split(" ", 1)[0]
        if word in _OPTION_OF:
            raise ValueError(_OPTION_OF[word] + text[len(word):]) from None
        raise


def _links_job(args, links: int) -> tuple[SynthesisSettings, Path]:
    """(settings, output) of an N-link synthesis (N >= 3), checked; the two-link options
    and the centralized table that no policy file can hold refused."""
    two_link = [o for o, given in (
        ("--model simplified", args.model == "simplified"),
        (f"--model {args.model}", args.model in IDENTIFIED_MODELS),
        ("--robust", args.robust is not None), ("--draws", args.draws is not None),
        ("--spread", args.spread is not None), ("--seed", args.seed is not None),
        ("--sweeps serial", (args.sweeps or "synchronous") != "synchronous"),
        ("--refine", args.refine not in (None, 1))) if given]
    if args.params is not None:
        raise ValueError(f"--params {args.params}: a parameter file describes a 2-link arm; "
                         f"--links {links} extends Table I by --rule")
    if two_link:
        raise ValueError(f"{', '.join(two_link)}: a two-link option; a {links}-link arm is "
                         f"synthesised on its full model, synchronous sweeps, the paper's "
                         f"grid")
    if args.kind == "centralized":
        if args.context is not None:
            raise ValueError("--context applies to the decentralized policy only")
        from twolink.synthesis.links_centralized import check_size
        est = check_size(links)                   # refuses over the memory cap, estimate
        if est.q_bytes > MAX_Q_BYTES:
            raise ValueError(f"a centralized {links}-link Q-table of {est.q_values:,} values "
                             f"({est.q_bytes / 2**30:.3g} GiB; synthesis needs about "
                             f"{est.peak_bytes / 2**30:.3g} GiB) is over the "
                             f"{MAX_Q_BYTES >> 20} MiB a policy file may hold; twolink "
                             f"scaling synthesises it in memory")
    settings = settings_of(kind=args.kind, links=links, rule=args.rule,
                           context=args.context, gamma=args.gamma, delta=args.delta)
    out, folders = output_file(args.output, links_file_name(args.kind, links, args.rule,
                                                            args.context))
    check_outputs({"-o": out}, creatable=folders)
    if out.exists() and not args.force:
        raise OSError(f"{out} exists; give --force to overwrite it or -o another file")
    return settings, out


def _number(text, option: str, kind: type):
    """``text`` as a ``kind`` (int or float), or a ValueError naming ``option``."""
    try:
        value = kind(text)
    except (TypeError, ValueError):
        value = None
    if value is None or (kind is float and not value == value):
        what = "a whole number" if kind is int else "a number"
        raise ValueError(f"{option} must be {what}, got {text!r}")
    return value


def _design_options(args) -> dict:
    """The settings' levels, bins, readout and agent2_link1 from --levels, --bins, the
    read-out options and --agent2-link1 (a two-link synthesis only); the read-out's
    options checked here, the rest by the settings."""
    opts = {}
    if args.levels is not None:
        opts["levels"] = _number(args.levels, "--levels", int)
    if args.bins is not None:
        opts["bins"] = args.bins
    width, beyond = 0.0, None
    if args.speed_dead_zone is not None:
        width = _number(args.speed_dead_zone, "--speed-dead-zone", float)
        if not 0.0 <= width <= GOAL_SPEED:
            raise ValueError(f"--speed-dead-zone must lie in [0, {GOAL_SPEED}] rad/s (the "
                             f"goal band's speed), got {args.speed_dead_zone}")
    if args.argmax_beyond is not None:
        beyond = _number(args.argmax_beyond, "--argmax-beyond-deg", float)
        if not MIN_ARGMAX_DEG <= beyond <= 180.0:
            raise ValueError(f"--argmax-beyond-deg must lie in [{MIN_ARGMAX_DEG:g}, 180] degrees, "
                             f"got {args.argmax_beyond}")
    gain, near = 1.0, None
    if args.near_gain is not None:
        gain = _number(args.near_gain, "--near-gain", float)
        if not 0.0 < gain <= 1.0:
            raise ValueError(f"--near-gain must lie in (0, 1], got {args.near_gain}")
        if args.near_deg is None and gain < 1.0:
            raise ValueError("--near-gain needs --near-deg, the angle (degrees) at which the "
                             "torque is full again")
    if args.near_deg is not None:
        if args.near_gain is None:
            raise ValueError("--near-deg goes with --near-gain")
        near = _number(args.near_deg, "--near-deg", float)
        if not NEAR_DEG_RANGE[0] <= near <= NEAR_DEG_RANGE[1]:
            raise ValueError(f"--near-deg must lie in [{NEAR_DEG_RANGE[0]:g}, "
                             f"{NEAR_DEG_RANGE[1]:g}] degrees, got {args.near_deg}")
    if width or beyond is not None or gain < 1.0:
        opts["readout"] = Readout(speed_dead_zone=width, argmax_beyond_deg=beyond,
                                  near_gain=gain, near_deg=near)
    if args.agent2_link1 is not None:
        opts["agent2_link1"] = args.agent2_link1
    return opts


def _robust_options(args) -> dict:
    """The settings' robust, draws, spread and seed from --robust/--draws/--spread/--seed
    (the draws' defaults filled in; their ranges are the settings' checks)."""
    given = [o for o, v in (("--draws", args.draws), ("--spread", args.spread),
                            ("--seed", args.seed)) if v is not None]
    if args.robust is None:
        if given:
            verb = "applies" if len(given) == 1 else "apply"
            raise ValueError(f"{', '.join(given)} {verb} to a robust synthesis only: give "
                             f"--robust worst or --robust mean")
        return {}
    draws = DEFAULT_DRAWS if args.draws is None else _number(args.draws, "--draws", int)
    spread = DEFAULT_SPREAD if args.spread is None else _number(args.spread, "--spread", float)
    seed = DEFAULT_SEED if args.seed is None else _number(args.seed, "--seed", int)
    return {"robust": args.robust, "draws": draws, "spread": spread, "seed": seed}


def _parameters(args) -> tuple:
    """(ArmParameters, provenance of their file or None) from --params, or Table I."""
    if args.params is None:
        if args.model in IDENTIFIED_MODELS:
            raise ValueError(f"--model {args.model} needs --params FILE (the identified "
                             f"parameters)")
        return TABLE_I, None
    from twolink.arm import parameter_file
    content = parameter_file.read(args.params)
    digest = json.loads(Path(args.params).read_bytes()).get("sha256")
    return content.params, {"path": str(args.params), "sha256": digest,
                            "provenance": content.provenance}


def _jobs(args) -> list[tuple[SynthesisSettings, Path]]:
    """(settings, output path) for every policy to write; all checked before any work."""
    links, _ = arm_of(args)
    if args.ship:
        if args.kind or args.model or args.context or args.output or args.force \
                or args.sweeps or args.refine or args.gamma != GAMMA or args.delta != DELTA \
                or args.robust or args.draws is not None or args.spread is not None \
                or args.seed is not None or args.params is not None or links != 2 \
                or args.rule != "tapered" or args.levels is not None \
                or args.bins is not None or args.speed_dead_zone is not None \
                or args.argmax_beyond is not None or args.agent2_link1 is not None \
                or args.near_gain is not None or args.near_deg is not None:
            raise ValueError("--ship takes everything from the registry: give no kind, "
                             "--model, --context, --sweeps, --refine, --robust, --draws, "
                             "--spread, --seed, --params, --gamma, --delta, --links, --rule, "
                             "--levels, --bins, --speed-dead-zone, --argmax-beyond-deg, "
                             "--near-gain, --near-deg, --agent2-link1, -o or --force with "
                             "it")
        names = list(SHIPPED) if "all" in args.ship else list(dict.fromkeys(args.ship))
        # A read-out entry ships as the stored Q-tables it reads: its table's owner entry.
        entries = [SHIPPED[o] for o in dict.fromkeys(shipped(n).table_owner for n in names)]
        if source_checkout() is None:
            raise RuntimeError("--ship writes into policies/ of a source checkout, and this "
                               "twolink is an installed package; use -o FILE instead")
        return [(SynthesisSettings.shipped(e.name), e.file) for e in entries]
    if args.kind is None:
        raise ValueError("give a policy kind (centralized or decentralized) or --ship NAME")
    if links != 2:
        given = [o for o, v in (("--levels", args.levels), ("--bins", args.bins),
                                ("--speed-dead-zone", args.speed_dead_zone),
                                ("--argmax-beyond-deg", args.argmax_beyond),
                                ("--near-gain", args.near_gain),
                                ("--near-deg", args.near_deg),
                                ("--agent2-link1", args.agent2_link1)) if v is not None]
        if given:
            raise ValueError(f"{', '.join(given)}: two-link options; a {links}-link arm takes "
                             f"the paper's levels and bins")
        return [_links_job(args, links)]
    if args.kind == "centralized" and args.context is not None:
        raise ValueError("--context applies to the decentralized policy only")
    robust = _robust_options(args)
    design = _design_options(args)
    p, source = _parameters(args)
    s = settings_of(kind=args.kind, model=args.model, context=args.context,
                    gamma=args.gamma, delta=args.delta, sweeps=args.sweeps or "synchronous",
                    refine=args.refine or 1, parameters=p, source=source, **robust, **design)
    out, folders = output_file(args.output, default_file_name(
        s.kind, s.model, s.context or "frozen", s.sweeps, s.refine, s.robust, s.levels,
        s.bins, s.agent2_link1))
    check_outputs({"-o": out}, creatable=folders)
    if out.exists() and not args.force:
        raise OSError(f"{out} exists; give --force to overwrite it or -o another file")
    return [(s, out)]


def _unchanged(out: Path, policy) -> bool:
    """Whether the shipped file ``out`` holds ``policy`` already (the same Q-tables bit for
    bit, :func:`twolink.policy.fuzzy_policy.same_tables`): --ship then keeps the file as it
    is, with its timings and provenance, so a re-ship of unchanged policies changes no byte."""
    from twolink.policy.fuzzy_policy import Policy, same_tables

    try:
        return out.is_file() and same_tables(Policy.load(out), policy)
    except (ValueError, OSError):          # a file Policy.load refuses is replaced
        return False


def run(args) -> int:
    jobs = _jobs(args)
    summary = []
    for settings, out in jobs:
        policy = synthesize(settings, progress=not args.json)
        kept = bool(args.ship) and _unchanged(out, policy)
        if not kept:
            out.parent.mkdir(exist_ok=True)      # -o DIR/: DIR passed check_outputs
            policy.save(out)
        info = {a.name: a.info for a in policy.agents}
        arm = {} if policy.links == 2 else {"links": policy.links, "rule": policy.meta["rule"]}
        summary.append({"path": str(out), "kind": policy.kind, **arm, "agents": info,
                        **({"unchanged": True} if kept else {})})
        if not args.json:
            for name, i in info.items():
                over = f" ({i['robust']} case over {i['draws']} models)" if "robust" in i else ""
                print(f"{name}: Q size {i['q_size']}, {i['iterations']} {i['sweeps']} "
                      f"sweeps{over}, {i['seconds']:.3f} s ({i['transition_seconds']:.3f} s "
                      f"transitions, {i['sweep_seconds']:.3f} s sweeps)")
            print(f"kept {out}: its Q-tables are these bit for bit" if kept
                  else f"wrote {out}")
    if args.json:
        print(json.dumps(summary[0] if len(summary) == 1 and not args.ship else summary,
                         indent=2))
    return 0


#: The names of 0.1 that said *chain*, kept until the next release (with a
#: DeprecationWarning; twolink._imports.renamed).
__getattr__ = renamed(__name__, {
    "chain_file_name": "links_file_name"
})
