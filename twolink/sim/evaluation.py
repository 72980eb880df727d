"""The one evaluation call the report, the tests and users share: :func:`evaluate`.

A policy runs from every initial state on every plant (a list of parameter sets, e.g.
drawn by a :class:`twolink.sim.challenges.Challenge`) as one batch on MuJoCo (one
``mujoco.rollout`` call per Ts, per-row models), under the challenge's delays, noise and
faults (:mod:`twolink.sim.perturbations`), optionally through the compensation wrapper of
:mod:`twolink.sim.estimation`. Success and settle time are those of the report
(:func:`twolink.sim.metrics.success`, :func:`twolink.sim.metrics.settle_time`) on the true
states; the controller only ever sees the measured ones.

Randomness: the seeding rule of :mod:`twolink.sim.challenges`, the one the robustness
sweeps (:mod:`twolink.sim.cells`) use too: the run of plant p from state s draws its noise
from ``SeedSequence([seed, NOISE_STREAM], spawn_key=(p, s))`` and its faults from
``SeedSequence([seed, FAULT_STREAM], spawn_key=(p, s))``
(:meth:`twolink.sim.challenges.Challenge.generators`), and drawn plants come from
:meth:`twolink.sim.challenges.Challenge.plants` with the same seed: a run's numbers never
depend on which plants and states share its batch.
"""
from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np

from twolink.arm.parameters import HORIZON, ArmParameters
from twolink.sim.challenges import (  # noqa: F401  (FAULT_STREAM re-exported)
    FAULT_STREAM,
    MAX_PLANTS,
    Challenge,
    check_horizon,
)
from twolink.sim.challenges import challenge as challenge_named
from twolink.sim.controller import check_timeout, checked, controller_name
from twolink.sim.metrics import (
    Score,
    discounted_return,
    evaluation_set,
    score,
    settle_time,
    success,
)
from twolink.sim.perturbations import (  # noqa: F401  (NOISE_STREAM re-exported)
    NOISE_STREAM,
    SPEED_PER_DEG,
    ActuationDelay,
)
from twolink.sim.plants import MujocoPlant, check_nthread, check_states
from twolink.sim.progress import progress_bar
from twolink.sim.rollout import rollout, rollout_grid, steps_for
from twolink.validate import real, whole

#: Plants drawn when a plant-perturbing challenge is given without ``params`` or ``count``.
DEFAULT_PLANTS = 32
#: Most runs (plants x states) one evaluation holds.
MAX_RUNS = 200_000


@dataclasses.dataclass(frozen=True)
class Evaluation:
    """Per-plant, per-state outcomes (P plants x n states) of :func:`evaluate`.

    ``success`` (P, n) bool, ``settle`` (P, n) seconds (inf if never settled), ``returns``
    (P, n) discounted returns of (15), all on the true states.
    """

    success: np.ndarray
    settle: np.ndarray
    returns: np.ndarray
    params: tuple
    x0: np.ndarray
    challenge: Challenge
    seed: int
    horizon: float
    compensated: bool
    label: str = ""

    @functools.cached_property
    def score(self) -> Score:
        """The shared summary of every run (:class:`twolink.sim.metrics.Score`: successes,
        Wilson interval, worst plant, median settle), row p of the arrays being plant p."""
        plant = np.repeat(np.arange(self.success.shape[0]), self.success.shape[1])
        return score(self.success, self.settle, plant)

    @property
    def count(self) -> int:
        """Successful runs."""
        return self.score.successes

    @property
    def runs(self) -> int:
        return self.score.n

    @property
    def rate(self) -> float:
        return self.score.rate

    @property
    def interval(self) -> tuple[float, float]:
        """95 % Wilson interval of :attr:`rate`."""
        return self.score.wilson_95

    @property
    def plant_counts(self) -> np.ndarray:
        """Successful runs per plant (P,)."""
        return self.success.sum(axis=1)

    @property
    def worst_plant(self) -> int | None:
        """Index of the plant with the fewest successes (the first such); None for one plant."""
        return self.score.worst_plant

    @property
    def worst_plant_rate(self) -> float:
        """Success rate of the worst plant (the rate itself for one plant)."""
        return int(self.plant_counts.min()) / self.success.shape[1]

    @property
    def worst_return(self) -> float:
        """The lowest return of any run (the worst case, RRLS-style)."""
        return float(self.returns.min())

    @property
    def mean_return(self) -> float:
        return math.fsum(float(v) for v in self.returns.ravel()) / self.runs

    @property
    def median_settle(self) -> float:
        """Median settle time over all runs (failures count as never settled, inf, so it is
        inf when half or more of the runs fail)."""
        return self.score.median_settle

    def as_dict(self, *, rows: bool = True) -> dict:
        """JSON-ready summary: the run's setting, the keys of
        :meth:`twolink.sim.metrics.Score.as_dict`, the per-plant successes, the worst
        plant's rate and the returns; with ``rows`` also the per-plant, per-state outcomes."""
        out = {"label": self.label, "challenge": self.challenge.as_dict(), "seed": self.seed,
               "horizon": self.horizon, "compensated": self.compensated,
               "plants": len(self.params), "states": int(self.success.shape[1]),
               **self.score.as_dict(),
               "plant_successes": [int(v) for v in self.plant_counts],
               "worst_plant_rate": self.worst_plant_rate,
               "worst_return": self.worst_return, "mean_return": self.mean_return}
        if rows:
            out.update(
                params=[p.as_dict() for p in self.params], x0=self.x0.tolist(),
                success=self.success.tolist(),
                settle=[[float(v) if math.isfinite(v) else None for v in r] for r in self.settle],
                returns=self.returns.tolist())
        return out


