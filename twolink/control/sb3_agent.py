"""A saved Stable-Baselines3 agent (PPO or SAC, a ``.zip`` of ``model.save``) as a
controller of the protocol of :mod:`twolink.sim.controller`, loaded as data only.

A save is read without unpickling anything of it (SB3's own ``PPO.load``/``SAC.load``
would unpickle the cloudpickled entries of its ``data``, which can run any code):

* :func:`read_save` opens the zip, checks every member's declared uncompressed size and
  their total against :data:`MAX_BYTES` (and the member count against
  :data:`MAX_MEMBERS`) before reading anything, and reads only ``data`` and
  ``policy.pth`` (stored or deflated; never more than the cap);
* :func:`saved_data` parses ``data`` as plain JSON; only the readable copies SB3 writes
  beside each ``":serialized:"`` blob are used, never the blob;
* :func:`sb3_algorithm` names the algorithm from the attributes only that algorithm saves
  (PPO's ``n_epochs``, ``clip_range``, ``gae_lambda``; SAC's ``target_entropy``,
  ``replay_buffer_class``, ``ent_coef``);
* :func:`load_policy` rebuilds the policy from the readable fields (the observation
  space's ``_shape``/``low``/``high``, the action space, ``use_sde`` and the
  ``policy_kwargs`` of :data:`POLICY_KWARGS`, an activation function named in
  :data:`ACTIVATIONS`) as SB3's ``ActorCriticPolicy`` (PPO's ``MlpPolicy``) or
  ``SACPolicy`` (SAC's), and loads ``policy.pth`` with
  ``torch.load(weights_only=True)`` and ``load_state_dict(strict=True)``.

Anything else (a member too large, another policy class or features extractor, missing
or extra weights, weights of other shapes) is one :class:`ControllerError` line.

:class:`SB3Agent` maps states (n, 2N) to torques (n, N) as the training environment
(:class:`twolink.envs.sb3.TwoLinkSB3VecEnv`, ``actions='normalized'``) does: the policy's
deterministic action on the features of the states (:func:`twolink.arm.observations.features`:
``'cos_sin'``, 3N numbers, or ``'state'``, 2N, by the saved space's size; with a
``history`` K > 1 in ``twolink.json`` the last K of them and K - 1 actions,
:mod:`twolink.control.history`, reset by ``reset(n)``), clipped to [-1, 1], times its
recorded ``action_gain`` (:mod:`twolink.control.action_gain`), scaled to +-tau_max and
added to a ``base`` controller's torques where one is named (:mod:`twolink.control.residual`).
N is the size of the saved action space (2 to 6); an agent of N > 2 links names its link
rule in ``twolink.json`` (:mod:`twolink.control.agent_meta`), whose ``links`` must agree
with the spaces; tau_max is that of :func:`twolink.arm.parameters.links_parameters`
(Table I's for two links). SB3 is imported only when an agent is built (without it, one
line naming the rl extras). ``meta`` holds the algorithm, seed, steps, base, gain and
file; no ``"model"`` (nothing for a compensator to predict with: plain rows only).
"""
from __future__ import annotations

import io
import json
import math
import re
import warnings
import zipfile
import zlib
from pathlib import Path

import numpy as np

from twolink.arm.observations import features
from twolink.arm.parameters import MAX_LINKS, MIN_LINKS, TABLE_I, links_parameters
from twolink.control.action_gain import agent_action_gain, gained
from twolink.control.agent_meta import AGENT_MEMBER, agent_arm, agent_observation
from twolink.control.history import ObservationHistory
from twolink.control.residual import agent_base, residual_torques
from twolink.sim.controller import ControllerError

#: Attributes only each algorithm's save holds (in its ``data`` JSON).
SIGNATURES = {"ppo": ("n_epochs", "clip_range", "gae_lambda"),
              "sac": ("target_entropy", "replay_buffer_class", "ent_coef")}
#: The message of a missing Stable-Baselines3.
NEEDS_RL = "needs the rl extras: pip install 'twolink[rl]'"
#: The most bytes a member, and all members together, may inflate to (agents: 0.2-2 MB).
MAX_BYTES = 32 * 2**20
#: The most members a save may hold (SB3 writes six to eight).
MAX_MEMBERS = 64
#: The members read (the optimizer states and the rest are never read).
READ = ("data", "policy.pth")
#: Activation functions (``torch.nn`` class names) a save's ``activation_fn`` may name.
ACTIVATIONS = ("Tanh", "ReLU", "ELU", "LeakyReLU", "GELU", "SiLU", "Mish", "SELU",
               "CELU", "Sigmoid", "Softplus", "ReLU6", "Hardtanh")
