"""The variants of the tuning table: label -> a function building the controller. Every
shipped design marked ``tuned`` in the registry was chosen from the table these make;
the label names the registry entry a row became, in parentheses.
"""
from __future__ import annotations

from twolink.policy.readout import Readout
from twolink.policy.registry import ROBUST_SEED
from twolink.synthesis.synthesize import synthesize

from .designs import agent2_worst_over_link1, delay_aware, noise_expectation, per_agent, \
    readout_of
from .wrappers import Hold, Hysteresis, LookAhead


def design(kind, levels=3, bins="paper", context=None, dead_zone=0.0, argmax=None,
           robust=False, refine=1, link1="free", near=None):
    """A function synthesising the ``kind`` design on the full model (6) with these
    levers (:func:`twolink.synthesis.synthesize.synthesize`): ``levels`` torque levels,
    ``bins``, agent 1's ``context``, a read-out (:func:`.designs.readout_of`), the worst
    case over 8 models within +-20 % (``robust``, the shipped seed), ``refine`` and agent
    2's view of joint 1 (``link1``)."""
    worst = {"robust": "worst", "draws": 8, "spread": 0.2, "seed": ROBUST_SEED} if robust \
        else {}
    return lambda: synthesize(kind, model="full", levels=levels, bins=bins, context=context,
                              refine=refine, readout=readout_of(dead_zone, argmax, near),
                              agent2_link1=link1, **worst)


