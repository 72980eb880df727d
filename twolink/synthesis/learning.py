"""Online fuzzy Q-learning (4)/(5) on the MuJoCo arm: many arms, one shared theta.

The approximator is the one of fuzzy Q-iteration: Q(x, u_j) = sum_m mu_m(x) theta[m, j]
(12) over the same grids, actions and rewards as :mod:`twolink.synthesis.synthesize`. Three learners:

* ``centralized`` - one agent over x with the joint actions (16) and reward (15);
* ``decentralized`` - the paper's ordered agents (18): agent 2 acts first on
  (theta2, dtheta2), agent 1 sees (theta1, dtheta1, theta2, tau2); each learns from its own
  reward (17), the agents' updates (5);
* ``independent`` - the same two agents, but agent 1 does not see tau2 (fully
  independent learners, for comparison).

Two ways of acting and updating (``update``):

* ``fuzzy`` - the learner acts as policy (14): every active bin m of x picks its
  own epsilon-greedy action j_m, the arm gets the membership-weighted torque
  sum_m mu_m u_{j_m}, and each (m, j_m) moves towards the target of Alg. 1,
  r + gamma * sum_m' mu_m'(x') max_j theta[m', j], with weight mu_m. theta[m, j] is then a
  weighted average of targets, so it stays within the range of possible values.
* ``rule`` - ``fuzzy`` with exploration per bin: each active bin takes its own
  epsilon-greedy draw (``fuzzy`` draws once per arm and, exploring, randomises every bin).
  This is the per-rule form theta[m, a_m] += alpha mu_m (r + gamma sum_m' mu_m'(x')
  max_u theta[m', u] - theta[m, a_m]).
* ``fql`` - acting as ``rule``, but the error is the gradient form of fuzzy Q-learning
  (Glorennec, Jouffe): r + gamma sum_m' mu_m'(x') max_u theta[m', u] - sum_m mu_m
  theta[m, a_m], so that, like ``discrete``, theta may leave [-25, 0].
* ``discrete`` (default) - plain Q-learning (4): one epsilon-greedy discrete action per arm
  from the interpolated Q(x, .), target r + gamma * max_j Q(x', j), and theta moved along
  the gradient mu_m of the temporal difference r + gamma max Q(x', .) - Q(x, u). theta may
  leave [-25, 0]. On MuJoCo this one learned and ``fuzzy`` did not (README, "Learning on
  the arm"); the saved policy is always read as policy (14).

Batched, synchronous: all arms step together on :class:`twolink.sim.plants.MujocoPlant`, then
one update sums every arm's contribution per entry (m, j): theta[m, j] moves by
min(1, alpha * W) times the membership-weighted mean (over arms) of its targets' error,
W being the entry's total membership weight in this step. At a bin centre (mu_m = 1) both
updates are theta[m, j] += alpha (r + gamma V(x') - theta[m, j]), so given the
transitions f(c_m, u_j) of Alg. 1 the learner converges to fuzzy Q-iteration's fixed
point. The learning rate follows alpha_t = alpha * h / (h + t) (t: control steps so far,
h: ``alpha_halflife``, 0 keeps alpha constant); exploration is epsilon-greedy per arm and
step (an exploring arm draws its action, or every active bin's action, at random; ``rule`` and
``fql`` draw per active bin), epsilon_t
decaying linearly from ``epsilon`` to ``epsilon_final`` over the run.

Against a noisy theta: two read-outs and a warm-start scale, none of which
changes the learning update itself. With a constant alpha the entries near
the goal, which most arms visit, move by min(1, alpha W) ~ 1 in every batched step, so
theta (and the one greedy action in a near-goal bin that decides every evaluation state)
follows the last few targets. ``average`` > 0 keeps an exponential average of theta over
about that many control steps, theta_bar += beta (theta - theta_bar) with
beta = min(1, arms / average) after every update (iterate averaging, Polyak-Ruppert); the
saved and evaluated policy (14) reads theta_bar, the learning itself is unchanged (same
theta bit for bit). ``init_scale`` lambda in (0, 1] starts a warm start from lambda times
the given Q: every bin's greedy action, hence the policy (14), is the given one, but the
values are nearer the optimistic 0 of a cold start (Q of (15)/(17) lies in [-25, 0]), so
that what the given model got wrong is explored rather than trusted. ``hysteresis`` m > 0
makes the policy's greedy action of each bin sticky: after every update it changes only
when another action's value (theta_bar, or theta without an average) beats the kept one
by more than m, so near-ties (measured: agent 1's bins flipping on differences of 0.02)
stop flipping the policy; the saved Q is the read theta with the kept action raised just
above its row's best where it trails by at most m. :class:`LearnConfig`'s defaults, which
``twolink learn`` takes, are average 200 k (none for the centralized learner), hysteresis
0.1 and a warm-start scale of 0.5; a checkpoint written without these settings resumes
with none of them (:data:`twolink.synthesis.learning_setup.LEGACY`).

Arms run episodes of ``episode`` sample periods from random poses (angles uniform,
at rest), staggered so that resets spread over time. Every random draw comes from one
seeded generator, so the same seed gives the same theta bit for bit; checkpoints (policy
files, ``Learner.policy(resume=True)``) hold theta, the generator, the arms and the learning
curve, so a resumed run continues exactly as an uninterrupted one.
"""
from __future__ import annotations

