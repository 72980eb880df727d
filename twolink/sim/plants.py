"""The three plants a policy can drive: ``simplified`` (11), ``full`` (6)-(9), ``mujoco``.

Every plant advances a batch of states (..., 2N) by one sample period Ts under
zero-order-hold torques (..., N), with the conventions of docs/conventions.md (torques clipped,
angles wrapped, speeds saturated at the end of the period). Plants are context managers
(``with make_plant("mujoco") as plant:``); only the MuJoCo plant holds resources.

N = 2 (Table I) unless the plant is made for a :class:`~twolink.arm.parameters.LinksParameters`
of more links: ``full`` is then the N-link rigid body (:func:`dynamics.links_acceleration`),
``mujoco`` the N-link MJCF; ``simplified`` exists for two links only. A two-link
LinksParameters runs the very code of its :class:`ArmParameters` (:meth:`as_arm`).

States a plant accepts are finite, with angles within :data:`MAX_ANGLE` and speeds
within :data:`SPEED_BOUND` times the plant's speed limit. A step that goes unstable (a
MuJoCo warning, a non-finite state) raises :class:`SimulationError`; it never returns.
"""
from __future__ import annotations

import contextlib
import os
import threading
from typing import Optional, Sequence

import mujoco
import numpy as np
from mujoco import rollout as mj_rollout

from twolink.arm import dynamics, mjcf
from twolink.arm.integrate import (
    SUBSTEPS,
    check_masses,
    check_sampling,
    finish_sample,
    sample_step,
)
from twolink.arm.parameters import (
    TABLE_I,
    TS,
    ArmParameters,
    LinksParameters,
    check_links,
    state_names,
)
from twolink.validate import whole

PLANTS = ("simplified", "full", "mujoco")
#: Largest |angle| (rad) a plant accepts. Angles are wrapped at the end of every sample
#: period, so a larger one can only be a typo (MuJoCo resets itself beyond 1e10).
MAX_ANGLE = 1e3
#: Largest |speed| a plant accepts, as a multiple of its speed limit (2 pi rad/s in
#: Table I, so 62.8 rad/s). Speeds saturate at the limit after the first sample period.
SPEED_BOUND = 10.0


#: The most threads a MuJoCo plant (and ``evaluate``) starts: four per core, at least 8.
#: MuJoCo's rollout gains nothing from more threads than cores.
MAX_NTHREAD = max(8, 4 * (os.cpu_count() or 1))


def check_nthread(nthread, what: str = "nthread") -> int:
    """``nthread`` as an int: None gives one thread per core, else a whole number from 1
    to :data:`MAX_NTHREAD`; a ValueError naming ``what`` for anything else."""
    if nthread is None:
        return min(MAX_NTHREAD, os.cpu_count() or 1)
    return whole(nthread, what, 1, MAX_NTHREAD,
                 message="{what} must be a whole number from 1 to {high} (threads of MuJoCo's "
                         "rollout, at most 4 per core), got {value!r}")


class SimulationError(RuntimeError):
    """A sample period that went unstable: a MuJoCo warning or a non-finite state.

    ``rows`` are the flat batch rows concerned.
    """

    def __init__(self, message: str, rows=()):
        super().__init__(message)
        self.rows = tuple(int(r) for r in rows)


