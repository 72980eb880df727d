"""Synthesis of the paper's policies with fuzzy Q-iteration (Alg. 1).

* centralized (16): Q(theta1, theta2, dtheta1, dtheta2, tau1, tau2), 7056 x 9 = 63504 values;
* agent 2 (18): Q2(theta2, dtheta2, tau2), 84 x 3 = 252 values, synthesised first;
* agent 1 (18): Q1(theta1, dtheta1, theta2, tau2, tau1), 3024 x 3 = 9072 values, using
  agent 2's policy. Two readings of agent 1's transitions (docs/conventions.md):
  ``frozen`` - theta2 and tau2 stay as they are over the transition (link 2 held at rest);
  ``propagated`` - link 2 moves from dtheta2 = 0 under tau2 and the next tau2 is agent 2's
  action at the new link-2 state.

Transitions f(c_m, u) come from the chosen model sampled over Ts (``twolink.arm.integrate``);
rewards are evaluated on the state reached, r_{k+1}.

Robust synthesis (``robust="worst"`` or ``"mean"``) solves every agent over K parameter
draws at once (:func:`twolink.fqi.iteration.fuzzy_q_iteration_robust`):
Q(m, u) = min_k [rho_k(c_m, u) + gamma sum_m~ T_k[(m, u), m~] max_u~ Q(m~, u~)] (or the
mean over k). Draw 0 is the centre model itself (so the nominal plant is always among the
K, and K = 1 is the ordinary synthesis, bit for bit); draws 1..K-1 change every parameter of
:data:`twolink.sim.perturbations.PHYSICAL` jointly, each uniform in +-spread
(:func:`parameter_draws`). The K models' transitions use the compiled RK4
(:func:`twolink.arm.integrate.sample_step_compiled`) over one theta1 slice of the grid, shifted
to the others (the horizontal arm's dynamics do not depend on theta1): equal to the numpy
path, which the agents' non-robust synthesis keeps, up to round-off (tests hold it to 1e-12).

The centralized problem, robust or not, takes its transitions from that compiled slice and
stores T factored along theta1 (``layout="factored"``, :mod:`twolink.fqi.factored`): the
memberships on the other three axes once per slice bin and action, shared by the twelve
theta1 blocks, swept on one thread (two for K >= 4 models or refined grids:
:func:`twolink.fqi.factored.default_threads`). Its sums run in another order than the fixed table's,
so Q differs from the fixed table's by ~1e-14 (the same sweeps and greedy actions). Serial sweeps and the agents read the fixed-width table.
"""
from __future__ import annotations

from typing import Optional

from twolink.arm.integrate import SUBSTEPS
from twolink.arm.parameters import DELTA, GAMMA, TABLE_I, TS, ArmParameters, links_parameters
from twolink.arm.task import PAPER_LEVELS
from twolink.artifacts import VERSION as __version__
from twolink.policy.fuzzy_policy import Policy
from twolink.policy.readout import Readout
from twolink.synthesis.links_decentralized import synthesize_links
from twolink.synthesis.problems import (
    agent1_problem,
    agent2_problem,
    centralized_problem,
    solve,
    solve_robust,
)
from twolink.synthesis.settings import SynthesisSettings

#: The fields of a two-link policy's header that no setting changes: the sample period,
#: RK4 substeps, the reward's reading and the version that wrote it.
_FIXED = {"ts": TS, "substeps": SUBSTEPS, "reward": "r_{k+1} on the state reached"}


def _meta(s: SynthesisSettings, **more) -> dict:
    """The header of a two-link policy synthesised with ``s``: its
    :meth:`~SynthesisSettings.header` fields (parameters, model, gamma and delta first,
    then the fixed fields, as the header has always been ordered) and ``more``."""
    fields = s.header()
    first = {k: fields.pop(k) for k in ("parameters", "model", "gamma", "delta")}
    return {**first, **_FIXED, "twolink_version": __version__, **fields, **more}


