"""The robust section of the mismatch report: every policy under every challenge level.

Each shipped policy runs on MuJoCo under each level of :data:`twolink.sim.challenges.LEVELS`
(random plants drawn per level from the plan's seed, actuation and observation delays,
noisy and faulty readings), as it is and, except the paper's policies (:func:`modes_for`),
behind the run-time compensator of :mod:`twolink.sim.estimation`. Every number comes from one call of the shared
:func:`twolink.sim.evaluation.evaluate` per (policy, level, compensation); nothing here rolls
out a second way. A level whose plants are all Table I and whose readings are exact is
deterministic, so it is run on one plant (repeating it would only inflate the count).

Returns data: a JSON-ready dict (success k/n with its 95 % Wilson interval, worst plant,
worst-case and mean return, settle-time quantiles) and the settle times for the figures.
What the numbers should reach is for the documentation to judge (docs/generate.py), not
this module.

For the commands ``rollout`` and ``render``: :func:`level` (the challenge a command line
asks for) and :func:`challenged_rollouts` (single trajectories through the same closed
loop as :func:`twolink.sim.evaluation.evaluate`).
"""
from __future__ import annotations

import math
import time
from typing import Iterable, Optional

import numpy as np

from twolink.policy.fuzzy_policy import load_policy
from twolink.policy.registry import SHIPPED
from twolink.sim.cells import states_of
from twolink.sim.challenges import LEVELS, Challenge, challenge
from twolink.sim.evaluation import evaluate
from twolink.sim.progress import progress_bar

#: The two ways a policy is run: as it is, and behind the run-time compensator.
MODES = ("plain", "compensated")


def modes_for(name: str) -> tuple[str, ...]:
    """The runs of policy ``name``: the paper's policies (synthesised on (11), which fail
    on the nominal MuJoCo arm already) only as they are; every other policy both ways."""
    entry = SHIPPED.get(name)
    return ("plain",) if entry is not None and entry.paper else MODES


def is_random(ch: Challenge) -> bool:
    """Whether a level draws anything: perturbed plants or noisy/faulty readings."""
    return any(v > 0 for v in (ch.spread, ch.angle_noise_deg, ch.speed_noise, ch.dropout,
                               ch.stuck))


def summarize(ev) -> dict:
    """The numbers of one (policy, level, mode): the evaluation's own summary
    (:meth:`twolink.sim.evaluation.Evaluation.as_dict`: successes, Wilson interval, worst
    plant, worst-case and mean return, median settle) plus the 90th percentile of the
    settle times and the fraction of runs that settled."""
    out = ev.as_dict(rows=False)
    st = np.asarray(ev.settle, dtype=float).ravel()
    p90 = float(np.quantile(st, 0.9, method="higher"))
    out["p90_settle"] = p90 if math.isfinite(p90) else None
    out["settled"] = float(np.isfinite(st).mean())
    return out


def study(policies: Iterable[str], *, plants: int, states: str, seed: int,
          levels: Optional[Iterable[str]] = None, progress: bool = False) -> tuple[dict, dict]:
    """Every policy x level x mode (:func:`modes_for`) through
    :func:`twolink.sim.evaluation.evaluate`.

    Returns the JSON-ready section and the settle times ``{(policy, level, mode): (P*n,)}``
    for the figures. ``levels`` default to every level of :data:`LEVELS` in its order.
    """
    policies = list(policies)
    levels = list(LEVELS) if levels is None else [challenge(n).name for n in levels]
    if plants < 1:
        raise ValueError(f"the robust section needs at least one plant per level, got {plants}")
    loaded = {name: load_policy(name) for name in policies}
    x0 = states_of(states)
    out: dict = {}
    settle: dict = {}
    t0, c0 = time.perf_counter(), time.process_time()
    bar = progress_bar(total=len(levels) * sum(len(modes_for(n)) for n in policies),
                       desc="robust section", unit=" runs", enabled=progress, leave=False)
    try:
        for name in policies:
            out[name] = {}
            for level in levels:
                ch = LEVELS[level]
                count = plants if is_random(ch) else 1
                out[name][level] = {}
                for mode in modes_for(name):
                    ev = evaluate(loaded[name], x0=x0, seed=seed, count=count,
                                  compensate=mode == "compensated", challenge=ch, label=name)
                    out[name][level][mode] = summarize(ev)
                    settle[(name, level, mode)] = np.asarray(ev.settle, dtype=float).ravel()
                    bar.update(1)
    finally:
        bar.close()
    section = {"seed": int(seed), "plants": int(plants), "states": int(len(x0)),
               "state_set": states, "modes": {n: list(modes_for(n)) for n in policies},
               "levels": {n: LEVELS[n].as_dict() for n in levels},
               "results": out, "seconds": time.perf_counter() - t0,
               "cpu_seconds": time.process_time() - c0}
    return section, settle
