"""Decentralized agents for an arm of N links: one agent per joint.

Agent i (joint i) is the paper's agent of (18) carried inward, joint by joint. The agents are
synthesised and run outermost first, N, N-1, ..., 1, as the paper runs agent 2 before
agent 1. Agent i reads its own angle and speed and a bounded context from its outer
neighbour i + 1: that link's angle, optionally its speed, and the torque tau_{i+1} the
neighbour has just chosen (as agent 1 reads theta2 and tau2 in (18)); agent N reads
(theta_N, dtheta_N) only. Every agent outputs tau_i in {-tau_i max, 0, tau_i max}, is
rewarded by (17) on its own link, and is solved by Alg. 1 (gamma, delta of the paper) on
the full N-link model sampled over Ts.

How an agent reads its transitions (:class:`Construction`, recorded in the policy):

* ``context`` - ``frozen``: link i + 1 is held where it is and tau_{i+1} stays as it was;
  ``propagated``: link i + 1 moves under tau_{i+1}, and the next tau_{i+1} is agent
  i + 1's action at the state reached (fed by agent i + 2's action there, recursively);
* ``speed_context`` - the context includes dtheta_{i+1} (otherwise link i + 1 starts
  each transition at rest);
* ``extra_speed_bins`` - two more speed bins at +-6 deg/s on the agents' own speed axes
  (``own``), on the context speed axes (``context``), on both, on none, on every context
  speed axis and the own axis of agent N - 1, the outermost agent's neighbour
  (``neighbour``), or on every context speed axis and the own axes of agents 1 and 2,
  Table I's links, unless one is the outermost (``base``);
* ``lock_inner`` - which inner joints an agent holds fixed in its transition model:
  ``none`` (the two-link reading: inner links free and at rest), ``middle`` (every agent
  but the outermost holds all of its inner joints 1..i-1), ``near`` (every agent but the
  outermost holds its inner neighbour's joint i-1 only; the others stay free at rest) or
  ``all`` (every agent holds joints 1..i-1);
* ``beyond`` - the links i + 2..N start each transition at rest at angle 0 and either
  move freely without torque (``rest``) or are held rigid to link i + 1 (``locked``).

What every agent is made of (:class:`Design`, recorded in the policy when it is not the
paper's): ``levels`` torque levels per joint (the paper's three by default; the context's
torque axis carries the neighbour's levels) and the bin layout ``bins`` of the agents' own
angle and speed axes (:data:`twolink.fqi.fuzzy.BIN_LAYOUTS`).

For two links the default construction (frozen context, no speed context, no extra bins,
nothing locked) is the paper's pair (18) on the full model (6), bit for bit: its
transitions go through :func:`twolink.synthesis.problems.model_step` exactly as
:func:`twolink.synthesis.problems.agent2_problem` and :func:`~twolink.synthesis.problems.agent1_problem`
do. For N >= 3 they come from :func:`twolink.arm.dynamics.links_acceleration`. Reading an
agent's transitions as for two links gives a middle agent far too little inertia (its
outer links free to swing away, its inner links free to recoil) and the arm limit-cycles;
the N >= 3 default has every middle agent hold its inner neighbour's joint, propagates
the context (with the neighbour's speed for tapered links) and adds the +-6 deg/s bins to
the context speed axes and to agent N - 1's own (see ``docs/studies/links_study.py``).
"""
from __future__ import annotations

import dataclasses
import time
from typing import Optional, Sequence

import numpy as np

from twolink._imports import renamed
from twolink.arm import dynamics
from twolink.arm.integrate import SUBSTEPS, sample_step
from twolink.arm.parameters import (
    DELTA,
    GAMMA,
    LINK_RULES,
    TABLE_I,
    TS,
    ArmParameters,
    LinksParameters,
    as_links,
    check_links,
    state_names,
)
from twolink.arm.task import PAPER_LEVELS, action_levels, agent_reward, check_levels
from twolink.artifacts import VERSION as __version__
from twolink.synthesis.problems import CONTEXTS, Problem, check_sweeps, model_step, solve
from twolink.fqi import fuzzy
from twolink.policy.fuzzy_policy import Agent, Policy
from twolink.policy.readout import Readout
from twolink.sim.progress import progress_bar

