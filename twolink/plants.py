"""The three plants a policy can drive: ``simplified`` (11), ``full`` (6)-(9), ``mujoco``.

Every plant advances a batch of states (..., 4) by one sample period Ts under
zero-order-hold torques (..., 2), with the conventions of SPEC.md (torques clipped,
angles wrapped, speeds saturated at the end of the period).
"""
from __future__ import annotations

import os
from typing import Optional, Sequence

import mujoco
import numpy as np
from mujoco import rollout as mj_rollout

from twolink import dynamics, mjcf
from twolink.integrate import SUBSTEPS, finish_sample, sample_step
from twolink.parameters import TABLE_I, TS, ArmParameters

PLANTS = ("simplified", "full", "mujoco")


def check_states(x, *, what: str = "state") -> np.ndarray:
    """A float array of shape (..., 4) with finite entries, or a clear ValueError."""
    x = np.asarray(x, dtype=float)
    if x.ndim == 0 or x.shape[-1] != 4:
        raise ValueError(f"{what} must have 4 components [theta1, theta2, dtheta1, dtheta2], "
                         f"got shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError(f"{what} contains NaN or infinite values")
    return x


def check_torques(tau) -> np.ndarray:
    tau = np.asarray(tau, dtype=float)
    if tau.ndim == 0 or tau.shape[-1] != 2:
        raise ValueError(f"torque must have 2 components [tau1, tau2], got shape {tau.shape}")
    if not np.all(np.isfinite(tau)):
        raise ValueError("torque contains NaN or infinite values")
    return tau


def substeps_per_sample(model: mujoco.MjModel) -> int:
    """MuJoCo timesteps in one sample period Ts (the MJCF sets timestep = Ts / SUBSTEPS)."""
    return int(round(TS / model.opt.timestep))


def finish_data(p: ArmParameters, data: mujoco.MjData) -> np.ndarray:
    """End a sample period on an ``MjData`` in place (:func:`finish_sample`); returns x."""
    x = finish_sample(p, np.concatenate([data.qpos, data.qvel]))
    data.qpos[:] = x[:2]
    data.qvel[:] = x[2:]
    return x


class Plant:
    """A discrete-time plant x_{k+1} = f(x_k, tau_k) with sample time Ts."""

    name = ""

    def __init__(self, params: ArmParameters = TABLE_I):
        self.params = params

    def step(self, x, tau) -> np.ndarray:
        x = check_states(x)
        tau = np.broadcast_to(check_torques(tau), x.shape[:-1] + (2,))
        return self._step(x, tau)

    def _step(self, x: np.ndarray, tau: np.ndarray) -> np.ndarray:
        raise NotImplementedError


class ModelPlant(Plant):
    """A numpy model integrated with fixed-step RK4 substeps inside Ts."""

    def __init__(self, name: str, params: ArmParameters = TABLE_I, *,
                 substeps: int = SUBSTEPS, gravity: bool = False):
        super().__init__(params)
        self.name = name
        self.substeps = substeps
        if name == "simplified":
            self._accel = dynamics.simplified_acceleration
        else:
            self._accel = (lambda p, x, tau: dynamics.full_acceleration(p, x, tau, gravity=gravity))

    def _step(self, x, tau):
        return sample_step(self._accel, self.params, x, tau, substeps=self.substeps)


class MujocoPlant(Plant):
    """The MJCF arm stepped by MuJoCo, a whole batch per call through ``mujoco.rollout``.

    ``params`` may be a sequence (one parameter set per batch row) for perturbed models.
    """

    name = "mujoco"

    def __init__(self, params: ArmParameters | Sequence[ArmParameters] = TABLE_I, *,
                 nthread: Optional[int] = None):
        self.per_row = not isinstance(params, ArmParameters)
        plist = list(params) if self.per_row else [params]
        super().__init__(plist[0] if not self.per_row else plist)
        self._plist = plist
        built: dict = {}        # one compiled model per distinct parameter set
        self.models = [built[p] if p in built else built.setdefault(p, mjcf.build_model(p))
                       for p in plist]
        # Limits per batch row (per-row plants) or shared (one plant), broadcast alike.
        self._tau_max = np.stack([p.tau_max for p in plist]) if self.per_row else plist[0].tau_max
        self._speed_max = (np.stack([p.speed_max for p in plist]) if self.per_row
                           else plist[0].speed_max)
        self.model = self.models[0]
        self.nstep = substeps_per_sample(self.model)
        self.nstate = mujoco.mj_stateSize(self.model, mujoco.mjtState.mjSTATE_FULLPHYSICS)
        if self.nstate != 1 + self.model.nq + self.model.nv:
            raise RuntimeError("unexpected MuJoCo state layout")
        self.nthread = max(1, nthread if nthread is not None else (os.cpu_count() or 1))
        self._datas = [mujoco.MjData(self.model) for _ in range(self.nthread)]
        self._pool = mj_rollout.Rollout(nthread=self.nthread if self.nthread > 1 else 0)

    def close(self):
        if self._pool is not None:
            self._pool.close()
            self._pool = None

    def __del__(self):
        try:
            self.close()
        except Exception:
            pass

    def _step(self, x, tau):
        batch = x.shape[:-1]
        xf = x.reshape(-1, 4)
        n = len(xf)
        if self.per_row and n != len(self._plist):
            raise ValueError(f"{len(self._plist)} parameter sets for a batch of {n} states")
        tau = np.clip(tau.reshape(-1, 2), -self._tau_max, self._tau_max)
        state0 = np.zeros((n, self.nstate))
        state0[:, 1:3] = xf[:, :2]
        state0[:, 3:5] = xf[:, 2:]
        control = np.repeat(tau[:, None, :], self.nstep, axis=1)
        models = self.models if self.per_row else self.model
        state, _ = self._pool.rollout(models, self._datas, state0, control,
                                      nstep=self.nstep, skip_checks=False)
        out = finish_sample(self._plist[0], state[:, -1, 1:5], speed_max=self._speed_max)
        return out.reshape(batch + (4,))

    def step_reference(self, x, tau) -> np.ndarray:
        """The same sample period with ``mj_step`` in a plain loop over states (for tests)."""
        x = check_states(x)
        tau = np.broadcast_to(check_torques(tau), x.shape[:-1] + (2,))
        xf, tf = x.reshape(-1, 4), tau.reshape(-1, 2)
        out = np.empty_like(xf)
        for i in range(len(xf)):
            model = self.models[i] if self.per_row else self.model
            p = self._plist[i] if self.per_row else self._plist[0]
            data = mujoco.MjData(model)
            data.qpos[:] = xf[i, :2]
            data.qvel[:] = xf[i, 2:]
            data.ctrl[:] = np.clip(tf[i], -p.tau_max, p.tau_max)
            for _ in range(self.nstep):
                mujoco.mj_step(model, data)
            out[i] = finish_data(p, data)
        return out.reshape(x.shape)


def make_plant(name: str, params: ArmParameters = TABLE_I, **kwargs) -> Plant:
    """A plant by name: one of :data:`PLANTS`."""
    if name in ("simplified", "full"):
        return ModelPlant(name, params, **kwargs)
    if name == "mujoco":
        return MujocoPlant(params, **kwargs)
    raise ValueError(f"unknown plant {name!r}; choose one of {', '.join(PLANTS)}")
