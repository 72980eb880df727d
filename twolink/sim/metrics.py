"""Metrics of docs/conventions.md: goal band, settle time, success, return, trajectory gap.

The evaluation set is the paper's x0 plus a fixed grid of angle pairs at rest; arms of N
links are evaluated on :func:`random_poses` instead. The metrics hold for any N
(trajectories of states (..., K+1, 2N)).
"""
from __future__ import annotations

import math

import numpy as np

from twolink.arm.integrate import wrap_angle
from twolink.arm.parameters import (
    GAMMA,
    GOAL_ANGLE,
    GOAL_SPEED,
    PAPER_X0,
    SUCCESS_MARGIN,
    check_links,
)
from twolink.arm.task import in_goal_band
from twolink.sim.rollout import Trajectory

#: Angles (degrees) of the evaluation grid: every pair (theta1, theta2), both at rest.
EVAL_ANGLES_DEG = (-150.0, -90.0, -45.0, -10.0, 10.0, 45.0, 90.0, 150.0)


def evaluation_set() -> np.ndarray:
    """The paper's x0 followed by the 8 x 8 grid of angle pairs at rest: shape (65, 4)."""
    a = np.deg2rad(EVAL_ANGLES_DEG)
    t1, t2 = np.meshgrid(a, a, indexing="ij")
    grid = np.stack([t1.ravel(), t2.ravel(), np.zeros(t1.size), np.zeros(t1.size)], -1)
    return np.concatenate([np.asarray(PAPER_X0, dtype=float)[None], grid])


#: Most poses :func:`random_poses` draws at once.
MAX_POSES = 100_000


def random_poses(links: int, count: int, seed) -> np.ndarray:
    """``count`` poses of an arm of ``links`` links at rest, shape (count, 2N): angles
    uniform in [-pi, pi), drawn row by row from ``np.random.default_rng(seed)`` (``seed``
    an int or a Generator), speeds zero. The evaluation sets of N-link arms."""
    n = check_links(links)
    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) \
            or not 1 <= count <= MAX_POSES:
        raise ValueError(f"count must be a whole number from 1 to {MAX_POSES}, got {count!r}")
    if seed is None or isinstance(seed, bool) or not isinstance(
            seed, (int, np.integer, np.random.Generator)):
        raise ValueError(f"seed must be an int or a numpy Generator, got {seed!r}")
    rng = np.random.default_rng(seed)
    poses = np.zeros((int(count), 2 * n))
    poses[:, :n] = rng.uniform(-math.pi, math.pi, size=(int(count), n))
    return poses


def settle_time(traj: Trajectory) -> np.ndarray:
    """First sample time after which the state stays in the goal band; inf if never."""
    inside = in_goal_band(traj.x)                     # (..., K+1)
    outside = ~inside
    k = inside.shape[-1]
    rev = outside[..., ::-1]
    last_out = np.where(rev.any(-1), k - 1 - np.argmax(rev, axis=-1), -1)
    idx = last_out + 1
    t = np.append(traj.t, np.inf)
    return np.where(idx >= k, np.inf, t[np.minimum(idx, k)])


def success(traj: Trajectory, *, margin: float = SUCCESS_MARGIN) -> np.ndarray:
    """Settled no later than ``margin`` seconds before the end of the horizon."""
    return settle_time(traj) <= traj.t[-1] - margin + 1e-9


def discounted_return(traj: Trajectory, *, gamma: float = GAMMA) -> np.ndarray:
    """sum_k gamma^k r_{k+1} with the centralized reward (15).

    Summed row by row (not a matrix product), so a row's value does not depend on the
    batch it ran in.
    """
    return np.sum(traj.r * gamma ** np.arange(traj.r.shape[-1]), axis=-1)


def stalled_at_band_edge(traj: Trajectory, *, slack_deg: float = 0.1) -> np.ndarray:
    """Runs that never settled yet ended at rest just outside the angle band.

    A diagnostic beside :func:`success`: the final speeds are inside the goal band and
    every final angle lies within ``slack_deg`` of the 5 degree band. The paper's +-5
    degree bin centres sit on the band's edge and their greedy action at rest is zero
    torque, so policy (14) barely pushes there and damping can park the arm a hair
    outside the band.
    """
    last = traj.x[..., -1, :]
    n = last.shape[-1] // 2
    resting = np.all(np.abs(last[..., n:]) <= GOAL_SPEED, axis=-1)
    near = np.all(np.abs(last[..., :n]) <= GOAL_ANGLE + math.radians(slack_deg), axis=-1)
    return ~success(traj) & resting & near


#: z of a two-sided 95 % interval.
_Z95 = 1.959963984540054


def wilson_interval(successes: int, n: int, *, z: float = _Z95) -> tuple[float, float]:
    """The Wilson score interval (95 % by default) of ``successes`` out of ``n`` trials.

    docs/conventions.md: every success rate is reported with its count and this interval; two rates
    whose intervals overlap are not called different.
    """
    if int(successes) != successes or int(n) != n or not 0 <= successes <= n:
        raise ValueError(f"need whole numbers 0 <= successes <= n, got {successes} of {n}")
    if n == 0:
        return (0.0, 1.0)
    p = successes / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return (max(0.0, centre - half), min(1.0, centre + half))


def final_offsets_deg(traj: Trajectory) -> np.ndarray:
    """Final link angles in degrees, shape (..., N)."""
    return np.rad2deg(traj.x[..., -1, :traj.x.shape[-1] // 2])


def trajectory_gap(a: Trajectory, b: Trajectory) -> dict:
    """RMS over time of the wrapped angle difference (rad) and speed difference (rad/s)."""
    if a.x.shape != b.x.shape:
        raise ValueError(f"trajectories differ in shape: {a.x.shape} vs {b.x.shape}")
    d = a.x - b.x
    n = d.shape[-1] // 2
    ang = wrap_angle(d[..., :n])
    return {"angle_rms": np.sqrt((ang**2).mean(axis=(-2, -1))),
            "speed_rms": np.sqrt((d[..., n:]**2).mean(axis=(-2, -1)))}


def summary(traj: Trajectory) -> dict:
    """Scalar metrics of a single (unbatched) trajectory, JSON-ready."""
    if traj.x.ndim != 2:
        raise ValueError("summary() takes a single trajectory; index a batch first")
    st = float(settle_time(traj))
    return {"settle_time": st if math.isfinite(st) else None,
            "success": bool(success(traj)),
            "return": float(discounted_return(traj)),
            "final_offsets_deg": final_offsets_deg(traj).tolist(),
            "final_state": traj.x[-1].tolist(),
            "duration": float(traj.t[-1])}



def compare(runs: dict, plants, *, reference: str = "simplified") -> list:
    """One entry per run of ``runs`` (``{(label, plant): Trajectory}``) on ``plants``:
    its :func:`summary` and, on a plant other than ``reference``, the
    :func:`trajectory_gap` to the same policy's run on ``reference`` (which ``runs``
    must hold)."""
    out = []
    for (label, plant), tr in runs.items():
        if plant not in plants:
            continue
        entry = {"policy": label, "plant": plant, **summary(tr)}
        if plant != reference:
            gap = trajectory_gap(tr, runs[(label, reference)])
            entry[f"gap_to_{reference}"] = {k: float(v) for k, v in gap.items()}
        out.append(entry)
    return out