#: Which speed axes get the two extra bins at +-:data:`EXTRA_SPEED_DEG`.
EXTRA_BINS = ("none", "own", "context", "both", "base", "neighbour")
#: Which agents hold their inner joints fixed in their transition model.
LOCKS = ("none", "middle", "near", "all")
#: What the links beyond the context link do during an agent's transition.
BEYOND = ("rest", "locked")
#: The extra speed bins (deg/s), one on each side of zero (one source: twolink.fqi.fuzzy).
EXTRA_SPEED_DEG = fuzzy.EXTRA_SPEED_DEG
#: The most memory the agents' transitions may take (estimated before any work).
MAX_BYTES = 2 * 2**30


@dataclasses.dataclass(frozen=True)
class Construction:
    """How every agent of an N-link arm reads its transitions (see the module docstring)."""

    context: str = "frozen"
    speed_context: bool = False
    extra_speed_bins: str = "none"
    lock_inner: str = "none"
    beyond: str = "rest"

    def __post_init__(self):
        for name, choices in (("context", CONTEXTS), ("extra_speed_bins", EXTRA_BINS),
                              ("lock_inner", LOCKS), ("beyond", BEYOND)):
            value = getattr(self, name)
            if value not in choices:
                raise ValueError(f"unknown {name} {value!r}; choose one of "
                                 f"{', '.join(choices)}")
        if not isinstance(self.speed_context, (bool, np.bool_)):
            raise ValueError(f"speed_context must be True or False, got "
                             f"{self.speed_context!r}")
        object.__setattr__(self, "speed_context", bool(self.speed_context))

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


@dataclasses.dataclass(frozen=True)
class Design:
    """What every agent is made of, beside how it reads its transitions: ``levels``
    torque levels per joint (:func:`twolink.arm.task.action_levels`; agent i's torque
    context axis carries link i + 1's levels) and the bin layout ``bins`` of the agents'
    own angle and speed axes (:data:`twolink.fqi.fuzzy.BIN_LAYOUTS`; the context axes keep
    the paper's bins). The default is the paper's: three levels and its bins."""

    levels: int = PAPER_LEVELS
    bins: str = "paper"

    def __post_init__(self):
        object.__setattr__(self, "levels", check_levels(self.levels))
        fuzzy.check_bins(self.bins)

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


#: The paper's design: three torque levels and its bins.
PAPER_DESIGN = Design()

#: The default construction for two links: the paper's pair (18) on the full model (6).
TWO_LINK_DEFAULT = Construction()
#: The default construction for three links and more (chosen on development seeds,
#: ``docs/studies/links_study.py``), for tapered links.
LINKS_DEFAULT = Construction(context="propagated", speed_context=True,
                             extra_speed_bins="neighbour", lock_inner="near", beyond="rest")
#: The defaults for three links and more by link rule: copied links (heavy outer links)
#: settle more surely without the neighbour's speed in the context (development seeds).
LINKS_DEFAULTS = {"tapered": LINKS_DEFAULT,
                  "copied": dataclasses.replace(LINKS_DEFAULT, speed_context=False)}


def construction(links: int, rule: str = "tapered", **options) -> Construction:
    """The default construction for an arm of ``links`` links made by ``rule``
    (:data:`TWO_LINK_DEFAULT` for two links, else :data:`LINKS_DEFAULTS`) with
    ``options`` (keywords of :class:`Construction`; None keeps the default) replaced."""
    if rule not in LINK_RULES:
        raise ValueError(f"unknown link rule {rule!r}; choose one of {', '.join(LINK_RULES)}")
    base = TWO_LINK_DEFAULT if check_links(links) == 2 else LINKS_DEFAULTS[rule]
    unknown = sorted(set(options) - {f.name for f in dataclasses.fields(Construction)})
    if unknown:
        raise ValueError(f"unknown construction option(s) {unknown}")
    return dataclasses.replace(base, **{k: v for k, v in options.items() if v is not None})