def check_states(x, *, what: str = "state", speed_max=None, links: int = 2) -> np.ndarray:
    """A float array of shape (..., 2N) for N = ``links``, finite, |angles| <= MAX_ANGLE
    and, when ``speed_max`` is given, |speeds| <= SPEED_BOUND * speed_max; else a clear
    ValueError."""
    n = check_links(links)
    x = np.asarray(x, dtype=float)
    if x.ndim == 0 or x.shape[-1] != 2 * n:
        raise ValueError(f"{what} must have {2 * n} components "
                         f"[{', '.join(state_names(n))}], got shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError(f"{what} contains NaN or infinite values")
    big = np.abs(x[..., :n]).max(initial=0.0)
    if big > MAX_ANGLE:
        raise ValueError(f"{what} has an angle of magnitude {big:.4g} rad, beyond the "
                         f"bound {MAX_ANGLE:g} rad")
    if speed_max is not None:
        bound = SPEED_BOUND * np.asarray(speed_max, dtype=float)
        over = np.abs(x[..., n:]) > bound
        if np.any(over):
            worst = np.abs(x[..., n:])[over].max()
            raise ValueError(f"{what} has a speed of magnitude {worst:.4g} rad/s, beyond the "
                             f"bound {np.max(bound):.4g} rad/s ({SPEED_BOUND:g} x the speed "
                             f"limit)")
    return x


def check_torques(tau, links: int = 2) -> np.ndarray:
    """A float array of shape (..., N) for N = ``links``, finite; else a clear ValueError."""
    n = check_links(links)
    tau = np.asarray(tau, dtype=float)
    if tau.ndim == 0 or tau.shape[-1] != n:
        names = ", ".join(f"tau{i}" for i in range(1, n + 1))
        raise ValueError(f"torque must have {n} components [{names}], got shape {tau.shape}")
    if not np.all(np.isfinite(tau)):
        raise ValueError("torque contains NaN or infinite values")
    return tau


def _fmt_state(x) -> str:
    return "[" + ", ".join(f"{v:+.4g}" for v in np.asarray(x).ravel()) + "]"


# --------------------------------------------------------------------------- MuJoCo state
#: x = [qpos, qvel] inside MuJoCo's full-physics state [time, qpos, qvel] (checked on load):
#: the time at index 0, x at indices 1 .. 2N.
_TIME, _X = 0, slice(1, None)


def _check_layout(model: mujoco.MjModel, links: int = 2) -> None:
    size = mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    if (model.nq, model.nv, model.na, size) != (links, links, 0, 1 + 2 * links):
        raise RuntimeError(f"unexpected MuJoCo state layout (nq={model.nq}, nv={model.nv}, "
                           f"na={model.na}, full physics size {size})")


def physics_state(x: np.ndarray) -> np.ndarray:
    """Full-physics states (n, 1 + 2N) at time 0 for states x (n, 2N)."""
    state = np.zeros((len(x), 1 + x.shape[-1]))
    state[:, _X] = x
    return state


def set_data(data: mujoco.MjData, x) -> None:
    """Put the state x (2N,) into ``data`` (qpos, qvel)."""
    n = len(data.qpos)
    data.qpos[:] = x[:n]
    data.qvel[:] = x[n:]


def data_state(data: mujoco.MjData) -> np.ndarray:
    """The state x (2N,) of ``data``."""
    return np.concatenate([data.qpos, data.qvel])


def substeps_per_sample(model: mujoco.MjModel) -> int:
    """MuJoCo timesteps in one sample period Ts (the MJCF sets timestep = Ts / SUBSTEPS)."""
    return int(round(TS / model.opt.timestep))


def finish_data(p: ArmParameters | LinksParameters, data: mujoco.MjData) -> np.ndarray:
    """End a sample period on an ``MjData`` in place (:func:`finish_sample`); returns x."""
    x = finish_sample(p, data_state(data))
    set_data(data, x)
    return x


_warn_lock = threading.Lock()
_warn_depth = 0
_warn_previous = None
_warn_messages: list = []


@contextlib.contextmanager
def mujoco_warnings():
    """Collect MuJoCo's warning messages (a list) instead of printing them and appending
    to MUJOCO_LOG.TXT; the previous handler is restored afterwards."""
    global _warn_depth, _warn_previous
    with _warn_lock:
        if _warn_depth == 0:
            _warn_previous = mujoco.get_mju_user_warning()
            _warn_messages.clear()
            mujoco.set_mju_user_warning(_warn_messages.append)
        _warn_depth += 1
        start = len(_warn_messages)
    mine: list = []
    try:
        yield mine
    finally:
        with _warn_lock:
            mine.extend(_warn_messages[start:])
            _warn_depth -= 1
            if _warn_depth == 0:
                mujoco.set_mju_user_warning(_warn_previous)
                _warn_previous = None


# --------------------------------------------------------------------------- plants
def constraint_free(model: mujoco.MjModel) -> bool:
    """Whether no constraint can ever become active in ``model``: contacts disabled, no
    joint or tendon limits, no equality constraints, no friction loss, no flexes. Then
    MuJoCo's constraint stage finds no constraint (``nefc`` 0) at every step."""
    return bool(model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONTACT
                and not model.jnt_limited.any() and model.neq == 0
                and not model.dof_frictionloss.any() and model.ntendon == 0
                and model.nflex == 0)


def _model(params) -> mujoco.MjModel:
    """The compiled MJCF of ``params``, refused first (a ValueError naming the link) if no
    plant can simulate it (:func:`twolink.arm.integrate.check_sampling`).

    A :func:`constraint_free` model (the arm's MJCF: contacts off, joints unlimited) has
    MuJoCo's constraint stage switched off (``mjDSBL_CONSTRAINT``): it would find nothing,
    so every state is the same bit for bit, and each step is about 8 % cheaper."""
    check_sampling(params)
    model = mjcf.build_model(params)
    if constraint_free(model):
        model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    return model


def _arm(params):
    """``params`` with a two-link :class:`LinksParameters` turned into its
    :class:`ArmParameters`, so that two links always run the same code."""
    if isinstance(params, LinksParameters) and params.links == 2:
        return params.as_arm()
    return params


class Plant:
    """A discrete-time plant x_{k+1} = f(x_k, tau_k) with sample time Ts, for states
    (..., 2N) and torques (..., N) of an arm of N = :attr:`links` links."""

    name = ""

    def __init__(self, params: ArmParameters | LinksParameters = TABLE_I):
        self.params = _arm(params)
        self._speed_max = self.params.speed_max

    @property
    def links(self) -> int:
        """N, the number of links (and joints) of the arm."""
        return (self.params[0] if isinstance(self.params, list) else self.params).links

    def check_states(self, x, *, what: str = "state") -> np.ndarray:
        """``x`` as a float array, or a ValueError if this plant refuses it."""
        return check_states(x, what=what, speed_max=self._speed_max, links=self.links)

    def step(self, x, tau) -> np.ndarray:
        n = self.links
        x = self.check_states(x)
        tau = np.broadcast_to(check_torques(tau, n), x.shape[:-1] + (n,))
        out = self._step(x, tau)
        bad = ~np.all(np.isfinite(out), axis=-1).reshape(-1)
        if bad.any():
            rows = np.flatnonzero(bad)
            raise SimulationError(
                f"the {self.name} plant reached a non-finite state from "
                f"x = {_fmt_state(x.reshape(-1, 2 * n)[rows[0]])} (batch row {rows[0]})", rows)
        return out

    def _step(self, x: np.ndarray, tau: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def close(self) -> None:
        """Release what the plant holds (nothing for the numpy plants)."""

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class ModelPlant(Plant):
    """A numpy model integrated with fixed-step RK4 substeps inside Ts.

    Two links: ``simplified`` (11) or ``full`` (6)-(9); more links: ``full`` only, the
    N-link rigid body of :func:`dynamics.links_acceleration` (horizontal, no gravity).
    """

    def __init__(self, name: str, params: ArmParameters | LinksParameters = TABLE_I, *,
                 substeps: int = SUBSTEPS, gravity: bool = False):
        super().__init__(params)
        self.name = name
        self.substeps = whole(substeps, "substeps", 1)
        n = self.links
        if name == "simplified":
            check_masses(self.params)     # (11) divides by P2 and M11 only
        else:
            check_sampling(self.params, substeps=self.substeps)
        if name == "simplified":
            if n != 2:
                raise ValueError(f"the simplified plant needs two links, the arm has {n}: "
                                 f"model (11) is the paper's two-link simplification")
            self._accel = dynamics.simplified_acceleration
        elif n == 2:
            self._accel = (lambda p, x, tau: dynamics.full_acceleration(p, x, tau, gravity=gravity))
        elif gravity:
            raise ValueError(f"gravity is modelled for two links only, the arm has {n}")
        else:
            self._accel = dynamics.links_acceleration

    def _step(self, x, tau):
        with np.errstate(all="ignore"):      # a blow-up is reported by step(), once
            return sample_step(self._accel, self.params, x, tau, substeps=self.substeps)


class MujocoPlant(Plant):
    """The MJCF arm stepped by MuJoCo, a whole batch per call through ``mujoco.rollout``.

    ``params`` may be a sequence (one parameter set per batch row) for perturbed models,
    all of the same number of links. Holds a thread pool: use it as a context manager or
    call :meth:`close`.
    """

    name = "mujoco"

    def __init__(self, params: ArmParameters | LinksParameters
                 | Sequence[ArmParameters | LinksParameters] = TABLE_I, *,
                 nthread: Optional[int] = None):
        self._pool = None
        self.per_row = not isinstance(params, (ArmParameters, LinksParameters))
        plist = [_arm(p) for p in params] if self.per_row else [_arm(params)]
        if not plist:
            raise ValueError("no parameter sets given")
        links = {p.links for p in plist}
        if len(links) > 1:
            raise ValueError(f"the parameter sets of a plant must all have the same number of "
                             f"links, got {', '.join(str(n) for n in sorted(links))}")
        self.nthread = check_nthread(nthread)
        Plant.__init__(self, plist[0])
        self.params = plist if self.per_row else plist[0]
        self._plist = plist
        built: dict = {}        # one compiled model per distinct parameter set
        self.models = [built[p] if p in built else built.setdefault(p, _model(p))
                       for p in plist]
        # Limits per batch row (per-row plants) or shared (one plant), broadcast alike.
        self._tau_max = np.stack([p.tau_max for p in plist]) if self.per_row else plist[0].tau_max
        self._speed_max = (np.stack([p.speed_max for p in plist]) if self.per_row
                           else plist[0].speed_max)
        self.model = self.models[0]
        _check_layout(self.model, self.links)
        self.nstep = substeps_per_sample(self.model)
        self._datas = [mujoco.MjData(self.model) for _ in range(self.nthread)]
        self._timestep = (np.array([m.opt.timestep for m in self.models]) if self.per_row
                          else self.model.opt.timestep)
        self._batch = None          # (rows, models per row, state output) of the last step
        self._pool = mj_rollout.Rollout(nthread=self.nthread if self.nthread > 1 else 0)

    def set_row_params(self, row: int, params: ArmParameters | LinksParameters) -> None:
        """Give batch row ``row`` of a per-row plant a new parameter set (its model is
        compiled now), e.g. a new random plant for one arm's next episode."""
        if not self.per_row:
            raise ValueError("this plant has one parameter set for all rows; make it with a "
                             "sequence of parameter sets to change a row's")
        params = _arm(params)
        if params.links != self.links:
            raise ValueError(f"a {params.links}-link parameter set for a plant of "
                             f"{self.links} links")
        model = _model(params)
        _check_layout(model, self.links)
        if substeps_per_sample(model) != self.nstep:
            raise ValueError(f"a parameter set of {substeps_per_sample(model)} MuJoCo steps "
                             f"per sample period for a plant of {self.nstep}")
        self._plist[row] = params
        self.models[row] = model
        self._timestep[row] = model.opt.timestep
        self._batch = None
        self._tau_max[row] = params.tau_max
        self._speed_max[row] = params.speed_max

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
        if self._pool is None:
            raise RuntimeError("the mujoco plant is closed")
        batch, links = x.shape[:-1], self.links
        xf = x.reshape(-1, 2 * links)
        n = len(xf)
        if self.per_row and n != len(self._plist):
            raise ValueError(f"{len(self._plist)} parameter sets for a batch of {n} states")
        tau = np.clip(tau.reshape(-1, links), -self._tau_max, self._tau_max)
        control = np.ascontiguousarray(np.repeat(tau[:, None, :], self.nstep, axis=1),
                                       dtype=np.float64)
        if self._batch is None or self._batch[0] != n:
            # The per-row models and the state output, made once per batch size: the
            # inputs are built here to the shapes mujoco.rollout wants, so its Python
            # checks (per row and per call) are skipped.
            models = list(self.models) if self.per_row else [self.model] * n
            nstate = 1 + 2 * links
            self._batch = (n, models, np.empty((n, self.nstep, nstate)),
                           np.empty((n, self.nstep, 0)))
        _, models, state, sensordata = self._batch
        with mujoco_warnings() as messages:
            self._pool.rollout(models, self._datas, physics_state(xf), control,
                               nstep=self.nstep, state=state, sensordata=sensordata,
                               skip_checks=True)
        end = state[:, -1]
        # After a warning MuJoCo resets the row and the rollout stops, so its clock
        # falls short of the sample period.
        bad = (end[:, _TIME] < (self.nstep - 0.5) * self._timestep) | \
            ~np.all(np.isfinite(end), -1)
        if bad.any() or messages:
            rows = np.flatnonzero(bad)
            where = (f"from x = {_fmt_state(xf[rows[0]])}, tau = {_fmt_state(tau[rows[0]])} "
                     f"(batch row {rows[0]}{f' and {len(rows) - 1} more' if len(rows) > 1 else ''})"
                     if len(rows) else f"in a batch of {n} states")
            why = f": {messages[0].strip()}" if messages else ""
            raise SimulationError(f"MuJoCo went unstable {where}{why}", rows)
        out = finish_sample(self._plist[0], end[:, _X], speed_max=self._speed_max)
        return out.reshape(batch + (2 * links,))


def make_plant(name: str, params: ArmParameters | LinksParameters = TABLE_I,
               **kwargs) -> Plant:
    """A plant by name: one of :data:`PLANTS`, for an arm of any number of links
    (``simplified`` two only)."""
    if name in ("simplified", "full"):
        return ModelPlant(name, params, **kwargs)
    if name == "mujoco":
        return MujocoPlant(params, **kwargs)
    raise ValueError(f"unknown plant {name!r}; choose one of {', '.join(PLANTS)}")
