"""Synthesis of the paper's policies with fuzzy Q-iteration (Alg. 1).

* centralized (16): Q(theta1, theta2, dtheta1, dtheta2, tau1, tau2), 7056 x 9 = 63504 values;
* agent 2 (18): Q2(theta2, dtheta2, tau2), 84 x 3 = 252 values, synthesised first;
* agent 1 (18): Q1(theta1, dtheta1, theta2, tau2, tau1), 3024 x 3 = 9072 values, using
  agent 2's policy. Two readings of agent 1's transitions (SPEC.md):
  ``frozen`` - theta2 and tau2 stay as they are over the transition (link 2 held at rest);
  ``propagated`` - link 2 moves from dtheta2 = 0 under tau2 and the next tau2 is agent 2's
  action at the new link-2 state.

Transitions f(c_m, u) come from the chosen model sampled over Ts (``twolink.integrate``);
rewards are evaluated on the state reached, r_{k+1}.
"""
from __future__ import annotations

import dataclasses
import itertools
import time
from typing import Optional

import numpy as np
from tqdm import tqdm

from twolink import __version__, dynamics, fuzzy
from twolink.fqi import fuzzy_q_iteration, transition_table
from twolink.integrate import SUBSTEPS, sample_step
from twolink.parameters import DELTA, GAMMA, TABLE_I, TS, ArmParameters
from twolink.policy import Agent, Policy
from twolink.reward import agent_reward, centralized_reward

SYNTHESIS_MODELS = ("simplified", "full")
#: How Alg. 1 sweeps (:func:`twolink.fqi.fuzzy_q_iteration`): ``synchronous`` as printed
#: (Q_{l+1} from Q_l), or ``serial`` (each Q(m, j) overwritten at once, bins outer and
#: actions inner, as the ``'serial'`` option of Busoniu's ApproxRL ``fuzzyqi.m``).
SWEEPS = ("synchronous", "serial")
CONTEXTS = ("frozen", "propagated")
KINDS = ("centralized", "decentralized")


@dataclasses.dataclass
class Problem:
    """A fuzzy MDP: the grid, the discrete actions and f(c_m, u_j), rho(c_m, u_j) for all pairs."""

    name: str
    grid: fuzzy.Grid
    actions: np.ndarray          # (N_U, len(outputs))
    outputs: tuple
    next_points: np.ndarray      # (N_X, N_U, d)
    rewards: np.ndarray          # (N_X, N_U)
    seconds: float = 0.0         # time to compute the transitions


def _accel(model: str):
    if model not in SYNTHESIS_MODELS:
        raise ValueError(f"unknown synthesis model {model!r}; choose one of "
                         f"{', '.join(SYNTHESIS_MODELS)}")
    return dynamics.MODELS[model]


def _levels(tmax: float) -> np.ndarray:
    return np.array([-tmax, 0.0, tmax])


def _grid(*axes: fuzzy.Axis, refine: int = 1) -> fuzzy.Grid:
    """The product grid of ``axes``, each refined ``refine`` times (the paper's: 1)."""
    return fuzzy.Grid(tuple(a.refined(refine) for a in axes))


def centralized_actions(p: ArmParameters = TABLE_I) -> np.ndarray:
    """The joint actions of the centralized problem (16): every pair of the levels
    {-tau_max, 0, tau_max} of both links, shape (9, 2), tau2 varying fastest."""
    return np.array(list(itertools.product(_levels(p.tau1_max), _levels(p.tau2_max))))


def centralized_problem(p: ArmParameters = TABLE_I, model: str = "simplified", *,
                        refine: int = 1) -> Problem:
    """The centralized MDP over x = [theta1, theta2, dtheta1, dtheta2], u = [tau1, tau2].

    ``refine`` > 1 subdivides every bin (for scaling studies; see :meth:`fuzzy.Axis.refined`).
    """
    start = time.perf_counter()
    accel = _accel(model)
    grid = _grid(fuzzy.angle_axis("theta1"), fuzzy.angle_axis("theta2"),
                 fuzzy.speed_axis("dtheta1"), fuzzy.speed_axis("dtheta2"), refine=refine)
    actions = centralized_actions(p)
    centers = grid.centers()
    nxt = sample_step(accel, p, centers[:, None, :], actions[None, :, :])
    return Problem("centralized", grid, actions, ("tau1", "tau2"), nxt,
                   centralized_reward(nxt), time.perf_counter() - start)


