"""The fuzzy MDPs of the paper's policies, and Alg. 1 run on them.

* centralized (16): Q(theta1, theta2, dtheta1, dtheta2, tau1, tau2), 7056 x 9 = 63504 values;
* agent 2 (18): Q2(theta2, dtheta2, tau2), 84 x 3 = 252 values, synthesised first;
* agent 1 (18): Q1(theta1, dtheta1, theta2, tau2, tau1), 3024 x 3 = 9072 values, using
  agent 2's policy. Two readings of agent 1's transitions (docs/conventions.md):
  ``frozen`` - theta2 and tau2 stay as they are over the transition (link 2 held at rest);
  ``propagated`` - link 2 moves from dtheta2 = 0 under tau2 and the next tau2 is agent 2's
  action at the new link-2 state.

Transitions f(c_m, u) come from the chosen model sampled over Ts (:func:`model_step`);
rewards are evaluated on the state reached, r_{k+1}. :func:`solve` and
:func:`solve_robust` build the transition table and run Alg. 1; the policy-level entry
point is :func:`twolink.synthesis.synthesize.synthesize`.
"""
from __future__ import annotations

import dataclasses
import itertools
import time
from typing import Optional

import numpy as np

from twolink.arm import dynamics
from twolink.arm.integrate import (
    sample_step,
    sample_step_compiled,
    wrap_angle,
)
from twolink.arm.parameters import (
    DELTA,
    GAMMA,
    TABLE_I,
    ArmParameters,
)
from twolink.arm.task import (
    action_levels,
    agent_reward,
    centralized_reward,
    check_levels,
)
from twolink.fqi import fuzzy
from twolink.fqi.factored import (
    default_threads,
    factored_q_iteration,
    factored_q_iteration_robust,
    factored_table,
    sweep_work,
)
from twolink.fqi.iteration import (
    ROBUST_MODES,
    fuzzy_q_iteration,
    fuzzy_q_iteration_robust,
)
from twolink.fqi.tables import robust_table, transition_table
from twolink.policy.fuzzy_policy import Agent
from twolink.sim.perturbations import MAX_SPREAD, PHYSICAL, random_perturbation
from twolink.sim.progress import progress_bar
from twolink.validate import real, whole

SYNTHESIS_MODELS = ("simplified", "full")
#: Models that take their parameters from a file (twolink.arm.parameter_file): the full
#: model (6) with identified parameters, recorded as model "identified".
IDENTIFIED_MODELS = {"identified": "full"}
#: Robust synthesis: the memory the K models' transitions may take (estimated by
#: :func:`robust_bytes` before any work); a draw's spread is below
#: :data:`twolink.sim.perturbations.MAX_SPREAD`.
MAX_ROBUST_BYTES = 2 * 2**30
#: How Alg. 1 sweeps (:func:`twolink.fqi.iteration.fuzzy_q_iteration`): ``synchronous`` as printed
#: (Q_{l+1} from Q_l), or ``serial`` (each Q(m, j) overwritten at once, bins outer and
#: actions inner, as the ``'serial'`` option of Busoniu's ApproxRL ``fuzzyqi.m``).
SWEEPS = ("synchronous", "serial")
CONTEXTS = ("frozen", "propagated")
#: How agent 2's transitions read link 1 (:func:`agent2_problem`): ``free`` - link 1
#: starts at rest and moves freely under link 2's reaction (the paper's reading, exact
#: under (11), where link 2 does not depend on link 1); ``locked`` - joint 1 is held, so
#: link 2 swings alone about a fixed joint (the full model (6) only).
LINK1_READINGS = ("free", "locked")
KINDS = ("centralized", "decentralized")
#: How T is stored for the sweeps: ``fixed`` (:func:`twolink.fqi.iteration.transition_table`, every
#: row's memberships; the agents and serial sweeps) or ``factored``
#: (:func:`twolink.fqi.factored.factored_table`: the horizontal arm ignores theta1, so the
#: memberships on the other axes are shared by the theta1 blocks; the centralized
#: problem's synchronous sweeps, about 2x QuantEcon's sweep on one core: README,
#: *Performance*). Both hold the same memberships; sums in another order move Q by ~1e-14.
LAYOUTS = ("fixed", "factored")


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


