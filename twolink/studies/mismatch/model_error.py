"""Open-loop model error: one-step predictions of (11) and (6) against MuJoCo.

For every bin centre c_m of the centralized grid and every discrete action u_j, each
model predicts x_{k+1} = f(c_m, u_j) over one sample period; MuJoCo gives the reference.
The full model (6) must agree with MuJoCo to integration accuracy (both run RK4 with the
same step); the gap of the simplified model (11) is what the paper's policies learn from.

A third prediction measures what decentralized agent 2 assumes when synthesised on (6):
it cannot see link 1, so it predicts link 2 as if link 1 were at rest (dtheta1 = 0,
tau1 = 0). Its error is reported on link 2's components only.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from twolink.arm import dynamics
from twolink.arm.integrate import sample_step, wrap_angle
from twolink.arm.parameters import STATE_NAMES, TABLE_I, ArmParameters
from twolink.synthesis.problems import centralized_problem
from twolink.sim.plants import MujocoPlant

#: Predictions compared with MuJoCo, in report order.
PREDICTIONS = ("simplified", "full", "agent2_assumption")


@dataclasses.dataclass
class OneStepError:
    """Signed errors prediction - MuJoCo, shape (N_X, N_U, 4) per prediction (angles
    wrapped), over the bin centres ``centers`` (N_X, 4) and ``actions`` (N_U, 2)."""

    centers: np.ndarray
    actions: np.ndarray
    grid_shape: tuple
    errors: dict

    def summary(self) -> dict:
        """Max and RMS absolute error per state component, per prediction (JSON-ready)."""
        out = {}
        for name, err in self.errors.items():
            a = np.abs(err).reshape(-1, 4)
            comps = [1, 3] if name == "agent2_assumption" else [0, 1, 2, 3]
            out[name] = {STATE_NAMES[c]: {"max": float(a[:, c].max()),
                                          "rms": float(np.sqrt((a[:, c] ** 2).mean()))}
                         for c in comps}
        return out

    def heat(self, name: str, link: int) -> np.ndarray:
        """Max |speed error| over the other axes and all actions, on link ``link``'s
        (theta, dtheta) bins: shape (12 angle bins, 7 speed bins)."""
        a = np.abs(self.errors[name][..., 2:])
        if name == "agent2_assumption":
            a = a[..., 1:]
        worst = a.max(axis=(-2, -1)).reshape(self.grid_shape)     # (t1, t2, d1, d2)
        if link == 1:
            return worst.max(axis=(1, 3))
        if link == 2:
            return worst.max(axis=(0, 2))
        raise ValueError(f"link must be 1 or 2, got {link}")


def one_step_error(p: ArmParameters = TABLE_I, *, nthread: int | None = None) -> OneStepError:
    """Errors of every prediction against MuJoCo over all bin centres and actions."""
    simp = centralized_problem(p, "simplified")
    full = centralized_problem(p, "full")
    centers = simp.grid.centers()
    actions = simp.actions
    x = np.broadcast_to(centers[:, None, :], (len(centers), len(actions), 4))
    tau = np.broadcast_to(actions[None], x.shape[:-1] + (2,))
    with MujocoPlant(p, nthread=nthread) as plant:
        ref = plant.step(x, tau)
    # Agent 2 on (6): link 1 assumed at rest, with no torque of its own.
    rest = np.array(x)
    rest[..., 2] = 0.0
    tau_rest = np.array(tau)
    tau_rest[..., 0] = 0.0
    agent2 = sample_step(dynamics.full_acceleration, p, rest, tau_rest)

    def diff(pred):
        d = pred - ref
        d[..., :2] = wrap_angle(d[..., :2])
        return d

    errors = {"simplified": diff(simp.next_points), "full": diff(full.next_points),
              "agent2_assumption": diff(agent2)}
    return OneStepError(centers, actions, simp.grid.shape, errors)
