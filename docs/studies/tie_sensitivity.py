"""How sensitive the shipped policies are to round-off in their Q-tables.

For each policy, policy (14) is rebuilt from its Q-tables under a variant of the greedy
rule: the shipped rule (the first action within ``TIE_TOLERANCE`` of the best), a plain
argmax (round-off decides near-ties), argmax after rounding Q to 1e-9, and argmax or the
shipped rule after adding +-eps (random signs, eps = 1e-12 ... 1e-6) to every Q-value.
Each variant is run on the simplified plant (11) from the paper's x0 and from random
states (angles uniform in [-pi, pi), at rest, as ``twolink rollout --x0 random``) drawn
from ``--seed``. Printed per variant: greedy bins that differ from the shipped rule,
success k/n with a 95 % Wilson interval, and how many failures are arms parked at rest
within 1e-5 deg of the 5 deg band edge. Also measured per policy: the bins whose best two
Q-values are exactly equal or closer than 1.5e-14 (round-off), and the smallest gap
between the best two above the tie tolerance (the genuine gaps).

``--json PATH`` also merges the run into PATH (schema ``twolink.tie_sensitivity``,
version 1: one entry of ``runs`` per states, seed and policies; a rerun replaces its
entry), from which ``python docs/generate.py`` writes docs/results/round-off.md.

Run: .venv/bin/python docs/studies/tie_sensitivity.py [--states 100] [--seed 0]
     [--json renders/tie_sensitivity/tie_sensitivity.json]
"""
from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import time

import numpy as np

from twolink.arm.parameters import PAPER_X0
from twolink.artifacts import check_outputs, provenance, read_runs, write_json
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
#: A gap between the best two Q-values below this is round-off of the sweeps' sums.
ROUND_OFF = 1.5e-14
#: What the --json file calls itself; docs/generate.py refuses any other.
SCHEMA, VERSION = "twolink.tie_sensitivity", 1


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


def gaps(names) -> list[dict]:
    """Per agent of each policy: its bins, how many have their best two Q-values exactly
    equal, how many closer than :data:`ROUND_OFF` (not equal), and the smallest gap
    between the best two above ``TIE_TOLERANCE``."""
    out = []
    for name in names:
        for a in load_policy(name).agents:
            top = np.sort(a.q, axis=1)[:, -2:]
            gap = top[:, 1] - top[:, 0]
            genuine = gap[gap > TIE_TOLERANCE]
            out.append({"policy": name, "agent": a.name, "bins": int(a.q.shape[0]),
                        "exact_ties": int(np.count_nonzero(gap == 0)),
                        "round_off_ties": int(np.count_nonzero((gap > 0) & (gap < ROUND_OFF))),
                        "within_tolerance": int(np.count_nonzero(gap <= TIE_TOLERANCE)),
                        "smallest_genuine_gap": float(genuine.min()) if len(genuine) else None})
    return out


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
    parser.add_argument("--json", default=None, metavar="PATH",
                        help="also write the rows to PATH (versioned JSON)")
    args = parser.parse_args(argv)
    if args.states < 1:
        parser.error("--states must be at least 1")
    if args.json:
        try:
            check_outputs({"--json": args.json})
            old = read_runs(args.json, SCHEMA, VERSION)
        except (OSError, ValueError) as exc:
            parser.error(str(exc))
    names = args.policy or [n for n, e in SHIPPED.items() if e.paper]
    start = time.perf_counter()
    rows = measure(names, states=args.states, seed=args.seed)
    ties = gaps(names)
    seconds = time.perf_counter() - start
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
    print(f"\nbest two Q-values per bin: exactly equal, closer than {ROUND_OFF:g} (round-off), "
          f"within the tolerance {TIE_TOLERANCE:g}; smallest gap above it")
    for t in ties:
        g = t["smallest_genuine_gap"]
        print(f"{t['policy']:<25}{t['agent']:<10}{t['bins']:>6} bins{t['exact_ties']:>6} equal"
              f"{t['round_off_ties']:>6} round-off{t['within_tolerance']:>6} tied   "
              f"{'-' if g is None else f'{g:.2g}'}")
    if args.json:
        run = {"states": args.states, "seed": args.seed, "policies": names,
               "seconds": seconds,
               "rows": [dict(dataclasses.asdict(r), x0_settle=r.x0_settle
                             if math.isfinite(r.x0_settle) else None) for r in rows],
               "ties": ties}
        key = ("states", "seed", "policies")
        kept = [r for r in old["runs"] if [r[k] for k in key] != [run[k] for k in key]]
        write_json(args.json, {
            "schema": SCHEMA, "version": VERSION, "tie_tolerance": TIE_TOLERANCE,
            "round_off": ROUND_OFF, "edge_slack_deg": EDGE_SLACK_DEG,
            "epsilons": list(EPSILONS), "provenance": provenance(), "runs": kept + [run]})
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
