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

from twolink.arm.integrate import SUBSTEPS, check_sampling
from twolink.arm.parameters import (
    DELTA,
    GAMMA,
    TABLE_I,
    TS,
    ArmParameters,
    chain,
    check_links,
)
from twolink.arm.task import PAPER_LEVELS, check_levels
from twolink.artifacts import VERSION as __version__
from twolink.synthesis.links_decentralized import synthesize_chain
from twolink.synthesis.problems import (
    CONTEXTS,
    IDENTIFIED_MODELS,
    KINDS,
    agent1_problem,
    agent2_problem,
    centralized_problem,
    check_link1,
    check_refine,
    check_robust,
    check_robust_size,
    check_size,
    check_sweeps,
    dynamics_of,
    parameter_draws,
    solve,
    solve_robust,
)
from twolink.fqi import fuzzy
from twolink.policy.fuzzy_policy import Policy
from twolink.policy.readout import Readout
from twolink.sim.perturbations import PHYSICAL


def _meta(p: ArmParameters, model: str, gamma: float, delta: float, **more) -> dict:
    return {"parameters": p.as_dict(), "model": model, "gamma": gamma, "delta": delta,
            "ts": TS, "substeps": SUBSTEPS, "reward": "r_{k+1} on the state reached",
            "twolink_version": __version__, **more}


def synthesize(kind: str, p: ArmParameters = TABLE_I, *, model: Optional[str] = None,
               context: Optional[str] = None, gamma: float = GAMMA, delta: float = DELTA,
               sweeps: str = "synchronous", refine: int = 1,
               robust: Optional[str] = None, draws: int = 1, spread: float = 0.0,
               seed: int = 0, source: Optional[dict] = None,
               progress: bool = False, links: int = 2, rule: str = "tapered",
               levels: int = PAPER_LEVELS, bins: str = "paper",
               readout: Optional[Readout] = None, agent2_link1: str = "free") -> Policy:
    """The centralized policy (16) or the decentralized pair (18), synthesised on ``model``
    with ``sweeps`` of Alg. 1 (:data:`SWEEPS`) over the paper's bins, each subdivided
    ``refine`` times (:meth:`fuzzy.Axis.refined`; 1: the paper's grid). Both are recorded
    in the policy's provenance (``meta``).

    ``robust`` ("worst" or "mean") solves every agent over the K = ``draws`` models of
    :func:`parameter_draws` (``p`` and K - 1 joint draws within +-``spread``, from
    ``seed``), recorded in ``meta["robust"]``; ``meta["parameters"]`` stays ``p``, the
    centre. ``model="identified"`` is the full model (6) with ``p`` read from a parameter
    file, whose provenance ``source`` is recorded as ``meta["parameters_source"]``.
    ``model`` defaults to ``"simplified"``, ``context`` to ``"frozen"``.

    ``levels`` torque levels per joint (:func:`twolink.arm.task.action_levels`; the
    paper's 3), the bin layout ``bins`` (:data:`twolink.fqi.fuzzy.BIN_LAYOUTS`; the
    paper's "paper") and the ``readout`` of the readings
    (:class:`twolink.policy.readout.Readout`; none) are recorded in ``meta`` when they are
    not the paper's, as is ``agent2_link1``, how agent 2's transitions read link 1
    (:data:`twolink.synthesis.problems.LINK1_READINGS`: ``free``, the paper's, or
    ``locked``, joint 1 held; decentralized on the full model only).

    ``links`` > 2: the decentralized agents of the arm ``parameters.chain(links, rule,
    base=p)`` on its full model (:func:`twolink.synthesis.links_decentralized.synthesize_chain`; ``context``
    None takes that construction's default).
    """
    levels, bins = check_levels(levels), fuzzy.check_bins(bins)
    if readout is not None and not isinstance(readout, Readout):
        raise TypeError(f"readout must be a twolink.policy.readout.Readout, got "
                        f"{type(readout).__name__}")
    design = {}
    if levels != PAPER_LEVELS:
        design["levels"] = levels
    if bins != "paper":
        design["bins"] = bins
    if readout is not None and readout.active:
        design["readout"] = readout.as_dict()
    if agent2_link1 != "free":
        if kind != "decentralized":
            raise ValueError(f"agent2_link1 is how the decentralized agent 2 reads link 1; "
                             f"the {kind} policy takes none")
        design["agent2_link1"] = check_link1(agent2_link1)
    if check_links(links) > 2:
        if design:
            raise ValueError(f"levels, bins, readout and agent2_link1 are two-link options; "
                             f"a {links}-link arm takes none of them")
        return _synthesize_links(kind, p, model, context, gamma, delta, sweeps, refine,
                                 (robust, draws, spread, seed), source, progress, links, rule)
    model = "simplified" if model is None else model
    context = "frozen" if context is None else context
    check_sweeps(sweeps)
    refine = check_refine(refine)
    dynamics_of(model)
    if kind not in KINDS:
        raise ValueError(f"unknown policy kind {kind!r}; choose one of {', '.join(KINDS)}")
    if kind == "decentralized" and context not in CONTEXTS:
        raise ValueError(f"unknown agent-1 context {context!r}; choose one of "
                         f"{', '.join(CONTEXTS)}")
    check_link1(agent2_link1, model)
    if dynamics_of(model) == "full":
        check_sampling(p)
    more = {"sweeps": sweeps, "refine": refine, **design}
    check_size(kind, refine, levels, bins)
    if model in IDENTIFIED_MODELS:
        more["dynamics"] = dynamics_of(model)
    if source is not None:
        more["parameters_source"] = dict(source)
    if robust is None:
        if (draws, spread, seed) != (1, 0.0, 0):
            raise ValueError("draws, spread and seed apply to a robust synthesis only: "
                             "give robust='worst' or 'mean'")
        return _synthesize_nominal(kind, p, model, context, gamma, delta, sweeps, refine,
                                   progress, more, levels, bins, agent2_link1)
    robust, draws, spread, seed = check_robust(robust, draws, spread, seed)
    if sweeps != "synchronous":
        raise ValueError("robust synthesis runs synchronous sweeps only")
    check_robust_size(kind, refine, draws, levels, bins)
    models = parameter_draws(p, draws, spread, seed)
    more["robust"] = {"mode": robust, "draws": draws, "spread": spread, "seed": seed,
                      "draw_0": "centre", "perturbed": list(PHYSICAL),
                      "models": [m.as_dict() for m in models]}
    opts = {"mode": robust, "gamma": gamma, "delta": delta, "progress": progress}
    build = {"model": model, "refine": refine, "compiled": True, "levels": levels,
             "bins": bins}
    if kind == "centralized":
        agent = solve_robust([centralized_problem(m, **build) for m in models], **opts,
                             layout="factored")
        return Policy(kind, [agent], _meta(p, model, gamma, delta, **more))
    a2 = solve_robust([agent2_problem(m, **build, link1=agent2_link1) for m in models],
                      **opts)
    a1 = solve_robust([agent1_problem(a2, m, context=context, **build) for m in models],
                      **opts, extra={"context": context})
    return Policy(kind, [a2, a1], _meta(p, model, gamma, delta, context=context, **more))


