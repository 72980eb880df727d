"""``twolink synthesize``: fuzzy Q-iteration of a policy, saved as a policy file."""
from __future__ import annotations

import json
from pathlib import Path

from twolink.parameters import DELTA, GAMMA, TABLE_I
from twolink.registry import SHIPPED
from twolink.synthesis import CONTEXTS, KINDS, SYNTHESIS_MODELS, synthesize


def add_parser(sub):
    p = sub.add_parser("synthesize", help="synthesise a policy with fuzzy Q-iteration (Alg. 1)",
                       description="Synthesise the centralized policy (16) or the decentralized "
                                   "agents (18) with fuzzy Q-iteration and save them as a policy file.")
    p.add_argument("kind", choices=KINDS)
    p.add_argument("--model", choices=SYNTHESIS_MODELS, default="simplified",
                   help="model used for the transitions (default: simplified, the paper's (11))")
    p.add_argument("--context", choices=CONTEXTS, default="frozen",
                   help="agent 1's reading of link 2 over a transition (decentralized only; "
                        "default: frozen)")
    p.add_argument("--gamma", type=float, default=GAMMA, help=f"discount factor (default {GAMMA})")
    p.add_argument("--delta", type=float, default=DELTA,
                   help=f"stop when max |Q_l - Q_(l-1)| <= delta (default {DELTA})")
    p.add_argument("-o", "--output", type=Path, default=None,
                   help="policy file to write (default: policies/<kind>.npz)")
    p.add_argument("--json", action="store_true", help="print the synthesis summary as JSON")
    return p


def run(args) -> int:
    policy = synthesize(args.kind, TABLE_I, model=args.model, context=args.context,
                        gamma=args.gamma, delta=args.delta, progress=not args.json)
    out = args.output or SHIPPED[args.kind].file
    policy.save(out)
    info = {a.name: a.info for a in policy.agents}
    if args.json:
        print(json.dumps({"path": str(out), "kind": policy.kind, "agents": info}, indent=2))
    else:
        for name, i in info.items():
            print(f"{name}: Q size {i['q_size']}, {i['iterations']} iterations, "
                  f"{i['seconds']:.3f} s ({i['transition_seconds']:.3f} s transitions, "
                  f"{i['sweep_seconds']:.3f} s sweeps)")
        print(f"wrote {out}")
    return 0