import math
import time
from typing import Callable, Optional

import numpy as np

from twolink.arm.parameters import HORIZON, TABLE_I, TS
from twolink.artifacts import VERSION as __version__
from twolink.policy.fuzzy_policy import TIE_TOLERANCE, Agent, Policy
from twolink.sim.metrics import (
    discounted_return,
    evaluation_set,
    score,
    settle_time,
    success,
)
from twolink.sim.plants import MujocoPlant
from twolink.sim.progress import progress_bar
from twolink.sim.rollout import rollout
from twolink.synthesis.learning_setup import (
    UPDATES,
    LearnConfig,
    make_agents,
    policy_kind,
    warm_start,
)
from twolink.synthesis.learning_state import (
    Evaluation,
    check_resume_state,
    indices,
    pack,
    unpack,
)

#: Updates that act as policy (14): every active bin its own action.
_FUZZY_ACTING = ("fuzzy", "rule", "fql")
#: Key of the learning provenance in a policy's ``meta``.
META_KEY = "learning"


def evaluate(policy: Policy, plant, x0: Optional[np.ndarray] = None, *, steps: int = 0,
             seconds: float = 0.0) -> Evaluation:
    """Success, median settle time and mean return of ``policy`` from ``x0`` (default the
    65-state evaluation set) over the metrics' horizon."""
    x0 = evaluation_set() if x0 is None else x0
    traj = rollout(policy, plant, x0, duration=HORIZON)
    return Evaluation(int(steps), score(success(traj), settle_time(traj)),
                      float(np.mean(discounted_return(traj))), float(seconds))


