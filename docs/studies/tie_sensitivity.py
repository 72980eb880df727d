"""How sensitive the shipped policies are to round-off in their Q-tables.

For each policy, policy (14) is rebuilt from its Q-tables under a variant of the greedy
rule: the shipped rule (the first action within ``TIE_TOLERANCE`` of the best), a plain
argmax (round-off decides near-ties), argmax after rounding Q to 1e-9, and argmax or the
shipped rule after adding +-eps (random signs, eps = 1e-12 ... 1e-6) to every Q-value.
Each variant is run on the simplified plant (11) from the paper's x0 and from random
states (angles uniform in [-pi, pi), at rest, as ``twolink rollout --x0 random``) drawn
from ``--seed``. Printed per variant: greedy bins that differ from the shipped rule,
success k/n with a 95 % Wilson interval, and how many failures are arms parked at rest
within 1e-5 deg of the 5 deg band edge.

Run: .venv/bin/python docs/studies/tie_sensitivity.py [--states 100] [--seed 0] [--json]
Used in docs/findings/round-off.md and docs/concepts/agents.md.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import math

import numpy as np

from twolink.arm.parameters import PAPER_X0
from twolink.policy.fuzzy_policy import (
    TIE_TOLERANCE,
    Agent,
    Policy,
    greedy_indices,
    load_policy,
)
from twolink.policy.registry import SHIPPED
from twolink.sim.metrics import (
    settle_time,
    stalled_at_band_edge,
    success,
    wilson_interval,
)
from twolink.sim.plants import make_plant
from twolink.sim.rollout import rollout

#: How close to the band edge (degrees) a parked arm counts as "on the edge".
EDGE_SLACK_DEG = 1e-5
EPSILONS = (1e-12, 1e-10, 1e-8, 1e-6)


@dataclasses.dataclass
class Row:
    policy: str
    variant: str
    changed_bins: int
    bins: int
    successes: int
    states: int
    wilson: tuple
    edge_stalls: int
    x0_settle: float
    x0_final_deg: tuple


def variants(seed: int):
    """(label, q -> (q', tolerance)) for every greedy-rule variant."""
    yield "shipped rule (tolerance 1e-9)", lambda q, rng: (q, TIE_TOLERANCE)
    yield "plain argmax", lambda q, rng: (q, 0.0)
    yield "argmax, Q rounded to 1e-9", lambda q, rng: (np.round(q, 9), 0.0)
    for eps in EPSILONS:
        yield (f"argmax, Q +- {eps:.0e}",
               lambda q, rng, e=eps: (q + e * rng.choice([-1.0, 1.0], q.shape), 0.0))
        yield (f"shipped rule, Q +- {eps:.0e}",
               lambda q, rng, e=eps: (q + e * rng.choice([-1.0, 1.0], q.shape), TIE_TOLERANCE))


def rebuilt(policy: Policy, change, rng) -> tuple[Policy, int, int]:
    """``policy`` with every agent's Q and tolerance changed; bins whose greedy action moved."""
    agents, moved, bins = [], 0, 0
    for a in policy.agents:
        q, tol = change(a.q, rng)
        agents.append(Agent(a.name, a.grid, a.actions, q, a.outputs, a.info, tol))
        moved += int(np.count_nonzero(greedy_indices(q, tol) != greedy_indices(a.q, a.tie_tolerance)))
        bins += a.q.shape[0]
    return Policy(policy.kind, agents, policy.meta), moved, bins


def measure(names, *, states: int = 100, seed: int = 0) -> list[Row]:
    rng = np.random.default_rng(seed)
    x0s = np.zeros((states, 4))
    x0s[:, :2] = rng.uniform(-np.pi, np.pi, (states, 2))
    plant = make_plant("simplified")
    rows = []
    for name in names:
        base = load_policy(name)
        for k, (label, change) in enumerate(variants(seed)):
            pol, moved, bins = rebuilt(base, change, np.random.default_rng([seed, k]))
            ev = rollout(pol, plant, x0s)
            ok = success(ev)
            edge = stalled_at_band_edge(ev, slack_deg=EDGE_SLACK_DEG)
            one = rollout(pol, plant, np.asarray(PAPER_X0, dtype=float))
            st = float(settle_time(one))
            rows.append(Row(name, label, moved, bins, int(ok.sum()), states,
                            wilson_interval(int(ok.sum()), states), int(edge.sum()),
                            st, tuple(np.rad2deg(one.x[-1, :2]).tolist())))
    return rows


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--states", type=int, default=100, help="random states (default 100)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the random states (default 0)")
    parser.add_argument("--policy", action="append", choices=list(SHIPPED), default=None,
                        help="policy to measure, repeatable (default: the paper's three)")
    parser.add_argument("--json", action="store_true", help="print the rows as JSON")
    args = parser.parse_args(argv)
    if args.states < 1:
        parser.error("--states must be at least 1")
    names = args.policy or [n for n, e in SHIPPED.items() if e.paper]
    rows = measure(names, states=args.states, seed=args.seed)
    if args.json:
        print(json.dumps([dataclasses.asdict(r) for r in rows], indent=2))
        return
    print(f"simplified plant (11), {args.states} random states at rest (seed {args.seed}), 5 s; "
          f"moved: greedy bins unlike the shipped rule's; edge: failures at rest within "
          f"{EDGE_SLACK_DEG:g} deg of the 5 deg band edge; x0 theta1: final angle [deg]")
    print(f"{'policy':<25}{'variant':<31}{'moved':>6}{'success':>9}{'Wilson 95%':>12}"
          f"{'edge':>7}{'x0 settle':>10}{'x0 theta1':>13}")
    for r in rows:
        st = "never" if not math.isfinite(r.x0_settle) else f"{r.x0_settle:.2f} s"
        lo, hi = r.wilson
        print(f"{r.policy:<25}{r.variant:<31}{r.changed_bins:>6}"
              f"{f'{r.successes}/{r.states}':>9}{f'[{100 * lo:.0f}, {100 * hi:.0f}] %':>12}"
              f"{f'{r.edge_stalls}/{r.states - r.successes}':>7}{st:>10}"
              f"{f'{r.x0_final_deg[0]:+.7f}':>13}")

if __name__ == "__main__":
    main()