#: The ``policy_kwargs`` rebuilt per algorithm, with the JSON type each must have.
POLICY_KWARGS = {
    "ppo": {"net_arch": "arch", "activation_fn": "activation", "ortho_init": bool,
            "log_std_init": float, "full_std": bool, "use_expln": bool,
            "squash_output": bool, "share_features_extractor": bool,
            "normalize_images": bool},
    "sac": {"net_arch": "arch", "activation_fn": "activation", "use_sde": bool,
            "log_std_init": float, "use_expln": bool, "clip_mean": float,
            "n_critics": int, "share_features_extractor": bool, "normalize_images": bool},
}
#: ``policy_kwargs`` that do not change the actions (the optimizer, the default features
#: extractor), skipped when they hold their readable default.
IGNORED_KWARGS = {"optimizer_class": None, "optimizer_kwargs": None, "device": None,
                  "features_extractor_class":
                      "<class 'stable_baselines3.common.torch_layers.FlattenExtractor'>",
                  "features_extractor_kwargs": {}}
#: The policy class SB3's ``MlpPolicy`` is for each algorithm.
POLICY_CLASSES = {"ppo": "ActorCriticPolicy", "sac": "SACPolicy"}


def _line(text, limit: int = 160) -> str:
    """``text`` on one line, at most ``limit`` characters."""
    text = " ".join(str(text).split())
    return text if len(text) <= limit else text[:limit - 3] + "..."


def read_save(path, members=READ, optional=()) -> dict:
    """``{name: bytes}`` of the ``members`` of the SB3 save at ``path`` (and of those of
    ``optional`` it holds), read only after every member's declared size and their total
    are within :data:`MAX_BYTES`; a one-line ControllerError when the file is missing, not
    a zip, too large, or lacks a member."""
    path = Path(path)
    if not path.is_file():
        raise ControllerError(f"agent file {path} does not exist")
    try:
        z = zipfile.ZipFile(path)
    except (zipfile.BadZipFile, zipfile.LargeZipFile, OSError, ValueError):
        raise ControllerError(f"{path} is not a zip file (a Stable-Baselines3 save is one)") \
            from None
    with z:
        infos = z.infolist()
        if len(infos) > MAX_MEMBERS:
            raise ControllerError(f"{path} holds {len(infos)} members, more than "
                                  f"{MAX_MEMBERS}; a Stable-Baselines3 save holds a few")
        for info in infos:
            if info.file_size > MAX_BYTES:
                raise ControllerError(f"{path}: member {_line(info.filename, 60)!r} inflates "
                                      f"to {info.file_size:,} bytes, more than the "
                                      f"{MAX_BYTES:,} a saved agent may hold")
        total = sum(info.file_size for info in infos)
        if total > MAX_BYTES:
            raise ControllerError(f"{path}: its members inflate to {total:,} bytes, more "
                                  f"than the {MAX_BYTES:,} a saved agent may hold")
        names = {info.filename for info in infos}
        if not all(m in names for m in members):
            raise ControllerError(f"{path} is not a Stable-Baselines3 save (the zip holds no "
                                  f"{' and '.join(members)})")
        return {m: _read_member(z, path, m) for m in (*members, *optional) if m in names}


def _read_member(z: zipfile.ZipFile, path: Path, name: str) -> bytes:
    """The bytes of member ``name`` (stored or deflated), read in chunks, never more than
    :data:`MAX_BYTES`."""
    info = z.getinfo(name)
    if info.compress_type not in (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED):
        raise ControllerError(f"{path}: member {name!r} is compressed with method "
                              f"{info.compress_type}; a Stable-Baselines3 save stores its "
                              f"members (or deflates them)")
    chunks, size = [], 0
    try:
        with z.open(info) as f:
            while True:
                chunk = f.read(2**20)
                if not chunk:
                    break
                size += len(chunk)
                if size > MAX_BYTES:
                    raise ControllerError(f"{path}: member {name!r} inflates to more than "
                                          f"the {MAX_BYTES:,} bytes a saved agent may hold")
                chunks.append(chunk)
    except ControllerError:
        raise
    except (zipfile.BadZipFile, zlib.error, RuntimeError, OSError, EOFError,
            NotImplementedError) as exc:
        raise ControllerError(f"{path}: member {name!r} cannot be read: "
                              f"{_line(exc, 100)}") from None
    return b"".join(chunks)