#: label -> a function building the controller.
VARIANTS = {
    "centralized_full (paper design on (6))": design("centralized"),
    "centralized 5 levels": design("centralized", levels=5),
    "centralized goal bins": design("centralized", bins="goal"),
    "centralized 5 levels, goal bins": design("centralized", levels=5, bins="goal"),
    "centralized 5 levels, goal bins, dead zone 0.05": design("centralized", 5, "goal",
                                                              dead_zone=0.05),
    "centralized 5 levels, goal bins, dead zone 0.08":
        design("centralized", 5, "goal", dead_zone=0.08),
    "centralized 5 levels, goal bins, dead zone 0.08, argmax beyond 30 deg (centralized_tuned)":
        design("centralized", 5, "goal", dead_zone=0.08, argmax=30.0),
    "centralized 7 levels, goal bins, dead zone 0.08": design("centralized", 7, "goal",
                                                              dead_zone=0.08),
    "centralized 7 levels, goal bins, dead zone 0.08, argmax beyond 30 deg":
        design("centralized", 7, "goal", dead_zone=0.08, argmax=30.0),
    "centralized 7 levels, goal bins, dead zone 0.04, argmax beyond 30 deg":
        design("centralized", 7, "goal", dead_zone=0.04, argmax=30.0),
    "centralized 9 levels, goal bins, dead zone 0.04, argmax beyond 30 deg":
        design("centralized", 9, "goal", dead_zone=0.04, argmax=30.0),
    "centralized 9 levels, goal bins, dead zone 0.04, argmax beyond 45 deg "
    "(centralized_9levels)":
        design("centralized", 9, "goal", dead_zone=0.04, argmax=45.0),
    "centralized 5 levels, goal bins, noise expectation": noise_expectation,
    "centralized_robust (worst of 8 models within +-20 %)": design("centralized", robust=True),
    "centralized_robust, argmax beyond 30 deg": design("centralized", argmax=30.0, robust=True),
    "centralized_robust, dead zone 0.04, argmax beyond 30 deg (centralized_robust_tuned)":
        design("centralized", dead_zone=0.04, argmax=30.0, robust=True),
    "centralized_robust, 5 levels, dead zone 0.05, argmax beyond 30 deg":
        design("centralized", 5, dead_zone=0.05, argmax=30.0, robust=True),
    "centralized_robust, edge bins, dead zone 0.04, argmax beyond 30 deg "
    "(centralized_robust_edge)":
        design("centralized", bins="edge", dead_zone=0.04, argmax=30.0, robust=True),
    "centralized_robust, 5 levels, edge bins, dead zone 0.04, argmax beyond 30 deg":
        design("centralized", 5, "edge", dead_zone=0.04, argmax=30.0, robust=True),
    "centralized 5 levels, edge bins, dead zone 0.08, argmax beyond 30 deg":
        design("centralized", 5, "edge", dead_zone=0.08, argmax=30.0),
    "decentralized_full (paper design on (6))": design("decentralized"),
    "decentralized 5 levels": design("decentralized", levels=5),
    "decentralized 5 levels, goal bins": design("decentralized", levels=5, bins="goal"),
    "decentralized 5 levels, propagated": design("decentralized", 5, context="propagated"),
    "decentralized 7 levels, propagated": design("decentralized", 7, context="propagated"),
    "decentralized 7 levels, propagated, dead zone 0.04":
        design("decentralized", 7, context="propagated", dead_zone=0.04),
    "decentralized 7 levels, propagated, dead zone 0.04, argmax beyond 30 deg":
        design("decentralized", 7, context="propagated", dead_zone=0.04, argmax=30.0),
    "decentralized 7 levels, propagated, dead zone 0.06, argmax beyond 30 deg "
    "(decentralized_tuned)":
        design("decentralized", 7, context="propagated", dead_zone=0.06, argmax=30.0),
    "decentralized 7 levels, propagated, dead zone 0.08, argmax beyond 30 deg":
        design("decentralized", 7, context="propagated", dead_zone=0.08, argmax=30.0),
    "decentralized 7 levels, propagated, dead zone 0.1, argmax beyond 30 deg":
        design("decentralized", 7, context="propagated", dead_zone=0.1, argmax=30.0),
    "decentralized 9 levels, propagated, dead zone 0.02":
        design("decentralized", 9, context="propagated", dead_zone=0.02),
    "decentralized 7 levels, propagated, worst of 8 models, dead zone 0.04, argmax 30 deg":
        design("decentralized", 7, context="propagated", dead_zone=0.04, argmax=30.0,
               robust=True),
    "decentralized 7 levels, propagated, refine 2, no read-out":
        design("decentralized", 7, context="propagated", refine=2),
    "decentralized 7 levels, propagated, refine 2, dead zone 0.06, argmax beyond 30 deg":
        design("decentralized", 7, context="propagated", dead_zone=0.06, argmax=30.0,
               refine=2),
    "decentralized 7 levels, propagated, refine 2, dead zone 0.1, argmax beyond 30 deg":
        design("decentralized", 7, context="propagated", dead_zone=0.1, argmax=30.0,
               refine=2),
    "decentralized 3 levels, propagated, refine 2, dead zone 0.06, argmax beyond 30 deg":
        design("decentralized", 3, context="propagated", dead_zone=0.06, argmax=30.0,
               refine=2),
    "decentralized_tuned, agent 1 refine 2": lambda: per_agent(refine1=2),
    "decentralized_tuned, agent 2's speed bins refined": lambda: per_agent(speed2=2),
    "decentralized_tuned, agent 2's angle bins refined": lambda: per_agent(angle2=2),
    "decentralized_tuned, agent 2's angle bins refined, agent 1 refine 2":
        lambda: per_agent(angle2=2, refine1=2),
    "decentralized 7 levels, propagated, edge bins, dead zone 0.06, argmax beyond 30 deg "
    "(decentralized_edge)":
        design("decentralized", 7, "edge", context="propagated", dead_zone=0.06, argmax=30.0),
    "decentralized 7 levels, propagated, edge bins, worst of 8 models, dead zone 0.06, "
    "argmax 30 deg":
        design("decentralized", 7, "edge", context="propagated", dead_zone=0.06, argmax=30.0,
               robust=True),
    "decentralized 7 levels, propagated, edge bins, agent 2 holds joint 1, dead zone 0.02, "
    "argmax 30 deg (decentralized_edge_locked)":
        design("decentralized", 7, "edge", context="propagated", dead_zone=0.02, argmax=30.0,
               link1="locked"),
    "decentralized 7 levels, propagated, edge bins, agent 2 holds joint 1, dead zone 0.06, "
    "argmax 30 deg":
        design("decentralized", 7, "edge", context="propagated", dead_zone=0.06, argmax=30.0,
               link1="locked"),
    "decentralized 7 levels, propagated, agent 2 holds joint 1, dead zone 0.1, argmax 30 deg "
    "(decentralized_locked)":
        design("decentralized", 7, context="propagated", dead_zone=0.1, argmax=30.0,
               link1="locked"),
    "decentralized 7 levels, propagated, paper bins, agent 2 holds joint 1, dead zone 0.02, "
    "argmax 30 deg":
        design("decentralized", 7, context="propagated", dead_zone=0.02, argmax=30.0,
               link1="locked"),
    "decentralized_edge, agent 2 the worst case over tau1 in +-10 % of its limit":
        lambda: agent2_worst_over_link1(tau1_fraction=0.1),
    "decentralized_edge, agent 2 the worst case over dtheta1 in +-0.05 rad/s":
        lambda: agent2_worst_over_link1(dtheta1=0.05),
    "decentralized_robust, argmax beyond 30 deg": design("decentralized", argmax=30.0,
                                                         robust=True),
    "decentralized delay-aware, 3 levels": delay_aware,
    "decentralized delay-aware, 5 levels": lambda: delay_aware(5),
    "decentralized 7 levels, propagated, dead zone 0.06, angle dead zone 1 deg, argmax 30 deg":
        lambda: synthesize("decentralized", model="full", levels=7, context="propagated",
                           readout=Readout(speed_dead_zone=0.06, angle_dead_zone_deg=1.0,
                                           argmax_beyond_deg=30.0)),
    "decentralized_tuned with a hold region (3 deg, 0.06 rad/s)":
        lambda: Hold(design("decentralized", 7, context="propagated", dead_zone=0.06,
                            argmax=30.0)(), 3.0, 0.06),
    "decentralized_edge with a hysteresis hold (in 4 deg, 0.05 rad/s; out 7 deg, 0.15 rad/s)":
        lambda: Hysteresis(design("decentralized", 7, "edge", context="propagated",
                                  dead_zone=0.06, argmax=30.0)(), 4.0, 0.05, 7.0, 0.15),
    "decentralized_edge, near-goal gain 0.2 from 90 deg (decentralized_edge_gain)":
        design("decentralized", 7, "edge", context="propagated", dead_zone=0.06,
               argmax=30.0, near=(0.2, 90.0)),
    "decentralized_edge, near-goal gain 0.5 from 180 deg (decentralized_edge_gain_hard)":
        design("decentralized", 7, "edge", context="propagated", dead_zone=0.06,
               argmax=30.0, near=(0.5, 180.0)),
    "decentralized_locked, near-goal gain 0.3 from 60 deg (decentralized_locked_gain)":
        design("decentralized", 7, context="propagated", dead_zone=0.1, argmax=30.0,
               link1="locked", near=(0.3, 60.0)),
    "decentralized_locked, near-goal gain 0.5 from 60 deg (decentralized_locked_gain_medium)":
        design("decentralized", 7, context="propagated", dead_zone=0.1, argmax=30.0,
               link1="locked", near=(0.5, 60.0)),
    "centralized_robust_edge, near-goal gain 0.1 from 90 deg (centralized_robust_edge_gain)":
        design("centralized", bins="edge", dead_zone=0.04, argmax=30.0, robust=True,
               near=(0.1, 90.0)),
    "centralized_robust_edge, near-goal gain 0.2 from 60 deg "
    "(centralized_robust_edge_gain_medium)":
        design("centralized", bins="edge", dead_zone=0.04, argmax=30.0, robust=True,
               near=(0.2, 60.0)),
    "centralized_tuned with a one-step look-ahead on (6) beyond 15 deg":
        lambda: LookAhead(design("centralized", 5, "goal", dead_zone=0.08, argmax=30.0)(), 15.0),
}