def _speed_axis(name: str, extra: bool, bins: str = "paper") -> fuzzy.Axis:
    """A speed axis of layout ``bins``, with two more bins at +-EXTRA_SPEED_DEG when
    ``extra`` (unless the layout has a bin within 2 deg/s of them already)."""
    axis = fuzzy.speed_axis(name, bins)
    if not extra or np.any(np.abs(np.abs(np.rad2deg(axis.centers)) - EXTRA_SPEED_DEG) < 2):
        return axis
    deg = sorted(fuzzy.BIN_LAYOUTS[bins][1] + (-EXTRA_SPEED_DEG, EXTRA_SPEED_DEG))
    return fuzzy.Axis(name, tuple(np.deg2rad(deg)))


def agent_grid(i: int, p: LinksParameters, c: Construction,
               design: Design = PAPER_DESIGN) -> fuzzy.Grid:
    """Agent i's fuzzy grid over (theta_i, dtheta_i[, theta_{i+1}, [dtheta_{i+1},]
    tau_{i+1}]); the own axes have the bins of ``design``, the torque axis is the
    ``design.levels`` torque values of link i + 1."""
    n = p.links
    extra = c.extra_speed_bins
    axes = [fuzzy.angle_axis(f"theta{i}", design.bins),
            _speed_axis(f"dtheta{i}", extra in ("own", "both")
                        or (extra == "base" and i <= 2 and i < n)
                        or (extra == "neighbour" and i == n - 1), design.bins)]
    if i < n:
        axes.append(fuzzy.angle_axis(f"theta{i + 1}"))
        if c.speed_context:
            axes.append(_speed_axis(f"dtheta{i + 1}",
                                    extra in ("context", "both", "base", "neighbour")))
        axes.append(fuzzy.torque_axis(f"tau{i + 1}", float(p.tau_max[i]),
                                      design.levels))
    return fuzzy.Grid(tuple(axes))


def locked_joints(i: int, links: int, c: Construction) -> tuple:
    """The joints agent i's transition model holds fixed, as a boolean per joint."""
    inner = c.lock_inner == "all" or (c.lock_inner in ("middle", "near") and i < links)
    first = i - 1 if c.lock_inner == "near" else 1
    return tuple((first <= j < i and inner) or (j > i + 1 and c.beyond == "locked")
                 for j in range(1, links + 1))


def _outer_torque(outer: Sequence[Agent], x: np.ndarray, links: int, i: int) -> np.ndarray:
    """tau_{i+1} of the agents N..i+1 (``outer``, in that order) at the states x."""
    signals = {name: x[..., k] for k, name in enumerate(state_names(links))}
    for agent in outer:
        out = agent.act(np.stack([signals[name] for name in agent.inputs], -1))
        for k, name in enumerate(agent.outputs):
            signals[name] = out[..., k]
    return signals[f"tau{i + 1}"]


def _transitions(p: LinksParameters, x: np.ndarray, tau: np.ndarray, locked: tuple,
                 moving: int) -> np.ndarray:
    """One sample period from the states x under the torques tau; joints beyond
    ``moving`` have their acceleration zeroed (the frozen context). Two links with nothing
    locked: the full model (6) through :func:`twolink.synthesis.problems.model_step`, as the paper's
    agents (bit for bit); otherwise :func:`twolink.arm.dynamics.links_acceleration`."""
    n = p.links
    if n == 2 and not any(locked):
        return model_step("full", p.as_arm(), x, tau, compiled=False, freeze_link2=moving < 2)
    mask = np.array([1.0 if j <= moving else 0.0 for j in range(1, n + 1)])
    locks = locked if any(locked) else None

    def accel(pp, s, t):
        a = dynamics.links_acceleration(pp, s, t, locked=locks)
        return a * mask if moving < n else a
    return sample_step(accel, p, x, tau)


