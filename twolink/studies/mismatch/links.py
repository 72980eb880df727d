"""The N-link section of the mismatch report: the numpy full N-link model against MuJoCo.

For an arm of N >= 3 links there is no simplified model (11); the policies are synthesised
on the full N-link model (:func:`twolink.arm.dynamics.chain_acceleration`), so the closed-loop
question is whether that model and the MuJoCo arm agree under feedback. Every policy runs
from the same random poses at rest (:func:`twolink.sim.metrics.random_poses`, one seed) on both
plants for one horizon; the section holds, per policy and plant, the successes k/n with
their 95 % Wilson interval and the median settle time, and per policy the largest RMS gap
between a pose's two trajectories. Measurement only: it returns a JSON-ready dict.
"""
from __future__ import annotations

import math

import numpy as np

from twolink.arm.parameters import ChainParameters
from twolink.policy.fuzzy_policy import check_links_match
from twolink.sim.metrics import (
    random_poses,
    settle_time,
    success,
    trajectory_gap,
    wilson_interval,
)
from twolink.sim.plants import make_plant
from twolink.sim.rollout import rollout

#: The plants compared, the model the policies were synthesised on first.
PLANTS = ("full", "mujoco")


def _median(settle: np.ndarray):
    """The median settle time over all runs (inf counts as never), None if over half never
    settle."""
    m = float(np.quantile(settle, 0.5, method="higher"))
    return m if math.isfinite(m) else None


def measure(policies: dict, params: ChainParameters, *, poses: int, seed: int,
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
            k, n = int(success(tr).sum()), int(success(tr).size)
            lo, hi = wilson_interval(k, n)
            results[label][name] = {"successes": k, "runs": n, "rate": k / n,
                                    "interval": [lo, hi],
                                    "median_settle": _median(settle_time(tr))}
        gap = trajectory_gap(runs["mujoco"], runs["full"])
        gaps[label] = {key: float(np.max(v)) for key, v in gap.items()}
        agree = success(runs["mujoco"]) == success(runs["full"])
        gaps[label]["same_outcome"] = int(agree.sum())
    return {"links": links, "rule": params.rule, "poses": poses, "seed": seed,
            "duration": duration, "plants": list(PLANTS), "results": results, "gap": gaps}
