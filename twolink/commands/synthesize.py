"""``twolink synthesize``: fuzzy Q-iteration of a policy, saved as a policy file.

By default the policy goes to a new file in the current directory, named after what was
synthesised (``./<kind>[_<model>][_<context>][_serial][_refine<K>].npz``), and an existing
file is kept unless ``--force``. ``--sweeps`` picks Alg. 1's sweeps (synchronous as printed,
or serial, in place, as ApproxRL's ``fuzzyqi.m``), ``--refine K`` subdivides every bin of
the paper's grid K times; both are recorded in the policy's provenance. ``--ship NAME`` (repeatable, or ``all``) re-synthesises a shipped policy of
:data:`twolink.registry.SHIPPED` into the source checkout's ``policies/``, with the kind,
model and context of its registry entry.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

from twolink.artifacts import check_outputs
from twolink.parameters import DELTA, GAMMA, TABLE_I
from twolink.registry import SHIPPED, shipped
from twolink.resources import source_checkout
from twolink.policy import MAX_Q_BYTES        # what Policy.load accepts per Q-table
from twolink.synthesis import (CONTEXTS, KINDS, SWEEPS, SYNTHESIS_MODELS, synthesize,
                               table_sizes)


def default_file_name(kind: str, model: str = "simplified", context: str = "frozen",
                      sweeps: str = "synchronous", refine: int = 1) -> str:
    """``<kind>[_<model>][_<context>][_<sweeps>][_refine<K>].npz``, each part only when not
    the default (so the five shipped combinations get their registry names)."""
    name = kind + ("" if model == "simplified" else f"_{model}")
    if kind == "decentralized" and context != "frozen":
        name += f"_{context}"
    if sweeps != "synchronous":
        name += f"_{sweeps}"
    if refine != 1:
        name += f"_refine{refine}"
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
        "synthesize", help="synthesise a policy with fuzzy Q-iteration (Alg. 1)",
        description="Synthesise the centralized policy (16) or the decentralized agents (18) "
                    "with fuzzy Q-iteration and save them as a policy file: by default "
                    "./<kind>[_<model>][_<context>].npz in the current directory (an existing "
                    "file is kept unless --force); --ship NAME rewrites a shipped policy "
                    "under policies/ of a source checkout.")
    p.add_argument("kind", nargs="?", choices=KINDS, help="policy kind (not with --ship)")
    p.add_argument("--model", choices=SYNTHESIS_MODELS, default=None,
                   help="model used for the transitions (default: simplified, the paper's (11))")
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
    p.add_argument("--gamma", type=float, default=GAMMA, help=f"discount factor (default {GAMMA})")
    p.add_argument("--delta", type=float, default=DELTA,
                   help=f"stop when max |Q_l - Q_(l-1)| <= delta (default {DELTA})")
    p.add_argument("-o", "--output", type=Path, default=None,
                   help="policy file to write (default: ./<kind>[_<model>][_<context>].npz)")
    p.add_argument("--force", action="store_true", help="overwrite an existing output file")
    p.add_argument("--ship", action="append", metavar="NAME", default=None,
                   help="re-synthesise the shipped policy NAME into policies/ of the source "
                        f"checkout (repeatable; 'all' for every one: {', '.join(SHIPPED)})")
    p.add_argument("--json", action="store_true", help="print the synthesis summary as JSON")
    return p


def _jobs(args) -> list[tuple[str, dict, Path]]:
    """(kind, synthesize() options, output path) for every policy to write; checks first."""
    if args.ship:
        if args.kind or args.model or args.context or args.output or args.force \
                or args.sweeps or args.refine or args.gamma != GAMMA or args.delta != DELTA:
            raise ValueError("--ship takes everything from the registry: give no kind, "
                             "--model, --context, --sweeps, --refine, --gamma, --delta, -o "
                             "or --force with it")
        names = list(SHIPPED) if "all" in args.ship else list(dict.fromkeys(args.ship))
        entries = [shipped(n) for n in names]
        if source_checkout() is None:
            raise RuntimeError("--ship writes into policies/ of a source checkout, and this "
                               "twolink is an installed package; use -o FILE instead")
        return [(e.kind, e.synthesis_options(), e.file) for e in entries]
    if args.kind is None:
        raise ValueError("give a policy kind (centralized or decentralized) or --ship NAME")
    model = args.model or "simplified"
    context = args.context or "frozen"
    if args.kind == "centralized" and args.context is not None:
        raise ValueError("--context applies to the decentralized policy only")
    sweeps = args.sweeps or "synchronous"
    refine = args.refine or 1
    biggest = max(table_sizes(args.kind, refine).values())
    if biggest * 8 > MAX_Q_BYTES:
        raise ValueError(f"--refine {refine}: a {args.kind} Q-table of {biggest} values "
                         f"({biggest * 8 / 2**20:.0f} MiB) is over the {MAX_Q_BYTES >> 20} "
                         f"MiB a policy file may hold")
    out = args.output or Path(default_file_name(args.kind, model, context, sweeps, refine))
    check_outputs({"-o": out})
    if out.exists() and not args.force:
        raise OSError(f"{out} exists; give --force to overwrite it or -o another file")
    opts = {"model": model, "context": context, "gamma": args.gamma, "delta": args.delta,
            "sweeps": sweeps, "refine": refine}
    return [(args.kind, opts, out)]


def run(args) -> int:
    jobs = _jobs(args)
    summary = []
    for kind, opts, out in jobs:
        policy = synthesize(kind, TABLE_I, progress=not args.json, **opts)
        policy.save(out)
        info = {a.name: a.info for a in policy.agents}
        summary.append({"path": str(out), "kind": policy.kind, "agents": info})
        if not args.json:
            for name, i in info.items():
                print(f"{name}: Q size {i['q_size']}, {i['iterations']} {i['sweeps']} sweeps, "
                      f"{i['seconds']:.3f} s ({i['transition_seconds']:.3f} s transitions, "
                      f"{i['sweep_seconds']:.3f} s sweeps)")
            print(f"wrote {out}")
    if args.json:
        print(json.dumps(summary[0] if len(summary) == 1 and not args.ship else summary,
                         indent=2))
    return 0