def agent2_problem(p: ArmParameters = TABLE_I, model: str = "simplified", *,
                   refine: int = 1) -> Problem:
    """Agent 2's MDP over (theta2, dtheta2), u = tau2.

    Under (11) link 2 does not depend on link 1. Under the full model agent 2 cannot see
    link 1 and assumes it at rest (theta1 = dtheta1 = 0, tau1 = 0).
    """
    start = time.perf_counter()
    accel = _accel(model)
    grid = _grid(fuzzy.angle_axis("theta2"), fuzzy.speed_axis("dtheta2"), refine=refine)
    actions = _levels(p.tau2_max)[:, None]
    c = grid.centers()
    x = np.zeros((len(c), 4))
    x[:, 1], x[:, 3] = c[:, 0], c[:, 1]
    tau = np.zeros((len(actions), 2))
    tau[:, 1] = actions[:, 0]
    nxt = sample_step(accel, p, x[:, None, :], tau[None, :, :])
    return Problem("agent2", grid, actions, ("tau2",), nxt[..., [1, 3]],
                   agent_reward(nxt, 2), time.perf_counter() - start)


def agent1_problem(agent2: Optional[Agent], p: ArmParameters = TABLE_I,
                   model: str = "simplified", context: str = "frozen", *,
                   refine: int = 1, axes: Optional[tuple] = None) -> Problem:
    """Agent 1's MDP over (theta1, dtheta1, theta2, tau2), u = tau1 (see module docstring).

    ``agent2`` (agent 2's synthesised controller) is needed by the propagated context only.
    ``refine`` subdivides the state bins; ``axes`` replaces the paper's (theta1, dtheta1,
    theta2) axes (coarse grids for tests). The tau2 axis stays the three torque values.
    """
    if context not in CONTEXTS:
        raise ValueError(f"unknown agent-1 context {context!r}; choose one of {', '.join(CONTEXTS)}")
    if context == "propagated" and agent2 is None:
        raise ValueError("the propagated context needs agent 2's controller")
    if axes is None:
        axes = (fuzzy.angle_axis("theta1"), fuzzy.speed_axis("dtheta1"),
                fuzzy.angle_axis("theta2"))
    if tuple(a.name for a in axes) != ("theta1", "dtheta1", "theta2"):
        raise ValueError(f"agent 1's state axes must be theta1, dtheta1, theta2, got "
                         f"{', '.join(a.name for a in axes)}")
    start = time.perf_counter()
    accel = _accel(model)
    grid = fuzzy.Grid(_grid(*axes, refine=refine).axes
                      + (fuzzy.torque_axis("tau2", p.tau2_max),))
    actions = _levels(p.tau1_max)[:, None]
    c = grid.centers()
    x = np.zeros((len(c), 4))
    x[:, 0], x[:, 2], x[:, 1] = c[:, 0], c[:, 1], c[:, 2]
    tau = np.zeros((len(c), len(actions), 2))
    tau[:, :, 0] = actions[None, :, 0]
    tau[:, :, 1] = c[:, 3:4]
    if context == "frozen":
        def link1_only(pp, s, t):
            return accel(pp, s, t) * np.array([1.0, 0.0])
        nxt = sample_step(link1_only, p, x[:, None, :], tau)
        tau2_next = np.broadcast_to(c[:, None, 3], nxt.shape[:-1])
    else:
        nxt = sample_step(accel, p, x[:, None, :], tau)
        tau2_next = agent2.act(nxt[..., [1, 3]])[..., 0]
    points = np.stack([nxt[..., 0], nxt[..., 2], nxt[..., 1], tau2_next], -1)
    return Problem("agent1", grid, actions, ("tau1",), points, agent_reward(nxt, 1),
                   time.perf_counter() - start)


def check_sweeps(sweeps: str) -> str:
    """``sweeps`` if it is one of :data:`SWEEPS`, else a ValueError naming them."""
    if sweeps not in SWEEPS:
        raise ValueError(f"unknown sweeps {sweeps!r}; choose one of {', '.join(SWEEPS)}")
    return sweeps


def check_refine(refine: int) -> int:
    """``refine`` if it is a positive whole number, else a ValueError."""
    if isinstance(refine, bool) or not isinstance(refine, (int, np.integer)) or refine < 1:
        raise ValueError(f"refine must be a positive whole number, got {refine!r}")
    return int(refine)


