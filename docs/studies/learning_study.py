"""Policy (14) against the discrete learner's own greedy policy, at every evaluation.

``python docs/studies/learning_study.py --seed 99 --steps 1.2e6 [--init decentralized]``: learns
the ordered agents with the discrete update (4) on MuJoCo (256 arms) and evaluates, at
every checkpoint, both the saved policy (14), sum_m mu_m argmax_u theta[m, u], and the
policy the learner acts on, argmax_u sum_m mu_m theta[m, u] (docs/results/learning.md, "why the
discrete update oscillates"). Prints one line per evaluation.
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
from twolink.policy.fuzzy_policy import load_policy  # noqa: E402


class OwnGreedy:
    """argmax_u of the interpolated Q of every agent, in acting order (agent 2 first)."""

    kind = "decentralized"

    def __init__(self, agents):
        self.agents = agents

    def __call__(self, x):
        x = np.asarray(x, dtype=float)
        flat = x.reshape(-1, 4)
        sig = {"theta1": flat[:, 0], "theta2": flat[:, 1], "dtheta1": flat[:, 2],
               "dtheta2": flat[:, 3]}
        for a in self.agents:
            idx, w = a.grid.memberships(np.stack([sig[k] for k in a.grid.names], -1))
            out = a.actions[greedy_index(np.einsum("nk,nku->nu", w, a.theta[idx]))]
            for k, name in enumerate(a.outputs):
                sig[name] = out[:, k]
        return np.stack([sig["tau1"], sig["tau2"]], -1).reshape(x.shape[:-1] + (2,))


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seed", type=int, default=99, help="seed (default 99, the seed the learner's settings were chosen on)")
    p.add_argument("--steps", type=float, default=1.2e6)
    p.add_argument("--arms", type=int, default=256)
    p.add_argument("--init", default=None, help="warm-start policy (e.g. decentralized)")
    args = p.parse_args(argv)
    steps = int(args.steps)
    cfg = LearnConfig(learner="decentralized", update="discrete", steps=steps,
                      arms=args.arms, seed=args.seed, eval_every=steps // 16)
    with Learner(cfg, init=load_policy(args.init) if args.init else None) as learner:
        def show(e):
            own = evaluate(OwnGreedy(learner.agents), learner.plant)
            print(f"{e.steps:>9} steps  policy (14): {e.successes}/{e.n}  "
                  f"own argmax Q: {own.successes}/{own.n}", flush=True)
        learner.run(on_eval=show)
    return 0


if __name__ == "__main__":
    sys.exit(main())