# --------------------------------------------------------------------------- learner
class Learner:
    """The batched online learner: ``config.arms`` MuJoCo arms and one shared theta.

    Call :meth:`step` for one synchronous control step of all arms and one update;
    :meth:`run` steps to ``config.steps`` with periodic evaluations and checkpoints.
    """

    def __init__(self, config: LearnConfig, *, init: Optional[Policy] = None,
                 plant=None, nthread: int = 1):
        self.config = config.check()
        self.agents = make_agents(config.learner)
        self.init_label = None
        if init is not None:
            warm_start(self.agents, init, config.learner)
            for a in self.agents:
                a.theta *= config.init_scale
            self.init_label = str(init.meta.get("source", init.kind))
        self.theta_bar = [a.theta.copy() for a in self.agents] if config.average else None
        self.kept = [greedy_index(q) for q in self._read()] if config.hysteresis else None
        self.rng = np.random.default_rng(config.seed)
        n = config.arms
        self.x = self._random_poses(n)
        self.clock = self.rng.integers(0, config.episode, n)     # staggered episodes
        self.iteration = 0
        self.curve: list = []
        self.learn_seconds = 0.0
        self._own_plant = plant is None
        self.plant = MujocoPlant(TABLE_I, nthread=nthread) if plant is None else plant

    # -- resources
    def close(self) -> None:
        if self._own_plant:
            self.plant.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    # -- schedules
    @property
    def steps_done(self) -> int:
        return self.iteration * self.config.arms

    def alpha(self) -> float:
        """alpha_t = alpha * h / (h + t), t the control steps so far (constant if h = 0)."""
        c = self.config
        t = self.steps_done
        return c.alpha if c.alpha_halflife == 0 else c.alpha * c.alpha_halflife / \
            (c.alpha_halflife + t)

    def epsilon(self) -> float:
        """epsilon decays linearly from ``epsilon`` to ``epsilon_final`` over the run."""
        c = self.config
        frac = min(1.0, self.steps_done / c.steps)
        return c.epsilon + (c.epsilon_final - c.epsilon) * frac

    def _random_poses(self, n: int) -> np.ndarray:
        x = np.zeros((n, 4))
        x[:, :2] = self.rng.uniform(-math.pi, math.pi, (n, 2))
        return x

    # -- acting and learning
    def _signals(self, x: np.ndarray) -> dict:
        return {"theta1": x[:, 0], "theta2": x[:, 1], "dtheta1": x[:, 2], "dtheta2": x[:, 3]}

    def _act(self, x: np.ndarray, eps: float):
        """Exploratory torques (n, 2) and, per agent, (bins, weights, chosen actions)."""
        sig = self._signals(x)
        fuzzy_update = self.config.update in _FUZZY_ACTING
        per_bin = self.config.update in ("rule", "fql")
        chosen = []
        for a in self.agents:
            idx, w = a.grid.memberships(np.stack([sig[k] for k in a.grid.names], -1))
            nu = len(a.actions)
            if fuzzy_update:                          # each active bin its own action
                j = greedy_index(a.theta[idx])
                explore = (self.rng.random(idx.shape if per_bin else len(x)) < eps)
                explore = explore if per_bin else explore[:, None]
                j = np.where(explore, self.rng.integers(0, nu, idx.shape), j)
                out = np.einsum("nk,nko->no", w, a.actions[j])
            else:                                     # one action per arm, from Q(x, .)
                q = np.einsum("nk,nku->nu", w, a.theta[idx])
                j1 = greedy_index(q)
                explore = self.rng.random(len(x)) < eps
                j1 = np.where(explore, self.rng.integers(0, nu, len(x)), j1)
                out = a.actions[j1]
                j = np.broadcast_to(j1[:, None], idx.shape)
            for k, name in enumerate(a.outputs):
                sig[name] = out[:, k]
            chosen.append((idx, w, j))
        return np.stack([sig["tau1"], sig["tau2"]], -1), chosen

    def _values(self, x: np.ndarray) -> list:
        """V_i(x') of every agent: sum_m mu_m max_j theta (fuzzy) or max_j Q(x', j)
        (discrete); earlier agents' outputs at x' are their greedy actions."""
        sig = self._signals(x)
        values = []
        for a in self.agents:
            idx, w = a.grid.memberships(np.stack([sig[k] for k in a.grid.names], -1))
            if self.config.update in _FUZZY_ACTING:
                rows = a.theta[idx]                                       # (n, K, N_U)
                values.append(np.einsum("nk,nk->n", w, rows.max(axis=-1)))
                out = np.einsum("nk,nko->no", w, a.actions[greedy_index(rows)])
            else:
                q = np.einsum("nk,nku->nu", w, a.theta[idx])
                values.append(q.max(axis=1))
                out = a.actions[greedy_index(q)]
            for k, name in enumerate(a.outputs):
                sig[name] = out[:, k]
        return values

    def update(self, chosen: list, rewards: list, values: list, alpha: float) -> None:
        """One synchronous update of every agent from a batch of transitions."""
        for a, (idx, w, j), r, v in zip(self.agents, chosen, rewards, values, strict=True):
            update_theta(a.theta, idx, w, j, r + self.config.gamma * v, alpha,
                         rule=self.config.update)

    def step(self) -> None:
        """One control step of every arm, then one update of theta; resets finished
        episodes to new random poses."""
        t0 = time.perf_counter()
        tau, chosen = self._act(self.x, self.epsilon())
        nxt = self.plant.step(self.x, tau)
        rewards = [a.reward(nxt) for a in self.agents]
        self.update(chosen, rewards, self._values(nxt), self.alpha())
        if self.theta_bar is not None:
            beta = min(1.0, self.config.arms / self.config.average)
            for bar, a in zip(self.theta_bar, self.agents):
                bar += beta * (a.theta - bar)
        if self.kept is not None:
            for kept, q in zip(self.kept, self._read()):
                g = greedy_index(q)
                rows = np.arange(len(kept))
                beaten = q[rows, g] > q[rows, kept] + self.config.hysteresis
                kept[beaten] = g[beaten]
        self.clock += 1
        done = self.clock >= self.config.episode
        self.x = nxt
        if done.any():
            self.x[done] = self._random_poses(int(done.sum()))
            self.clock[done] = 0
        self.iteration += 1
        self.learn_seconds += time.perf_counter() - t0

    # -- results
    def policy(self, *, resume: bool = False) -> Policy:
        """The greedy policy (14) of the current theta (of its average theta_bar when
        ``average`` is set), with its provenance; ``resume`` adds what :meth:`resume` needs
        (the generator, the arms, the curve and, with an average, theta itself)."""
        kind = policy_kind(self.config.learner)
        read = [q.copy() for q in self._read()]
        patched = {}
        for a, q, kept in zip(self.agents, read, self.kept or [None] * len(read)):
            if kept is not None:           # the kept action raised just above the row's best
                rows = np.flatnonzero(greedy_index(q) != kept)
                patched[a.name] = {"rows": rows.tolist(), "values": pack(q[rows])}
                q[rows, kept[rows]] = q[rows].max(axis=1) + 4 * TIE_TOLERANCE
        agents = [Agent(a.name, a.grid, a.actions, q, a.outputs,
                        {"learned": True, "link_reward": a.link,
                         "averaged": self.theta_bar is not None,
                         "hysteresis": self.config.hysteresis})
                  for a, q in zip(self.agents, read)]
        info = {"config": self.config.as_dict(), "steps": self.steps_done,
                "iterations": self.iteration, "init": self.init_label,
                "exploration": f"epsilon-greedy ({self.config.update}), epsilon "
                               f"{self.config.epsilon:g} -> {self.config.epsilon_final:g}",
                "learn_seconds": self.learn_seconds,
                "curve": [e.as_dict() for e in self.curve]}
        if resume:
            info["resume"] = {"rng": self.rng.bit_generator.state,
                              "x": pack(self.x), "clock": self.clock.tolist()}
            if self.theta_bar is not None:       # the policy holds theta_bar; theta here
                info["resume"]["theta"] = {a.name: pack(a.theta) for a in self.agents}
            if self.kept is not None:            # the read rows before the kept actions
                info["resume"]["patched"] = patched
                info["resume"]["kept"] = {a.name: k.tolist()
                                          for a, k in zip(self.agents, self.kept)}
        meta = {"model": "mujoco (online learning)", "gamma": self.config.gamma, "ts": TS,
                "parameters": TABLE_I.as_dict(), "source": f"learned {self.config.learner}",
                "twolink_version": __version__, META_KEY: info}
        return Policy(kind, agents, meta)

    def _read(self) -> list:
        """What the policy reads: theta_bar with an average, else theta (views)."""
        return self.theta_bar if self.theta_bar is not None else [a.theta for a in self.agents]

    def evaluate(self, x0: Optional[np.ndarray] = None) -> Evaluation:
        return evaluate(self.policy(), self.plant, x0, steps=self.steps_done,
                        seconds=self.learn_seconds)

    def run(self, *, checkpoint=None, progress: bool = False,
            on_eval: Optional[Callable[[Evaluation], None]] = None) -> list:
        """Step to ``config.steps``, evaluating (and checkpointing to ``checkpoint``) every
        ``eval_iterations`` and at the end; returns the learning curve."""
        c = self.config
        if not self.curve:
            self._record(checkpoint, on_eval)
        with progress_bar(total=c.iterations * c.arms, initial=self.steps_done,
                          unit=" steps", unit_scale=True, desc=f"learn {c.learner}",
                          enabled=progress, mininterval=0.5) as bar:
            while self.iteration < c.iterations:
                self.step()
                bar.update(c.arms)
                if self.iteration % c.eval_iterations == 0 or self.iteration == c.iterations:
                    e = self._record(checkpoint, on_eval)
                    bar.set_postfix(success=f"{e.successes}/{e.n}")
        return self.curve

    def _record(self, checkpoint, on_eval) -> Evaluation:
        e = self.evaluate()
        self.curve.append(e)
        if checkpoint is not None:
            self.policy(resume=True).save(checkpoint)
        if on_eval is not None:
            on_eval(e)
        return e

    @classmethod
    def resume(cls, policy: Policy, *, steps: Optional[int] = None, plant=None,
               nthread: int = 1) -> "Learner":
        """A learner continuing from a checkpoint (a policy saved with ``resume=True``);
        ``steps`` may extend the run's total. Every field of the resume state is checked
        (:func:`twolink.synthesis.learning_state.check_resume_state`: types, sizes, ranges) before anything is built; a
        bad one is a one-line ValueError "malformed learning checkpoint (...)"."""
        info = policy.meta.get(META_KEY)
        if not isinstance(info, dict) or "resume" not in info:
            raise ValueError("not a learning checkpoint (the policy carries no resume state; "
                             "checkpoints are written by `twolink learn`)")
        try:
            data = dict(info["config"])
            if steps is not None:
                data["steps"] = steps
            config = LearnConfig.from_dict(data)
        except (KeyError, TypeError) as exc:
            raise ValueError(f"malformed learning checkpoint ({exc})") from None
        state = check_resume_state(info, config)
        self = cls(config, plant=plant, nthread=nthread)
        try:
            theirs = {a.name: a for a in policy.agents}
            for k, a in enumerate(self.agents):
                if a.name not in theirs:
                    raise ValueError(f"malformed learning checkpoint (no agent {a.name})")
                q = theirs[a.name].q
                if q.shape != a.theta.shape:
                    raise ValueError(f"agent {a.name}: Q of shape {q.shape}, expected "
                                     f"{a.theta.shape}")
                q = np.array(q, dtype=float)
                if self.kept is not None:
                    rows = indices(state["patched"][a.name]["rows"], len(q), "patched rows")
                    q[rows] = unpack(state["patched"][a.name]["values"], (len(rows), q.shape[1]))
                    kept = indices(state["kept"][a.name], q.shape[1], "kept actions")
                    if kept.shape != (len(q),):
                        raise ValueError("malformed learning checkpoint (kept actions)")
                    self.kept[k] = kept
                if self.theta_bar is None:
                    a.theta = q
                else:
                    self.theta_bar[k] = q
                    a.theta = unpack(state["theta"][a.name], a.theta.shape)
            try:
                self.rng.bit_generator.state = state["rng"]
            except (KeyError, TypeError, ValueError) as exc:
                raise ValueError(f"malformed learning checkpoint (rng: {exc})") from None
        except (KeyError, TypeError) as exc:
            self.close()
            raise ValueError(f"malformed learning checkpoint ({exc})") from None
        except BaseException:
            self.close()
            raise
        self.x, self.clock = state["x"], state["clock"]
        self.iteration, self.learn_seconds = state["iterations"], state["learn_seconds"]
        self.init_label = info.get("init")
        self.curve = state["curve"]
        return self


