"""Slow, obviously correct reference plants, for holding the fast ones against.

Written independently of :mod:`twolink.sim.plants`: one ``MjData`` per state, ``mj_step`` in
a plain loop, and its own wrap and saturation at the end of the sample period.
"""
from __future__ import annotations

import math

import mujoco
import numpy as np

from twolink.arm import mjcf
from twolink.arm.parameters import TABLE_I, TS


class MujocoStepLoop:
    """The MuJoCo plant, one state at a time: ``mj_step`` for every substep of Ts.

    ``params`` is one parameter set or one per batch row (as ``MujocoPlant``).
    """

    name = "mujoco"

    def __init__(self, params=TABLE_I):
        self.per_row = not hasattr(params, "tau_max")
        self.plist = list(params) if self.per_row else [params]
        self.models = [mjcf.build_model(p) for p in self.plist]

    def close(self):
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        pass

    def step(self, x, tau) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        tau = np.broadcast_to(np.asarray(tau, dtype=float), x.shape[:-1] + (2,))
        xf, tf = x.reshape(-1, 4), tau.reshape(-1, 2)
        out = np.empty_like(xf)
        for i in range(len(xf)):
            j = i if self.per_row else 0
            model, p = self.models[j], self.plist[j]
            data = mujoco.MjData(model)
            data.qpos[0], data.qpos[1] = xf[i, 0], xf[i, 1]
            data.qvel[0], data.qvel[1] = xf[i, 2], xf[i, 3]
            data.ctrl[0] = min(max(tf[i, 0], -p.tau1_max), p.tau1_max)
            data.ctrl[1] = min(max(tf[i, 1], -p.tau2_max), p.tau2_max)
            for _ in range(int(round(TS / model.opt.timestep))):
                mujoco.mj_step(model, data)
            for link, limit in enumerate((p.dtheta1_max, p.dtheta2_max)):
                angle = math.fmod(data.qpos[link] + math.pi, 2 * math.pi)
                out[i, link] = (angle + 2 * math.pi if angle < 0 else angle) - math.pi
                out[i, 2 + link] = min(max(data.qvel[link], -limit), limit)
        return out.reshape(x.shape)
