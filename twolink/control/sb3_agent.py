"""A saved Stable-Baselines3 agent (PPO or SAC, a ``.zip`` of ``model.save``) as a
controller of the protocol of :mod:`twolink.sim.controller`.

:func:`sb3_algorithm` reads the save's ``data`` (JSON, no SB3 needed) and names its
algorithm from the attributes only that algorithm saves (PPO's ``n_epochs``,
``clip_range``, ``gae_lambda``; SAC's ``target_entropy``, ``replay_buffer_class``), or
refuses the file in one :class:`twolink.sim.controller.ControllerError` line.
:class:`SB3Agent` loads the model (SB3 imported only then: without it, one line saying
the rl extras are needed) and maps states (n, 4) to torques (n, 2) as the training
environment (:class:`twolink.envs.sb3.TwoLinkSB3VecEnv`, ``actions='normalized'``) does:
the observation :func:`twolink.arm.observations.features` of the states (``'cos_sin'``
or ``'state'``, told apart by the saved observation space's size), the deterministic
action of ``model.predict``, clipped to [-1, 1] and scaled to +-tau_max.

Its ``meta`` holds the algorithm, seed, environment steps trained and the file; no
``"model"``: the agent names no model a compensator could predict with, so the
leaderboard gives it plain rows only.
"""
from __future__ import annotations

import json
import zipfile
from pathlib import Path

import numpy as np

from twolink.arm.observations import features
from twolink.arm.parameters import TABLE_I
from twolink.sim.controller import ControllerError

#: Attributes only each algorithm's save holds (in its ``data`` JSON).
SIGNATURES = {"ppo": ("n_epochs", "clip_range", "gae_lambda"),
              "sac": ("target_entropy", "replay_buffer_class", "ent_coef")}
#: The message of a missing Stable-Baselines3.
NEEDS_RL = "needs the rl extras: pip install 'twolink[rl]'"


def saved_data(path) -> dict:
    """The ``data`` JSON of the SB3 save at ``path``; a one-line ControllerError when the
    file is missing, not a zip, or not an SB3 save."""
    path = Path(path)
    if not path.is_file():
        raise ControllerError(f"agent file {path} does not exist")
    try:
        with zipfile.ZipFile(path) as z:
            names = set(z.namelist())
            raw = z.read("data") if "data" in names else None
    except zipfile.BadZipFile:
        raise ControllerError(f"{path} is not a zip file (a Stable-Baselines3 save is one)") \
            from None
    if raw is None or "policy.pth" not in names:
        raise ControllerError(f"{path} is not a Stable-Baselines3 save (the zip holds no "
                              f"data and policy.pth)")
    try:
        data = json.loads(raw)
    except (ValueError, UnicodeDecodeError):
        raise ControllerError(f"{path} is not a Stable-Baselines3 save (its data is not "
                              f"JSON)") from None
    if not isinstance(data, dict):
        raise ControllerError(f"{path} is not a Stable-Baselines3 save (its data is not a "
                              f"dict)")
    return data


def sb3_algorithm(path) -> str:
    """``'ppo'`` or ``'sac'``: the algorithm of the SB3 save at ``path``, from the
    attributes its data holds (:data:`SIGNATURES`); a one-line ControllerError otherwise."""
    data = saved_data(path)
    found = [algo for algo, keys in SIGNATURES.items() if all(k in data for k in keys)]
    if len(found) != 1:
        raise ControllerError(f"{path} is a Stable-Baselines3 save of neither PPO nor SAC; "
                              f"the leaderboard runs those two")
    return found[0]


def _observation(data: dict, path) -> str:
    """The observation the agent was trained on, from its saved space's size (4: the
    state, 6: cos/sin of two links)."""
    shape = (data.get("observation_space") or {}).get("_shape")
    by_size = {(4,): "state", (6,): "cos_sin"}
    shape = tuple(shape) if isinstance(shape, list) else None
    if shape not in by_size:
        raise ControllerError(f"{path}: the agent observes shape {shape}; a two-link agent "
                              f"observes the state (4,) or its cos/sin features (6,)")
    return by_size[shape]


def model_torques(model, x, observation: str, tau_max) -> np.ndarray:
    """Torques (..., 2) of an SB3 ``model`` (in memory) at states x (..., 4): its
    deterministic action on the features ``observation`` of x
    (:func:`twolink.arm.observations.features`), clipped to [-1, 1] and scaled to
    +-``tau_max``."""
    obs = features(np.asarray(x, dtype=float), observation)
    action, _ = model.predict(obs, deterministic=True)
    return np.clip(np.asarray(action, dtype=float), -1.0, 1.0) * np.asarray(tau_max, dtype=float)


class SB3Agent:
    """The SB3 agent saved at ``path`` as a controller: states (n, 4) -> torques (n, 2)
    (see the module docstring); ``name`` the file's stem unless given."""

    def __init__(self, path, *, name: str | None = None, params=TABLE_I):
        path = Path(path)
        self.algo = sb3_algorithm(path)
        data = saved_data(path)
        self.observation = _observation(data, path)
        try:
            import stable_baselines3 as sb3
        except ImportError:
            raise ControllerError(f"controller {path.name} {NEEDS_RL}") from None
        cls = sb3.PPO if self.algo == "ppo" else sb3.SAC
        try:
            self.model = cls.load(path, device="cpu")
        except Exception as exc:
            raise ControllerError(f"cannot load the {self.algo.upper()} agent {path}: "
                                  f"{type(exc).__name__}: {exc}") from None
        space = self.model.action_space
        if getattr(space, "shape", None) != (2,) or not (
                np.all(space.low == -1.0) and np.all(space.high == 1.0)):
            raise ControllerError(f"{path}: the agent's actions are {space}; the controller "
                                  f"runs normalized actions, a Box [-1, 1]^2")
        self.tau_max = np.asarray(params.tau_max, dtype=float)
        self.name = name or path.stem
        self.path = path
        self.meta = {"algo": self.algo, "seed": data.get("seed"),
                     "steps": data.get("num_timesteps"), "observation": self.observation,
                     "file": str(path), "stable_baselines3": sb3.__version__}

    def __call__(self, x) -> np.ndarray:
        """Torques (..., 2) of states x (..., 4): the clipped deterministic action scaled
        to +-tau_max."""
        return model_torques(self.model, x, self.observation, self.tau_max)

    def __reduce__(self):
        """Pickled as its file and name (a worker loads the file again)."""
        return (sb3_agent, (str(self.path), self.name))


def sb3_agent(path, name: str | None = None) -> SB3Agent:
    """The controller of the SB3 agent saved at ``path`` (see :class:`SB3Agent`)."""
    return SB3Agent(path, name=name)


def saved_agents(folder) -> list:
    """The ``*.zip`` agents in ``folder`` (sorted), as paths; none when the folder is
    missing or Stable-Baselines3 does not import."""
    folder = Path(folder)
    zips = sorted(folder.glob("*.zip")) if folder.is_dir() else []
    if not zips:
        return []
    try:
        import stable_baselines3  # noqa: F401
    except ImportError:
        return []
    return [str(p) for p in zips]