def dynamics_of(model: str) -> str:
    """The name in ``dynamics.MODELS`` of synthesis model ``model`` ("identified" is the
    full model (6)), or a ValueError naming the models."""
    if model in IDENTIFIED_MODELS:
        return IDENTIFIED_MODELS[model]
    if model not in SYNTHESIS_MODELS:
        raise ValueError(f"unknown synthesis model {model!r}; choose one of "
                         f"{', '.join(SYNTHESIS_MODELS + tuple(IDENTIFIED_MODELS))}")
    return model


def _accel(model: str):
    return dynamics.MODELS[dynamics_of(model)]


def model_step(model: str, p: ArmParameters, x: np.ndarray, tau: np.ndarray, *,
          compiled: bool, freeze_link2: bool = False, theta1_bins: int = 1) -> np.ndarray:
    """One sample period of ``model`` from every x (N, 1, 4) under every tau: the numpy RK4
    (``sample_step``, the shipped non-robust policies) or the compiled one.

    ``theta1_bins`` > 1 (compiled only): the N rows of x, and of tau when it has N rows,
    are that many equal blocks differing only in theta1 (the grid's first axis). The
    horizontal arm's (6) and (11) do not depend on theta1, so one block is integrated from
    theta1 = 0 and every block's theta1 added to it and wrapped: the same transitions up to
    round-off (the sum is rounded in another order), at 1/theta1_bins of the work.
    """
    if not compiled:
        accel = _accel(model)
        if freeze_link2:
            def link1_only(pp, s, t):
                return accel(pp, s, t) * np.array([1.0, 0.0])
            return sample_step(link1_only, p, x, tau)
        return sample_step(accel, p, x, tau)
    name = dynamics_of(model)
    if theta1_bins == 1:
        return sample_step_compiled(name, p, x, tau, freeze_link2=freeze_link2)
    n = len(x) // theta1_bins
    blocks = x.reshape((theta1_bins, n) + x.shape[1:])
    per_row = tau.shape[0] == len(x) and len(x) > 1
    tau0 = tau[:n] if per_row else tau
    if n * theta1_bins != len(x) or not np.array_equal(
            blocks[..., 1:], np.broadcast_to(blocks[:1, ..., 1:], blocks[..., 1:].shape)) \
            or (per_row and not np.array_equal(
                tau.reshape((theta1_bins, n) + tau.shape[1:]),
                np.broadcast_to(tau0, (theta1_bins,) + tau0.shape))):
        raise RuntimeError("theta1_bins: the rows are not blocks differing in theta1 only")
    x0 = np.array(blocks[0])
    x0[..., 0] = 0.0
    moved = sample_step_compiled(name, p, x0, tau0, freeze_link2=freeze_link2)
    out = np.tile(moved, (theta1_bins,) + (1,) * (moved.ndim - 1))
    out[..., 0] = wrap_angle(x[..., 0] + out[..., 0])
    return out


def _grid(*axes: fuzzy.Axis, refine: int = 1) -> fuzzy.Grid:
    """The product grid of ``axes``, each refined ``refine`` times (the paper's: 1)."""
    return fuzzy.Grid(tuple(a.refined(refine) for a in axes))


def centralized_actions(p: ArmParameters = TABLE_I, levels: int = 3) -> np.ndarray:
    """The joint actions of the centralized problem (16): every pair of the ``levels``
    torque levels of both links (:func:`twolink.arm.task.action_levels`; the paper's
    {-tau_max, 0, tau_max}: shape (9, 2)), tau2 varying fastest."""
    return np.array(list(itertools.product(action_levels(p.tau1_max, levels),
                                           action_levels(p.tau2_max, levels))))


def centralized_problem(p: ArmParameters = TABLE_I, model: str = "simplified", *,
                        refine: int = 1, compiled: bool = False, levels: int = 3,
                        bins: str = "paper") -> Problem:
    """The centralized MDP over x = [theta1, theta2, dtheta1, dtheta2], u = [tau1, tau2].

    ``refine`` > 1 subdivides every bin (for scaling studies; see :meth:`fuzzy.Axis.refined`);
    ``compiled`` samples the model with the compiled RK4 over one theta1 slice
    (see :func:`model_step`; equal to the numpy path up to round-off); ``levels`` torque
    levels per joint and the bin layout ``bins`` (:data:`fuzzy.BIN_LAYOUTS`; the paper's:
    3 and "paper").
    """
    start = time.perf_counter()
    dynamics_of(model)
    grid = _grid(fuzzy.angle_axis("theta1", bins), fuzzy.angle_axis("theta2", bins),
                 fuzzy.speed_axis("dtheta1", bins), fuzzy.speed_axis("dtheta2", bins),
                 refine=refine)
    actions = centralized_actions(p, levels)
    centers = grid.centers()
    nxt = model_step(model, p, centers[:, None, :], actions[None, :, :], compiled=compiled,
                theta1_bins=grid.axes[0].size if compiled else 1)
    return Problem("centralized", grid, actions, ("tau1", "tau2"), nxt,
                   centralized_reward(nxt), time.perf_counter() - start)


