"""Scoring a controller of an N-link arm on random poses at rest: the scaling table's protocol.

One function, :func:`score_poses`, scores every controller the scaling table
(:mod:`twolink.studies.scaling.measure`) and ``twolink evaluate --links N`` report: fuzzy
agents, the per-joint PD of :mod:`twolink.control.links_pd`, learned agents or a
callable of yours. The protocol: the poses of :func:`twolink.sim.metrics.random_poses`
(angles uniform in [-pi, pi), at rest), one MuJoCo rollout of the longest horizon, and at
every horizon asked for the success rule of :func:`twolink.sim.metrics.success` (inside
the goal band at every sample from 1 s before the end on) and the settle time
(:func:`twolink.sim.metrics.settle_time`) of the run cut there (:func:`truncated`; the plant
and the controller are causal, so the cut run is the shorter rollout).
"""
from __future__ import annotations

import dataclasses

from twolink.arm.parameters import HORIZON, TS, horizon
from twolink.sim.metrics import Score, random_poses, score, settle_time, success
from twolink.sim.plants import make_plant
from twolink.sim.rollout import Trajectory, rollout


def horizons(links: int) -> tuple:
    """Every horizon the scaling table reports for N links: (5 s,) for N = 2, (5 s, 8 s)
    for N >= 3 (the paper's 5 s and :func:`twolink.arm.parameters.horizon`)."""
    long = horizon(links)
    return (HORIZON,) if long == HORIZON else (HORIZON, long)


def truncated(traj: Trajectory, duration: float) -> Trajectory:
    """The first ``duration`` seconds of ``traj`` (the plant and policy are causal and
    deterministic, so this is the shorter rollout)."""
    k = int(round(duration / TS))
    if not 1 <= k <= traj.steps:
        raise ValueError(f"cannot cut a {traj.t[-1]:g} s trajectory at {duration:g} s")
    return dataclasses.replace(traj, t=traj.t[:k + 1], x=traj.x[..., :k + 1, :],
                               u=traj.u[..., :k, :], r=traj.r[..., :k],
                               r_links=traj.r_links[..., :k, :])


def score_poses(policy, params, x0, durations, plant: str = "mujoco") -> dict:
    """``{duration: Score}``: ``policy`` run on the arm ``params`` from the states ``x0``
    (B, 2N) for the longest of ``durations`` (seconds) and scored at each (successes, 95 %
    Wilson interval, median settle time: :func:`twolink.sim.metrics.score`). ``plant``:
    ``mujoco`` (the MJCF arm) or ``full`` (the rigid-body model (6), for N links
    :func:`twolink.arm.dynamics.links_acceleration`), :func:`make_plant`'s names."""
    durations = tuple(durations)
    with make_plant(plant, params) as plant:
        traj = rollout(policy, plant, x0, duration=max(durations))
    out = {}
    for h in durations:
        part = truncated(traj, h)
        out[h] = score(success(part), settle_time(part))
    return out


def poses_for(links: int, poses: int, seed: int):
    """The evaluation poses of N links for a seed: ``random_poses(links, poses, seed +
    links)``, as the scaling table draws them (seed + N: arms of other sizes never share
    a draw)."""
    return random_poses(links, poses, seed + links)


def score_on_poses(policy, params, *, poses: int, seed: int,
                   durations=None, plant: str = "mujoco") -> tuple[int, dict]:
    """The scaling table's evaluation of ``policy`` on the arm ``params``: ``poses``
    random poses at rest of :func:`poses_for` (seed + N), scored at every horizon of
    ``durations`` (default :func:`horizons`) on ``plant`` (:func:`score_poses`). Returns
    (the seed the poses were drawn from, ``{duration: Score}``)."""
    links = params.links
    x0 = poses_for(links, poses, seed)
    return seed + links, score_poses(policy, params, x0,
                                     horizons(links) if durations is None else durations,
                                     plant=plant)


__all__ = ["Score", "horizons", "poses_for", "score_on_poses", "score_poses", "truncated"]
