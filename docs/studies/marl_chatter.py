"""How far a multi-agent controller's policy means sit outside [-1, 1], and how often they flip.

``python docs/studies/marl_chatter.py AGENT [AGENT ...] [--json]`` runs each agent (a
``.marl.pt`` path or a catalogue name such as ``ippo_medium``) on the nominal two-link arm
in MuJoCo from the 65 states of the evaluation set for 5 s, records every agent's mean
action a_i (the policy's output before the controller clips it to [-1, 1]) at every
sample, and prints per agent: the fraction of samples with |a_i| > 1 (the torque at its
limit whatever the mean), the median |a_i|, and the fraction of samples whose sign differs
from the sample before (a torque that chatters between the limits flips at nearly every
sample). The training guide quotes it for the IPPO agents trained under ``medium`` with
and without ``--std-floor``.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import numpy as np  # noqa: E402

import twolink.control.marl_agent as marl_agent  # noqa: E402
from twolink.control.learned import LEARNED, learned_agent  # noqa: E402
from twolink.sim.metrics import evaluation_set  # noqa: E402
from twolink.sim.plants import make_plant  # noqa: E402
from twolink.sim.rollout import rollout  # noqa: E402


def means(spec: str) -> np.ndarray:
    """The mean actions (samples, states, agents) of the controller ``spec`` over the
    nominal rollouts."""
    if spec in LEARNED:
        agent = learned_agent(spec)
    elif spec.endswith(".marl.pt"):
        agent = marl_agent.load_marl_agent(spec)
    else:
        raise SystemExit(f"marl_chatter: {spec} is neither a catalogue name nor a .marl.pt")
    if not isinstance(agent, marl_agent.MarlController):
        raise SystemExit(f"marl_chatter: {spec} is not a multi-agent (.marl.pt) controller")
    seen = []
    clip = marl_agent.residual_torques

    def spy(base, x, a, tau):
        seen.append(np.array(a, dtype=float))
        return clip(base, x, a, tau)

    marl_agent.residual_torques = spy
    try:
        with make_plant("mujoco") as plant:
            rollout(agent, plant, evaluation_set(), duration=5.0)
    finally:
        marl_agent.residual_torques = clip
    return np.stack(seen)


def measure(spec: str) -> dict:
    a = means(spec)
    flips = np.diff(np.sign(a), axis=0) != 0
    return {"agent": spec, "samples": int(a.shape[0] * a.shape[1]),
            "beyond_limits": np.round((np.abs(a) > 1).mean(axis=(0, 1)), 4).tolist(),
            "median_abs": np.round(np.median(np.abs(a), axis=(0, 1)), 4).tolist(),
            "sign_flips": np.round(flips.mean(axis=(0, 1)), 4).tolist()}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("agents", nargs="+", metavar="AGENT")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    from twolink.sim.controller import ControllerError

    try:
        rows = [measure(s) for s in args.agents]
    except (ControllerError, OSError, ValueError) as exc:
        raise SystemExit(f"marl_chatter: {exc}") from None
    if args.json:
        print(json.dumps(rows, indent=1))
        return 0
    for r in rows:
        print(f"{r['agent']}: |a| > 1 in {r['beyond_limits']} of the samples per agent, "
              f"median |a| {r['median_abs']}, sign flips {r['sign_flips']}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
