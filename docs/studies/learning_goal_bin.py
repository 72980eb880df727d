"""Why the per-rule fuzzy updates lose a good policy: agent 2's goal bin .

``python docs/studies/learning_goal_bin.py [--update rule] [--alpha 0.2] [--seed 99]``
evaluates the (6) policy on MuJoCo as shipped and with only agent 2's goal bin
(theta2 = 0, dtheta2 = 0) made to prefer -tau2 or +tau2, then learns from (6) with the
given update (decentralized, 256 arms) and prints, every 25 batched steps, success, how
many greedy actions flipped (all bins, and bins within 6 deg / 0.6 rad/s of the goal) and
agent 2's goal-bin values.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import numpy as np  # noqa: E402

from twolink.synthesis.learning import Learner, evaluate, greedy_index  # noqa: E402
from twolink.synthesis.learning_setup import LearnConfig  # noqa: E402
from twolink.policy.fuzzy_policy import Agent, Policy, load_policy  # noqa: E402
from twolink.sim.plants import MujocoPlant  # noqa: E402


def _goal_bin(agent) -> int:
    return int(np.ravel_multi_index(tuple(list(ax.centers).index(0.0) for ax in agent.grid.axes),
                                    agent.grid.shape))


def _near_goal(agent) -> np.ndarray:
    cen = np.stack(np.meshgrid(*[np.array(ax.centers) for ax in agent.grid.axes],
                               indexing="ij"), -1).reshape(-1, len(agent.grid.axes))
    k = 2 if agent.name == "agent2" else 3          # angles and speeds, not tau2
    return np.all(np.abs(cen[:, :k]) < 0.6, axis=1)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--update", default="rule")
    ap.add_argument("--alpha", type=float, default=0.2)
    ap.add_argument("--seed", type=int, default=99)
    ap.add_argument("--blocks", type=int, default=8)
    args = ap.parse_args(argv)
    init = load_policy("decentralized_full")
    with MujocoPlant() as plant:
        print(f"(6) as shipped: {evaluate(init, plant).successes}/65")
        for u, name in ((0, "-tau2"), (2, "+tau2")):
            agents = []
            for a in init.agents:
                q = np.array(a.q, dtype=float)
                if a.name == "agent2":
                    i = _goal_bin(a)
                    q[i] = q[i].min() - 1.0
                    q[i, u] = 0.0
                agents.append(Agent(a.name, a.grid, a.actions, q, a.outputs, a.info))
            e = evaluate(Policy(init.kind, agents, init.meta), plant)
            print(f"(6), agent 2's goal bin preferring {name}: {e.successes}/65")
    cfg = LearnConfig(learner="decentralized", steps=256 * 25 * args.blocks, arms=256,
                      seed=args.seed, update=args.update, alpha=args.alpha)
    with Learner(cfg, init=init) as learner:
        g0 = [greedy_index(a.theta) for a in learner.agents]
        a2 = learner.agents[0]
        print(f"from (6), {args.update}, alpha {args.alpha}: agent 2 goal bin "
              f"{np.round(a2.theta[_goal_bin(a2)], 2)}")
        for _ in range(args.blocks):
            for _ in range(25):
                learner.step()
            e = learner.evaluate()
            parts = []
            for a, g in zip(learner.agents, g0):
                flipped = greedy_index(a.theta) != g
                parts.append(f"{a.name} {flipped.sum()} flipped ({(flipped & _near_goal(a)).sum()} "
                             f"near goal)")
            q = a2.theta[_goal_bin(a2)]
            print(f"{learner.steps_done:>7} steps {e.successes:>2}/65  {'; '.join(parts)}; "
                  f"agent 2 goal bin {np.round(q, 2)} (spread {np.ptp(q):.2f}, greedy "
                  f"{greedy_index(q)})", flush=True)


if __name__ == "__main__":
    main()
