"""The slow, obviously correct sweep: one rollout per (plant, state), ``mj_step`` loops.

Written independently of :func:`twolink.sim.cells.run_cells`: it steps one row at a time,
builds the generator of the run of plant p from state s itself from the seed's spawn key
(p, s) and draws that run's noise for the whole rollout before the next run starts (the
batched path draws step by step across rows), and delays torques with its own queue. It
covers the challenges' plant changes, actuation delay and noise (not faults or reading
delays: those the evaluation-call tests hold).
"""
from __future__ import annotations

import math

import numpy as np
from reference_plants import MujocoStepLoop

from twolink.policy.fuzzy_policy import load_policy
from twolink.sim.cells import Cell, cell_record, policy_digest
from twolink.sim.metrics import discounted_return, settle_time, success
from twolink.sim.perturbations import NOISE_STREAM
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


def _noise(c: Cell, plant: int, state: int):
    """The observation of run (plant, state), or None: its own generator, its own draws."""
    ch = c.challenge
    if not (ch.angle_noise_deg or ch.speed_noise):
        return None
    seq = np.random.SeedSequence([c.seed, NOISE_STREAM], spawn_key=(plant, state))
    rng = np.random.Generator(np.random.PCG64(seq))
    scale = np.array([math.radians(ch.angle_noise_deg)] * 2 + [ch.speed_noise] * 2)
    return lambda k, x: rng.normal(x, scale)


def reference_cell(c: Cell) -> dict:
    """The record :func:`twolink.sim.cells.run_cells` must give for ``c``, bit for bit."""
    ch = c.challenge
    assert not (ch.dropout or ch.stuck or ch.observation_delay), "not covered here"
    policy = load_policy(c.policy)
    plist, x0, keys = c.rows()
    st, ok, ret = [], [], []
    for p, x, (i, j) in zip(plist, x0, keys):
        with MujocoStepLoop(p) as plant:
            actor = _Delayed(policy, ch.action_delay) if ch.action_delay else policy
            tr = rollout(actor, plant, x, duration=c.duration, observe=_noise(c, i, j))
        st.append(float(settle_time(tr)))
        ok.append(bool(success(tr)))
        ret.append(float(discounted_return(tr)))
    return cell_record(c, np.array(st), np.array(ok), np.array(ret), policy_digest(policy))
