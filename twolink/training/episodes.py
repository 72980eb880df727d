"""The mid-episode state of a challenge or history run, for checkpoints that resume exactly.

A checkpoint falls at an update boundary, mostly in the middle of the arms' episodes.
Beside what :mod:`twolink.training.checkpoint` keeps (states, clocks, generators), an
arm under a challenge level is in the middle of an episode on its own drawn plant, with
torques in flight (the actuation delay), readings in flight (the observation delay),
and readings repeated or stuck (the faults); an agent with an observation history has
its last K observations and K - 1 actions; an action-rate penalty, its last actions. :func:`capture` takes all of these as
numbers and tensors (read back with ``torch.load(weights_only=True)``, nothing
unpickled) and :func:`restore` puts them back into a freshly built environment.
"""
from __future__ import annotations

import dataclasses

import numpy as np


def _tensor(a):
    import torch

    return torch.from_numpy(np.ascontiguousarray(a, dtype=float).copy())


def _array(t) -> np.ndarray:
    return t.detach().cpu().numpy().copy()


def base(env):
    """The :class:`twolink.envs.sb3.TwoLinkSB3VecEnv` under any wrappers of ``env``."""
    while hasattr(env, "venv"):
        env = env.venv
    return env


def capture(env) -> dict:
    """The mid-episode state of the (wrapped) vector environment ``env``, after its
    first reset."""
    arms = base(env)._live()
    out = {}
    if arms._size:                               # a plant drawn per episode and arm
        names = [f.name for f in dataclasses.fields(arms.plant.params[0])]
        out["plants"] = {"names": names, "values": _tensor(
            [[getattr(p, n) for n in names] for p in arms.plant.params])}
    out["actuation"] = [_tensor(u) for u in arms._delay._history]
    faults, delay = arms.sensors.faults, arms.sensors.delay
    if faults._last is not None:
        out["faults"] = {"last": _tensor(faults._last), "left": _tensor(faults._left),
                         "fresh": _tensor(faults._fresh)}
    if delay._buffer is not None:
        out["observation_delay"] = {"buffer": _tensor(delay._buffer),
                                    "age": _tensor(delay._age)}
    history = getattr(env, "history", None)
    if history is not None:
        out["history"] = {k: _tensor(v) for k, v in history.state().items()}
    rate = _action_rate(env)
    if rate is not None:
        out["action_rate"] = {k: _tensor(v) for k, v in rate.action_rate_state().items()}
    return out


def _action_rate(env):
    """The :mod:`twolink.training.action_rate` wrapper among ``env``'s wrappers, or None."""
    while env is not None:
        if hasattr(type(env), "action_rate_state"):
            return env
        env = getattr(env, "venv", None)
    return None


def restore(env, state: dict) -> None:
    """Put the state of :func:`capture` back into ``env`` (built for the same run)."""
    arms = base(env)._live()
    if "plants" in state:
        cls = type(arms.params)
        names = state["plants"]["names"]
        for i, row in enumerate(_array(state["plants"]["values"])):
            arms.plant.set_row_params(i, cls(**dict(zip(names, map(float, row)))))
    arms._delay._history = [_array(t) for t in state["actuation"]]
    faults, delay = arms.sensors.faults, arms.sensors.delay
    if "faults" in state:
        faults._last = _array(state["faults"]["last"])
        faults._left = _array(state["faults"]["left"]).astype(int)
        faults._fresh = _array(state["faults"]["fresh"]).astype(bool)
    if "observation_delay" in state:
        buffer = _array(state["observation_delay"]["buffer"])
        delay._buffer = buffer
        delay._age = _array(state["observation_delay"]["age"]).astype(int)
        delay._samples = np.broadcast_to(delay.samples, (len(buffer),))
    if "history" in state:
        env.history.set_state({k: _array(v) for k, v in state["history"].items()})
    if "action_rate" in state:
        _action_rate(env).set_action_rate_state(
            {k: _array(v) for k, v in state["action_rate"].items()})