def _parse_data(raw: bytes, path) -> dict:
    """The ``data`` member parsed as plain JSON (nothing unpickled)."""
    try:
        data = json.loads(raw)
    except (ValueError, UnicodeDecodeError, RecursionError):
        raise ControllerError(f"{path} is not a Stable-Baselines3 save (its data is not "
                              f"JSON)") from None
    if not isinstance(data, dict):
        raise ControllerError(f"{path} is not a Stable-Baselines3 save (its data is not a "
                              f"dict)")
    return data


def saved_data(path) -> dict:
    """The ``data`` JSON of the SB3 save at ``path``, parsed as plain JSON (its
    ``":serialized:"`` blobs stay base64 text, never unpickled); one-line ControllerError
    when the file is missing, too large, not a zip, or not an SB3 save."""
    return _parse_data(read_save(path, ("data", "policy.pth"))["data"], path)


def _algorithm(data: dict, path) -> str:
    found = [algo for algo, keys in SIGNATURES.items() if all(k in data for k in keys)]
    if len(found) != 1:
        raise ControllerError(f"{path} is a Stable-Baselines3 save of neither PPO nor SAC; "
                              f"the leaderboard runs those two")
    return found[0]


def sb3_algorithm(path) -> str:
    """``'ppo'`` or ``'sac'``: the algorithm of the SB3 save at ``path``, from the
    attributes its data holds (:data:`SIGNATURES`); a one-line ControllerError otherwise."""
    return _algorithm(saved_data(path), path)


def _numbers(text, path, what: str) -> np.ndarray:
    """The numbers of a readable numpy array (``'[-1. -1.]'``), one dimension."""
    if not isinstance(text, str) or not (text.strip().startswith("[")
                                          and text.strip().endswith("]")):
        raise ControllerError(f"{path}: its data holds no readable {what}")
    try:
        return np.array([float(t) for t in text.strip()[1:-1].split()], dtype=float)
    except ValueError:
        raise ControllerError(f"{path}: its data's {what} {_line(text, 60)!r} is not a "
                              f"list of numbers") from None


def _space(data: dict, key: str, path) -> tuple:
    """(shape, low, high, dtype) of the Box ``data[key]``, from its readable fields."""
    space = data.get(key)
    shape = space.get("_shape") if isinstance(space, dict) else None
    if not (isinstance(shape, list) and len(shape) == 1 and isinstance(shape[0], int)
            and not isinstance(shape[0], bool) and 1 <= shape[0] <= 512):
        raise ControllerError(f"{path}: its data's {key} is no readable one-dimensional Box "
                              f"(shape {_line(shape, 40)})")
    low = _numbers(space.get("low"), path, f"{key} low")
    high = _numbers(space.get("high"), path, f"{key} high")
    dtype = space.get("dtype")
    if low.shape != tuple(shape) or high.shape != tuple(shape) or \
            dtype not in ("float32", "float64") or np.any(np.isnan(low) | np.isnan(high)) \
            or np.any(low > high):
        raise ControllerError(f"{path}: its data's {key} is no readable Box of shape "
                              f"{tuple(shape)} (low, high, dtype float32 or float64)")
    return tuple(shape), low, high, dtype


def _observation(data: dict, path, links: int, extra) -> tuple:
    """(history K, observation) from the saved space's size and the ``twolink.json``
    member (:func:`twolink.control.agent_meta.agent_observation`)."""
    space = data.get("observation_space")
    shape = space.get("_shape") if isinstance(space, dict) else None
    size = shape[0] if isinstance(shape, list) and len(shape) == 1 else shape
    return agent_observation(path, extra, size, links)


def _action_space(data: dict, path) -> tuple:
    """(low, high, dtype) of the saved action space, which must be a Box [-1, 1]^N with
    N from 2 to 6 (the arm's links)."""
    shape, low, high, dtype = _space(data, "action_space", path)
    if not MIN_LINKS <= shape[0] <= MAX_LINKS or \
            not (np.all(low == -1.0) and np.all(high == 1.0)):
        raise ControllerError(f"{path}: the agent's actions are a Box of shape {shape} from "
                              f"{low.tolist()} to {high.tolist()}; the controller runs "
                              f"normalized actions, a Box [-1, 1]^N of N = {MIN_LINKS} to "
                              f"{MAX_LINKS} links")
    return low, high, dtype


