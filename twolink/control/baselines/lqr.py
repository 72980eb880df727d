"""Saturated discrete-time LQR on the zero-order-hold linearisation of the full model (6)
at the origin (centralized: each torque sees the whole state).

At x = 0 the Coriolis terms (quadratic in the speeds) vanish, so the linearisation is

    d/dt [theta; dtheta] = [[0, I], [0, -M0^-1 D]] [theta; dtheta] + [[0], [M0^-1]] tau,

M0 = M(theta2 = 0) of (7), D = diag(b1, b2). It is sampled at Ts with the torque held
(``scipy.signal.cont2discrete``, ``zoh``) and the gain K of the discrete algebraic Riccati
equation (``scipy.linalg.solve_discrete_are``) for the weights diag(q) on the state and
diag(r) on the torque gives tau = clip(-K x, +-tau_max), the angles of x wrapped.

``delay`` d > 0 is the delay-aware variant for an actuation delay of d samples (the
torque issued at k acts from k + d on): the state is augmented with the last d torques
issued, z_k = [x_k, u_{k-d}, ..., u_{k-1}], x_{k+1} = Ad x_k + Bd u_{k-d}, and the Riccati
equation solved for the augmented system with no weight on the torques in the pipeline.
That controller remembers what it issued: :func:`twolink.sim.rollout.rollout` calls its
``reset(rows)`` before every rollout (the controller protocol of
:mod:`twolink.sim.controller`); it also starts afresh by itself when the batch size
changes.
"""
from __future__ import annotations

import numpy as np

from twolink.arm.dynamics import mass_matrix
from twolink.arm.parameters import TABLE_I, TS, ArmParameters
from twolink.control.baselines.common import (
    Baseline,
    check_params,
    check_vector,
    split_state,
)

#: Longest actuation delay (samples) the delay-aware variant accepts: 1 s.
MAX_DELAY = 20


def linearisation(params: ArmParameters = TABLE_I) -> tuple[np.ndarray, np.ndarray]:
    """(A (4, 4), B (4, 2)) of the full model (6) linearised at the origin."""
    minv = np.linalg.inv(mass_matrix(params, np.float64(0.0)))
    a = np.zeros((4, 4))
    a[:2, 2:] = np.eye(2)
    a[2:, 2:] = -minv @ np.diag([params.b1, params.b2])
    b = np.zeros((4, 2))
    b[2:] = minv
    return a, b


def discrete_linearisation(params: ArmParameters = TABLE_I, ts: float = TS
                           ) -> tuple[np.ndarray, np.ndarray]:
    """(Ad, Bd) of :func:`linearisation` sampled at ``ts`` with the torque held (ZOH)."""
    a, b = linearisation(params)
    import scipy.signal              # imported here: the module loads without it (0.5 s)

    ad, bd, *_ = scipy.signal.cont2discrete((a, b, np.eye(4), np.zeros((4, 2))), ts,
                                            method="zoh")
    return ad, bd


def augmented(ad: np.ndarray, bd: np.ndarray, delay: int) -> tuple[np.ndarray, np.ndarray]:
    """The delay-augmented system of the module docstring, state [x, u_{k-d}..u_{k-1}]."""
    n, m = bd.shape
    size = n + m * delay
    a = np.zeros((size, size))
    b = np.zeros((size, m))
    a[:n, :n] = ad
    if delay == 0:
        return ad.copy(), bd.copy()
    a[:n, n:n + m] = bd
    for j in range(delay - 1):          # the pipeline shifts by one torque per sample
        a[n + m * j:n + m * (j + 1), n + m * (j + 1):n + m * (j + 2)] = np.eye(m)
    b[n + m * (delay - 1):] = np.eye(m)
    return a, b


def lqr_gain(q, r, *, params: ArmParameters = TABLE_I, delay: int = 0, ts: float = TS
             ) -> np.ndarray:
    """The discrete LQR gain K (2, 4 + 2 delay): u = -K z minimises sum z'Qz + u'Ru with
    Q = diag(q, 0 for the pipelined torques), R = diag(r)."""
    a, b = augmented(*discrete_linearisation(params, ts), delay)
    qm = np.zeros((len(a), len(a)))
    qm[:4, :4] = np.diag(q)
    rm = np.diag(r)
    import scipy.linalg

    p = scipy.linalg.solve_discrete_are(a, b, qm, rm)
    return np.linalg.solve(rm + b.T @ p @ b, b.T @ p @ a)


class SaturatedLQR(Baseline):
    """tau = clip(-K z, +-tau_max) with K of :func:`lqr_gain` for the weights ``q`` (4
    numbers, > 0: theta1, theta2, dtheta1, dtheta2) and ``r`` (2, > 0), designed on
    ``params`` (Table I; its torque limits are the saturation), ``delay`` samples of
    actuation delay (0: the plain LQR)."""

    TYPE = "lqr"
    KIND = "centralized"
    FIELDS = ("q", "r", "delay", "params")

    def __init__(self, q, r, *, delay: int = 0, params=TABLE_I, name: str | None = None):
        super().__init__(name)
        self.q = check_vector("q", q, size=4)
        self.r = check_vector("r", r)
        if isinstance(delay, bool) or not isinstance(delay, (int, np.integer)) \
                or not 0 <= delay <= MAX_DELAY:
            raise ValueError(f"delay must be a whole number of samples from 0 to "
                             f"{MAX_DELAY}, got {delay!r}")
        self.delay = int(delay)
        self.params = check_params(params)
        self.tau_max = self.params.tau_max
        self.K = lqr_gain(self.q, self.r, params=self.params, delay=self.delay)
        self._history = None            # (delay, rows, 2): issued torques, oldest first

    @property
    def design_params(self) -> ArmParameters:
        return self.params

    def closed_loop_matrix(self) -> np.ndarray:
        """A - B K of the (augmented) discrete linearisation."""
        a, b = augmented(*discrete_linearisation(self.params), self.delay)
        return a - b @ self.K

    def reset(self, rows: int | None = None) -> None:
        """A new episode (the controller protocol's ``reset``, called before every
        rollout of ``rows`` rows): forget the torques issued; the pipeline holds zeros, as
        the delayed actuators do until the first command arrives."""
        self._history = None if rows is None or not self.delay else \
            np.zeros((self.delay, int(rows), 2))

    def __call__(self, x) -> np.ndarray:
        theta, speed = split_state(x)
        z = np.concatenate([theta, speed], -1)
        if not self.delay:
            return np.clip(-z @ self.K.T, -self.tau_max, self.tau_max)
        shape = z.shape[:-1]
        flat = z.reshape(-1, 4)
        if self._history is None or self._history.shape[1] != len(flat):
            self._history = np.zeros((self.delay, len(flat), 2))
        pipe = np.moveaxis(self._history, 0, 1).reshape(len(flat), -1)
        u = np.clip(-np.concatenate([flat, pipe], -1) @ self.K.T, -self.tau_max, self.tau_max)
        self._history = np.concatenate([self._history[1:], u[None]])
        return u.reshape(shape + (2,))

    def fields(self) -> dict:
        return {"q": self.q.tolist(), "r": self.r.tolist(), "delay": self.delay,
                "params": self.params.as_dict()}
