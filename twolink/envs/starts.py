"""Initial poses beyond the uniform draw: the poses a joint's own motor cannot bring home.

A pose's own-motor time (:func:`twolink.arm.task.own_motor_seconds`, the largest over
its joints) bounds from below the time its slowest joint needs with every other joint
held. Beyond the deadline of an episode (its horizon less the 1 s a success must hold:
7 s of 8 s for three links or more) a pose can succeed only if the other joints' motion
turns the slow one; uniform poses ask for it only at six tapered links, and there for a
minority of poses (docs/results/scaling.md). The ``x0`` words of :data:`STARTS` let a learner
meet them more often:

* ``'slow'``: angles uniform in [-pi, pi), at rest, conditioned on an own-motor time
  beyond the deadline (rejection sampling: :func:`slow_pose`);
* ``'mixed'``: each episode ``'slow'`` with probability 1/2, else ``'random'``.

Both need an arm with such poses (:func:`check_slow_starts`); evaluation stays on
uniform poses.
"""
from __future__ import annotations

import math

import numpy as np

from twolink.arm.parameters import horizon
from twolink.arm.task import own_motor_seconds, own_motor_speed

#: The ``x0`` words that draw poses beyond the own motors' reach.
STARTS = ("slow", "mixed")
#: Seconds a success holds before an episode's end (the scaling table's rule).
HOLD_S = 1.0
#: Most draws :func:`slow_pose` makes before giving up (a few suffice where such poses
#: exist: :func:`check_slow_starts` refuses the arms without any).
MAX_DRAWS = 100_000


def deadline(params) -> float:
    """The own-motor time beyond which a pose needs the other joints: the arm's episode
    horizon (:func:`twolink.arm.parameters.horizon`) less :data:`HOLD_S`."""
    return horizon(params.links) - HOLD_S


def check_slow_starts(x0, params, what: str = "x0") -> None:
    """A one-line ValueError when ``x0`` is a word of :data:`STARTS` and no pose of the
    arm ``params`` has an own-motor time beyond :func:`deadline` (the slowest joint's
    pi / speed is within it); ``what`` names the option in the message."""
    if not (isinstance(x0, str) and x0 in STARTS):
        return
    longest = math.pi / float(np.min(own_motor_speed(params)))
    if longest <= deadline(params):
        raise ValueError(f"{what}={x0!r}: no pose of this {params.links}-link arm is beyond "
                         f"its own motors' reach (the slowest joint needs at most "
                         f"{longest:.2f} s, the deadline is {deadline(params):g} s); use "
                         f"'random'")


def slow_pose(params, random) -> np.ndarray:
    """One state at rest (2N,) whose own-motor time exceeds :func:`deadline`: uniform
    angles drawn from ``random`` (a ``RandomState`` or ``Generator``) until one does."""
    n, limit = params.links, deadline(params)
    for _ in range(MAX_DRAWS):
        angles = random.uniform(-np.pi, np.pi, n)
        if own_motor_seconds(params, angles).max() > limit:
            return np.concatenate([angles, np.zeros(n)])
    raise ValueError(f"no pose beyond the own motors' reach in {MAX_DRAWS} draws")


def start_pose(x0: str, params, random) -> np.ndarray:
    """The first state of an episode for ``x0`` ``'slow'`` or ``'mixed'`` (module
    docstring)."""
    if x0 == "mixed" and random.uniform() < 0.5:
        return np.concatenate([random.uniform(-np.pi, np.pi, params.links),
                               np.zeros(params.links)])
    return slow_pose(params, random)