def _arch(value, path, keys) -> dict:
    """``net_arch`` (a list of widths, or a dict of them under ``keys``) as that dict."""
    if isinstance(value, list) and value and isinstance(value[0], dict):
        value = value[0]                      # SB3 < 1.8's [dict(pi=..., vf=...)]

    def widths(w):
        if not (isinstance(w, list) and len(w) <= 64 and all(
                isinstance(n, int) and not isinstance(n, bool) and 1 <= n for n in w)):
            raise ControllerError(f"{path}: its policy_kwargs net_arch {_line(value, 60)} is "
                                  f"not a list of layer widths (or a dict of them under "
                                  f"{' and '.join(keys)})")
        return list(w)

    if isinstance(value, dict):
        if not set(value) <= set(keys):
            raise ControllerError(f"{path}: its policy_kwargs net_arch has the keys "
                                  f"{sorted(value)}; give {' and '.join(keys)}")
        return {k: widths(value.get(k, [])) for k in keys}
    w = widths(value)
    return {k: w for k in keys}


def _activation(value, path):
    """The ``torch.nn`` class a readable ``activation_fn`` names, if in :data:`ACTIVATIONS`."""
    import torch

    m = re.fullmatch(r"<class 'torch\.nn\.modules\.activation\.(\w+)'>", str(value))
    if m is None or m.group(1) not in ACTIVATIONS:
        raise ControllerError(f"{path}: its activation function {_line(value, 60)} is none "
                              f"of torch.nn's {', '.join(ACTIVATIONS)}")
    return getattr(torch.nn, m.group(1))


def _policy_kwargs(data: dict, algo: str, path) -> dict:
    """The keyword arguments of the policy, from the readable ``policy_kwargs``."""
    raw = data.get("policy_kwargs")
    if raw is None:
        raw = {}
    if not isinstance(raw, dict):
        raise ControllerError(f"{path}: its data's policy_kwargs is not a dict")
    allowed = POLICY_KWARGS[algo]
    out = {}
    for key, value in raw.items():
        if key.startswith(":"):               # the pickled blob and its type: never read
            continue
        if key in IGNORED_KWARGS and IGNORED_KWARGS[key] in (None, value):
            continue
        kind = allowed.get(key)
        if kind is None:
            raise ControllerError(f"{path}: its policy_kwargs set {key!r}, which this loader "
                                  f"does not rebuild (it rebuilds {', '.join(allowed)})")
        if kind == "arch":
            out[key] = _arch(value, path, ("pi", "vf") if algo == "ppo" else ("pi", "qf"))
        elif kind == "activation":
            out[key] = _activation(value, path)
        elif kind is float:
            if isinstance(value, bool) or not isinstance(value, (int, float)) or \
                    not math.isfinite(value):
                raise ControllerError(f"{path}: its policy_kwargs {key} is "
                                      f"{_line(value, 40)}, not a number")
            out[key] = float(value)
        elif kind is int:
            if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= 16:
                raise ControllerError(f"{path}: its policy_kwargs {key} is "
                                      f"{_line(value, 40)}, not a whole number from 1 to 16")
            out[key] = value
        elif not isinstance(value, bool):
            raise ControllerError(f"{path}: its policy_kwargs {key} is {_line(value, 40)}, "
                                  f"not true or false")
        else:
            out[key] = value
    return out


def _parameter_count(algo: str, n_obs: int, kwargs: dict, n_act: int = 2) -> int:
    """How many weights the policy of these kwargs has (about: its linear layers)."""
    default = [64, 64] if algo == "ppo" else [256, 256]
    arch = kwargs.get("net_arch") or {k: default for k in
                                      (("pi", "vf") if algo == "ppo" else ("pi", "qf"))}

    def mlp(n_in, widths, n_out):
        sizes = [n_in, *widths, n_out]
        return sum(a * b + b for a, b in zip(sizes, sizes[1:]))

    if algo == "ppo":
        return mlp(n_obs, arch["pi"], n_act) + mlp(n_obs, arch["vf"], 1)
    return mlp(n_obs, arch["pi"], 2 * n_act) + 2 * kwargs.get("n_critics", 2) * mlp(
        n_obs + n_act, arch["qf"], 1)


