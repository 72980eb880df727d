"""Closed-loop rollouts of a policy on a plant, batched over initial states.

At each sample k the policy sees x_k, the plant holds tau_k over Ts and returns x_{k+1};
the rewards r_{k+1} of (15) and (17) are evaluated on x_{k+1}. The arm has N =
``plant.links`` links (2 for Table I): states (..., 2N), torques (..., N).

Horizons are bounded: at most :data:`MAX_DURATION` seconds, and the trajectory arrays
of a batch at most :data:`MAX_TRAJECTORY_BYTES`, checked before anything is allocated.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from twolink.arm.parameters import HORIZON, TABLE_I, TS, check_links
from twolink.arm.task import agent_reward, centralized_reward
from twolink.policy.fuzzy_policy import check_links_match
from twolink.sim.controller import reset_controller
from twolink.sim.plants import Plant, SimulationError, check_states, make_plant
from twolink.validate import numbers

#: Longest horizon a rollout accepts: one hour, 72 000 sample periods.
MAX_DURATION = 3600.0
#: Memory budget of one rollout's trajectory arrays (states, torques, rewards).
MAX_TRAJECTORY_BYTES = 2 * 2**30


def _bytes_per_sample(links: int) -> int:
    """Bytes per batch row and sample: x (2N), u (N), r (1), r_links (N) as float64."""
    return (4 * links + 1) * 8


#: Bytes per batch row and sample of the two-link arm: x (4), u (2), r (1), r_links (2).
_BYTES_PER_SAMPLE = _bytes_per_sample(2)


@dataclasses.dataclass
class Trajectory:
    """Times (K+1,), states (..., K+1, 2N), torques (..., K, N), rewards (..., K) of (15)
    and per-link rewards (..., K, N) of (17), for an arm of N links.

    ``label`` names the policy (``decentralized_propagated``, a file's stem), ``kind`` says
    what it is (``centralized`` (16) or ``decentralized`` (18), whose reward is (17)).
    """

    t: np.ndarray
    x: np.ndarray
    u: np.ndarray
    r: np.ndarray
    r_links: np.ndarray
    plant: str = ""
    label: str = ""
    kind: str = ""

    @property
    def steps(self) -> int:
        return len(self.t) - 1

    @property
    def links(self) -> int:
        """N, the number of links of the arm."""
        return self.u.shape[-1]

    def __getitem__(self, i) -> "Trajectory":
        """The trajectory of batch row ``i``."""
        return dataclasses.replace(self, x=self.x[i], u=self.u[i], r=self.r[i],
                                   r_links=self.r_links[i])


def steps_for(duration: float, *, rows: int = 1, links: int = 2) -> int:
    """Number of sample periods in ``duration`` seconds (rounded to the nearest whole
    number), for a batch of ``rows`` states of an arm of ``links`` links; a ValueError
    below one sample period, beyond :data:`MAX_DURATION` or :data:`MAX_TRAJECTORY_BYTES`."""
    if not np.isfinite(duration) or duration <= 0:
        raise ValueError(f"duration must be a positive number of seconds, got {duration}")
    if duration > MAX_DURATION:
        raise ValueError(f"duration must be at most {MAX_DURATION:g} s "
                         f"({round(MAX_DURATION / TS)} sample periods), got {duration:g}")
    n = int(round(duration / TS))
    if n < 1:
        raise ValueError(f"duration must be at least one sample period ({TS:g} s), got "
                         f"{duration:g}")
    need = rows * (n + 1) * _bytes_per_sample(check_links(links))
    if need > MAX_TRAJECTORY_BYTES:
        raise ValueError(f"{rows} states x {n} sample periods need {need / 2**30:.1f} GiB of "
                         f"trajectory arrays, over the {MAX_TRAJECTORY_BYTES / 2**30:g} GiB "
                         f"budget; shorten the duration or the batch")
    return n


def _read_only(x) -> np.ndarray:
    """A read-only float64 copy of ``x``: what a policy is handed, so that no policy can
    change the plant's state (or a reading another part of the loop keeps)."""
    x = np.array(x, dtype=float)
    x.setflags(write=False)
    return x


def _fmt(x) -> str:
    return "[" + ", ".join(f"{v:+.4g}" for v in np.asarray(x).ravel()) + "]"


def rollout(policy, plant: Plant, x0, *, duration: float = HORIZON, observe=None,
            label: str | None = None) -> Trajectory:
    """Run ``policy`` on ``plant`` from x0 (2N,) or a batch (B, 2N) for ``duration``
    seconds, N = ``plant.links`` (2 for a plant without it).

    ``policy`` is a controller of :mod:`twolink.sim.controller`'s protocol; its
    ``reset(rows)``, if it has one, is called first. ``observe(k, x)`` may return the
    state the policy sees (for noise or delays); by default it sees the true state.
    Either way the policy gets a read-only copy: it cannot change the state the plant
    steps from. ``label`` names the policy in the trajectory (default: its kind). A
    policy that knows its number of links (``policy.links``) must match the plant's (a
    ValueError otherwise). A plant that goes unstable raises
    :class:`SimulationError` naming the initial state and the time.
    """
    links = getattr(plant, "links", 2)
    if hasattr(policy, "links"):
        check_links_match(policy, links, name=label)
    check = getattr(plant, "check_states", None)
    numbers(x0, "x0")                    # a TypeError naming x0 for a dict, a word, ...
    x0 = check(x0, what="x0") if check is not None else check_states(x0, what="x0",
                                                                        links=links)
    rows = int(np.prod(x0.shape[:-1], dtype=int))
    n = steps_for(duration, rows=rows, links=links)
    reset_controller(policy, rows)
    xs = np.empty(x0.shape[:-1] + (n + 1, 2 * links))
    us = np.empty(x0.shape[:-1] + (n, links))
    x = x0
    xs[..., 0, :] = x
    for k in range(n):
        seen = x if observe is None else observe(k, x)
        u = policy(_read_only(seen))
        try:
            x = plant.step(x, u)
        except SimulationError as exc:
            row = exc.rows[0] if exc.rows else 0
            start = x0.reshape(-1, 2 * links)[row] if x0.ndim > 1 else x0
            raise SimulationError(f"rollout from x0 = {_fmt(start)} failed at "
                                  f"t = {k * TS:.2f} s: {exc}", exc.rows) from None
        us[..., k, :] = u
        xs[..., k + 1, :] = x
    nxt = xs[..., 1:, :]
    r_links = np.stack([agent_reward(nxt, i) for i in range(1, links + 1)], -1)
    kind = getattr(policy, "kind", "")
    return Trajectory(np.arange(n + 1) * TS, xs, us, centralized_reward(nxt), r_links,
                      getattr(plant, "name", ""), kind if label is None else label, kind)


def rollout_grid(policies: dict, plants, x0, *, duration: float = HORIZON,
                 params=None, loop=None) -> dict:
    """Every policy (``{label: policy}``) on every plant (names) from x0:
    ``{(label, plant): Trajectory}``, plant by plant, each plant made once and closed.

    ``loop(policy) -> (act, observe)``, when given, builds each run's closed loop (the
    controller the plant sees and the reading it gets, as :func:`rollout` takes them);
    without it the policy reads the true state."""
    runs = {}
    for plant_name in dict.fromkeys(plants):
        with make_plant(plant_name, TABLE_I if params is None else params) as plant:
            for label, policy in policies.items():
                act, observe = (policy, None) if loop is None else loop(policy)
                runs[(label, plant_name)] = rollout(act, plant, x0, duration=duration,
                                                    observe=observe, label=label)
    return {(label, p): runs[(label, p)] for label in policies for p in dict.fromkeys(plants)}
