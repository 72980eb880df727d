"""Metrics of docs/conventions.md: goal band, settle time, success, return, trajectory gap.

The evaluation set is the paper's x0 plus a fixed grid of angle pairs at rest; arms of N
links are evaluated on :func:`random_poses` instead. The metrics hold for any N
(trajectories of states (..., K+1, 2N)).
"""
from __future__ import annotations

import dataclasses
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
from twolink.validate import whole
from twolink.validate import seed as check_seed

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
    whole(count, "count", 1, MAX_POSES)
    check_seed(seed, none=False, generator=True)   # TypeError / ValueError naming seed
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


@dataclasses.dataclass(frozen=True)
class Score:
    """The one evaluation result: successes of ``n`` runs, their 95 % Wilson interval, the
    worst plant and the median settle time; :meth:`as_dict` is its JSON, one spelling of
    every key (:data:`SCORE_KEYS`). Build it with :func:`score` from per-run arrays.

    Why ``Score``, here: three classes named ``Evaluation`` already hold the runs that a
    score sums up, and each composes this one - :class:`twolink.sim.evaluation.Evaluation`
    (per-plant, per-state outcomes), :class:`twolink.synthesis.learning.Evaluation` (a
    learning-curve point: a score plus steps, return and time) and
    :class:`twolink.studies.scaling.measure.Evaluation` (a score per horizon). A fourth
    ``Evaluation`` would tell none of them apart. It lives beside :func:`success`,
    :func:`settle_time` and :func:`wilson_interval`, which it is made of, and needs neither
    MuJoCo nor a policy, so every layer above sim scores its own runs with it.

    ``wilson_95``: (low, high) of :func:`wilson_interval`. ``median_settle``: seconds, a
    failed run counting as never settled (inf), so inf when half or more of the runs fail
    (more than half for an odd ``n``). ``worst_plant``, ``worst_plant_successes``: the
    plant with the lowest success rate (the first such) and its successes, None unless the
    runs span several plants.
    """

    successes: int
    n: int
    wilson_95: tuple
    median_settle: float
    worst_plant: int | None = None
    worst_plant_successes: int | None = None

    @property
    def rate(self) -> float:
        return self.successes / self.n

    def as_dict(self) -> dict:
        """JSON-ready, keys :data:`SCORE_KEYS` (``median_settle`` None when inf)."""
        med = self.median_settle
        return {"successes": self.successes, "n": self.n, "rate": self.rate,
                "wilson_95": [float(v) for v in self.wilson_95],
                "worst_plant": self.worst_plant,
                "worst_plant_successes": self.worst_plant_successes,
                "median_settle": float(med) if math.isfinite(med) else None}

    @classmethod
    def from_dict(cls, d: dict) -> Score:
        """The score of a stored :meth:`as_dict`, or of an older spelling
        (:func:`score_keys`); the interval is recomputed from the counts (stored learning
        curves have none), a missing worst plant is None and a None median is inf."""
        d = score_keys(d)
        k, n = int(d["successes"]), int(d["n"])
        med = d.get("median_settle")
        worst, worst_k = d.get("worst_plant"), d.get("worst_plant_successes")
        return cls(k, n, wilson_interval(k, n), math.inf if med is None else float(med),
                   None if worst is None else int(worst),
                   None if worst_k is None else int(worst_k))


#: The keys of :meth:`Score.as_dict`, in order.
SCORE_KEYS = ("successes", "n", "rate", "wilson_95", "worst_plant", "worst_plant_successes",
              "median_settle")
#: Older spellings of score keys in committed files, and the key each now is:
#: ``runs`` and ``wilson95`` (twolink.sim.evaluation, e.g. renders/mismatch/report.json),
#: ``interval`` (the N-link mismatch section).
OLD_SCORE_KEYS = {"runs": "n", "wilson95": "wilson_95", "interval": "wilson_95"}


def score_keys(d: dict) -> dict:
    """A copy of ``d`` (a stored score, or a record holding a score's keys) with the keys
    of :meth:`Score.as_dict`: every old spelling of :data:`OLD_SCORE_KEYS` is renamed,
    unless ``d`` also holds the new key (which then wins); other keys pass unchanged.
    What formatters call on dicts that may come from files written before the one
    spelling, so that those files still read."""
    out = dict(d)
    for old, new in OLD_SCORE_KEYS.items():
        if old in out:
            value = out.pop(old)
            out.setdefault(new, value)
    return out


def score(success, settle, plant=None) -> Score:
    """The :class:`Score` of runs given as per-run arrays (any shape, raveled alike):
    ``success`` bools, ``settle`` seconds (inf: never settled; a failed run counts as
    never settled whatever its time) and optionally ``plant``, each run's plant index (the
    worst plant is reported when there are several)."""
    ok = np.asarray(success, dtype=bool).ravel()
    st = np.asarray(settle, dtype=float).ravel()
    if not ok.size or st.shape != ok.shape:
        raise ValueError(f"need as many settle times as successes, at least one run; got "
                         f"{st.size} and {ok.size}")
    k, n = int(ok.sum()), int(ok.size)
    med = float(np.median(np.where(ok, st, np.inf)))
    worst = worst_k = None
    if plant is not None:
        idx = np.asarray(plant).ravel()
        if idx.shape != ok.shape or not np.issubdtype(idx.dtype, np.integer) \
                or (idx < 0).any():
            raise ValueError("plant must hold a non-negative whole plant index per run")
        plants, runs = np.unique(idx, return_counts=True)
        if len(plants) > 1:
            wins = np.bincount(idx, weights=ok, minlength=plants.max() + 1)[plants]
            w = int(np.argmin(wins / runs))
            worst, worst_k = int(plants[w]), int(wins[w])
    return Score(k, n, wilson_interval(k, n), med, worst, worst_k)


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
