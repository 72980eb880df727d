"""An observation history: the last K observations and the last K-1 actions, per row.

A controller that sees only the present reading cannot tell a torque already on its way
(an actuation delay) or a noisy reading from the arm's motion; one that sees a short
history can. :class:`ObservationHistory` is the one buffer that the training wrappers
(:mod:`twolink.envs.history`, Gymnasium and Stable-Baselines3) and the saved agent as a
controller (:class:`twolink.control.sb3_agent.SB3Agent`) keep, so an agent sees in
evaluation exactly what it saw in training.

Layout of one history observation (:func:`history_layout`), for observations of ``d``
numbers, actions of ``m`` and history length K::

    [o_{t-K+1}, ..., o_{t-1}, o_t,  a_{t-K+1}, ..., a_{t-1}]     (K d + (K - 1) m numbers)

oldest first: the K last observations, then the K - 1 last actions (the action a_j is
the one given on observation o_j, clipped to the action space). Slots before an
episode's first observation hold zeros (zero-padded), and a new episode starts from
zeros again. K = 1 is the observation alone.
"""
from __future__ import annotations

import numpy as np

from twolink.validate import whole

#: The longest history (``--history``): 16 samples are 0.8 s at Ts = 0.05 s.
MAX_HISTORY = 16
#: The message of a bad history length (a :func:`twolink.validate.whole` template).
BAD_HISTORY = ("{what} must be a whole number of samples from {low} to {high}, got "
               "{value!r}")


def check_history(k, what: str = "history") -> int:
    """``k`` if it is a whole number from 1 to :data:`MAX_HISTORY`, else one ValueError line."""
    return whole(k, what, 1, MAX_HISTORY, message=BAD_HISTORY)


def history_size(k: int, obs_size: int, act_size: int) -> int:
    """Numbers in one history observation: K d + (K - 1) m."""
    return k * obs_size + (k - 1) * act_size


def history_layout(k: int, obs_size: int, act_size: int) -> dict:
    """The layout of one history observation, JSON-ready (what the agent file records)."""
    return {"history": int(k), "observation_size": int(obs_size),
            "action_size": int(act_size), "size": history_size(k, obs_size, act_size),
            "order": "K observations oldest first, then K-1 actions oldest first; "
                     "zeros before an episode's start"}


class ObservationHistory:
    """The histories of ``rows`` rows (see the module docstring): :meth:`observe` adds
    each row's newest observation and returns the history observations, :meth:`act`
    adds the actions given on them, :meth:`reset` starts rows afresh (zeros)."""

    def __init__(self, rows: int, obs_size: int, act_size: int, k: int):
        self.k = check_history(k)
        self.rows, self.obs_size, self.act_size = int(rows), int(obs_size), int(act_size)
        self.observations = np.zeros((self.rows, self.k, self.obs_size))
        self.actions = np.zeros((self.rows, self.k - 1, self.act_size))

    @property
    def size(self) -> int:
        return history_size(self.k, self.obs_size, self.act_size)

    def _rows(self, rows):
        return np.arange(self.rows) if rows is None else np.asarray(rows, dtype=int)

    def reset(self, rows=None) -> None:
        """Rows ``rows`` (default all) start a new episode: every slot zero."""
        idx = self._rows(rows)
        self.observations[idx] = 0.0
        self.actions[idx] = 0.0

    def observe(self, obs, rows=None) -> np.ndarray:
        """Add observations (len(rows), d) as the newest of ``rows``; their history
        observations (len(rows), size)."""
        idx = self._rows(rows)
        obs = np.asarray(obs, dtype=float).reshape(len(idx), self.obs_size)
        self.observations[idx] = np.roll(self.observations[idx], -1, axis=1)
        self.observations[idx, -1] = obs
        return self.stacked(idx)

    def act(self, actions, rows=None) -> None:
        """Add the actions (len(rows), m) given on the rows' newest observations."""
        if self.k == 1:
            return
        idx = self._rows(rows)
        actions = np.asarray(actions, dtype=float).reshape(len(idx), self.act_size)
        self.actions[idx] = np.roll(self.actions[idx], -1, axis=1)
        self.actions[idx, -1] = actions

    def stacked(self, rows=None) -> np.ndarray:
        """The history observations (len(rows), size) of ``rows`` as they stand."""
        idx = self._rows(rows)
        return np.concatenate([self.observations[idx].reshape(len(idx), -1),
                               self.actions[idx].reshape(len(idx), -1)], axis=1)

    def state(self) -> dict:
        """The buffers (copies), for a checkpoint."""
        return {"obs": self.observations.copy(), "act": self.actions.copy()}

    def set_state(self, state: dict) -> None:
        """Put the buffers of :meth:`state` back (shapes checked)."""
        obs, act = np.asarray(state["obs"], float), np.asarray(state["act"], float)
        if obs.shape != self.observations.shape or act.shape != self.actions.shape:
            raise ValueError(f"a history of shapes {obs.shape} and {act.shape}, not "
                             f"{self.observations.shape} and {self.actions.shape}")
        self.observations[:], self.actions[:] = obs, act
