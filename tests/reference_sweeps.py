"""The slow, obviously correct sweep: one rollout per (plant, state), ``mj_step`` loops.

Written independently of :func:`twolink.sim.cells.run_cells`: it steps one row at a time,
builds row i's noise generator itself from the seed's i-th spawn key and draws that
row's noise for the whole rollout before the next row starts (the batched path draws
step by step across rows), and delays torques with its own queue.
"""
from __future__ import annotations

import math

import numpy as np
from reference_plants import MujocoStepLoop

from twolink.policy.fuzzy_policy import load_policy
from twolink.sim.cells import (
    NOISE_STREAM,
    SPEED_PER_DEG,
    Cell,
    cell_record,
    policy_digest,
)
from twolink.sim.metrics import discounted_return, settle_time, success
from twolink.sim.rollout import rollout


class _Delayed:
    """The torque of ``delay`` samples ago, zero before the first one arrives."""

    def __init__(self, policy, delay: int):
        self.policy, self.delay, self.sent = policy, delay, []
        self.kind = policy.kind

    def __call__(self, x):
        self.sent.append(np.asarray(self.policy(x)))
        k = len(self.sent) - 1
        return self.sent[k - self.delay] if k >= self.delay else np.zeros(2)


def _noise(c: Cell, row: int):
    """Row ``row``'s observation, or None: its own generator, its own normal draws."""
    if c.family != "noise" or c.size == 0:
        return None
    seq = np.random.SeedSequence([c.seed, NOISE_STREAM], spawn_key=(row,))
    rng = np.random.Generator(np.random.PCG64(seq))
    scale = np.array([math.radians(c.size)] * 2 + [c.size * SPEED_PER_DEG] * 2)
    return lambda k, x: rng.normal(x, scale)


def reference_cell(c: Cell) -> dict:
    """The record :func:`twolink.sim.cells.run_cells` must give for ``c``, bit for bit."""
    policy = load_policy(c.policy)
    plist, x0 = c.rows()
    st, ok, ret = [], [], []
    for row, (p, x) in enumerate(zip(plist, x0)):
        with MujocoStepLoop(p) as plant:
            actor = _Delayed(policy, int(c.size)) if c.family == "delay" else policy
            tr = rollout(actor, plant, x, duration=c.duration, observe=_noise(c, row))
        st.append(float(settle_time(tr)))
        ok.append(bool(success(tr)))
        ret.append(float(discounted_return(tr)))
    return cell_record(c, np.array(st), np.array(ok), np.array(ret), policy_digest(policy))