def agent_problem(i: int, p: LinksParameters, c: Construction,
                  outer: Sequence[Agent] = (), design: Design = PAPER_DESIGN) -> Problem:
    """Agent i's MDP (see the module docstring) made as ``design`` says; ``outer`` are
    the agents N..i+1 already synthesised (the propagated context runs them on the state
    reached)."""
    n = p.links
    if not 1 <= i <= n:
        raise ValueError(f"agent {i}: an arm of {n} links has agents 1 to {n}")
    if c.context == "propagated" and i < n and len(outer) != n - i:
        raise ValueError(f"agent {i}: the propagated context needs the {n - i} outer agents")
    start = time.perf_counter()
    grid = agent_grid(i, p, c, design)
    actions = action_levels(float(p.tau_max[i - 1]), design.levels)[:, None]
    centers = grid.centers()
    x = np.zeros((len(centers), 2 * n))
    x[:, i - 1], x[:, n + i - 1] = centers[:, 0], centers[:, 1]
    if i == n:
        tau = np.zeros((len(actions), n))
        tau[:, i - 1] = actions[:, 0]
        tau = tau[None, :, :]
    else:
        x[:, i] = centers[:, 2]
        if c.speed_context:
            x[:, n + i] = centers[:, 3]
        tau = np.zeros((len(centers), len(actions), n))
        tau[:, :, i - 1] = actions[None, :, 0]
        tau[:, :, i] = centers[:, -1:]
    frozen = c.context == "frozen" and i < n
    nxt = _transitions(p, x[:, None, :], tau, locked_joints(i, n, c), i if frozen else n)
    columns = [nxt[..., i - 1], nxt[..., n + i - 1]]
    if i < n:
        columns.append(nxt[..., i])
        if c.speed_context:
            columns.append(nxt[..., n + i])
        if frozen:
            columns.append(np.broadcast_to(centers[:, None, -1], nxt.shape[:-1]))
        else:
            columns.append(_outer_torque(outer, nxt, n, i))
    return Problem(f"agent{i}", grid, actions, (f"tau{i}",), np.stack(columns, -1),
                   agent_reward(nxt, i), time.perf_counter() - start)


def transition_bytes(p: LinksParameters, c: Construction,
                     design: Design = PAPER_DESIGN) -> int:
    """Peak bytes of the largest agent's transitions, known before any work: per (bin,
    action) row its RK4 states and the model's temporaries (about 16 state vectors and
    four N x N matrices), its reached point and reward, and its row of T (at most 2**d
    memberships of int32 index + float64 weight)."""
    n = p.links
    need = 0
    for i in range(1, n + 1):
        grid = agent_grid(i, p, c, design)
        d = len(grid.axes)
        rows = grid.size * design.levels
        need = max(need, rows * (8 * (16 * 2 * n + 4 * n * n + d + 1) + 12 * 2 ** d))
    return need


def check_size(p: LinksParameters, c: Construction, max_bytes: int = MAX_BYTES,
               design: Design = PAPER_DESIGN) -> int:
    """:func:`transition_bytes`, or a ValueError with the estimate over ``max_bytes``."""
    need = transition_bytes(p, c, design)
    if need > max_bytes:
        raise ValueError(f"the {p.links}-link agents' transitions take about "
                         f"{need / 2**20:.0f} MiB, over the {max_bytes >> 20} MiB a "
                         f"decentralized synthesis may use")
    return need


def design(levels: int = PAPER_LEVELS, bins: str = "paper") -> Design:
    """The :class:`Design` of these options, checked: a ValueError naming a level count
    outside 2-9 or an unknown bin layout."""
    return Design(levels, bins)