def synthesize(kind: "str | SynthesisSettings", p: ArmParameters = TABLE_I, *,
               model: Optional[str] = None, context: Optional[str] = None,
               gamma: float = GAMMA, delta: float = DELTA, sweeps: str = "synchronous",
               refine: int = 1, robust: Optional[str] = None, draws: int = 1,
               spread: float = 0.0, seed: int = 0, source: Optional[dict] = None,
               progress: bool = False, links: int = 2, rule: str = "tapered",
               levels: int = PAPER_LEVELS, bins: str = "paper",
               readout: Optional[Readout] = None, agent2_link1: str = "free") -> Policy:
    """The policy of ``settings`` (:class:`twolink.synthesis.settings.SynthesisSettings`):
    ``synthesize(settings, progress=False)``. The keyword form
    ``synthesize(kind, p, model=..., ...)`` makes the settings of those keywords
    (``p`` is ``parameters``) and synthesises them; ``progress`` shows progress bars.

    Two links: the centralized policy (16) or the decentralized pair (18), synthesised on
    the settings' model with their sweeps of Alg. 1 over the paper's bins, each
    subdivided ``refine`` times (:meth:`fuzzy.Axis.refined`), with their torque levels,
    bin layout, read-out and agent 2's reading of link 1. A robust synthesis solves every
    agent over the K models of :meth:`~SynthesisSettings.draw_models` (the worst case or
    the mean). The policy's header (``meta``) holds the settings'
    :meth:`~SynthesisSettings.header` (``meta["parameters"]`` is the centre of the draws;
    ``meta["parameters_source"]`` the provenance of an identified model's file).

    More links: the decentralized agents of the arm ``links_parameters(links, rule, base=p)`` on its
    full model (:func:`twolink.synthesis.links_decentralized.synthesize_links`).
    """
    if isinstance(kind, SynthesisSettings):
        settings = kind
        given = {"p": p is not TABLE_I, "model": model, "context": context,
                 "gamma": gamma != GAMMA, "delta": delta != DELTA,
                 "sweeps": sweeps != "synchronous", "refine": refine != 1, "robust": robust,
                 "draws": draws != 1, "spread": spread != 0.0, "seed": seed != 0,
                 "source": source, "links": links != 2, "rule": rule != "tapered",
                 "levels": levels != PAPER_LEVELS, "bins": bins != "paper",
                 "readout": readout, "agent2_link1": agent2_link1 != "free"}
        extra = [k for k, v in given.items() if v not in (None, False)]
        if extra:
            raise ValueError(f"synthesize(settings) takes its settings from them; "
                             f"{', '.join(extra)} given as well")
    else:
        settings = SynthesisSettings(
            kind, model=model, context=context, gamma=gamma, delta=delta, sweeps=sweeps,
            refine=refine, robust=robust, draws=draws, spread=spread, seed=seed,
            links=links, rule=rule, levels=levels, bins=bins, readout=readout,
            agent2_link1=agent2_link1, parameters=p, source=source)
    return synthesize_settings(settings, progress=progress)


def synthesize_settings(s: SynthesisSettings, *, progress: bool = False) -> Policy:
    """The policy of the checked settings ``s`` (:func:`synthesize`)."""
    if not isinstance(s, SynthesisSettings):
        raise TypeError(f"settings must be a twolink.synthesis.settings.SynthesisSettings, "
                        f"got {type(s).__name__}")
    if s.links > 2:
        policy = synthesize_links(links_parameters(s.links, s.rule, base=s.parameters),
                                  context=s.context, gamma=s.gamma, delta=s.delta,
                                  sweeps=s.sweeps, progress=progress)
        policy.meta.update(s.header())        # the same values: the settings' spelling
        return policy
    build = {"refine": s.refine, "levels": s.levels, "bins": s.bins}
    if s.robust is None:
        opts = {"gamma": s.gamma, "delta": s.delta, "sweeps": s.sweeps, "progress": progress}
        if s.kind == "centralized":
            agent = solve(centralized_problem(s.parameters, s.model, compiled=True, **build),
                          **opts, layout="factored")
            return Policy(s.kind, [agent], _meta(s))
        a2 = solve(agent2_problem(s.parameters, s.model, **build, link1=s.agent2_link1),
                   **opts)
        a1 = solve(agent1_problem(a2, s.parameters, s.model, s.context, **build), **opts,
                   extra={"context": s.context})
        return Policy(s.kind, [a2, a1], _meta(s))
    models = s.draw_models()
    opts = {"mode": s.robust, "gamma": s.gamma, "delta": s.delta, "progress": progress}
    build.update(model=s.model, compiled=True)
    if s.kind == "centralized":
        agent = solve_robust([centralized_problem(m, **build) for m in models], **opts,
                             layout="factored")
        return Policy(s.kind, [agent], _meta(s))
    a2 = solve_robust([agent2_problem(m, **build, link1=s.agent2_link1) for m in models],
                      **opts)
    a1 = solve_robust([agent1_problem(a2, m, context=s.context, **build) for m in models],
                      **opts, extra={"context": s.context})
    return Policy(s.kind, [a2, a1], _meta(s))
