"""The paper's experiment (Section IV), measured: synthesis, rollouts from x0, the
evaluation set and the integration error, returned as data (the table that presents
it is :mod:`twolink.studies.reproduce.table`).

The policies are the paper's, from :data:`twolink.policy.registry.PAPER_POLICIES` (the
centralized policy (16) and the decentralized agents (18) with both readings of agent
1's context), synthesised afresh on the simplified model (11) and compared bit for bit
with the shipped files. Each is also synthesised with serial sweeps (ApproxRL's in-place
update, :data:`twolink.synthesis.problems.SWEEPS`), whose sweep counts are reported beside the
synchronous ones.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from twolink.arm import dynamics
from twolink.arm.integrate import SUBSTEPS, integration_error
from twolink.arm.parameters import HORIZON, PAPER_X0, TABLE_I
from twolink.artifacts import provenance
from twolink.synthesis.problems import centralized_problem
from twolink.synthesis.synthesize import synthesize
from twolink.policy.fuzzy_policy import Policy
from twolink.policy.registry import PAPER_POLICIES, SHIPPED, TWO_LINK
from twolink.sim.metrics import (
    evaluation_set,
    stalled_at_band_edge,
    success,
    summary,
    wilson_interval,
)
from twolink.sim.plants import make_plant
from twolink.sim.rollout import Trajectory, rollout
from twolink.studies.reproduce import paper

#: The plants every policy runs on: the synthesis model and the full dynamics.
PLANTS = ("simplified", "mujoco")
#: Longest horizon of the experiment (the paper's is 5 s): 60 s already takes about 30 s
#: of rollouts (the evaluation set on MuJoCo), and the time grows with the horizon.
MAX_DURATION = 60.0
#: RK4 substeps of the fine reference the chosen SUBSTEPS are compared against.
REFERENCE_SUBSTEPS = 100
_AGENT_INFO = ("q_size", "iterations", "seconds", "cpu_seconds", "transition_seconds",
               "sweep_seconds")
#: The times of a process's first synthesis, reported apart from the warm ones: the first
#: call also loads the compiled kernels.
_TIMES = ("seconds", "cpu_seconds")


@dataclasses.dataclass
class Reproduction:
    """What :func:`reproduce` measured. Dictionaries are keyed by policy name (the
    registry's), then plant; ``trajectories`` by (policy, plant), from the paper's x0.
    ``synthesis[name]["agents"]`` holds each agent's sweeps and times of a second, warm
    synthesis (the figure Table II compares), ``["first_call"]`` the times of the first
    one (which also loads the compiled kernels), ``["serial"]`` those with serial sweeps.
    ``rollouts[name][plant]`` is the run's :func:`summary` and whether it is an edge stall
    (:func:`twolink.sim.metrics.stalled_at_band_edge`)."""

    x0: list
    duration: float
    synthesis: dict
    rollouts: dict
    evaluation_set: dict
    integration_error: dict
    trajectories: dict = dataclasses.field(repr=False, default_factory=dict)

    def report(self) -> dict:
        """JSON-ready report: the measurements, the paper's figures and provenance."""
        return {"x0": self.x0, "duration": self.duration, "synthesis": self.synthesis,
                "rollouts": self.rollouts, "evaluation_set": self.evaluation_set,
                "integration_error": self.integration_error,
                "paper": {"iterations": paper.ITERATIONS, "q_sizes": paper.Q_SIZES,
                          "cpu_seconds": paper.CPU_SECONDS,
                          "settle_time": paper.SETTLE_TIME},
                "provenance": provenance()}


def integration_report() -> dict:
    """One-step error of SUBSTEPS RK4 substeps against REFERENCE_SUBSTEPS, for both numpy
    models, over every centralized bin centre and joint action (63504 transitions)."""
    prob = centralized_problem(TABLE_I)
    x = prob.grid.centers()[:, None, :]
    u = prob.actions[None, :, :]
    return {name: integration_error(dynamics.MODELS[name], TABLE_I, x, u, substeps=SUBSTEPS,
                                    reference_substeps=REFERENCE_SUBSTEPS)
            for name in ("simplified", "full")}


def matches_shipped(name: str, policy: Policy) -> bool | None:
    """Whether ``policy`` has the Q-tables of the shipped file ``name`` bit for bit
    (None if the file is missing)."""
    path = SHIPPED[name].file
    if not path.is_file():
        return None
    shipped = Policy.load(path)
    return len(shipped.agents) == len(policy.agents) and all(
        np.array_equal(a.q, b.q) for a, b in zip(shipped.agents, policy.agents))


def _evaluate(ev: Trajectory) -> dict:
    ok, stalled = success(ev), stalled_at_band_edge(ev)
    return {"states": int(len(ok)), "successes": int(ok.sum()),
            "success_rate": float(ok.mean()),
            "wilson_95": list(wilson_interval(int(ok.sum()), len(ok))),
            "failures": int((~ok).sum()), "failures_stalled_at_band_edge": int(stalled.sum())}


def check_duration(duration: float) -> float:
    """``duration`` if it is a horizon the experiment accepts, else a clear ValueError."""
    if not (np.isfinite(duration) and 0 < duration <= MAX_DURATION):
        raise ValueError(f"duration must be a positive number of seconds, at most "
                         f"{MAX_DURATION:g}, got {duration:g}")
    return duration


def reproduce(duration: float = HORIZON, *, policies=PAPER_POLICIES,
              progress: bool = False) -> Reproduction:
    """Synthesise ``policies`` (registry names) as the registry says, run each from the
    paper's x0 and over the evaluation set on every plant of :data:`PLANTS`: the paper's
    two-link arm, so only two-link policies (:data:`twolink.policy.registry.TWO_LINK`)."""
    check_duration(duration)
    other = [name for name in policies if name not in TWO_LINK]
    if other:
        raise ValueError(f"reproduce runs the paper's two-link arm; {other[0]!r} is not one "
                         f"of its shipped policies ({', '.join(TWO_LINK)})")
    x0 = np.asarray(PAPER_X0, dtype=float)
    res = Reproduction(list(PAPER_X0), duration, {}, {}, {}, integration_report())
    with make_plant("simplified") as simplified, make_plant("mujoco") as mj:
        plants = {"simplified": simplified, "mujoco": mj}
        for name in policies:
            entry = SHIPPED[name]
            first = synthesize(entry.kind, TABLE_I, progress=progress,
                               **entry.synthesis_options())
            policy = synthesize(entry.kind, TABLE_I, progress=progress,
                                **entry.synthesis_options())
            opts = {**entry.synthesis_options(), "sweeps": "serial"}
            serial = synthesize(entry.kind, TABLE_I, progress=progress, **opts)
            res.synthesis[name] = {
                "sweeps": policy.meta["sweeps"],
                "agents": {a.name: {k: a.info[k] for k in _AGENT_INFO} for a in policy.agents},
                "first_call": {a.name: {k: a.info[k] for k in _TIMES} for a in first.agents},
                "serial": {a.name: {k: a.info[k] for k in _AGENT_INFO} for a in serial.agents},
                "matches_shipped_policy": matches_shipped(name, policy)}
            res.rollouts[name], res.evaluation_set[name] = {}, {}
            for plant_name, plant in plants.items():
                tr = rollout(policy, plant, x0, duration=duration, label=name)
                res.trajectories[(name, plant_name)] = tr
                res.rollouts[name][plant_name] = {
                    **summary(tr), "stalled_at_band_edge": bool(stalled_at_band_edge(tr))}
                ev = rollout(policy, plant, evaluation_set(), duration=duration, label=name)
                res.evaluation_set[name][plant_name] = _evaluate(ev)
    return res
