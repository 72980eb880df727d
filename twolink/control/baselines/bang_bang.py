"""Per-joint proximate time-optimal servo (PTOS): bang-bang far from the goal, linear
near it (Workman's PTOS; decentralized, joint i sees only theta_i and dtheta_i).

With a_i = tau_max_i / J_i the joint's acceleration at full torque (J_i its inertia on
its own, :func:`twolink.control.baselines.common.joint_inertia`), alpha_i in (0, 1] an
acceleration discount and omega_i the natural frequency of the linear zone
(k1 = omega^2, k2 = sqrt(2 k1 / alpha) so that the two zones join continuously):

    f(e) = (k1 / k2) e                                   |e| <= a / k1
    f(e) = sign(e) (sqrt(2 alpha a |e|) - a / k2)        otherwise
    tau_i = clip(-J_i k2 (f(theta_i) + dtheta_i), -tau_max_i, tau_max_i)

Far out the speed is driven onto the braking curve dtheta = -f(theta) of the discounted
acceleration alpha a (full torque, a bang-bang law); inside |theta| <= a / k1 the law is
the PD -J (k1 theta + k2 dtheta). alpha > 1 is accepted: joint damping brakes too, so the
arm can stop harder than a alone says.
"""
from __future__ import annotations

import numpy as np

from twolink.arm.parameters import TABLE_I
from twolink.control.baselines.common import (
    Baseline,
    check_vector,
    joint_inertia,
    split_state,
)


class ProximateTimeOptimal(Baseline):
    """Per-joint PTOS: ``alpha`` (> 0) and ``omega`` (rad/s, > 0) per joint; ``inertia``
    (kg m^2) and ``tau_max`` default to Table I's (:func:`joint_inertia`)."""

    TYPE = "bang_bang"
    KIND = "decentralized"
    FIELDS = ("alpha", "omega", "inertia", "tau_max")

    def __init__(self, alpha, omega, *, inertia=None, tau_max=None, name: str | None = None):
        super().__init__(name)
        self.alpha = check_vector("alpha", alpha)
        self.omega = check_vector("omega", omega)
        self.inertia = check_vector("inertia", joint_inertia(TABLE_I) if inertia is None
                                    else inertia)
        self.tau_max = check_vector("tau_max", TABLE_I.tau_max if tau_max is None else tau_max)
        self.accel = self.tau_max / self.inertia
        self.k1 = self.omega ** 2
        self.k2 = np.sqrt(2.0 * self.k1 / self.alpha)
        self.linear_zone = self.accel / self.k1        # rad

    def curve(self, theta) -> np.ndarray:
        """f(theta) of the module docstring, per joint (theta (..., 2))."""
        e = np.abs(theta)
        far = np.sign(theta) * (np.sqrt(2.0 * self.alpha * self.accel * e) - self.accel / self.k2)
        return np.where(e <= self.linear_zone, (self.k1 / self.k2) * theta, far)

    def __call__(self, x) -> np.ndarray:
        theta, speed = split_state(x)
        u = -self.inertia * self.k2 * (self.curve(theta) + speed)
        return np.clip(u, -self.tau_max, self.tau_max)

    def fields(self) -> dict:
        return {"alpha": self.alpha.tolist(), "omega": self.omega.tolist(),
                "inertia": self.inertia.tolist(), "tau_max": self.tau_max.tolist()}