def check_link1(link1: str, model: str = "full") -> str:
    """``link1`` if it names a reading of :data:`LINK1_READINGS` that ``model`` allows,
    else a ValueError naming the readings."""
    if link1 not in LINK1_READINGS:
        raise ValueError(f"unknown reading of link 1 by agent 2 {link1!r}; choose one of "
                         f"{', '.join(LINK1_READINGS)}")
    if link1 == "locked" and dynamics_of(model) != "full":
        raise ValueError("agent 2 holding joint 1 (locked) is a reading of the full model "
                         "(6); under (11) link 2 does not depend on link 1")
    return link1


def _joint1_locked(p: ArmParameters, x: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """ddtheta of (6) with joint 1 held: 0 for joint 1, link 2 alone about a fixed joint."""
    return dynamics.links_acceleration(p, x, tau, locked=(True, False))


def agent2_problem(p: ArmParameters = TABLE_I, model: str = "simplified", *,
                   refine: int = 1, axes: Optional[tuple] = None, compiled: bool = False,
                   levels: int = 3, bins: str = "paper", link1: str = "free") -> Problem:
    """Agent 2's MDP over (theta2, dtheta2), u = tau2.

    Under (11) link 2 does not depend on link 1. Under the full model agent 2 cannot see
    link 1: ``link1="free"`` assumes it at rest and free (theta1 = dtheta1 = 0, tau1 = 0,
    link 1 recoiling under link 2's reaction), ``"locked"`` holds joint 1 fixed, as
    agent 1's torque opposes that recoil (:data:`LINK1_READINGS`; the transitions then
    come from the numpy RK4 of :func:`twolink.arm.dynamics.links_acceleration` whatever
    ``compiled`` says). ``axes`` replaces the (theta2, dtheta2) axes of the layout
    ``bins`` (each refined ``refine`` times).
    """
    check_link1(link1, model)
    if axes is None:
        axes = (fuzzy.angle_axis("theta2", bins), fuzzy.speed_axis("dtheta2", bins))
    if tuple(a.name for a in axes) != ("theta2", "dtheta2"):
        raise ValueError(f"agent 2's state axes must be theta2, dtheta2, got "
                         f"{', '.join(a.name for a in axes)}")
    start = time.perf_counter()
    dynamics_of(model)
    grid = _grid(*axes, refine=refine)
    actions = action_levels(p.tau2_max, levels)[:, None]
    c = grid.centers()
    x = np.zeros((len(c), 4))
    x[:, 1], x[:, 3] = c[:, 0], c[:, 1]
    tau = np.zeros((len(actions), 2))
    tau[:, 1] = actions[:, 0]
    if link1 == "locked":
        nxt = sample_step(_joint1_locked, p, x[:, None, :], tau[None, :, :])
    else:
        nxt = model_step(model, p, x[:, None, :], tau[None, :, :], compiled=compiled)
    return Problem("agent2", grid, actions, ("tau2",), nxt[..., [1, 3]],
                   agent_reward(nxt, 2), time.perf_counter() - start)


def agent1_problem(agent2: Optional[Agent], p: ArmParameters = TABLE_I,
                   model: str = "simplified", context: str = "frozen", *,
                   refine: int = 1, axes: Optional[tuple] = None,
                   compiled: bool = False, levels: int = 3, bins: str = "paper") -> Problem:
    """Agent 1's MDP over (theta1, dtheta1, theta2, tau2), u = tau1 (see module docstring).

    ``agent2`` (agent 2's synthesised controller) is needed by the propagated context only.
    ``refine`` subdivides the state bins; ``axes`` replaces the paper's (theta1, dtheta1,
    theta2) axes (coarse grids for tests), else they follow the layout ``bins``. The tau2
    axis holds agent 2's ``levels`` torque values, and agent 1 chooses among as many.
    """
    if context not in CONTEXTS:
        raise ValueError(f"unknown agent-1 context {context!r}; choose one of {', '.join(CONTEXTS)}")
    if context == "propagated" and agent2 is None:
        raise ValueError("the propagated context needs agent 2's controller")
    if axes is None:
        axes = (fuzzy.angle_axis("theta1", bins), fuzzy.speed_axis("dtheta1", bins),
                fuzzy.angle_axis("theta2", bins))
    if tuple(a.name for a in axes) != ("theta1", "dtheta1", "theta2"):
        raise ValueError(f"agent 1's state axes must be theta1, dtheta1, theta2, got "
                         f"{', '.join(a.name for a in axes)}")
    start = time.perf_counter()
    dynamics_of(model)
    grid = fuzzy.Grid(_grid(*axes, refine=refine).axes
                      + (fuzzy.torque_axis("tau2", p.tau2_max, levels),))
    actions = action_levels(p.tau1_max, levels)[:, None]
    c = grid.centers()
    x = np.zeros((len(c), 4))
    x[:, 0], x[:, 2], x[:, 1] = c[:, 0], c[:, 1], c[:, 2]
    tau = np.zeros((len(c), len(actions), 2))
    tau[:, :, 0] = actions[None, :, 0]
    tau[:, :, 1] = c[:, 3:4]
    slices = {"compiled": compiled, "theta1_bins": grid.axes[0].size if compiled else 1}
    if context == "frozen":
        nxt = model_step(model, p, x[:, None, :], tau, freeze_link2=True, **slices)
        tau2_next = np.broadcast_to(c[:, None, 3], nxt.shape[:-1])
    else:
        nxt = model_step(model, p, x[:, None, :], tau, **slices)
        tau2_next = agent2.act(nxt[..., [1, 3]])[..., 0]
    points = np.stack([nxt[..., 0], nxt[..., 2], nxt[..., 1], tau2_next], -1)
    return Problem("agent1", grid, actions, ("tau1",), points, agent_reward(nxt, 1),
                   time.perf_counter() - start)


def check_sweeps(sweeps: str) -> str:
    """``sweeps`` if it is one of :data:`SWEEPS`, else a ValueError naming them."""
    if sweeps not in SWEEPS:
        raise ValueError(f"unknown sweeps {sweeps!r}; choose one of {', '.join(SWEEPS)}")
    return sweeps


#: Most subdivisions of the paper's bins: beyond 16, agent 1's table alone (2.6e8 values at
#: 16) outgrows any machine's memory for its transitions.
MAX_REFINE = 16


def check_refine(refine: int) -> int:
    """``refine`` if it is a whole number from 1 to :data:`MAX_REFINE`, else a ValueError."""
    return whole(refine, "refine", 1, MAX_REFINE)


def table_sizes(kind: str, refine: int = 1, levels: int = 3, bins: str = "paper") -> dict:
    """Q-table size of every agent of ``kind`` on the grid of layout ``bins`` refined
    ``refine`` times with ``levels`` torque levels per joint, known before anything is
    synthesised: ``{agent: N_X * N_U}``."""
    refine = check_refine(refine)
    levels = check_levels(levels)
    ang = fuzzy.angle_axis("a", bins).refined_size(refine)
    spd = fuzzy.speed_axis("s", bins).refined_size(refine)
    if kind == "centralized":
        return {"centralized": ang * ang * spd * spd * levels * levels}
    if kind == "decentralized":
        return {"agent2": ang * spd * levels, "agent1": ang * spd * ang * levels * levels}
    raise ValueError(f"unknown policy kind {kind!r}; choose one of {', '.join(KINDS)}")


def check_size(kind: str, refine: int = 1, levels: int = 3, bins: str = "paper") -> int:
    """The peak bytes of a (non-robust) synthesis (:func:`robust_bytes` of one model), or a
    ValueError when it is over :data:`MAX_ROBUST_BYTES` or a Q-table would not fit in a
    policy file (:data:`twolink.policy.fuzzy_policy.MAX_Q_BYTES`)."""
    from twolink.policy.fuzzy_policy import MAX_Q_BYTES
    for agent, size in table_sizes(kind, refine, levels, bins).items():
        if 8 * size > MAX_Q_BYTES:
            raise ValueError(f"--levels {levels} --bins {bins} --refine {refine}: the {agent} "
                             f"Q-table of {size} values ({8 * size / 2**20:.0f} MiB) is over "
                             f"the {MAX_Q_BYTES >> 20} MiB a policy file may hold")
    need = robust_bytes(kind, refine, 1, levels, bins)
    if need > MAX_ROBUST_BYTES:
        raise ValueError(f"--levels {levels} --bins {bins} --refine {refine}: the "
                         f"transitions take about {need / 2**20:.0f} MiB, over the "
                         f"{MAX_ROBUST_BYTES >> 20} MiB a synthesis may use")
    return need


def check_robust(robust: str, draws: int, spread: float, seed: int) -> tuple:
    """(mode, K, spread, seed) of a robust synthesis, or a ValueError saying what is wrong."""
    if robust not in ROBUST_MODES:
        raise ValueError(f"unknown robust mode {robust!r}; choose one of {', '.join(ROBUST_MODES)}")
    draws = whole(draws, "draws", 1)
    spread = real(spread, "spread", 0.0, MAX_SPREAD, open_high=True,
                  message="{what} must lie in [0, {high}), got {value!r}")
    return robust, draws, spread, whole(seed, "seed", 0)


def parameter_draws(p: ArmParameters, draws: int, spread: float, seed: int
                    ) -> list[ArmParameters]:
    """The K models of a robust synthesis: draw 0 is ``p`` itself; draws 1..K-1 change
    every parameter of :data:`~twolink.sim.perturbations.PHYSICAL` of ``p`` jointly, each by a
    relative amount uniform in +-``spread``, in turn from ``numpy.random.default_rng(seed)``."""
    _, draws, spread, seed = check_robust("worst", draws, spread, seed)
    rng = np.random.default_rng(seed)
    return [p] + [random_perturbation(rng, spread, p, PHYSICAL) for _ in range(draws - 1)]


def robust_bytes(kind: str, refine: int = 1, draws: int = 1, levels: int = 3,
                 bins: str = "paper") -> int:
    """Peak bytes a robust synthesis of the largest agent of ``kind`` takes, known before
    any work, per model and (bin, action) row: its reached point, reward and table.
    The agents' tables are fixed-width (at most 2**d memberships of int32 index + float64
    weight, :func:`twolink.fqi.iteration.robust_table`, beside the RK4 state); the centralized one is
    factored along theta1 (:func:`twolink.fqi.factored.factored_table`: theta1's two
    memberships per row, the other axes' 2**(d-1) once per theta1 block), built and then
    stacked for the sweeps (twice), plus 48 bytes per row once (Q, Q' and the policy's
    copy). Measured within 10 % of this on the paper's grid (tests)."""
    sizes = table_sizes(kind, refine, levels, bins)
    dims = {"centralized": 4, "agent2": 2, "agent1": 4}
    if kind == "centralized":
        d, rows = dims["centralized"], sizes["centralized"]
        first = fuzzy.angle_axis("theta1", bins).refined_size(check_refine(refine))
        table = 2 * (24 + 12 * 2 ** (d - 1) / first)
        return int(draws * rows * (8 * d + 16 + table) + 48 * rows)
    return max(draws * rows * (8 * dims[a] + 32 + 8 + 12 * 2 ** dims[a])
               for a, rows in sizes.items())


def check_robust_size(kind: str, refine: int, draws: int, levels: int = 3,
                      bins: str = "paper") -> int:
    """:func:`robust_bytes`, or a ValueError with the estimate when it is over
    :data:`MAX_ROBUST_BYTES`."""
    check_size(kind, refine, levels, bins)
    need = robust_bytes(kind, refine, draws, levels, bins)
    if need > MAX_ROBUST_BYTES:
        raise ValueError(f"--draws {draws}: the transitions of {draws} {kind} models take "
                         f"about {need / 2**20:.0f} MiB, over the {MAX_ROBUST_BYTES >> 20} MiB "
                         f"a robust synthesis may use")
    return need


def solve(problem: Problem, *, gamma: float = GAMMA, delta: float = DELTA,
          sweeps: str = "synchronous", progress: bool = False,
          extra: Optional[dict] = None, layout: str = "fixed") -> Agent:
    """Build the transition table once, in ``layout`` (:data:`LAYOUTS`; serial sweeps read
    the fixed one), then run Alg. 1 to convergence with ``sweeps`` (:data:`SWEEPS`)."""
    check_sweeps(sweeps)
    layout = _check_layout(layout)
    if sweeps == "serial":
        layout = "fixed"
    cpu0 = time.process_time()
    t0 = time.perf_counter()
    if layout == "factored":
        trans = factored_table(problem.grid, problem.next_points)
        threads = default_threads(sweep_work(trans))
    else:
        trans = transition_table(problem.grid, problem.next_points)
        threads = 1
    build = problem.seconds + time.perf_counter() - t0
    with progress_bar(desc=f"Q-iteration {problem.name}", unit=" sweeps", enabled=progress,
                      leave=False, mininterval=0.25) as bar:
        def tick(ell, change):
            bar.update(1)
            bar.set_postfix(change=f"{change:.3g}")
        if layout == "factored":
            result = factored_q_iteration(trans, problem.rewards, gamma=gamma, delta=delta,
                                          callback=tick if progress else None,
                                          threads=threads)
        else:
            result = fuzzy_q_iteration(trans, problem.rewards, gamma=gamma, delta=delta,
                                       sweeps=sweeps, state_shape=problem.grid.shape,
                                       callback=tick if progress else None)
    if not result.converged:
        raise RuntimeError(f"Q-iteration for {problem.name} did not converge")
    info = {"iterations": result.iterations, "sweeps": sweeps, "converged": result.converged,
            "final_change": float(result.history[-1]), "layout": layout,
            "threads": threads, "transition_seconds": build, "sweep_seconds": result.seconds,
            "seconds": build + result.seconds,
            "cpu_seconds": time.process_time() - cpu0 + problem.seconds,
            "q_size": int(result.q.size), "transition_nnz": int(trans.nnz)}
    info.update(extra or {})
    return Agent(problem.name, problem.grid, problem.actions, result.q, problem.outputs, info)


def _check_layout(layout: str) -> str:
    if layout not in LAYOUTS:
        raise ValueError(f"unknown layout {layout!r}; choose one of {', '.join(LAYOUTS)}")
    return layout


def solve_robust(problems: list, *, mode: str = "worst", gamma: float = GAMMA,
                 delta: float = DELTA, progress: bool = False,
                 extra: Optional[dict] = None, layout: str = "fixed") -> Agent:
    """Alg. 1 over the K ``problems`` (one grid and action set, K models) at once:
    Q(m, u) = min_k (``mode="worst"``) or mean_k of rho_k + gamma T_k max_u Q, the K
    tables in ``layout`` (:data:`LAYOUTS`)."""
    layout = _check_layout(layout)
    if not problems:
        raise ValueError("a robust synthesis needs at least one problem")
    first = problems[0]
    for other in problems[1:]:
        if other.grid.shape != first.grid.shape or not np.array_equal(other.actions,
                                                                        first.actions):
            raise ValueError("the robust problems must share one grid and one action set")
    cpu0 = time.process_time()
    t0 = time.perf_counter()
    if layout == "factored":
        table = [factored_table(first.grid, pr.next_points) for pr in problems]
        nnz = sum(t.nnz for t in table)
        threads = default_threads(sum(sweep_work(t) for t in table))
    else:
        table = robust_table(first.grid, [pr.next_points for pr in problems])
        nnz = table.nnz
        threads = 1
    table_seconds = time.perf_counter() - t0
    model_seconds = sum(pr.seconds for pr in problems)
    with progress_bar(desc=f"robust Q-iteration {first.name}", unit=" sweeps",
                      enabled=progress, leave=False, mininterval=0.25) as bar:
        def tick(ell, change):
            bar.update(1)
            bar.set_postfix(change=f"{change:.3g}")
        solver = factored_q_iteration_robust if layout == "factored" \
            else fuzzy_q_iteration_robust
        result = solver(table, [pr.rewards for pr in problems], mode=mode, gamma=gamma,
                        delta=delta, callback=tick if progress else None, threads=threads)
    if not result.converged:
        raise RuntimeError(f"robust Q-iteration for {first.name} did not converge")
    build = model_seconds + table_seconds
    info = {"iterations": result.iterations, "sweeps": "synchronous",
            "converged": result.converged, "final_change": float(result.history[-1]),
            "robust": mode, "draws": len(problems), "layout": layout, "threads": threads,
            "model_seconds": model_seconds, "table_seconds": table_seconds,
            "transition_seconds": build, "sweep_seconds": result.seconds,
            "seconds": build + result.seconds,
            "cpu_seconds": time.process_time() - cpu0 + model_seconds,
            "q_size": int(result.q.size),
            "transition_nnz": nnz}
    info.update(extra or {})
    return Agent(first.name, first.grid, first.actions, result.q, first.outputs, info)
