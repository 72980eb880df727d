"""Model mismatch and imperfect observation: perturbed parameters, state noise, delays,
dropped and stuck readings.

One implementation of each perturbation, per batch row, shared by the environments
(:mod:`twolink.envs.dm`, :mod:`twolink.envs.gym`, :mod:`twolink.envs.pettingzoo`), rollouts, the
robustness sweeps (:mod:`twolink.sim.cells`) and the evaluation call
(:mod:`twolink.sim.evaluation`), so the same perturbation means the same thing everywhere;
the named challenge levels that combine them live in :mod:`twolink.sim.challenges`.
Randomness only through injected generators, one per batch row: a row's noise never
depends on which rows share its batch.
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from twolink.arm.parameters import GOAL_ANGLE, GOAL_SPEED, TABLE_I, ArmParameters
from twolink.validate import whole_array

#: Table I parameters a challenge's ``offsets`` may change (the plant's physical constants
#: and torque limits).
PERTURBABLE = ("l1", "m1", "m2", "I1", "I2", "c1", "c2", "b1", "b2", "tau1_max", "tau2_max")
#: The ten physical parameters of the arm (not its torque or speed limits): what a
#: challenge's joint plant perturbation and a robust synthesis's model draws change.
#: l2 has no dynamic effect on the horizontal arm (only the drawn arm's length).
PHYSICAL = ("l1", "l2", "m1", "m2", "I1", "I2", "c1", "c2", "b1", "b2")
#: Largest relative change of a physical parameter (a challenge's spread, a robust
#: synthesis's draws): 90 % or more would leave a parameter near 0.
MAX_SPREAD = 0.9
#: Speed noise std (rad/s) per degree of angle noise where only an angle noise is given
#: (sweeps, ``evaluate`` without a challenge): the goal band's ratio, 0.1 rad/s
#: per 5 deg, so 1 deg goes with 0.02 rad/s, as in the ``medium`` challenge.
SPEED_PER_DEG = GOAL_SPEED / math.degrees(GOAL_ANGLE)
#: Second word of the seeds of observation noise: a noisy run draws from a child of
#: ``SeedSequence([seed, NOISE_STREAM])`` (the seeding rule of twolink.sim.challenges).
NOISE_STREAM = 7919


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

    def __call__(self, x: np.ndarray, rows=None) -> np.ndarray:
        """The measured state(s): x (4,) or (rows, 4) plus this step's noise.

        ``rows``: x holds only these rows of the batch (in this order), e.g. the arms a
        vector environment resets; only with ``block`` 1.
        """
        if not len(self._noisy):
            return x
        x = np.asarray(x, dtype=float)
        flat = x.reshape(-1, 4)
        if rows is not None:
            return self._rows(flat, _row_indices(rows, len(flat), len(self.rngs),
                                                 self.block)).reshape(x.shape)
        if len(flat) != len(self.rngs):
            raise ValueError(f"{len(self.rngs)} noise generators for a batch of {len(flat)} states")
        if not len(self._drawn):
            self._drawn = np.stack([self.rngs[i].standard_normal((self.block, 4))
                                    for i in self._noisy], 1)
        z, self._drawn = self._drawn[0], self._drawn[1:]
        seen = flat.copy()
        seen[self._noisy] += self.std[self._noisy] * z
        return seen.reshape(x.shape)

    def _rows(self, flat, rows):
        seen = flat.copy()
        for j, i in enumerate(rows):
            if np.any(self.std[i] > 0):
                seen[j] += self.std[i] * self.rngs[i].standard_normal(4)
        return seen


def _row_indices(rows, n: int, size: int, block: int) -> np.ndarray:
    """Checked indices ``rows`` of a batch of ``size`` rows for a call with ``n`` of them."""
    if block != 1:
        raise ValueError("a call on some rows of the batch needs block 1")
    rows = np.asarray(rows, dtype=int).reshape(-1)
    if len(rows) != n or np.any((rows < 0) | (rows >= size)):
        raise ValueError(f"rows {rows.tolist()} do not index {n} of {size} batch rows")
    return rows


#: The message of a bad delay (a :func:`twolink.validate.whole_array` template).
_SAMPLES = "{what} must be a non-negative whole number of samples, got {value}"


class ActuationDelay:
    """A batched policy whose torque reaches the plant late, row by row.

    Row i gets the torque the policy computed ``samples[i]`` sample periods ago (one
    number applies to every row); until that first command arrives its actuators hold
    zero torque. State lives in the wrapper, so make a new one per rollout.
    """

    def __init__(self, policy, samples=1):
        self.samples = whole_array(samples, "delay", message=_SAMPLES)
        self.policy = policy
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



def keyed_generators(entropy, keys) -> list[np.random.Generator]:
    """One generator per key (a tuple of whole numbers): ``SeedSequence(entropy,
    spawn_key=key)``, the child a chain of ``spawn`` calls would give (key (p, s) is the
    s-th child of the p-th child). A row keyed by (plant, state) thus draws the same
    numbers whatever the number of plants and states beside it."""
    return [np.random.Generator(np.random.PCG64(
        np.random.SeedSequence(entropy, spawn_key=tuple(int(k) for k in key))))
        for key in keys]


class ObservationDelay:
    """Readings that reach the controller late, row by row.

    Row i is handed the reading it was given ``samples[i]`` sample periods ago (one number
    applies to every row). Until that many readings exist it is handed its first reading of
    the episode (the sensor's buffer starts full of it). Readings are the (B, d) or (d,)
    arrays of successive calls (``rows``: the call holds only these rows of the batch);
    state lives in the object, so make one per rollout or call :meth:`restart`.
    """

    def __init__(self, samples=1, *, size: int | None = None):
        self.samples = whole_array(samples, "observation delay", message=_SAMPLES)
        self.size = size                  # rows of the batch (default: the first call's)
        self._buffer = None               # (batch, D + 1, d): row i's reading k at k % (D + 1)
        self._age = None                  # readings each row has had since its restart

    def __call__(self, x, rows=None) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        if not self.samples.any():
            return x
        flat = x.reshape(-1, x.shape[-1])
        if self._buffer is None:
            if rows is not None and self.size is None:
                raise ValueError("the first call of an observation delay of unknown size "
                                 "holds every row")
            n = len(flat) if self.size is None else int(self.size)
            depth = int(self.samples.max()) + 1
            self._buffer = np.zeros((n, depth, flat.shape[-1]))
            self._age = np.zeros(n, dtype=int)
            try:
                self._samples = np.broadcast_to(self.samples, (n,))
            except ValueError:
                raise ValueError(f"{self.samples.size} delays for a batch of {n} "
                                 f"readings") from None
        size, depth = self._buffer.shape[:2]
        idx = np.arange(size) if rows is None else _row_indices(rows, len(flat), size, 1)
        if len(idx) != len(flat):
            raise ValueError(f"an observation delay of {size} rows given {len(flat)} readings")
        self._buffer[idx, self._age[idx] % depth] = flat
        self._age[idx] += 1
        back = np.minimum(self._samples[idx], self._age[idx] - 1)
        return self._buffer[idx, (self._age[idx] - 1 - back) % depth].reshape(x.shape)

    def restart(self, rows) -> None:
        """Rows ``rows`` start afresh: their next reading is their first."""
        if self._age is not None:
            self._age[rows] = 0


#: Sample periods a stuck reading stays stuck (0.2 s at Ts = 0.05 s): the sample it
#: sticks at and the next STUCK_SAMPLES - 1.
STUCK_SAMPLES = 4


class ReadingFaults:
    """Dropped and stuck readings, row by row (a sensor bus that loses or freezes data).

    Every sample, a faulty row (one with a non-zero ``dropout`` or ``stuck`` probability)
    draws two uniforms [u_drop, u_stick] in [0, 1) from its own generator ``rngs[i]``
    (rows with both probabilities zero draw nothing), and is handed, in this order of
    precedence:

    1. its new reading on the first sample of an episode (nothing to repeat yet; no
       fault starts there);
    2. the reading it was last handed while it is stuck;
    3. the reading it was last handed if u_stick < stuck: it sticks for this sample and
       the next ``hold - 1`` (:data:`STUCK_SAMPLES` by default);
    4. the reading it was last handed if u_drop < dropout (a dropped reading);
    5. otherwise its new reading.

    ``block`` as in :class:`ObservationNoise`: the uniforms of ``block`` steps drawn at
    once (the same numbers); keep 1 when the generators serve other draws between steps.
    """

    def __init__(self, dropout=0.0, stuck=0.0, *, rngs: Sequence, hold: int = STUCK_SAMPLES,
                 block: int = 1):
        drop = np.atleast_1d(np.asarray(dropout, dtype=float))
        stick = np.atleast_1d(np.asarray(stuck, dtype=float))
        for name, p in (("dropout", drop), ("stuck", stick)):
            if not np.all(np.isfinite(p)) or np.any(p < 0) or np.any(p >= 1):
                raise ValueError(f"{name} probability must lie in [0, 1), got {p.tolist()}")
        if int(hold) != hold or hold < 1:
            raise ValueError(f"hold must be a positive whole number of samples, got {hold}")
        if int(block) != block or block < 1:
            raise ValueError(f"block must be a positive whole number of steps, got {block}")
        self.rngs = list(rngs)
        rows = len(self.rngs)
        try:
            drop, stick = (np.broadcast_to(v, (rows,)) for v in (drop, stick))
        except ValueError:
            raise ValueError(f"{rows} generators for fault probabilities of {len(drop)} and "
                             f"{len(stick)} rows") from None
        self.dropout, self.stuck, self.hold, self.block = drop, stick, int(hold), int(block)
        self._faulty = np.flatnonzero((drop > 0) | (stick > 0))
        self._drawn = np.empty((0, len(self._faulty), 2))
        self._last = None                               # the readings last handed (rows, d)
        self._left = np.zeros(rows, dtype=int)          # samples a stuck row stays stuck
        self._fresh = np.ones(rows, dtype=bool)         # next sample is an episode's first

    def __call__(self, x, rows=None) -> np.ndarray:
        """The readings handed on for new readings x (rows, d) or (d,); ``rows``: x holds
        only these rows of the batch (in this order; only with ``block`` 1)."""
        if not len(self._faulty):
            return x
        x = np.asarray(x, dtype=float)
        flat = x.reshape(-1, x.shape[-1])
        size = len(self.rngs)
        if rows is None:
            if len(flat) != size:
                raise ValueError(f"{size} fault generators for a batch of {len(flat)} readings")
            idx, pos = np.arange(size), self._faulty
            if not len(self._drawn):
                self._drawn = np.stack([self.rngs[i].random((self.block, 2))
                                        for i in self._faulty], 1)
            u, self._drawn = self._drawn[0], self._drawn[1:]
        else:
            idx = _row_indices(rows, len(flat), size, self.block)
            pos = np.flatnonzero((self.dropout[idx] > 0) | (self.stuck[idx] > 0))
            u = np.array([self.rngs[i].random(2) for i in idx[pos]]).reshape(-1, 2)
        if self._last is None:
            self._last = np.zeros((size, flat.shape[-1]))
        f = idx[pos]                                   # faulty batch rows of this call
        fresh = self._fresh[f]
        held = self._left[f] > 0
        sticks = ~held & (u[:, 1] < self.stuck[f])
        drops = ~held & ~sticks & (u[:, 0] < self.dropout[f])
        repeat = (held | sticks | drops) & ~fresh
        self._left[f] = np.where(fresh, 0, np.where(held, self._left[f] - 1,
                                                    np.where(sticks, self.hold - 1, 0)))
        out = flat.copy()
        out[pos[repeat]] = self._last[f[repeat]]
        self._last[idx] = out
        self._fresh[idx] = False
        return out.reshape(x.shape)

    def restart(self, rows) -> None:
        """Rows ``rows`` start a new episode (not stuck; their next reading gets through)."""
        self._left[rows] = 0
        self._fresh[rows] = True


class Sensors:
    """What a controller is handed of the true states, row by row: Gaussian noise
    (:class:`ObservationNoise`), then dropped and stuck readings (:class:`ReadingFaults`),
    then the observation delay (:class:`ObservationDelay`), in that order (a sensor
    measures, the bus loses or freezes the reading, it arrives late).

    ``rngs``: one generator per row for the noise; ``fault_rngs`` one per row for the
    faults (default: the same generators, each step drawing the noise's 4 normals, then
    the faults' 2 uniforms; keep ``block`` 1 then).
    """

    def __init__(self, angle_std=0.0, speed_std=0.0, dropout=0.0, stuck=0.0, delay=0, *,
                 rngs: Sequence, fault_rngs: Sequence | None = None, block: int = 1):
        self.noise = ObservationNoise(angle_std, speed_std, rngs=rngs, block=block)
        self.faults = ReadingFaults(dropout, stuck, rngs=rngs if fault_rngs is None
                                    else fault_rngs, block=block)
        self.delay = ObservationDelay(delay, size=len(self.noise.rngs))

    @property
    def noisy(self) -> bool:
        """Whether any row's readings may leave the true states' bounds (Gaussian noise)."""
        return bool(np.any(self.noise.std > 0))

    def __call__(self, x, rows=None) -> np.ndarray:
        """The readings handed to the controller for true states x (B, 4) or (4,);
        ``rows``: x holds only these rows of the batch (in this order; ``block`` 1)."""
        return self.delay(self.faults(self.noise(x, rows), rows), rows)

    def set_generator(self, row: int, rng) -> None:
        """Row ``row`` draws its noise and faults from ``rng`` from now on (a new episode)."""
        self.noise.rngs[row] = rng
        self.faults.rngs[row] = rng

    def restart(self, rows) -> None:
        """Rows ``rows`` start a new episode (see :meth:`ReadingFaults.restart` and
        :meth:`ObservationDelay.restart`)."""
        self.faults.restart(rows)
        self.delay.restart(rows)
