"""Model mismatch and imperfect observation: perturbed parameters, state noise, delay.

One implementation of each perturbation, per batch row, shared by the dm_env tasks
(:mod:`twolink.env`), rollouts and the robustness sweeps (:mod:`twolink.sweeps`), so the
same perturbation means the same thing everywhere. Randomness only through injected
generators, one per batch row: a row's noise never depends on which rows share its batch.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from twolink.parameters import TABLE_I, ArmParameters

#: Table I parameters a sweep may perturb (the plant's physical constants).
PERTURBABLE = ("l1", "m1", "m2", "I1", "I2", "c1", "c2", "b1", "b2", "tau1_max", "tau2_max")
#: The ten physical parameters of the arm (not its torque or speed limits): what a
#: challenge's joint plant perturbation and a robust synthesis's model draws change.
#: l2 has no dynamic effect on the horizontal arm (only the drawn arm's length).
PHYSICAL = ("l1", "l2", "m1", "m2", "I1", "I2", "c1", "c2", "b1", "b2")


def perturbed(base: ArmParameters = TABLE_I, **relative: float) -> ArmParameters:
    """Parameters with relative changes, e.g. ``perturbed(m2=+0.2)`` is m2 * 1.2."""
    return base.scaled(**{k: 1.0 + float(v) for k, v in relative.items()})


def random_perturbation(rng: np.random.Generator, size: float,
                        base: ArmParameters = TABLE_I,
                        names: tuple = PERTURBABLE) -> ArmParameters:
    """All ``names`` perturbed jointly, each by a relative change uniform in [-size, size]."""
    if not 0.0 <= size < 1.0:
        raise ValueError(f"perturbation size must lie in [0, 1), got {size}")
    return perturbed(base, **{n: rng.uniform(-size, size) for n in names})


def torque_limited(base: ArmParameters = TABLE_I, relative: float = 0.0) -> ArmParameters:
    """The plant's torque limits tau1_max and tau2_max both changed by ``relative``.

    The policy keeps commanding its own action levels; the plant clips them.
    """
    return perturbed(base, tau1_max=relative, tau2_max=relative)


def row_generators(entropy, rows: int) -> list[np.random.Generator]:
    """``rows`` independent generators, row i's from ``SeedSequence(entropy).spawn``'s i-th child."""
    return [np.random.default_rng(s) for s in np.random.SeedSequence(entropy).spawn(rows)]


class ObservationNoise:
    """Gaussian noise on the measured state, row by row.

    Row i of a batch (B, 4) sees x_i + std_i * z_i, where std_i = (angle, angle, speed,
    speed) std of that row and z_i is the next standard normal 4-vector of row i's own
    generator ``rngs[i]``. Rows with zero std draw nothing. A single state (4,) is one row.
    ``rngs`` may be numpy Generators or RandomStates (anything with ``standard_normal``).

    ``block``: each noisy row draws the normals of ``block`` steps at once (the same
    numbers as one step at a time, since a generator fills an array in order), so the
    loop over rows runs once per block, not once per step. Keep 1 when a generator is
    shared with other draws between steps (the environment's task random state).
    """

    def __init__(self, angle_std=0.0, speed_std=0.0, *, rngs: Sequence, block: int = 1):
        angle = np.atleast_1d(np.asarray(angle_std, dtype=float))
        speed = np.atleast_1d(np.asarray(speed_std, dtype=float))
        if not (np.all(np.isfinite(angle)) and np.all(np.isfinite(speed))) or \
                np.any(angle < 0) or np.any(speed < 0):
            raise ValueError("noise standard deviations must be finite and non-negative")
        if int(block) != block or block < 1:
            raise ValueError(f"block must be a positive whole number of steps, got {block}")
        self.rngs = list(rngs)
        rows = len(self.rngs)
        try:
            angle, speed = (np.broadcast_to(v, (rows,)) for v in (angle, speed))
        except ValueError:
            raise ValueError(f"{rows} generators for noise levels of {len(angle)} and "
                             f"{len(speed)} rows") from None
        self.std = np.stack([angle, angle, speed, speed], -1)            # (rows, 4)
        self._noisy = np.flatnonzero(np.any(self.std > 0, axis=-1))
        self.block = int(block)
        self._drawn = np.empty((0, len(self._noisy), 4))                  # (steps, noisy, 4)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """The measured state(s): x (4,) or (rows, 4) plus this step's noise."""
        if not len(self._noisy):
            return x
        x = np.asarray(x, dtype=float)
        flat = x.reshape(-1, 4)
        if len(flat) != len(self.rngs):
            raise ValueError(f"{len(self.rngs)} noise generators for a batch of {len(flat)} states")
        if not len(self._drawn):
            self._drawn = np.stack([self.rngs[i].standard_normal((self.block, 4))
                                    for i in self._noisy], 1)
        z, self._drawn = self._drawn[0], self._drawn[1:]
        seen = flat.copy()
        seen[self._noisy] += self.std[self._noisy] * z
        return seen.reshape(x.shape)


class ActuationDelay:
    """A batched policy whose torque reaches the plant late, row by row.

    Row i gets the torque the policy computed ``samples[i]`` sample periods ago (one
    number applies to every row); until that first command arrives its actuators hold
    zero torque. State lives in the wrapper, so make a new one per rollout.
    """

    def __init__(self, policy, samples=1):
        d = np.asarray(samples, dtype=float)
        if not np.all(np.isfinite(d)) or np.any(d < 0) or np.any(d != np.round(d)):
            raise ValueError(f"delay must be a non-negative whole number of samples, got {samples}")
        self.policy = policy
        self.samples = d.astype(int)
        self.kind = getattr(policy, "kind", "")
        self._history: list = []

    def __call__(self, x) -> np.ndarray:
        u = np.asarray(self.policy(x))
        if not self.samples.any():
            return u
        self._history.append(u)
        delays = np.broadcast_to(self.samples, u.shape[:-1])
        out = np.zeros_like(u)
        for d in np.unique(delays):
            if len(self._history) > d:
                rows = delays == d
                out[rows] = self._history[-1 - d][rows]
        del self._history[:-1 - int(self.samples.max())]
        return out

    def restart(self, rows) -> None:
        """Rows ``rows`` start afresh (a new episode): their actuators hold zero torque
        until their next commands arrive, as a new wrapper's would."""
        self._history = [u.copy() for u in self._history]     # never the caller's arrays
        for u in self._history:
            u[rows] = 0.0