def _policy_class(data: dict, algo: str, path) -> None:
    """Refuse a save whose readable policy class is not the algorithm's MLP policy."""
    init = (data.get("policy_class") or {}).get("__init__") \
        if isinstance(data.get("policy_class"), dict) else None
    if init is None:
        return
    m = re.match(r"<function (\w+)\.__init__ ", str(init))
    if m is None or m.group(1) != POLICY_CLASSES[algo]:
        name = m.group(1) if m else _line(init, 40)
        raise ControllerError(f"{path}: its policy is {name}; the loader rebuilds "
                              f"{algo.upper()}'s MlpPolicy ({POLICY_CLASSES[algo]})")


def load_policy(path, data: dict, algo: str, weights: bytes):
    """The SB3 policy of the save at ``path`` (its parsed ``data``, algorithm ``algo``
    and ``policy.pth`` bytes), rebuilt from the readable fields and loaded with
    ``torch.load(weights_only=True)`` and ``load_state_dict(strict=True)``, in evaluation
    mode on the CPU. Needs SB3 (imported here); one-line ControllerError for anything
    that does not fit."""
    import torch
    from gymnasium import spaces

    _policy_class(data, algo, path)
    shape, low, high, dtype = _space(data, "observation_space", path)
    a_low, a_high, a_dtype = _action_space(data, path)
    n_act = len(a_low)
    kwargs = _policy_kwargs(data, algo, path)
    if algo == "ppo":
        use_sde = data.get("use_sde", False)
        if not isinstance(use_sde, bool):
            raise ControllerError(f"{path}: its use_sde is {_line(use_sde, 40)}, not true "
                                  f"or false")
        kwargs["use_sde"] = use_sde
    count = _parameter_count(algo, shape[0], kwargs, n_act)
    if count > MAX_BYTES // 4:
        raise ControllerError(f"{path}: its net_arch asks for about {count:,} weights, more "
                              f"than a policy.pth of {MAX_BYTES:,} bytes holds")
    try:
        with warnings.catch_warnings():        # torch's notes on odd pickles: the error says it
            warnings.simplefilter("ignore")
            state = torch.load(io.BytesIO(weights), weights_only=True, map_location="cpu")
    except Exception as exc:
        raise ControllerError(f"{path}: its policy.pth is no weights-only torch file: "
                              f"{type(exc).__name__}: {_line(exc, 100)}") from None
    if not (isinstance(state, dict) and all(isinstance(k, str) and isinstance(v, torch.Tensor)
                                            for k, v in state.items())):
        raise ControllerError(f"{path}: its policy.pth is not a state dict of tensors")
    if algo == "ppo":
        from stable_baselines3.common.policies import ActorCriticPolicy as policy_class
    else:
        from stable_baselines3.sac.policies import SACPolicy as policy_class
    observation_space = spaces.Box(low.astype(dtype), high.astype(dtype), shape, dtype=dtype)
    action_space = spaces.Box(a_low.astype(a_dtype), a_high.astype(a_dtype), (n_act,),
                              dtype=a_dtype)
    try:
        policy = policy_class(observation_space, action_space, lambda _: 0.0, **kwargs)
    except Exception as exc:
        raise ControllerError(f"{path}: cannot rebuild its {algo.upper()} policy: "
                              f"{type(exc).__name__}: {_line(exc, 100)}") from None
    expected = policy.state_dict()
    missing = [k for k in expected if k not in state]
    extra = [k for k in state if k not in expected]
    shapes = [f"{k} {tuple(state[k].shape)} not {tuple(v.shape)}" for k, v in expected.items()
              if k in state and state[k].shape != v.shape]
    if missing or extra or shapes:
        parts = [f"{label} {', '.join(items[:2])}" + (f" (+{len(items) - 2})"
                                                       if len(items) > 2 else "")
                 for label, items in (("shapes", shapes), ("missing", missing),
                                      ("unexpected", extra)) if items]
        raise ControllerError(f"{path}: its policy.pth does not fit the policy its data "
                              f"describes: {_line('; '.join(parts), 240)}")
    try:
        policy.load_state_dict(state, strict=True)
    except Exception as exc:
        raise ControllerError(f"{path}: cannot load its policy.pth: {type(exc).__name__}: "
                              f"{_line(exc, 100)}") from None
    policy.set_training_mode(False)
    return policy


