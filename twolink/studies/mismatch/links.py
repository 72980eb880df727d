"""The N-link section of the mismatch report: the numpy full N-link model against MuJoCo.

For an arm of N >= 3 links there is no simplified model (11); the policies are synthesised
on the full N-link model (:func:`twolink.arm.dynamics.links_acceleration`), so the closed-loop
question is whether that model and the MuJoCo arm agree under feedback. Every policy runs
from the same random poses at rest (:func:`twolink.sim.metrics.random_poses`, one seed) on both
plants for one horizon; the section holds, per policy and plant, the score of its runs
(:meth:`twolink.sim.metrics.Score.as_dict`: the successes k/n with their 95 % Wilson
interval and the median settle time), and per policy the largest RMS gap
between a pose's two trajectories. Measurement only: it returns a JSON-ready dict.
"""
from __future__ import annotations

import numpy as np

from twolink.arm.parameters import LinksParameters
from twolink.policy.fuzzy_policy import check_links_match
from twolink.sim.metrics import (
    random_poses,
    score,
    settle_time,
    success,
    trajectory_gap,
)
from twolink.sim.plants import make_plant
from twolink.sim.rollout import rollout

#: The plants compared, the model the policies were synthesised on first.
PLANTS = ("full", "mujoco")


def measure(policies: dict, params: LinksParameters, *, poses: int, seed: int,
            duration: float) -> dict:
    """``policies`` (``{label: Policy}``, all for ``params.links`` links) from ``poses``
    random poses at rest drawn with ``seed``, on the full N-link model and MuJoCo for
    ``duration`` seconds: the section as a dict (see the module docstring)."""
    links = params.links
    if not policies:
        raise ValueError("no policies to measure")
    for label, policy in policies.items():
        check_links_match(policy, links, name=label)
    x0 = random_poses(links, poses, seed)
    results, gaps = {}, {}
    for label, policy in policies.items():
        runs = {}
        for name in PLANTS:
            with make_plant(name, params) as plant:
                runs[name] = rollout(policy, plant, x0, duration=duration, label=label)
        results[label] = {}
        for name, tr in runs.items():
            results[label][name] = score(success(tr), settle_time(tr)).as_dict()
        gap = trajectory_gap(runs["mujoco"], runs["full"])
        gaps[label] = {key: float(np.max(v)) for key, v in gap.items()}
        agree = success(runs["mujoco"]) == success(runs["full"])
        gaps[label]["same_outcome"] = int(agree.sum())
    return {"links": links, "rule": params.rule, "poses": poses, "seed": seed,
            "duration": duration, "plants": list(PLANTS), "results": results, "gap": gaps}