def _challenge(challenge, delay, angle_noise_deg) -> Challenge:
    """The challenge in force: the one given, or one made of ``delay`` and ``angle_noise_deg``."""
    delay = real(delay, "delay")
    angle = real(angle_noise_deg, "angle_noise_deg")
    if challenge is not None:
        if delay or angle:
            raise ValueError("give either a challenge or delay/angle_noise_deg, not both "
                             "(the challenge sets its own delays and noise)")
        return challenge_named(challenge)
    if angle < 0:
        raise ValueError(f"angle_noise_deg must be non-negative, got {angle_noise_deg}")
    return Challenge("custom", action_delay=delay, angle_noise_deg=angle,
                     speed_noise=angle * SPEED_PER_DEG,
                     description=f"{delay:g}-sample delay, {angle:g} deg noise")


def _plants(params, ch: Challenge, count, seed) -> list[ArmParameters]:
    if params is None:
        if count is None:
            count = DEFAULT_PLANTS if ch.spread > 0 else 1
        return ch.plants(count, seed)
    if isinstance(params, ArmParameters):
        params = [params]
    params = list(params)
    if not params or not all(isinstance(p, ArmParameters) for p in params):
        raise ValueError("params must be a non-empty list of ArmParameters")
    if len(params) > MAX_PLANTS:
        raise ValueError(f"at most {MAX_PLANTS} plants, got {len(params)}")
    if count is not None and count != len(params):
        raise ValueError(f"count {count!r} disagrees with the {len(params)} params given")
    return params


def _states(x0) -> np.ndarray:
    if x0 is None:
        return evaluation_set()
    x0 = check_states(x0, what="x0")
    if x0.ndim == 1:
        x0 = x0[None]
    if x0.ndim != 2 or not len(x0):
        raise ValueError(f"x0 must be states of shape (n, 4), got shape {x0.shape}")
    return x0


def controller(policy, ch: Challenge, *, compensate: bool = True):
    """The policy as the controller sees it: wrapped by
    :func:`twolink.sim.estimation.compensated` for the challenge's delays and noise when
    ``compensate`` and there is anything to compensate, else the policy itself. The
    observer is designed for the challenge's own noise levels when it has both (a
    challenge with faults but no noise keeps the estimator's design noise)."""
    noise = bool(ch.angle_noise_deg or ch.speed_noise or ch.dropout or ch.stuck)
    if not compensate or not (ch.action_delay or ch.observation_delay or noise):
        return policy
    from twolink.sim.estimation import compensated  # running layer, beside this module
    design = ({"angle_noise_deg": ch.angle_noise_deg, "speed_noise": ch.speed_noise}
              if ch.angle_noise_deg > 0 and ch.speed_noise > 0 else {})
    return compensated(policy, delay=ch.action_delay,
                       observation_delay=ch.observation_delay, noise=noise, **design)


def closed_loop(policy, ch: Challenge, *, keys, seed: int, steps: int,
                compensate: bool = True):
    """The closed loop :func:`evaluate` runs, for the runs ``keys`` ((plant, state) index
    pairs, one per batch row): ``(act, observe)`` for
    ``rollout(act, plant, x0, duration=steps * Ts, observe=observe)``. ``observe(k, x)``
    hands on the challenge's readings of the true states x (noise and faults drawn from
    each run's own generators, then the reading delay); ``act`` is the controller
    (:func:`controller`) behind the actuation delay. Make a new pair per rollout."""
    rngs, fault_rngs = ch.generators(seed, keys)
    sensors = ch.sensors(rngs=rngs, fault_rngs=fault_rngs, block=steps)
    act = ActuationDelay(controller(policy, ch, compensate=compensate), ch.action_delay)
    return act, lambda k, x: sensors(x)