def synthesize_links(p: "LinksParameters | ArmParameters" = TABLE_I, *,
                     context: Optional[str] = None, speed_context: Optional[bool] = None,
                     extra_speed_bins: Optional[str] = None, lock_inner: Optional[str] = None,
                     beyond: Optional[str] = None, levels: int = PAPER_LEVELS,
                     bins: str = "paper", gamma: float = GAMMA,
                     delta: float = DELTA, sweeps: str = "synchronous",
                     max_bytes: int = MAX_BYTES, readout=None,
                     progress: bool = False) -> Policy:
    """The decentralized policy of an N-link arm ``p``: agents N..1 (see the module
    docstring), each solved by Alg. 1 with ``sweeps``. Construction options left at None
    take the default for N links and the rule of ``p`` (:func:`construction`: the paper's
    pair for N = 2, :data:`LINKS_DEFAULTS` beyond); ``levels`` and ``bins`` make
    the :class:`Design` (the paper's by default). Every option and the memory the
    transitions take (refused over ``max_bytes``) are checked before any work. The
    policy's ``meta`` records the links, the rule, the parameters, the construction (and
    the design when it is not the paper's), gamma, delta, Ts, the RK4 substeps and every
    agent's sweeps and timings; ``readout`` (a :class:`twolink.policy.readout.Readout`,
    e.g. the argmax of Q far from the goal) is recorded there as the policy's read-out."""
    p = as_links(p)
    n = p.links
    c = construction(n, p.rule, context=context, speed_context=speed_context,
                     extra_speed_bins=extra_speed_bins, lock_inner=lock_inner, beyond=beyond)
    made = design(levels, bins)
    check_sweeps(sweeps)
    if not (isinstance(gamma, (int, float)) and 0.0 < gamma < 1.0):
        raise ValueError(f"gamma must lie in (0, 1), got {gamma!r}")
    if not (isinstance(delta, (int, float)) and delta > 0.0):
        raise ValueError(f"delta must be positive, got {delta!r}")
    if readout is not None and not isinstance(readout, Readout):
        raise TypeError(f"readout must be a twolink.policy.readout.Readout, got "
                        f"{type(readout).__name__}")
    need = check_size(p, c, max_bytes, made)
    start = time.perf_counter()
    agents = []
    with progress_bar(total=n, desc=f"{n}-link agents", unit=" agent", enabled=progress,
                      leave=False) as bar:
        for i in range(n, 0, -1):
            bar.set_postfix(agent=i)
            problem = agent_problem(i, p, c, agents, made)
            agents.append(solve(problem, gamma=gamma, delta=delta, sweeps=sweeps,
                                progress=progress,
                                extra={"locked": list(locked_joints(i, n, c))}))
            bar.update(1)
    meta = {"links": n, "rule": p.rule, "parameters": p.as_dict(), "model": "full",
            "construction": c.as_dict(), "context": c.context, "gamma": gamma,
            "delta": delta, "ts": TS, "substeps": SUBSTEPS, "sweeps": sweeps,
            "reward": "r_{k+1} on the state reached", "twolink_version": __version__,
            "estimated_bytes": need, "seconds": time.perf_counter() - start,
            "agents": {a.name: {k: a.info[k] for k in ("iterations", "transition_seconds",
                                                      "sweep_seconds", "seconds", "q_size",
                                                      "transition_nnz")}
                       for a in agents}}
    if made != PAPER_DESIGN:
        meta["design"] = made.as_dict()
    if readout is not None and readout.active:
        meta["readout"] = readout.as_dict()
    return Policy("decentralized", agents, meta)


#: The names of 0.1 that said *chain*, kept until the next release (with a
#: DeprecationWarning; twolink._imports.renamed).
__getattr__ = renamed(__name__, {
    "synthesize_chain": "synthesize_links", "CHAIN_DEFAULT": "LINKS_DEFAULT",
    "CHAIN_DEFAULTS": "LINKS_DEFAULTS"
})