def update_theta(theta: np.ndarray, idx: np.ndarray, w: np.ndarray, j: np.ndarray,
                 target: np.ndarray, alpha: float, *, rule: str = "fuzzy") -> np.ndarray:
    """Update theta (N_X, N_U) in place from n transitions and return it.

    ``idx``, ``w`` (n, K): the active bins of x_k and their memberships; ``j`` (n, K) the
    action each bin took (one per row for ``discrete``); ``target`` (n,) r + gamma V(x').
    Every entry e = (m, j) hit by weight W_e = sum mu moves by min(1, alpha W_e) times the
    weighted mean error sum mu err / W_e, where err is target - theta[m, j] (``fuzzy``,
    ``rule``: per rule) or target - Q(x_k, u_k) = target - sum_m mu_m theta[m, j_m]
    (``discrete``, (4), one j per row; ``fql``, a j per bin).
    """
    nu = theta.shape[1]
    flat = theta.reshape(-1)
    entry = idx * nu + j
    if rule in ("fuzzy", "rule"):
        err = target[:, None] - flat[entry]
    elif rule in ("discrete", "fql"):
        err = np.broadcast_to((target - np.einsum("nk,nk->n", w, flat[entry]))[:, None],
                              w.shape)
    else:
        raise ValueError(f"unknown update {rule!r}; choose one of {', '.join(UPDATES)}")
    weight = np.bincount(entry.ravel(), w.ravel(), minlength=flat.size)
    total = np.bincount(entry.ravel(), (w * err).ravel(), minlength=flat.size)
    hit = weight > 0
    flat[hit] += np.minimum(1.0, alpha * weight[hit]) * total[hit] / weight[hit]
    return theta


def greedy_index(q: np.ndarray) -> np.ndarray:
    """argmax over the last axis, ties to the first action (as policy (14))."""
    return np.argmax(q >= q.max(axis=-1, keepdims=True) - TIE_TOLERANCE, axis=-1)


def steps_to_reach(curve: list, rate: float = 0.9) -> Optional[int]:
    """Control steps at the first evaluation with success >= ``rate`` (None: never)."""
    for e in curve:
        if e.rate >= rate:
            return e.steps
    return None


def stays_above(curve: list, rate: float = 0.9) -> bool:
    """Whether every evaluation from the first one reaching ``rate`` on stays >= ``rate``."""
    first = steps_to_reach(curve, rate)
    return first is not None and all(e.rate >= rate for e in curve if e.steps >= first)