def _synthesize_nominal(kind, p, model, context, gamma, delta, sweeps, refine, progress,
                        more, levels, bins, link1) -> Policy:
    opts = {"gamma": gamma, "delta": delta, "sweeps": sweeps, "progress": progress}
    design = {"refine": refine, "levels": levels, "bins": bins}
    if kind == "centralized":
        agent = solve(centralized_problem(p, model, compiled=True, **design), **opts,
                      layout="factored")
        return Policy(kind, [agent], _meta(p, model, gamma, delta, **more))
    a2 = solve(agent2_problem(p, model, **design, link1=link1), **opts)
    a1 = solve(agent1_problem(a2, p, model, context, **design), **opts,
               extra={"context": context})
    return Policy(kind, [a2, a1], _meta(p, model, gamma, delta, context=context, **more))


def _synthesize_links(kind, p, model, context, gamma, delta, sweeps, refine, robust, source,
                      progress, links, rule) -> Policy:
    """The ``links``-link decentralized agents (twolink.synthesis.links_decentralized), refusing what only
    the two-link synthesis offers."""
    if kind not in KINDS:
        raise ValueError(f"unknown policy kind {kind!r}; choose one of {', '.join(KINDS)}")
    if kind != "decentralized":
        raise ValueError(f"the centralized synthesis of a {links}-link arm is "
                         f"twolink.synthesis.links_centralized; synthesize builds its decentralized "
                         f"agents")
    if model not in (None, "full"):
        raise ValueError(f"a {links}-link arm is synthesised on its full model, not "
                         f"{model!r} (model (11) is the paper's two-link simplification)")
    if robust != (None, 1, 0.0, 0) or refine != 1 or source is not None:
        raise ValueError(f"robust synthesis, refine and parameter files are two-link "
                         f"options; a {links}-link arm takes none of them")
    return synthesize_chain(chain(links, rule, base=p), context=context, gamma=gamma,
                            delta=delta, sweeps=sweeps, progress=progress)