def evaluate(policy, params=None, x0=None, delay=0, angle_noise_deg=0.0, seed=0,
             horizon: float = HORIZON, compensate: bool = False, challenge=None, *,
             count: int | None = None, nthread: int | None = None, label: str | None = None,
             progress: bool = False, timeout: float | None = None) -> Evaluation:
    """Run ``policy`` from every state of ``x0`` on every plant of ``params`` on MuJoCo.

    ``policy``: any controller of :mod:`twolink.sim.controller`'s protocol (a shipped
    policy's name or a policy file's path loads it); it is held to the protocol
    (:class:`twolink.sim.controller.Checked`), so a wrong shape, NaN or an exception ends
    in one line naming it; it gets read-only copies of the measured states (never the
    plant's) and its prints go to stderr.
    ``params``: the plants (a list of ArmParameters; default: drawn by the challenge,
    ``count`` of them (32 when the challenge perturbs the plant), else Table I).
    Given ``params`` are the plants as they are (e.g. ``challenge.plants(count, seed)``);
    the challenge then adds only its delays, noise and faults.
    ``x0``: initial states (n, 4) (default: the evaluation set of docs/conventions.md, 65 states).
    ``challenge``: a :class:`twolink.sim.challenges.Challenge` or a level name; without one,
    ``delay`` (samples of actuation delay) and ``angle_noise_deg`` (deg, with speed noise
    :data:`SPEED_PER_DEG` rad/s per deg) apply. ``seed``: drawn plants, noise and faults.
    ``horizon``: seconds per run (success = settled 1 s before its end).
    ``nthread``: MuJoCo's rollout threads, 1 to :data:`twolink.sim.plants.MAX_NTHREAD`
    (default: one per core).
    ``compensate``: drive the policy through :func:`twolink.sim.estimation.compensated`
    (it predicts with the model the controller names in ``meta["model"]``). Off by
    default: a comparison of controllers scores each as it is; the result records the
    choice (``compensated``).
    ``progress``: a bar of the samples simulated on stderr
    (:func:`twolink.sim.progress.progress_bar`: lines when stderr is not a terminal);
    off by default.
    ``timeout``: seconds one call of the policy may take (None: no limit; a policy already
    checked with a limit keeps it), else one ControllerError line; the run is in this
    process, and the limit holds on its main thread only (a SIGALRM timer).
    """
    ch = _challenge(challenge, delay, angle_noise_deg)
    horizon = real(horizon, "horizon")
    whole(seed, "seed", 0)
    nthread = check_nthread(nthread)
    timeout = check_timeout(timeout)
    plants = _plants(params, ch, count, seed)
    x0 = _states(x0)
    runs = len(plants) * len(x0)
    if runs > MAX_RUNS:
        raise ValueError(f"{len(plants)} plants x {len(x0)} states = {runs} runs, over the "
                         f"{MAX_RUNS} an evaluation holds; evaluate fewer at a time")
    steps = steps_for(horizon, rows=runs)
    check_horizon(ch, steps, horizon)
    if isinstance(policy, str):
        from twolink.policy.fuzzy_policy import load_policy
        label = policy if label is None else label
        policy = load_policy(policy)
    if label is None:
        label = (str(getattr(policy, "meta", {}).get("name", "")) or getattr(policy, "kind", "")
                 or controller_name(policy))
    policy = checked(policy, name=label, timeout=timeout)

    keys = [(p, s) for p in range(len(plants)) for s in range(len(x0))]
    act, sensed = closed_loop(policy, ch, keys=keys, seed=seed, steps=steps,
                              compensate=compensate)
    bar = progress_bar(total=steps, desc=f"evaluate {label}", unit=" Ts", leave=False,
                       enabled=progress)

    def observe(k, x):
        bar.update()
        return sensed(k, x)

    try:
        with MujocoPlant([p for p in plants for _ in x0], nthread=nthread) as plant:
            traj = rollout(act, plant, np.tile(x0, (len(plants), 1)), duration=horizon,
                           observe=observe)
    finally:
        bar.close()
    shape = (len(plants), len(x0))
    return Evaluation(success(traj).reshape(shape), settle_time(traj).reshape(shape),
                      discounted_return(traj).reshape(shape), tuple(plants), x0.copy(), ch,
                      int(seed), horizon, act.policy is not policy, label)


def challenged_rollouts(policies: dict, plants, x0, ch: Challenge, *, seed: int,
                        compensate: bool, duration: float = HORIZON) -> dict:
    """Single trajectories under a challenge: every policy (``{label: policy}``) on every
    plant (names) from x0 (4,), ``{(label, plant): Trajectory}``.

    The closed loop of :func:`twolink.sim.evaluation.evaluate` for its plant 0 and state 0:
    the plant is the challenge's first plant drawn from ``seed``, the readings go through
    the challenge's sensors with the generators evaluate gives run (0, 0), the torques
    through :func:`twolink.sim.evaluation.controller` and the actuation delay. So a MuJoCo
    trajectory here settles exactly as ``evaluate(policy, x0=[x0], count=1, seed=seed,
    challenge=ch)`` says.
    """
    steps = steps_for(duration)
    check_horizon(ch, steps, duration)
    x0 = np.asarray(x0, dtype=float)[None]

    def loop(policy):
        return closed_loop(policy, ch, keys=[(0, 0)], seed=seed, steps=steps,
                           compensate=compensate)

    runs = rollout_grid(policies, plants, x0, duration=duration,
                        params=ch.plants(1, seed)[0], loop=loop)
    return {key: traj[0] for key, traj in runs.items()}
