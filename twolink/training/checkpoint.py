"""Checkpoints of a training run that resume it exactly, read without unpickling code.

A checkpoint is written at an update boundary (:mod:`twolink.training.config`) and
holds everything the rest of the run depends on, so that a resumed run gives bit for
bit the curve and weights of an uninterrupted one (on the CPU, the same torch and
Stable-Baselines3, the same threads):

* the networks and optimizers (:meth:`_get_torch_save_params` of the SB3 model: the
  policy's and every optimizer's ``state_dict``, SAC's ``log_ent_coef``);
* the generators: Python's ``random``, numpy's global one, torch's (CPU, and CUDA's when
  the run is on it), the action space's (SAC's warm-up actions), each arm's;
* SB3's counters and last step: ``num_timesteps``, ``_n_updates``, ``_episode_num``,
  ``_last_obs``, ``_last_episode_starts``; SAC's replay buffer (the filled part);
* the arms (:class:`twolink.envs.gym_arms.Arms`): states, episode clocks, the last
  sample outside the goal band;
* a JSON header (:data:`SCHEMA`, :data:`VERSION`, the run's config, the versions of
  Stable-Baselines3 and torch, the learning curve so far and the clocks).

The file is one ``torch.save`` of ``{"header": <JSON text>, "state": <tensors, numbers,
lists and dicts>}`` and is read with ``torch.load(weights_only=True)`` (torch's loader
that builds tensors and plain containers only); numpy arrays travel as tensors. A file
that is missing, truncated, not of this schema and version, or of another run is one
ValueError line naming it.
"""
from __future__ import annotations

import io
import json
import random
import warnings
from pathlib import Path

import numpy as np

from twolink.artifacts import atomic_path

#: Schema and version of the header.
SCHEMA, VERSION = "twolink.train.checkpoint", 1
#: The largest checkpoint read (a full SAC replay buffer of six links is about 2 GB).
MAX_BYTES = 8 * 2**30


def to_tensor(a):
    """A torch tensor holding a copy of the numpy array ``a``."""
    import torch

    return torch.from_numpy(np.ascontiguousarray(a).copy())


def to_array(t) -> np.ndarray:
    """A numpy copy of the torch tensor ``t``."""
    return t.detach().cpu().numpy().copy()


def generator_state(rng) -> dict:
    """The JSON-ready state of a numpy ``Generator``."""
    return rng.bit_generator.state


def generator_from_state(state: dict) -> np.random.Generator:
    """A numpy ``Generator`` in the state :func:`generator_state` returned."""
    bits = getattr(np.random, state["bit_generator"])()
    bits.state = state
    return np.random.Generator(bits)


def capture(model, env) -> tuple[dict, dict]:
    """(JSON-ready state, tensor state) of the SB3 ``model`` training on the
    :class:`twolink.envs.sb3.TwoLinkSB3VecEnv` ``env``, at an update boundary."""
    import torch
    from stable_baselines3.common.save_util import recursive_getattr
    from stable_baselines3.common.utils import get_device

    arms = env._live()
    names, variables = model._get_torch_save_params()
    tensors = {"state_dicts": {n: recursive_getattr(model, n).state_dict() for n in names},
               "variables": {n: recursive_getattr(model, n).detach().cpu().clone()
                             for n in variables},
               "torch_rng": torch.get_rng_state()}
    started = model._last_obs is not None        # before the first step: not yet reset
    if started:
        tensors.update(last_obs=to_tensor(model._last_obs),
                       last_episode_starts=to_tensor(model._last_episode_starts),
                       arms={"x": to_tensor(arms.x), "k": to_tensor(arms.k),
                             "last_out": to_tensor(arms.last_out)})
    if get_device(model.device).type == "cuda":
        tensors["cuda_rng"] = torch.cuda.get_rng_state_all()
    np_state = np.random.get_state(legacy=False)
    tensors["numpy_key"] = to_tensor(np_state["state"]["key"].astype(np.int64))
    buffer = getattr(model, "replay_buffer", None)
    if buffer is not None:
        end = buffer.buffer_size if buffer.full else buffer.pos
        tensors["replay"] = {k: to_tensor(getattr(buffer, k)[:end]) for k in
                             ("observations", "next_observations", "actions", "rewards",
                              "dones", "timeouts")}
    py = random.getstate()
    plain = {"started": started,
             "num_timesteps": int(model.num_timesteps), "n_updates": int(model._n_updates),
             "episode_num": int(model._episode_num),
             "numpy": {"pos": int(np_state["state"]["pos"]),
                       "has_gauss": int(np_state["has_gauss"]),
                       "gauss": float(np_state["gauss"])},
             "python_random": [py[0], list(py[1]), py[2]],
             "action_space": generator_state(model.action_space.np_random),
             "arm_generators": [generator_state(r) for r in arms.rngs] if started else []}
    if buffer is not None:
        plain["replay"] = {"pos": int(buffer.pos), "full": bool(buffer.full)}
    return plain, tensors