def table_sizes(kind: str, refine: int = 1) -> dict:
    """Q-table size of every agent of ``kind`` on the paper's grid refined ``refine`` times,
    known before anything is synthesised: ``{agent: N_X * N_U}``."""
    refine = check_refine(refine)
    ang, spd = fuzzy.angle_axis("a").refined(refine).size, fuzzy.speed_axis("s").refined(refine).size
    if kind == "centralized":
        return {"centralized": ang * ang * spd * spd * 9}
    if kind == "decentralized":
        return {"agent2": ang * spd * 3, "agent1": ang * spd * ang * 3 * 3}
    raise ValueError(f"unknown policy kind {kind!r}; choose one of {', '.join(KINDS)}")


def solve(problem: Problem, *, gamma: float = GAMMA, delta: float = DELTA,
          sweeps: str = "synchronous", progress: bool = False,
          extra: Optional[dict] = None) -> Agent:
    """Build the sparse transition matrix once, then run Alg. 1 to convergence with
    ``sweeps`` (:data:`SWEEPS`)."""
    check_sweeps(sweeps)
    cpu0 = time.process_time()
    t0 = time.perf_counter()
    trans = transition_table(problem.grid, problem.next_points)
    build = problem.seconds + time.perf_counter() - t0
    with tqdm(desc=f"Q-iteration {problem.name}", unit=" sweeps", disable=None if progress else True,
              leave=False, mininterval=0.25) as bar:
        def tick(ell, change):
            bar.update(1)
            bar.set_postfix(change=f"{change:.3g}")
        result = fuzzy_q_iteration(trans, problem.rewards, gamma=gamma, delta=delta,
                                   sweeps=sweeps, state_shape=problem.grid.shape,
                                   callback=tick)
    if not result.converged:
        raise RuntimeError(f"Q-iteration for {problem.name} did not converge")
    info = {"iterations": result.iterations, "sweeps": sweeps, "converged": result.converged,
            "final_change": float(result.history[-1]),
            "transition_seconds": build, "sweep_seconds": result.seconds,
            "seconds": build + result.seconds,
            "cpu_seconds": time.process_time() - cpu0 + problem.seconds,
            "q_size": int(result.q.size), "transition_nnz": int(trans.nnz)}
    info.update(extra or {})
    return Agent(problem.name, problem.grid, problem.actions, result.q, problem.outputs, info)


def _meta(p: ArmParameters, model: str, gamma: float, delta: float, **more) -> dict:
    return {"parameters": p.as_dict(), "model": model, "gamma": gamma, "delta": delta,
            "ts": TS, "substeps": SUBSTEPS, "reward": "r_{k+1} on the state reached",
            "twolink_version": __version__, **more}


def synthesize(kind: str, p: ArmParameters = TABLE_I, *, model: str = "simplified",
               context: str = "frozen", gamma: float = GAMMA, delta: float = DELTA,
               sweeps: str = "synchronous", refine: int = 1,
               progress: bool = False) -> Policy:
    """The centralized policy (16) or the decentralized pair (18), synthesised on ``model``
    with ``sweeps`` of Alg. 1 (:data:`SWEEPS`) over the paper's bins, each subdivided
    ``refine`` times (:meth:`fuzzy.Axis.refined`; 1: the paper's grid). Both are recorded
    in the policy's provenance (``meta``)."""
    check_sweeps(sweeps)
    refine = check_refine(refine)
    opts = {"gamma": gamma, "delta": delta, "sweeps": sweeps, "progress": progress}
    more = {"sweeps": sweeps, "refine": refine}
    if kind == "centralized":
        agent = solve(centralized_problem(p, model, refine=refine), **opts)
        return Policy(kind, [agent], _meta(p, model, gamma, delta, **more))
    if kind == "decentralized":
        if context not in CONTEXTS:
            raise ValueError(f"unknown agent-1 context {context!r}; choose one of "
                             f"{', '.join(CONTEXTS)}")
        a2 = solve(agent2_problem(p, model, refine=refine), **opts)
        a1 = solve(agent1_problem(a2, p, model, context, refine=refine), **opts,
                   extra={"context": context})
        return Policy(kind, [a2, a1], _meta(p, model, gamma, delta, context=context, **more))
    raise ValueError(f"unknown policy kind {kind!r}; choose one of {', '.join(KINDS)}")