def model_torques(model, x, observation: str, tau_max) -> np.ndarray:
    """Torques (..., N) of an SB3 ``model`` or policy (in memory) at states x (..., 2N):
    its deterministic action on the features ``observation`` of x
    (:func:`twolink.arm.observations.features`), clipped to [-1, 1] and scaled to
    +-``tau_max``."""
    obs = features(np.asarray(x, dtype=float), observation)
    action, _ = model.predict(obs, deterministic=True)
    return np.clip(np.asarray(action, dtype=float), -1.0, 1.0) * np.asarray(tau_max, dtype=float)


class SB3Agent:
    """The SB3 agent saved at ``path`` as a controller: states (n, 2N) -> torques (n, N)
    (see the module docstring); ``name`` the file's stem unless given. Its ``policy`` is
    the rebuilt SB3 policy (:func:`load_policy`), ``links`` N and ``rule`` the link rule
    (None for two links). ``params`` (two links only) replaces Table I's tau_max."""

    def __init__(self, path, *, name: str | None = None, params=None):
        path = Path(path)
        members = read_save(path, optional=(AGENT_MEMBER,))
        data = _parse_data(members["data"], path)
        self.algo = _algorithm(data, path)
        self.links, self.rule = agent_arm(path, len(_action_space(data, path)[0]),
                                          members.get(AGENT_MEMBER))
        if params is None:
            params = TABLE_I if self.links == 2 else links_parameters(self.links, self.rule)
        elif params.links != self.links:
            raise ControllerError(f"{path}: a {self.links}-link agent given the parameters "
                                  f"of {params.links} links")
        self.history, self.observation = _observation(data, path, self.links,
                                                      members.get(AGENT_MEMBER))
        self._buffer = None
        try:
            import stable_baselines3 as sb3
        except ImportError:
            raise ControllerError(f"controller {path.name} {NEEDS_RL}") from None
        self.policy = load_policy(path, data, self.algo, members["policy.pth"])
        self.tau_max = np.asarray(params.tau_max, dtype=float)
        self.base_name, self.base = agent_base(path, members.get(AGENT_MEMBER), params)
        self.action_gain = agent_action_gain(path, members.get(AGENT_MEMBER))
        self.name, self.path = name or path.stem, path
        self.meta = {"algo": self.algo, "seed": data.get("seed"),
                     "steps": data.get("num_timesteps"), "observation": self.observation,
                     "links": self.links, "rule": self.rule, "history": self.history,
                     "base": self.base_name, "action_gain": self.action_gain,
                     "file": str(path), "stable_baselines3": sb3.__version__}

    def __call__(self, x) -> np.ndarray:
        """Torques (..., N) of states x (..., 2N): the clipped deterministic action times
        the action gain, clipped, scaled to +-tau_max (plus the base's torques, clipped)."""
        x = np.asarray(x, dtype=float)
        if x.shape[-1:] != (2 * self.links,):
            raise ValueError(f"a {self.links}-link agent maps states (..., {2 * self.links}) "
                             f"to torques, got states of shape {x.shape}")
        if self.history == 1:       # the clipped action (tau_max 1)
            a = model_torques(self.policy, x, self.observation, 1.0)
        else:
            obs = features(x, self.observation).reshape(x.size // x.shape[-1], -1)
            if self._buffer is None or self._buffer.rows != len(obs):
                self.reset(len(obs))
            action, _ = self.policy.predict(self._buffer.observe(obs), deterministic=True)
            a = np.clip(np.asarray(action, dtype=float), -1.0, 1.0)
            self._buffer.act(a)
            a = a.reshape(x.shape[:-1] + (-1,))
        return residual_torques(self.base, x, gained(a, self.action_gain), self.tau_max)

    def reset(self, n: int) -> None:
        """Start ``n`` rows afresh: with a history K > 1, its buffers of zeros."""
        if self.history > 1:
            d = 3 * self.links if self.observation == "cos_sin" else 2 * self.links
            self._buffer = ObservationHistory(int(n), d, self.links, self.history)

    def __reduce__(self):
        """Pickled as its file and name (a worker loads the file again)."""
        return (sb3_agent, (str(self.path), self.name))


def sb3_agent(path, name: str | None = None) -> SB3Agent:
    """The controller of the SB3 agent saved at ``path`` (see :class:`SB3Agent`)."""
    return SB3Agent(path, name=name)