def restore(model, env, plain: dict, tensors: dict) -> None:
    """Put ``model`` and ``env`` (just built for the same config) into the state
    :func:`capture` took (before the first step: the weights and generators; the arms
    are then reset by the first ``learn`` as in an uninterrupted run)."""
    import torch
    from stable_baselines3.common.save_util import recursive_getattr

    for name, sd in tensors["state_dicts"].items():
        recursive_getattr(model, name).load_state_dict(sd)
    with torch.no_grad():
        for name, value in tensors["variables"].items():
            recursive_getattr(model, name).copy_(value)
    model.num_timesteps = plain["num_timesteps"]
    model._n_updates = plain["n_updates"]
    model._episode_num = plain["episode_num"]
    buffer = getattr(model, "replay_buffer", None)
    if buffer is not None:
        for k, t in tensors["replay"].items():
            getattr(buffer, k)[:len(t)] = to_array(t)
        buffer.pos, buffer.full = plain["replay"]["pos"], plain["replay"]["full"]
    if plain["started"]:
        model._last_obs = to_array(tensors["last_obs"])
        model._last_episode_starts = to_array(tensors["last_episode_starts"])
        model._last_original_obs = None
        arms = env._live()
        arms.x[:] = to_array(tensors["arms"]["x"])
        arms.k[:] = to_array(tensors["arms"]["k"])
        arms.last_out[:] = to_array(tensors["arms"]["last_out"])
        for i, state in enumerate(plain["arm_generators"]):
            arms.rngs[i] = generator_from_state(state)
            arms.sensors.set_generator(i, arms.rngs[i])
        env._reset_seeds()
        env._started, env._actions = True, None
    model.action_space.np_random.bit_generator.state = plain["action_space"]
    version, key, gauss = plain["python_random"]
    random.setstate((version, tuple(key), gauss))
    np.random.set_state({"bit_generator": "MT19937",
                         "state": {"key": to_array(tensors["numpy_key"]).astype(np.uint32),
                                   "pos": plain["numpy"]["pos"]},
                         "has_gauss": plain["numpy"]["has_gauss"],
                         "gauss": plain["numpy"]["gauss"]})
    torch.set_rng_state(tensors["torch_rng"])
    if "cuda_rng" in tensors:
        torch.cuda.set_rng_state_all(tensors["cuda_rng"])


def save(path, header: dict, tensors: dict, *, schema: str = SCHEMA,
         version: int = VERSION) -> Path:
    """Write the checkpoint atomically (a reader never sees half a file): ``header`` as
    JSON text, tagged ``schema`` and ``version``, beside the ``tensors``."""
    import torch

    text = json.dumps(dict(header, schema=schema, version=version))
    with atomic_path(path) as tmp:
        torch.save({"header": text, "state": tensors}, tmp)
    return Path(path)


def read(path, *, max_bytes: int = MAX_BYTES) -> tuple[dict, dict]:
    """(header, tensors) of a file :func:`save` wrote, read with
    ``torch.load(weights_only=True)`` (nothing unpickled), its schema not yet checked; a
    one-line ValueError when it is missing, larger than ``max_bytes``, truncated or
    foreign."""
    import torch

    path = Path(path)
    if not path.is_file():
        raise ValueError(f"no checkpoint {path} to resume from")
    if path.stat().st_size > max_bytes:
        raise ValueError(f"{path} is {path.stat().st_size:,} bytes, more than a checkpoint "
                         f"holds")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            obj = torch.load(io.BytesIO(path.read_bytes()), weights_only=True,
                             map_location="cpu")
    except Exception as exc:
        why = " ".join(str(exc).split())[:100]
        raise ValueError(f"{path} is not a readable twolink training checkpoint (truncated "
                         f"or foreign: {type(exc).__name__}: {why})") from None
    header = None
    if isinstance(obj, dict) and isinstance(obj.get("header"), str) and \
            isinstance(obj.get("state"), dict):
        try:
            header = json.loads(obj["header"])
        except ValueError:
            header = None
    if not isinstance(header, dict):
        raise ValueError(f"{path} is not a twolink training checkpoint")
    return header, obj["state"]


def load(path) -> tuple[dict, dict]:
    """(header, tensors) of the single-agent checkpoint at ``path`` (:func:`read`); a
    one-line ValueError for another schema or version too."""
    header, state = read(path)
    if header.get("schema") != SCHEMA:
        algo = (header.get("config") or {}).get("algo") if isinstance(
            header.get("config"), dict) else None
        if algo in ("ippo", "mappo"):
            raise ValueError(f"{path} is a checkpoint of a {algo} run (skrl), not of a ppo "
                             f"or sac run: resume it with --algo {algo}")
        raise ValueError(f"{path} is not a twolink training checkpoint")
    if header.get("version") != VERSION:
        raise ValueError(f"{path} is a training checkpoint of version "
                         f"{header.get('version')!r}; this twolink reads version {VERSION}")
    return header, state
